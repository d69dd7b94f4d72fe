//! The plugin's configuration: `<config key=... value=.../>` of an MJCF plugin instance. `sheet` names an
//! actuator sheet (pneumatics/*.toml); every other sheet value can be overridden inline by its dotted key
//! as the sheet's own errors spell it (`cylinder.bore_m`, `valve.sonic_conductance_m3_per_s_pa`,
//! `supply.pressure_abs_pa`, `mechanics.coulomb_n`, ...). The override is written into a copy of the
//! sheet's text and loaded by `pneuflex_pneumatics::ActuatorSheet::load_overlaid`, so an inline value is
//! validated exactly as the same value in the file. `command` chooses what ctrl is: the valve command
//! (`"valve"`, one actuator per cylinder) or the chambers' pressure set-points behind a pressure regulator in
//! front of each chamber (`"pressure"`, two actuators per cylinder, `regulator.time_constant_s`). Plain Rust,
//! no MuJoCo: tested here directly.

use std::collections::BTreeMap;
use std::ffi::CStr;
use std::path::{Path, PathBuf};

use pneuflex_pneumatics::{
    Actuator, ActuatorSheet, ChamberState, ComponentError, FileOverlay, Friction,
    PressureRegulator, T_DEFAULT,
};

/// The file of the sheet a key lives in.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum File {
    /// The actuator sheet itself (`[gas]`, `[mechanics]`).
    Sheet,
    /// The cylinder sheet it names (`components.cylinder`).
    Cylinder,
    /// The valve sheet (`components.valve`).
    Valve,
    /// The supply sheet (`components.supply`: `[supply]`, `[atmosphere]`).
    Supply,
}

impl File {
    /// The actuator sheet's `[components]` key naming this file.
    fn component(self) -> Option<&'static str> {
        match self {
            File::Sheet => None,
            File::Cylinder => Some("cylinder"),
            File::Valve => Some("valve"),
            File::Supply => Some("supply"),
        }
    }
}

/// What a key holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Value {
    /// One of the plugin's own keys.
    Own,
    /// A sheet number.
    Number,
    /// A sheet string (an enum name such as `valve.kind`).
    Text,
}

/// A configuration key the plugin declares to MuJoCo (MuJoCo's compiler rejects any other, naming it).
pub struct Key {
    /// The key as written in `<config key="..."/>`.
    pub name: &'static CStr,
    /// The sheet file of a sheet key.
    pub file: Option<File>,
    /// What it holds.
    pub value: Value,
}

const fn own(name: &'static CStr) -> Key {
    Key {
        name,
        file: None,
        value: Value::Own,
    }
}
const fn num(name: &'static CStr, file: File) -> Key {
    Key {
        name,
        file: Some(file),
        value: Value::Number,
    }
}
const fn text(name: &'static CStr, file: File) -> Key {
    Key {
        name,
        file: Some(file),
        value: Value::Text,
    }
}

