//! Key paths and values, and how they are written into a copy of a scene (or of its actuator sheet).
//!
//! A scene key is spelt as the scene's errors spell it: dotted names, an array element by index or, for
//! arrays of tables with a `name` (runs, metrics, materials, claims), by name: `environment.stiffness_n_per_m`,
//! `runs[adaptive].inner.kp_per_m`, `runs[1].inner.kp_per_m`, `events[0].stiffness_n_per_m`,
//! `plant.materials[iron].stiffness_n_per_m`; `[*]` sets every element (`runs[*].inner.kp_per_m`). A value of a file the scene names is reached through the key
//! that names it, a colon, then the key inside that file: `plant.actuator:mechanics.moving_mass_kg` (the
//! actuator sheet), `plant.actuator:components.valve:valve.sonic_conductance_m3_per_s_pa` (the valve sheet
//! the actuator sheet names). The edit is made on the file's text (toml_edit keeps every other line, comment
//! and position as written), and the scene's own parser and validation then judge the result.

use std::fmt;
use std::path::{Path, PathBuf};

use toml_edit::{DocumentMut, Item, Value as TValue};

/// A value written at a key: the spelling of the spec decides integer, float, boolean or string.
#[derive(Clone, Debug, PartialEq)]
pub enum Value {
    /// An integer literal (`10`).
    Int(i64),
    /// A number (`0.5`, `1e-3`, or a value of a range).
    Float(f64),
    /// `true` / `false`.
    Bool(bool),
    /// Anything else, written as a TOML string.
    Str(String),
}

impl Value {
    /// Reads one value of a list spec: integer, float, boolean, else a string (quotes optional).
    pub fn parse(token: &str) -> Value {
        let t = token.trim();
        if let Ok(i) = t.parse::<i64>() {
            return Value::Int(i);
        }
        if let Ok(x) = t.replace('_', "").parse::<f64>() {
            return Value::Float(x);
        }
        match t {
            "true" => Value::Bool(true),
            "false" => Value::Bool(false),
            _ => Value::Str(t.trim_matches('"').to_string()),
        }
    }

    /// The value as a number, when it is one.
    pub fn as_f64(&self) -> Option<f64> {
        match *self {
            Value::Int(i) => Some(i as f64),
            Value::Float(x) => Some(x),
            _ => None,
        }
    }

    /// The TOML value to write over `old` (when there is one): a float over a float stays a float even when
    /// written as an integer (`kp_per_m = 7`), an integral number over an integer stays an integer.
    fn to_toml(&self, old: Option<&TValue>) -> TValue {
        match (self, old) {
            (Value::Int(i), Some(TValue::Float(_))) => TValue::from(*i as f64),
            (Value::Float(x), Some(TValue::Integer(_))) if x.fract() == 0.0 && x.abs() < 9.0e15 => {
                TValue::from(*x as i64)
            }
            (Value::Int(i), _) => TValue::from(*i),
            (Value::Float(x), _) => TValue::from(*x),
            (Value::Bool(b), _) => TValue::from(*b),
            (Value::Str(s), _) => TValue::from(s.as_str()),
        }
    }
}

impl fmt::Display for Value {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Value::Int(i) => write!(f, "{i}"),
            Value::Float(x) => write!(f, "{x}"),
            Value::Bool(b) => write!(f, "{b}"),
            Value::Str(s) => f.write_str(s),
        }
    }
}

/// One step of a key path.
#[derive(Clone, Debug, PartialEq, Eq)]
enum Seg {
    /// A table key.
    Key(String),
    /// An array element by position.
    Index(usize),
    /// An array-of-tables element by its `name`.
    Name(String),
    /// Every element (`[*]`).
    All,
}

/// A parsed key path: the scene key, then for a file the scene names, the keys inside it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct KeyPath {
    /// As written on the command line.
    pub text: String,
    /// The parts between colons: part 0 is in the scene, part i + 1 in the file part i names.
    parts: Vec<Vec<Seg>>,
}

/// A key that cannot be applied: its text and why.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("{key}: {message}")]
pub struct KeyError {
    /// The key as written.
    pub key: String,
    /// What is wrong.
    pub message: String,
}

impl KeyError {
    /// Why the key `key` cannot be applied.
    fn of(key: &str, message: String) -> Self {
        KeyError {
            key: key.to_string(),
            message,
        }
    }
}

