//! `pneuflex perturb`: a hidden truth for tests and demonstrations, the sheet with chosen keys moved
//! (crates/identify/src/perturb.rs), written with `truth.json`.

use std::path::Path;

use anyhow::{Context, bail};
use pneuflex_files::OutputDir;
use pneuflex_files::output::{Manifest, Writer};
use pneuflex_identify::params::Key;

/// `pneuflex perturb --actuator S --keys K,... --seed N --out DIR`: a hidden truth for tests, written with
/// `truth.json` (shipped and perturbed value per key). DIR must not exist; it is staged beside and renamed
/// into place, so a refused value leaves nothing behind.
pub fn perturb(actuator: &Path, keys: &[String], seed: u64, out: &Path) -> anyhow::Result<()> {
    let mut ks: Vec<Key> = Vec::new();
    for k in keys.iter().flat_map(|k| k.split(',')).map(str::trim) {
        if k.is_empty() {
            continue;
        }
        let key = Key::parse(k).with_context(|| {
            format!(
                "--keys: {k}: no such parameter; the keys are {}",
                pneuflex_identify::params::ALL
                    .iter()
                    .map(|k| k.name())
                    .collect::<Vec<_>>()
                    .join(", ")
            )
        })?;
        if ks.contains(&key) {
            bail!(
                "--keys: {k}: given twice (as `{}`): one key, one truth",
                key.name()
            );
        }
        ks.push(key);
    }
    if ks.is_empty() {
        bail!("--keys: no parameter to perturb");
    }
    if std::fs::symlink_metadata(out).is_ok() {
        bail!(
            "{}: exists; perturb writes a new directory and replaces nothing",
            out.display()
        );
    }
    let stage = OutputDir::create(out, &[actuator], Writer::simulation("perturb"))?;
    let (sheet, changes) = pneuflex_identify::perturb::perturb(actuator, &ks, seed, stage.path())?;
    let table: Vec<serde_json::Value> = changes
        .iter()
        .map(|c| serde_json::json!({"key": c.key.name(), "shipped": c.shipped, "truth": c.truth}))
        .collect();
    let json = stage.path().join("truth.json");
    std::fs::write(&json, serde_json::to_string_pretty(&table)?)
        .with_context(|| format!("{}: cannot write", json.display()))?;
    let inputs = vec![pneuflex_files::InputDigest::of_file(actuator, "actuator")?];
    let dest = stage.commit(Manifest::new("perturb", env!("CARGO_PKG_VERSION"), inputs))?;
    let sheet = dest.join(sheet.file_name().unwrap_or_default());
    outln!(
        "hidden truth: {} (values in {})",
        sheet.display(),
        dest.join("truth.json").display()
    );
    Ok(())
}