/// Every key: the plugin's own, then the sheet values (docs/pneumatics.md has their units and ranges).
/// Not declared: the sheet's moving mass, K_v, incline and gravity (the MJCF's bodies, joint damping and
/// gravity are those), the sensors, and the stick-slip friction keys (refused, see [`parse`]).
pub const KEYS: &[Key] = &[
    own(c"sheet"),
    own(c"chamber_substeps"),
    own(c"initial_p_a_pa"),
    own(c"initial_p_b_pa"),
    own(c"initial_temperature_k"),
    own(c"command"),
    own(c"regulator.time_constant_s"),
    num(c"cylinder.bore_m", File::Cylinder),
    num(c"cylinder.rod_m", File::Cylinder),
    num(c"cylinder.stroke_m", File::Cylinder),
    num(c"cylinder.dead_volume_a_m3", File::Cylinder),
    num(c"cylinder.dead_volume_b_m3", File::Cylinder),
    text(c"valve.kind", File::Valve),
    num(c"valve.sonic_conductance_m3_per_s_pa", File::Valve),
    num(c"valve.critical_pressure_ratio", File::Valve),
    num(c"valve.response_time_s", File::Valve),
    num(c"valve.underlap", File::Valve),
    num(c"valve.pwm_frequency_hz", File::Valve),
    num(c"valve.switching_delay_s", File::Valve),
    num(
        c"valve.paths.supply_a.sonic_conductance_m3_per_s_pa",
        File::Valve,
    ),
    num(c"valve.paths.supply_a.critical_pressure_ratio", File::Valve),
    num(
        c"valve.paths.a_exhaust.sonic_conductance_m3_per_s_pa",
        File::Valve,
    ),
    num(
        c"valve.paths.a_exhaust.critical_pressure_ratio",
        File::Valve,
    ),
    num(
        c"valve.paths.supply_b.sonic_conductance_m3_per_s_pa",
        File::Valve,
    ),
    num(c"valve.paths.supply_b.critical_pressure_ratio", File::Valve),
    num(
        c"valve.paths.b_exhaust.sonic_conductance_m3_per_s_pa",
        File::Valve,
    ),
    num(
        c"valve.paths.b_exhaust.critical_pressure_ratio",
        File::Valve,
    ),
    num(c"supply.pressure_abs_pa", File::Supply),
    num(c"supply.temperature_k", File::Supply),
    num(c"atmosphere.pressure_abs_pa", File::Supply),
    num(c"atmosphere.temperature_k", File::Supply),
    num(c"gas.gas_constant_j_per_kg_k", File::Sheet),
    num(c"gas.polytropic_exponent", File::Sheet),
    text(c"mechanics.friction", File::Sheet),
    num(c"mechanics.coulomb_n", File::Sheet),
    num(c"mechanics.smooth_velocity_m_per_s", File::Sheet),
];

/// The keys of one valve kind: switching `valve.kind` inline drops the other kind's keys from the
/// sheet's valve (a sheet cannot hold both), unless they are given inline too.
const VALVE_KIND_KEYS: &[(&str, &[&str])] = &[
    ("proportional", &["response_time_s", "underlap"]),
    ("on_off_pwm", &["pwm_frequency_hz", "switching_delay_s"]),
];

/// Most chamber substeps per MuJoCo step (a 1 ms step in 1 us substeps).
const MAX_SUBSTEPS: u32 = 1000;

/// Initial chamber pressures, Pa absolute: the supply sheet's bounds (a vacuum exhaust's 1 kPa, the
/// largest supply's 10 MPa).
const CHAMBER_PRESSURE_PA: (f64, f64) = (1e3, 10e6);

/// Initial gas temperature, K: the sheets' range of the constant-property air model.
const GAS_TEMPERATURE_K: (f64, f64) = (200.0, 400.0);

/// The pressure regulators' time constant unless given, s (`command="pressure"`): a fast proportional
/// pressure regulator, as the Gymnasium environments' default.
pub const REGULATOR_TIME_CONSTANT_S: f64 = 0.01;

/// What an actuator's ctrl is.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Command {
    /// The valve command u in [-1, 1]: one actuator per cylinder.
    Valve,
    /// The set-points of a pressure regulator in front of each chamber, Pa absolute: two actuators per
    /// cylinder, chamber A's ctrl then chamber B's (`pneuflex_pneumatics::regulator`).
    Pressure(PressureRegulator),
}

impl Command {
    /// Actuators (and so controls) per cylinder.
    pub fn actuators_per_cylinder(self) -> usize {
        match self {
            Command::Valve => 1,
            Command::Pressure(_) => 2,
        }
    }
}

/// What the plugin runs: the sheet with its inline values applied.
#[derive(Clone, Debug)]
pub struct Config {
    /// Cylinder, gas, valve, supply.
    pub actuator: Actuator,
    /// The sheet's Coulomb friction of piston and guide (smooth only).
    pub friction: Friction,
    /// Chamber substeps per MuJoCo step.
    pub chamber_substeps: u32,
    /// Chambers at reset.
    pub initial: ChamberState,
    /// What ctrl is.
    pub command: Command,
}