fn segments(key: &str, part: &str) -> Result<Vec<Seg>, KeyError> {
    let err = |m: String| KeyError::of(key, m);
    if part.is_empty() {
        return Err(err("empty key".into()));
    }
    let mut out = Vec::new();
    for word in part.split('.') {
        let (name, mut rest) = match word.find('[') {
            Some(i) => (&word[..i], &word[i..]),
            None => (word, ""),
        };
        if name.is_empty() && out.is_empty() {
            return Err(err(format!("`{word}`: a key starts with a name")));
        }
        if !name.is_empty() {
            if !name
                .chars()
                .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-')
            {
                return Err(err(format!(
                    "`{name}` is not a key name (letters, digits, `_` and `-`; `.` between keys, `[i]` or `[name]` for an element)"
                )));
            }
            out.push(Seg::Key(name.to_string()));
        } else if !word.starts_with('[') {
            return Err(err("empty key between dots".into()));
        }
        while let Some(r) = rest.strip_prefix('[') {
            let end = r
                .find(']')
                .ok_or_else(|| err(format!("`{word}`: `[` without `]`")))?;
            let inner = r[..end].trim().trim_matches('"');
            if inner.is_empty() {
                return Err(err(format!("`{word}`: empty `[]`")));
            }
            out.push(match inner.parse::<usize>() {
                Ok(i) => Seg::Index(i),
                Err(_) if inner == "*" => Seg::All,
                Err(_) => Seg::Name(inner.to_string()),
            });
            rest = &r[end + 1..];
        }
        if !rest.is_empty() {
            return Err(err(format!("`{word}`: unexpected `{rest}` after `]`")));
        }
    }
    Ok(out)
}

impl KeyPath {
    /// Parses `a.b[c].d` or `a.b:c.d` (see the module's documentation).
    pub fn parse(key: &str) -> Result<KeyPath, KeyError> {
        let key = key.trim();
        let parts = key
            .split(':')
            .map(|p| segments(key, p))
            .collect::<Result<Vec<_>, _>>()?;
        let kp = KeyPath {
            text: key.to_string(),
            parts,
        };
        if kp.parts.len() > 1 {
            // Only the actuator sheet is read through the scene's overlay (Scene::load_sheet), and the
            // component files it names through the sheet.
            // A mechanism's actuator by name or position: `actuators[left].sheet:KEY` (a sheet that
            // several actuators share changes for every one of them: the edit is the file's).
            let sheet = [Seg::Key("plant".into()), Seg::Key("actuator".into())];
            let one_of_several = matches!(
                kp.parts[0].as_slice(),
                [Seg::Key(a), Seg::Name(_) | Seg::Index(_), Seg::Key(s)] if a == "actuators" && s == "sheet"
            );
            if kp.parts[0] != sheet && !one_of_several {
                return Err(KeyError {
                    key: kp.text.clone(),
                    message: format!(
                        "`{}:` — only an actuator sheet's values can be reached through a file key: \
                         `plant.actuator:KEY` (or `actuators[NAME].sheet:KEY` in a scene with several \
                         actuators), or `plant.actuator:components.NAME:KEY` for a component sheet",
                        join(&kp.parts[0])
                    ),
                });
            }
            if kp.parts.len() > 3
                || (kp.parts.len() == 3
                    && !(kp.parts[1].len() == 2 && kp.parts[1][0] == Seg::Key("components".into())))
            {
                return Err(KeyError {
                    key: kp.text.clone(),
                    message:
                        "a component sheet is reached as `plant.actuator:components.NAME:KEY` \
                              (NAME: cylinder, valve, supply, pressure_sensor, position_sensor)"
                            .into(),
                });
            }
        }
        Ok(kp)
    }

    /// Whether the key is inside the scene file itself (not a sheet).
    pub fn in_scene(&self) -> bool {
        self.parts.len() == 1
    }
}

fn join(segs: &[Seg]) -> String {
    let mut s = String::new();
    for seg in segs {
        match seg {
            Seg::Key(k) => {
                if !s.is_empty() {
                    s.push('.');
                }
                s.push_str(k);
            }
            Seg::Index(i) => s.push_str(&format!("[{i}]")),
            Seg::Name(n) => s.push_str(&format!("[{n}]")),
            Seg::All => s.push_str("[*]"),
        }
    }
    s
}

/// A TOML file open for edits, with the text it was read from.
#[derive(Clone, Debug)]
pub struct EditableFile {
    /// The file (for messages, and the overlay's key).
    pub path: PathBuf,
    /// Its text as read.
    pub text: String,
    doc: DocumentMut,
}

