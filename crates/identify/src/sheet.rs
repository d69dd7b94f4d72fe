//! Writing sheets with new values: copies of the actuator sheet and its component sheets, the chosen keys
//! replaced in place (comments and layout kept, `toml_edit`), the components named by their new file
//! names, a comment on top saying where the values came from. The result has the same schema and is
//! loaded back (`ActuatorSheet::load`) before it counts as written.

use std::path::{Path, PathBuf};

use pneuflex_pneumatics::ActuatorSheet;
use toml_edit::{DocumentMut, Item, Table, value};

use crate::IdentifyError;
use crate::params::Key;

/// The `[components]` keys of an actuator sheet.
const COMPONENTS: [&str; 5] = [
    "cylinder",
    "valve",
    "supply",
    "pressure_sensor",
    "position_sensor",
];

fn read(path: &Path) -> Result<String, IdentifyError> {
    pneuflex_files::read_text(path, pneuflex_files::InputKind::Sheet)
        .map_err(|e| IdentifyError::Input(e.to_string()))
}

fn parse(path: &Path, text: &str) -> Result<DocumentMut, IdentifyError> {
    text.parse::<DocumentMut>()
        .map_err(|e| IdentifyError::Output {
            file: path.to_path_buf(),
            message: format!("cannot edit: {e}"),
        })
}

fn write(path: &Path, text: &str) -> Result<(), IdentifyError> {
    std::fs::write(path, text).map_err(|e| IdentifyError::Output {
        file: path.to_path_buf(),
        message: format!("cannot write: {e}"),
    })
}

/// Sets the dotted key `name` (`valve.paths.supply_a.critical_pressure_ratio`) to `v`, creating the tables
/// on the way (the intermediate ones implicit, so that only `[valve.paths.supply_a]` is written).
fn set_dotted(doc: &mut DocumentMut, name: &str, v: f64) {
    let parts: Vec<&str> = name.split('.').collect();
    let (last, tables) = parts.split_last().unwrap_or((&name, &[]));
    let mut item = doc.as_item_mut();
    for (i, t) in tables.iter().enumerate() {
        if item.get(t).is_none()
            && let Some(tl) = item.as_table_like_mut()
        {
            // A `[a.b]` table, not an inline one; the ones on the way implicit (no empty header).
            let mut new = Table::new();
            new.set_implicit(i + 1 < tables.len());
            tl.insert(t, Item::Table(new));
        }
        item = &mut item[*t];
    }
    item[*last] = value(v);
}

/// Writes the sheet set of `src` into the existing directory `dir` with `values` (sensor offsets are left
/// out: they are not sheet keys) and `header` (each line becomes a `#` comment) on top of the actuator
/// sheet. Returns the new actuator sheet's path.
pub fn write_sheets(
    src: &ActuatorSheet,
    values: &[(Key, f64)],
    dir: &Path,
    header: &str,
) -> Result<PathBuf, IdentifyError> {
    write_sheets_with(src, values, &[], dir, header)
}

/// [`write_sheets`] with `mechanics` edits of the actuator sheet's `[mechanics]` table too: a key set to a
/// value (`friction = "lugre"`), or removed (None): another friction law and its keys.
pub fn write_sheets_with(
    src: &ActuatorSheet,
    values: &[(Key, f64)],
    mechanics: &[(&str, Option<toml_edit::Value>)],
    dir: &Path,
    header: &str,
) -> Result<PathBuf, IdentifyError> {
    let src_dir = src.path.parent().unwrap_or_else(|| Path::new(""));
    let text = read(&src.path)?;
    let mut doc = parse(&src.path, &text)?;
    let mut used_names: Vec<String> = Vec::new();
    let act_name = src
        .path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "actuator.toml".into());
    used_names.push(act_name.clone());
    for comp in COMPONENTS {
        let Some(rel) = doc
            .get("components")
            .and_then(|c| c.get(comp))
            .and_then(|v| v.as_str())
            .map(str::to_string)
        else {
            continue;
        };
        let from = src_dir.join(&rel);
        let ctext = read(&from)?;
        let mut cdoc = parse(&from, &ctext)?;
        for &(k, v) in values {
            if k.file() == Some(comp) {
                set_dotted(&mut cdoc, k.name(), v);
            }
        }
        let mut name = Path::new(&rel)
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_else(|| format!("{comp}.toml"));
        if used_names.contains(&name) {
            name = format!("{comp}-{name}");
        }
        used_names.push(name.clone());
        write(&dir.join(&name), &cdoc.to_string())?;
        doc["components"][comp] = value(name);
    }
    for (k, v) in mechanics {
        if let Some(t) = doc.get_mut("mechanics").and_then(Item::as_table_like_mut) {
            match v {
                Some(v) => {
                    t.insert(k, Item::Value(v.clone()));
                }
                None => {
                    t.remove(k);
                }
            }
        }
    }
    for &(k, v) in values {
        if k.file() == Some("actuator") {
            set_dotted(&mut doc, k.name(), v);
        }
    }
    let mut out = String::new();
    for line in header.lines() {
        out.push_str("# ");
        out.push_str(line);
        out.push('\n');
    }
    out.push_str(&doc.to_string());
    let dest = dir.join(&act_name);
    write(&dest, &out)?;
    // Same schema: it must load.
    ActuatorSheet::load(&dest)?;
    Ok(dest)
}