/// A configuration error: the key it is about and what is wrong.
#[derive(Clone, Debug, PartialEq)]
pub struct ConfigError {
    /// The key (or keys, comma-separated) as written in the MJCF.
    pub key: String,
    /// What was expected and what was found.
    pub message: String,
}

impl std::fmt::Display for ConfigError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "config key '{}': {}", self.key, self.message)
    }
}

fn err(key: &str, message: impl Into<String>) -> ConfigError {
    ConfigError {
        key: key.to_string(),
        message: message.into(),
    }
}

/// Reads the configuration through `get`, which returns a key's value or `None` when it is absent
/// (MuJoCo gives "" for a declared key that is not set: the same as absent).
pub fn parse(get: impl Fn(&str) -> Option<String>) -> Result<Config, ConfigError> {
    let given = |k: &str| get(k).filter(|v| !v.trim().is_empty());
    let Some(sheet) = given("sheet") else {
        return Err(err(
            "sheet",
            "required: the path of an actuator sheet (pneumatics/*.toml), absolute or relative to the \
             working directory",
        ));
    };
    let stick_slip = || {
        err(
            "mechanics.friction",
            "\"stick_slip\" needs the net drive on the joint, which an actuator does not see: use \
             \"smooth\" (or mechanics.coulomb_n = 0 and the joint's frictionloss)",
        )
    };
    // Before the sheet is loaded: its smooth-friction keys would be the error otherwise.
    if given("mechanics.friction").is_some_and(|v| v.trim() == "stick_slip") {
        return Err(stick_slip());
    }
    let sheet_path = PathBuf::from(sheet.trim());
    let overrides: Vec<(&Key, String)> = KEYS
        .iter()
        .filter(|k| k.file.is_some())
        .filter_map(|k| given(name(k)).map(|v| (k, v.trim().to_string())))
        .collect();
    // The sheet as it is first, so that its own errors keep their file and line; one that an inline
    // value replaces is no error.
    let sheet = match ActuatorSheet::load(&sheet_path) {
        Ok(s) if overrides.is_empty() => s,
        Err(ComponentError::Invalid { key, .. })
            if overrides.iter().any(|(k, _)| name(k) == key) =>
        {
            overridden(&sheet_path, &overrides)?
        }
        Err(e) if sheet_path.is_relative() && !sheet_path.exists() => {
            // MuJoCo gives a plugin no model folder: say where a relative path was looked for.
            let cwd =
                std::env::current_dir().map_or_else(|_| "?".into(), |d| d.display().to_string());
            return Err(err(
                "sheet",
                format!(
                    "{e} (a relative sheet is read from the working directory, {cwd}, not the model's \
                     folder: give an absolute path)"
                ),
            ));
        }
        Err(e) => return Err(err("sheet", e.to_string())),
        Ok(_) => overridden(&sheet_path, &overrides)?,
    };
    // The plugin's state holds the paper's chambers and valve only (ValveState::to_array).
    let beyond = sheet.effects_beyond_paper();
    if !beyond.is_empty() {
        return Err(err(
            "sheet",
            format!(
                "{} gives {}: the plugin models the paper's chambers, valve and friction only; remove them \
                 (the 1-DOF model of a pneuflex scene runs them)",
                sheet_path.display(),
                beyond.join(", ")
            ),
        ));
    }
    let friction = sheet.mechanics.friction;
    if let Friction::StickSlip { .. } = friction {
        return Err(stick_slip());
    }
    let actuator = sheet.actuator();
    let chamber_substeps = match given("chamber_substeps") {
        None => 1,
        Some(v) => match v.trim().parse::<u32>() {
            Ok(n) if (1..=MAX_SUBSTEPS).contains(&n) => n,
            _ => {
                return Err(err(
                    "chamber_substeps",
                    format!("expected a whole number in [1, {MAX_SUBSTEPS}], got '{v}'"),
                ));
            }
        },
    };
    // The sheets' own ranges: absolute pressures from a vacuum exhaust's 1 kPa to the largest supply's
    // 10 MPa, temperatures of the constant-property air model. A chamber at 1e300 Pa gives an infinite
    // force on the first step, one at 1e-300 Pa a meaningless one.
    let within =
        |key: &str, (lo, hi): (f64, f64), what: &str| -> Result<Option<f64>, ConfigError> {
            match given(key) {
                None => Ok(None),
                Some(v) => match v.trim().parse::<f64>() {
                    Ok(x) if (lo..=hi).contains(&x) => Ok(Some(x)),
                    _ => Err(err(key, format!("expected {what}, got '{v}'"))),
                },
            }
        };
    let pressure = |key: &str| {
        within(
            key,
            CHAMBER_PRESSURE_PA,
            "an absolute pressure in [1e3, 1e7] Pa (gauge + atmosphere)",
        )
    };
    let s = &actuator.supply;
    // Defaults: B at the mean of supply and atmosphere (as the scene plants start), A where the piston
    // force is zero (gravity and loads are the MJCF's).
    let p_b = pressure("initial_p_b_pa")?
        .unwrap_or(0.5 * (s.supply_pressure_pa + s.atmosphere_pressure_pa));
    let c = &actuator.cylinder;
    let p_a = pressure("initial_p_a_pa")?
        .unwrap_or((p_b * c.area_b() + s.atmosphere_pressure_pa * c.area_rod()) / c.area_a());
    let t_k = within(
        "initial_temperature_k",
        GAS_TEMPERATURE_K,
        "a temperature in [200, 400] K",
    )?
    .unwrap_or(T_DEFAULT);
    Ok(Config {
        actuator,
        friction,
        chamber_substeps,
        initial: ChamberState::with_temperature(p_a, p_b, t_k),
        command: command(&given)?,
    })
}