impl EditableFile {
    /// Parses `text` (read from `path`).
    pub fn new(path: &Path, text: &str) -> Result<Self, KeyError> {
        let doc = text.parse::<DocumentMut>().map_err(|e| KeyError {
            key: String::new(),
            message: format!("{}: not TOML: {e}", path.display()),
        })?;
        Ok(Self {
            path: path.to_path_buf(),
            text: text.to_string(),
            doc,
        })
    }

    /// The text with the edits made so far.
    pub fn render(&self) -> String {
        self.doc.to_string()
    }

    /// The string value at `segs` (a key naming another file), if there is one.
    fn string_at(&self, segs: &[Seg]) -> Option<String> {
        // `plant.actuator`, or an element's key as in `actuators[left].sheet`.
        get_in_item(self.doc.as_item(), segs)?
            .as_str()
            .map(str::to_string)
    }

    /// The file the string at `segs` names (relative to `dir`, the folder of this file `path`); `key` is the
    /// whole key the errors name.
    fn named_file(
        &self,
        segs: &[Seg],
        path: &Path,
        dir: &Path,
        key: &KeyPath,
    ) -> Result<PathBuf, KeyError> {
        let Some(name) = self.string_at(segs) else {
            return Err(KeyError {
                key: key.text.clone(),
                message: format!(
                    "`{}` in {} does not name a file",
                    join(segs),
                    path.display()
                ),
            });
        };
        let p = Path::new(&name);
        Ok(if p.is_absolute() {
            p.to_path_buf()
        } else {
            dir.join(p)
        })
    }

    /// Writes `value` at the key path `segs`; `key` names the whole key in errors. A missing last key of an
    /// existing table is added (the scene's parser then says whether such a key exists).
    fn set(&mut self, key: &str, segs: &[Seg], value: &Value) -> Result<(), KeyError> {
        set_in_item(self.doc.as_item_mut(), key, segs, value, &[])
    }
}

fn here(walked: &[Seg]) -> String {
    if walked.is_empty() {
        "the top level".to_string()
    } else {
        format!("`{}`", join(walked))
    }
}

fn with(walked: &[Seg], seg: &Seg) -> Vec<Seg> {
    let mut v = walked.to_vec();
    v.push(seg.clone());
    v
}

fn set_in_tablelike(
    table: &mut dyn toml_edit::TableLike,
    inline: bool,
    key: &str,
    segs: &[Seg],
    value: &Value,
    walked: &[Seg],
) -> Result<(), KeyError> {
    let err = |m: String| KeyError::of(key, m);
    let Some((seg, rest)) = segs.split_first() else {
        return Err(err(format!("{} is a table, not a value", here(walked))));
    };
    let Seg::Key(k) = seg else {
        return Err(err(format!(
            "{} is a table, not an array: no `{}`",
            here(walked),
            join(std::slice::from_ref(seg))
        )));
    };
    let sub = with(walked, seg);
    if rest.is_empty() {
        match table.get_mut(k) {
            Some(Item::Value(old)) if !matches!(old, TValue::InlineTable(_) | TValue::Array(_)) => {
                let decor = old.decor().clone();
                let mut v = value.to_toml(Some(old));
                *v.decor_mut() = decor;
                *old = v;
            }
            Some(Item::None) | None => {
                let mut v = value.to_toml(None);
                if inline {
                    v.decor_mut().set_prefix(" ");
                    v.decor_mut().set_suffix(" ");
                }
                table.insert(k, Item::Value(v));
            }
            Some(_) => {
                return Err(err(format!(
                    "`{}` is a table or an array, not a value",
                    join(&sub)
                )));
            }
        }
        return Ok(());
    }
    if table.get(k).is_none() {
        // A table the file leaves out (its keys all have defaults): added, for the scene's parser to judge.
        if !matches!(rest.first(), Some(Seg::Key(_))) {
            return Err(err(format!("{} has no key `{k}`", here(walked))));
        }
        let new = if inline {
            Item::Value(TValue::InlineTable(toml_edit::InlineTable::new()))
        } else {
            let mut t = toml_edit::Table::new();
            t.set_implicit(false);
            Item::Table(t)
        };
        table.insert(k, new);
    }
    let item = table.get_mut(k).expect("present or added");
    set_in_item(item, key, rest, value, &sub)
}

fn inline_names(a: &toml_edit::Array) -> impl Iterator<Item = Option<String>> + '_ {
    a.iter().map(|v| match v {
        TValue::InlineTable(t) => t.get("name").and_then(|v| v.as_str()).map(str::to_string),
        _ => None,
    })
}

