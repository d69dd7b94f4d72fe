//! Hidden truths for tests and demonstrations: the shipped sheet with chosen parameters each moved by
//! 20-40 % up or down (seeded), written as a sheet set with [`crate::sheet::write_sheets`].

use std::path::{Path, PathBuf};

use pneuflex_pneumatics::ActuatorSheet;

use crate::IdentifyError;
use crate::params::{Key, Offsets};

/// One perturbed parameter.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Perturbed {
    /// Which parameter.
    pub key: Key,
    /// The shipped value.
    pub shipped: f64,
    /// The truth.
    pub truth: f64,
}

/// splitmix64: deterministic pseudo-random words from a seed.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    fn uniform(&mut self) -> f64 {
        (self.next() >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// The factors: each key's value times `1 +- f`, f uniform in [lo, hi] (sign at random), for `seed`.
pub fn factors(keys: &[Key], seed: u64, lo: f64, hi: f64) -> Vec<f64> {
    let mut r = Rng(seed);
    keys.iter()
        .map(|_| {
            let f = lo + (hi - lo) * r.uniform();
            if r.next() & 1 == 0 { 1.0 + f } else { 1.0 - f }
        })
        .collect()
}

/// Writes into `dir` (created if missing) a copy of the sheet `src` with `keys` moved by 20-40 % each (seeded; sensor offsets
/// cannot be perturbed this way and are refused). Returns the new actuator sheet and what changed.
pub fn perturb(
    src: &Path,
    keys: &[Key],
    seed: u64,
    dir: &Path,
) -> Result<(PathBuf, Vec<Perturbed>), IdentifyError> {
    let sheet = ActuatorSheet::load(src)?;
    let model = sheet.model();
    let off = Offsets::default();
    let f = factors(keys, seed, 0.2, 0.4);
    let mut changes = Vec::new();
    for (k, f) in keys.iter().zip(f) {
        k.applies(&model).map_err(|m| IdentifyError::Key {
            option: "--keys",
            key: k.name().into(),
            message: m,
        })?;
        if k.file().is_none() {
            return Err(IdentifyError::Key {
                option: "--keys",
                key: k.name().into(),
                message: "a sensor offset is not a sheet key".into(),
            });
        }
        let shipped = k.get(&model, &off);
        // The polytropic exponent moves its distance from isothermal (n - 1), towards isothermal: 20-40 %
        // of 1.4 either way would leave the sheet's range [1, 1.67] or be no gas at all.
        let truth = if *k == Key::PolytropicExponent {
            1.0 + (shipped - 1.0) * (1.0 - (f - 1.0).abs())
        } else {
            shipped * f
        };
        changes.push(Perturbed {
            key: *k,
            shipped,
            truth,
        });
    }
    let header = format!(
        "HIDDEN TRUTH for identification tests: {} perturbed by 20-40 % (seed {seed}) from {}",
        keys.iter().map(|k| k.name()).collect::<Vec<_>>().join(", "),
        src.display()
    );
    let values: Vec<(Key, f64)> = changes.iter().map(|c| (c.key, c.truth)).collect();
    std::fs::create_dir_all(dir).map_err(|e| IdentifyError::Output {
        file: dir.to_path_buf(),
        message: format!("cannot create: {e}"),
    })?;
    let path = crate::sheet::write_sheets(&sheet, &values, dir, &header)?;
    Ok((path, changes))
}