/// `command` and `regulator.time_constant_s`.
fn command(given: &impl Fn(&str) -> Option<String>) -> Result<Command, ConfigError> {
    const TAU: &str = "regulator.time_constant_s";
    let tau = given(TAU);
    match given("command").as_deref().map(str::trim) {
        None | Some("valve") => match tau {
            None => Ok(Command::Valve),
            Some(_) => Err(err(
                TAU,
                "the regulators replace the valve: give it with command=\"pressure\"",
            )),
        },
        Some("pressure") => {
            let t = match tau {
                None => REGULATOR_TIME_CONSTANT_S,
                Some(v) => v
                    .trim()
                    .parse::<f64>()
                    .map_err(|_| err(TAU, format!("expected a time constant in s, got '{v}'")))?,
            };
            PressureRegulator::new(t)
                .map(Command::Pressure)
                .map_err(|e| err(TAU, e))
        }
        Some(other) => Err(err(
            "command",
            format!(
                "expected \"valve\" (ctrl the valve command) or \"pressure\" (the chambers' pressure \
                 set-points, two actuators per cylinder), got '{other}'"
            ),
        )),
    }
}

/// A key's name as text.
pub fn name(k: &Key) -> &'static str {
    // Every name above is ASCII.
    k.name.to_str().unwrap_or("")
}