fn set_in_item(
    item: &mut Item,
    key: &str,
    segs: &[Seg],
    value: &Value,
    walked: &[Seg],
) -> Result<(), KeyError> {
    let err = |m: String| KeyError::of(key, m);
    let Some(seg) = segs.first() else {
        return Err(err(format!("{} is a table, not a value", here(walked))));
    };
    let what = join(walked);
    match (item, seg) {
        (Item::Table(t), _) => set_in_tablelike(t, false, key, segs, value, walked),
        (Item::Value(TValue::InlineTable(t)), _) => {
            set_in_tablelike(t, true, key, segs, value, walked)
        }
        (Item::ArrayOfTables(a), Seg::Index(_) | Seg::Name(_) | Seg::All) => {
            for i in element(a.iter().map(name_of_table), seg, &what).map_err(err)? {
                let t = a.get_mut(i).expect("index checked");
                let sub = with(walked, &Seg::Index(i));
                set_in_tablelike(t, false, key, &segs[1..], value, &sub)?;
            }
            Ok(())
        }
        (Item::Value(TValue::Array(a)), Seg::Index(_) | Seg::Name(_) | Seg::All) => {
            for i in element(inline_names(a), seg, &what).map_err(err)? {
                let sub = with(walked, &Seg::Index(i));
                match a.get_mut(i).expect("index checked") {
                    TValue::InlineTable(t) => {
                        set_in_tablelike(t, true, key, &segs[1..], value, &sub)?
                    }
                    old if segs.len() == 1 && !matches!(old, TValue::Array(_)) => {
                        let decor = old.decor().clone();
                        let mut v = value.to_toml(Some(old));
                        *v.decor_mut() = decor;
                        *old = v;
                    }
                    _ => {
                        return Err(err(format!(
                            "`{}` has no `{}`",
                            join(&sub),
                            join(&segs[1..])
                        )));
                    }
                }
            }
            Ok(())
        }
        (Item::ArrayOfTables(_) | Item::Value(TValue::Array(_)), Seg::Key(k)) => Err(err(format!(
            "`{what}` is an array: select an element first, `{what}[0].{k}` (or by name)"
        ))),
        (_, _) => Err(err(format!(
            "`{what}` is a value, not a table or an array: it has no `{}`",
            join(segs)
        ))),
    }
}

fn name_of_table(t: &toml_edit::Table) -> Option<String> {
    t.get("name").and_then(|i| i.as_str()).map(str::to_string)
}

/// The positions of the elements `seg` selects among `names` (each element's `name`, if it has one).
fn element(
    names: impl Iterator<Item = Option<String>>,
    seg: &Seg,
    what: &str,
) -> Result<Vec<usize>, String> {
    let names: Vec<Option<String>> = names.collect();
    match seg {
        Seg::All if names.is_empty() => Err(format!("`{what}` is empty: `[*]` selects nothing")),
        Seg::All => Ok((0..names.len()).collect()),
        Seg::Index(i) => {
            if *i < names.len() {
                Ok(vec![*i])
            } else {
                Err(format!(
                    "`{what}` has {} element(s), no [{i}] (indices start at 0)",
                    names.len()
                ))
            }
        }
        Seg::Name(n) => {
            if let Some(i) = names.iter().position(|m| m.as_deref() == Some(n)) {
                return Ok(vec![i]);
            }
            let known: Vec<&str> = names.iter().flatten().map(String::as_str).collect();
            if known.is_empty() {
                Err(format!(
                    "the elements of `{what}` have no `name`: select one by index, `{what}[0]`"
                ))
            } else {
                Err(format!(
                    "`{what}` has no element named {n:?}, expected one of {known:?} (or an index)"
                ))
            }
        }
        Seg::Key(_) => unreachable!("element() is called for [..] segments"),
    }
}

/// The value at `segs` below `item` (the first element for `[*]`), if there is one.
fn get_in_item<'a>(item: &'a Item, segs: &[Seg]) -> Option<&'a Item> {
    let Some((seg, rest)) = segs.split_first() else {
        return Some(item);
    };
    match (item, seg) {
        (_, Seg::Key(k)) => get_in_item(item.as_table_like()?.get(k)?, rest),
        (Item::ArrayOfTables(a), _) => {
            let i = *element(a.iter().map(name_of_table), seg, "")
                .ok()?
                .first()?;
            let t = a.get(i)?;
            match rest.split_first() {
                None => None,
                Some((Seg::Key(k), more)) => get_in_item(t.get(k)?, more),
                Some(_) => None,
            }
        }
        (Item::Value(TValue::Array(a)), _) => {
            let i = *element(inline_names(a), seg, "").ok()?.first()?;
            let v = a.get(i)?;
            match (v, rest.split_first()) {
                (TValue::InlineTable(t), Some((Seg::Key(k), more))) => {
                    get_in_item(t.get_key_value(k)?.1, more)
                }
                _ => None,
            }
        }
        _ => None,
    }
}