/// The sheet with the inline values written into copies of its files.
fn overridden(sheet: &Path, overrides: &[(&Key, String)]) -> Result<ActuatorSheet, ConfigError> {
    let read = |p: &Path| {
        pneuflex_files::read_text(p, pneuflex_files::InputKind::Sheet)
            .map_err(|e| err("sheet", e.to_string()))
    };
    let table = |p: &Path, text: &str| -> Result<toml::Table, ConfigError> {
        text.parse::<toml::Table>()
            .map_err(|e| err("sheet", format!("{}: {e}", p.display())))
    };
    // The file of each key, as the loader resolves it: the sheet, or its folder joined with the name in
    // [components] (the overlay is looked up by that path).
    let sheet_text = read(sheet)?;
    let sheet_table = table(sheet, &sheet_text)?;
    let dir = sheet.parent().unwrap_or_else(|| Path::new(""));
    let path_of = |f: File| -> PathBuf {
        match f.component() {
            None => sheet.to_path_buf(),
            Some(c) => {
                let named = sheet_table
                    .get("components")
                    .and_then(|t| t.get(c))
                    .and_then(|v| v.as_str())
                    .unwrap_or_default();
                dir.join(named)
            }
        }
    };
    let mut files: BTreeMap<File, (PathBuf, toml::Table, Vec<&str>)> = BTreeMap::new();
    for (k, v) in overrides {
        let file = k.file.unwrap_or(File::Sheet);
        let (_, t, keys) = match files.entry(file) {
            std::collections::btree_map::Entry::Occupied(e) => e.into_mut(),
            std::collections::btree_map::Entry::Vacant(e) => {
                let p = path_of(file);
                let t = if file == File::Sheet {
                    sheet_table.clone()
                } else {
                    table(&p, &read(&p)?)?
                };
                e.insert((p, t, Vec::new()))
            }
        };
        let key = name(k);
        let value = match k.value {
            Value::Text => toml::Value::String(v.clone()),
            _ => toml::Value::Float(
                v.parse::<f64>()
                    .map_err(|_| err(key, format!("expected a number (SI units), got '{v}'")))?,
            ),
        };
        set(
            t,
            key,
            value,
            &overrides.iter().map(|(k, _)| name(k)).collect::<Vec<_>>(),
        );
        keys.push(key);
    }
    let overlay: FileOverlay = files
        .values()
        .map(|(p, t, _)| (p.clone(), t.to_string()))
        .collect();
    ActuatorSheet::load_overlaid(sheet, &overlay).map_err(|e| blame(e, &files, &overlay))
}

/// Writes `value` at the dotted `key` of `t` (creating tables: `[atmosphere]` may be absent). A new
/// `valve.kind` drops the other kind's keys that are not among `inline`.
fn set(t: &mut toml::Table, key: &str, value: toml::Value, inline: &[&str]) {
    let parts: Vec<&str> = key.split('.').collect();
    let (last, tables) = parts.split_last().expect("keys have a table and a name");
    let mut here = t;
    for p in tables {
        let entry = here
            .entry(p.to_string())
            .or_insert_with(|| toml::Value::Table(toml::Table::new()));
        if !entry.is_table() {
            *entry = toml::Value::Table(toml::Table::new());
        }
        here = entry.as_table_mut().expect("made a table above");
    }
    if let (true, Some(kind)) = (key == "valve.kind", value.as_str()) {
        for (k, keys) in VALVE_KIND_KEYS {
            if *k != kind {
                for other in *keys {
                    if !inline.contains(&format!("valve.{other}").as_str()) {
                        here.remove(*other);
                    }
                }
            }
        }
    }
    here.insert(last.to_string(), value);
}