/// The concrete places `segs` names below `item`: one dotted path per value written, every array element
/// by its index (`runs[adaptive]` and `runs[1]` are the same place when run 1 is named adaptive; `[*]` is
/// every element). Keys the file leaves out are named as written.
fn places_in(item: Option<&Item>, segs: &[Seg], walked: String, out: &mut Vec<String>) {
    let Some((seg, rest)) = segs.split_first() else {
        out.push(walked);
        return;
    };
    let names: Option<Vec<Option<String>>> = match item {
        Some(Item::ArrayOfTables(a)) => Some(a.iter().map(name_of_table).collect()),
        Some(Item::Value(TValue::Array(a))) => Some(inline_names(a).collect()),
        _ => None,
    };
    match seg {
        Seg::Key(k) => {
            let sub = item.and_then(|i| i.as_table_like()).and_then(|t| t.get(k));
            let w = if walked.is_empty() {
                k.clone()
            } else {
                format!("{walked}.{k}")
            };
            places_in(sub, rest, w, out);
        }
        Seg::Index(_) | Seg::Name(_) | Seg::All => {
            let indices = names
                .and_then(|n| element(n.into_iter(), seg, "").ok())
                .unwrap_or_default();
            if indices.is_empty() {
                // Not resolvable here: the edit itself reports it; name it as written.
                places_in(
                    None,
                    rest,
                    format!("{walked}{}", join(std::slice::from_ref(seg))),
                    out,
                );
            }
            for i in indices {
                let elem = match item {
                    Some(Item::ArrayOfTables(a)) => {
                        a.get(i).map(|t| t as &dyn toml_edit::TableLike)
                    }
                    Some(Item::Value(TValue::Array(a))) => match a.get(i) {
                        Some(TValue::InlineTable(t)) => Some(t as &dyn toml_edit::TableLike),
                        _ => None,
                    },
                    _ => None,
                };
                let w = format!("{walked}[{i}]");
                match rest.split_first() {
                    None => out.push(w),
                    Some((Seg::Key(k), more)) => {
                        let sub = elem.and_then(|t| t.get(k));
                        places_in(sub, more, format!("{w}.{k}"), out);
                    }
                    Some(_) => places_in(None, rest, w, out),
                }
            }
        }
    }
}

/// The scene's text and its actuator sheet's files, with the edits of one point applied.
#[derive(Clone, Debug)]
pub struct Edited {
    /// The scene's text.
    pub scene_text: String,
    /// The edited sheet files' texts, by resolved path (a scene's overlay).
    pub overlay: pneuflex_pneumatics::FileOverlay,
}

/// A scene file and the files its keys name, ready for edits.
#[derive(Clone, Debug)]
pub struct Base {
    /// The scene file.
    pub scene: EditableFile,
    /// The folder relative paths of the scene are resolved against.
    pub base_dir: PathBuf,
}

impl Base {
    /// Reads the scene file at `path`.
    pub fn load(path: &Path) -> Result<Self, KeyError> {
        let text =
            pneuflex_files::read_text(path, pneuflex_files::InputKind::Scene).map_err(|e| {
                KeyError {
                    key: String::new(),
                    message: e.to_string(),
                }
            })?;
        Ok(Self {
            scene: EditableFile::new(path, &text)?,
            base_dir: path.parent().map(Path::to_path_buf).unwrap_or_default(),
        })
    }

    /// The number at a scene key (not a sheet key), as the file has it; None when absent or not a number.
    pub fn number(&self, key: &KeyPath) -> Option<f64> {
        if !key.in_scene() {
            return None;
        }
        let item = get_in_item(self.scene.doc.as_item(), &key.parts[0])?;
        match item {
            Item::Value(TValue::Float(f)) => Some(*f.value()),
            Item::Value(TValue::Integer(i)) => Some(*i.value() as f64),
            _ => None,
        }
    }

    /// The concrete places a key writes, each as `FILE:PATH` with every array element by index: two keys
    /// that share a place are the same key, however they are spelt (`runs[1]` and `runs[adaptive]`). A
    /// sheet key's file is the one the scene (and the sheet) names, resolved.
    pub fn places(&self, key: &KeyPath) -> Result<Vec<String>, KeyError> {
        let mut doc = self.scene.doc.clone();
        let mut file = self.scene.path.clone();
        let mut dir = self.base_dir.clone();
        for (i, part) in key.parts.iter().enumerate() {
            if i + 1 == key.parts.len() {
                let mut out = Vec::new();
                places_in(Some(doc.as_item()), part, String::new(), &mut out);
                let f = std::fs::canonicalize(&file).unwrap_or(file.clone());
                return Ok(out
                    .into_iter()
                    .map(|p| format!("{}:{p}", f.display()))
                    .collect());
            }
            let holder = EditableFile {
                path: file.clone(),
                text: String::new(),
                doc: doc.clone(),
            };
            let p = holder.named_file(part, &file, &dir, key)?;
            let text =
                pneuflex_files::read_text(&p, pneuflex_files::InputKind::Sheet).map_err(|e| {
                    KeyError {
                        key: key.text.clone(),
                        message: e.to_string(),
                    }
                })?;
            doc = EditableFile::new(&p, &text)
                .map_err(|mut e| {
                    e.key = key.text.clone();
                    e
                })?
                .doc;
            dir = p.parent().map(Path::to_path_buf).unwrap_or_default();
            file = p;
        }
        Ok(Vec::new())
    }

    /// Refuses two keys that write the same place (see [`Base::places`]): `keys` are (option, key) in the
    /// order given; the error names both spellings and the place.
    pub fn check_distinct(&self, keys: &[(&str, &KeyPath)]) -> Result<(), KeyError> {
        let mut seen: Vec<(String, usize)> = Vec::new();
        for (k, (option, key)) in keys.iter().enumerate() {
            for place in self.places(key)? {
                if let Some((_, j)) = seen.iter().find(|(p, j)| p == &place && *j != k) {
                    let (o2, k2) = keys[*j];
                    let at = place.rsplit_once(':').map_or(place.as_str(), |(_, p)| p);
                    return Err(KeyError {
                        key: key.text.clone(),
                        message: if k2.text == key.text {
                            format!("given twice ({o2} and {option})")
                        } else {
                            format!(
                                "the same key as {o2} {} (both are `{at}`): one key, one value",
                                k2.text
                            )
                        },
                    });
                }
                seen.push((place, k));
            }
        }
        Ok(())
    }

    /// The scene text and sheet overlay with every `(key, value)` written in order.
    pub fn edit(&self, edits: &[(&KeyPath, &Value)]) -> Result<Edited, KeyError> {
        let mut scene = self.scene.clone();
        let mut files: Vec<EditableFile> = Vec::new();
        for (key, value) in edits {
            if key.in_scene() {
                scene.set(&key.text, &key.parts[0], value)?;
                continue;
            }
            // Follow the chain of file keys: plant.actuator (relative to the scene), then
            // components.NAME (relative to the sheet).
            let mut dir = self.base_dir.clone();
            let mut holder_path = scene.path.clone();
            let mut target: Option<PathBuf> = None;
            for (i, part) in key.parts[..key.parts.len() - 1].iter().enumerate() {
                let holder = if i == 0 {
                    &scene
                } else {
                    files
                        .iter()
                        .find(|f| Some(&f.path) == target.as_ref())
                        .expect("opened")
                };
                let p = holder.named_file(part, &holder_path, &dir, key)?;
                if !files.iter().any(|f| f.path == p) {
                    let text = pneuflex_files::read_text(&p, pneuflex_files::InputKind::Sheet)
                        .map_err(|e| KeyError {
                            key: key.text.clone(),
                            message: e.to_string(),
                        })?;
                    files.push(EditableFile::new(&p, &text).map_err(|mut e| {
                        e.key = key.text.clone();
                        e
                    })?);
                }
                dir = p.parent().map(Path::to_path_buf).unwrap_or_default();
                holder_path = p.clone();
                target = Some(p);
            }
            let target = target.expect("a file key has a file part");
            let file = files.iter_mut().find(|f| f.path == target).expect("opened");
            file.set(&key.text, key.parts.last().expect("parts"), value)?;
        }
        Ok(Edited {
            scene_text: scene.render(),
            overlay: files.iter().map(|f| (f.path.clone(), f.render())).collect(),
        })
    }
}