/// The inline key(s) to blame for an error of the overridden sheet.
fn blame(
    e: ComponentError,
    files: &BTreeMap<File, (PathBuf, toml::Table, Vec<&str>)>,
    overlay: &FileOverlay,
) -> ConfigError {
    let of_file = |file: &Path| files.values().find(|(p, _, _)| p == file);
    match e {
        ComponentError::Invalid {
            file, key, message, ..
        } => match of_file(&file) {
            Some((_, _, keys)) if keys.contains(&key.as_str()) => err(&key, message),
            Some((_, _, keys)) => err(
                &keys.join("', '"),
                format!(
                    "with this value, the sheet's {key} ({}) is not valid: {message}",
                    file.display()
                ),
            ),
            None => err("sheet", format!("{}: {key}: {message}", file.display())),
        },
        ComponentError::Parse {
            file, at, message, ..
        } => match of_file(&file) {
            Some((_, _, keys)) => {
                let text = overlay.get(&file).map(String::as_str).unwrap_or_default();
                let line = at.map(|p| p.line);
                let hit: Vec<&str> = keys
                    .iter()
                    .copied()
                    .filter(|k| {
                        line.is_some()
                            && pneuflex_files::toml_key_position(text, k).map(|p| p.line) == line
                    })
                    .collect();
                let keys = if hit.is_empty() { keys.clone() } else { hit };
                err(&keys.join("', '"), message)
            }
            None => err("sheet", format!("{}: {message}", file.display())),
        },
        other => err("sheet", other.to_string()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use pneuflex_pneumatics::ValveKind;

    fn repo(p: &str) -> String {
        format!("{}/../../{p}", env!("CARGO_MANIFEST_DIR"))
    }

    fn with<'a>(kv: &'a [(&'a str, &'a str)]) -> impl Fn(&str) -> Option<String> + 'a {
        move |k| kv.iter().find(|(a, _)| *a == k).map(|(_, v)| v.to_string())
    }

    #[test]
    fn the_sheet_alone_gives_the_sheet() {
        let sheet = repo("pneumatics/paper-actuator.toml");
        let c = parse(with(&[("sheet", &sheet)])).unwrap();
        let s = ActuatorSheet::load(&sheet).unwrap();
        assert_eq!(c.actuator, s.actuator());
        assert_eq!(c.friction, s.mechanics.friction);
        assert_eq!(c.chamber_substeps, 1);
        // Defaults: B at the mean of supply and atmosphere, A where the piston force is zero.
        let p_b = 0.5 * (601_325.0 + 101_325.0);
        assert_eq!(c.initial.p_b, p_b);
        let f = c.actuator.piston_force(&c.initial);
        assert!(f.abs() < 1e-9, "piston force at the default chambers {f} N");
        assert_eq!(c.initial.t_a, T_DEFAULT);
        assert_eq!(c.command, Command::Valve);
        let c = parse(with(&[("sheet", &sheet), ("command", "pressure")])).unwrap();
        assert_eq!(
            c.command,
            Command::Pressure(PressureRegulator::new(REGULATOR_TIME_CONSTANT_S).unwrap())
        );
        let c = parse(with(&[
            ("sheet", &sheet),
            ("command", "pressure"),
            ("regulator.time_constant_s", "0.05"),
        ]))
        .unwrap();
        assert_eq!(c.command.actuators_per_cylinder(), 2);
        assert_eq!(
            c.command,
            Command::Pressure(PressureRegulator::new(0.05).unwrap())
        );
    }

    #[test]
    fn inline_values_override_the_sheet_in_each_file() {
        let sheet = repo("pneumatics/paper-actuator.toml");
        let c = parse(with(&[
            ("sheet", &sheet),
            ("cylinder.bore_m", "0.02"),
            ("valve.sonic_conductance_m3_per_s_pa", "7e-9"),
            ("valve.paths.a_exhaust.critical_pressure_ratio", "0.25"),
            ("supply.pressure_abs_pa", "701325"),
            ("atmosphere.temperature_k", "300"),
            ("gas.polytropic_exponent", "1.2"),
            ("mechanics.coulomb_n", "0"),
            ("chamber_substeps", "10"),
            ("initial_p_a_pa", "2e5"),
            ("initial_p_b_pa", "3e5"),
            ("initial_temperature_k", "310"),
        ]))
        .unwrap();
        let a = c.actuator;
        assert_eq!(a.cylinder.bore_m, 0.02);
        assert_eq!(a.cylinder.rod_m, 0.005, "the other keys stay the sheet's");
        assert_eq!(a.valve.orifice.sonic_conductance_m3_per_s_pa, 7e-9);
        assert_eq!(a.valve.path(1).critical_pressure_ratio, 0.25);
        assert_eq!(a.valve.path(1).sonic_conductance_m3_per_s_pa, 7e-9);
        assert_eq!(a.valve.path(0).critical_pressure_ratio, 0.3);
        assert_eq!(a.supply.supply_pressure_pa, 701_325.0);
        assert_eq!(a.supply.atmosphere_temperature_k, 300.0);
        assert_eq!(a.supply.atmosphere_pressure_pa, 101_325.0);
        assert_eq!(a.gas.polytropic_exponent, 1.2);
        assert!(matches!(c.friction, Friction::Smooth { coulomb_n, .. } if coulomb_n == 0.0));
        assert_eq!(c.chamber_substeps, 10);
        assert_eq!(c.initial, ChamberState::with_temperature(2e5, 3e5, 310.0));
    }

    #[test]
    fn switching_the_valve_kind_drops_the_other_kinds_keys() {
        let sheet = repo("pneumatics/paper-actuator.toml");
        let c = parse(with(&[
            ("sheet", &sheet),
            ("valve.kind", "proportional"),
            ("valve.response_time_s", "0.004"),
        ]))
        .unwrap();
        assert_eq!(
            c.actuator.valve.kind,
            ValveKind::Proportional {
                response_time_s: 0.004
            }
        );
        // Without the new kind's required key the sheet's own message names it.
        let e = parse(with(&[("sheet", &sheet), ("valve.kind", "proportional")])).unwrap_err();
        assert_eq!(e.key, "valve.kind");
        assert!(e.message.contains("valve.response_time_s"), "{e}");
        assert!(e.message.contains("required"), "{e}");
    }

    #[test]
    fn every_error_names_its_key() {
        let sheet = repo("pneumatics/paper-actuator.toml");
        // (inline keys, the key the error must name, a piece of its message)
        type Case<'a> = (&'a [(&'a str, &'a str)], &'a str, &'a str);
        let cases: &[Case] = &[
            (&[], "sheet", "required"),
            (
                &[("sheet", "/no/such/sheet.toml")],
                "sheet",
                "/no/such/sheet.toml",
            ),
            (&[("cylinder.bore_m", "-3")], "cylinder.bore_m", "got -3"),
            (
                &[("cylinder.bore_m", "16 mm")],
                "cylinder.bore_m",
                "'16 mm'",
            ),
            (&[("cylinder.bore_m", "nan")], "cylinder.bore_m", "finite"),
            (&[("valve.kind", "magic")], "valve.kind", "magic"),
            (
                &[("valve.critical_pressure_ratio", "1")],
                "valve.critical_pressure_ratio",
                "[0, 1)",
            ),
            (
                &[("supply.pressure_abs_pa", "9e4")],
                "supply.pressure_abs_pa",
                "above the atmosphere",
            ),
            (
                &[("mechanics.friction", "stick_slip")],
                "mechanics.friction",
                "stick_slip",
            ),
            (&[("chamber_substeps", "0")], "chamber_substeps", "got '0'"),
            (
                &[("chamber_substeps", "2.5")],
                "chamber_substeps",
                "got '2.5'",
            ),
            (
                &[("initial_p_a_pa", "-1")],
                "initial_p_a_pa",
                "[1e3, 1e7] Pa",
            ),
            // Beyond any chamber: an infinite force on the first step, or a meaningless one.
            (
                &[("initial_p_b_pa", "1e300")],
                "initial_p_b_pa",
                "got '1e300'",
            ),
            (
                &[("initial_p_a_pa", "1e-300")],
                "initial_p_a_pa",
                "got '1e-300'",
            ),
            (&[("initial_p_b_pa", "nan")], "initial_p_b_pa", "got 'nan'"),
            // A relative sheet that is not there: where it was looked for.
            (
                &[("sheet", "no/such/sheet.toml")],
                "sheet",
                "read from the working directory",
            ),
            (
                &[("initial_temperature_k", "inf")],
                "initial_temperature_k",
                "[200, 400] K",
            ),
            (
                &[("initial_temperature_k", "1000")],
                "initial_temperature_k",
                "got '1000'",
            ),
            (&[("command", "torque")], "command", "got 'torque'"),
            (
                &[("regulator.time_constant_s", "0.01")],
                "regulator.time_constant_s",
                "command=\"pressure\"",
            ),
            (
                &[("command", "pressure"), ("regulator.time_constant_s", "0")],
                "regulator.time_constant_s",
                "got 0",
            ),
            (
                &[
                    ("command", "pressure"),
                    ("regulator.time_constant_s", "10 ms"),
                ],
                "regulator.time_constant_s",
                "'10 ms'",
            ),
            // A value that makes another (not inline) value of its file invalid names the inline key.
            (
                &[("cylinder.bore_m", "0.004")],
                "cylinder.bore_m",
                "cylinder.rod_m",
            ),
        ];
        for (kv, key, says) in cases {
            let mut all: Vec<(&str, &str)> = kv.to_vec();
            if !kv.iter().any(|(k, _)| *k == "sheet") && *key != "sheet" {
                all.push(("sheet", &sheet));
            }
            let e = parse(with(&all)).unwrap_err();
            assert_eq!(e.key, *key, "{kv:?}: {e}");
            assert!(e.message.contains(says), "{kv:?}: '{e}' lacks '{says}'");
        }
    }

    #[test]
    fn a_bad_sheet_is_blamed_on_sheet_with_its_own_file_and_key() {
        let dir = tempfile::tempdir().unwrap();
        let src = repo("pneumatics");
        for f in [
            "smc-mqm16-cylinder.toml",
            "a05ps25x-5-2-valve.toml",
            "supply-0p5mpa.toml",
        ] {
            std::fs::copy(format!("{src}/{f}"), dir.path().join(f)).unwrap();
        }
        let text = std::fs::read_to_string(format!("{src}/paper-actuator.toml"))
            .unwrap()
            .replace("coulomb_n = 0.6", "coulomb_n = -0.6")
            .replace(
                "pressure_sensor = \"pre-u-ps12001-pressure-transmitter.toml\"\n",
                "",
            )
            .replace("position_sensor = \"mps-0327-position-sensor.toml\"\n", "");
        let sheet = dir.path().join("a.toml");
        std::fs::write(&sheet, text).unwrap();
        let s = sheet.to_string_lossy().to_string();
        let e = parse(with(&[("sheet", &s)])).unwrap_err();
        assert_eq!(e.key, "sheet");
        assert!(
            e.message.contains("a.toml") && e.message.contains("mechanics.coulomb_n"),
            "{e}"
        );
        // Fixed inline, it loads.
        let c = parse(with(&[("sheet", &s), ("mechanics.coulomb_n", "0.6")]));
        assert!(c.is_ok(), "{:?}", c.err());
    }

    #[test]
    fn a_sheet_with_effects_beyond_the_paper_is_refused_naming_them() {
        // The plugin's state has no room for leaks, lines or a spool's pending moves: running such a sheet
        // would silently drop them.
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path();
        for e in std::fs::read_dir(repo("pneumatics")).unwrap() {
            let p = e.unwrap().path();
            if p.extension().is_some_and(|x| x == "toml") {
                std::fs::copy(&p, dir.join(p.file_name().unwrap())).unwrap();
            }
        }
        let cyl = dir.join("smc-mqm16-cylinder.toml");
        let text = std::fs::read_to_string(&cyl).unwrap();
        std::fs::write(
            &cyl,
            format!("{text}\n[cylinder.leaks.piston]\nsonic_conductance_m3_per_s_pa = 1e-11\n"),
        )
        .unwrap();
        let sheet = dir.join("paper-actuator.toml");
        let e = parse(with(&[("sheet", sheet.to_str().unwrap())])).unwrap_err();
        assert_eq!(e.key, "sheet");
        assert!(e.message.contains("[cylinder.leaks.piston]"), "{e}");
        assert!(e.message.contains("paper-actuator.toml"), "{e}");
    }

    #[test]
    fn keys_are_unique_and_ascii() {
        let mut names: Vec<&str> = KEYS.iter().map(name).collect();
        assert!(names.iter().all(|n| !n.is_empty() && n.is_ascii()));
        names.sort();
        names.dedup();
        assert_eq!(names.len(), KEYS.len());
    }
}
