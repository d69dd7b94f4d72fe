//! Component data sheets as TOML (`pneumatics/*.toml`): cylinder, valve, supply, sensors, and the
//! actuator sheet that names them. Loaded with serde, unknown keys rejected, values validated; every error
//! names the file and the field.

use std::path::{Path, PathBuf};

use serde::Deserialize;

use crate::actuator::{Actuator, Cylinder, Gas, R_AIR, STANDARD_GRAVITY, Supply};
use crate::effects::{Effects, LEAKS, Leaks, Lines, SpoolDynamics, WallHeat};
use crate::flow::Orifice;
use crate::mechanics::{Friction, Mechanics, OneDofModel};
use crate::valve::{PATHS, ValveKind, ValveModel};
use pneuflex_files::Position;

/// Error reading or validating a component file.
#[derive(Debug, thiserror::Error)]
pub enum ComponentError {
    /// The operating system refused to read the file (missing, permissions, ...).
    #[error("{}: cannot read: {os_error}", file.display())]
    Io {
        /// The file.
        file: PathBuf,
        /// The OS error: in the message, not a `source()`, so that it is printed once.
        os_error: std::io::Error,
    },
    /// Not a regular file (a FIFO, a device, a directory), larger than a sheet may be, or not UTF-8.
    #[error(transparent)]
    Input(pneuflex_files::InputError),
    /// The file is not valid TOML or does not match the schema (unknown key, wrong type, missing key).
    #[error("{}{}: {message}", file.display(), at_pos(at))]
    Parse {
        /// The file.
        file: PathBuf,
        /// Line and column of the error, when known.
        at: Option<Position>,
        /// Parser message (names the key).
        message: String,
    },
    /// A value is out of range.
    #[error("{}{}: {key}: {message}", file.display(), at_pos(at))]
    Invalid {
        /// The file.
        file: PathBuf,
        /// Line and column of the key (or of its table when the key is absent), when known.
        at: Option<Position>,
        /// Dotted key, e.g. `cylinder.bore_m`.
        key: String,
        /// What was expected and what was found.
        message: String,
    },
    /// A file named by a key of this file could not be read.
    #[error("{}{}: {key}: {error}", file.display(), at_pos(at))]
    Referenced {
        /// The file holding the key.
        file: PathBuf,
        /// Line and column of the key, when known.
        at: Option<Position>,
        /// Dotted key, e.g. `components.valve`.
        key: String,
        /// Why the named file could not be read (in the message, not a `source()`: printed once).
        error: Box<ComponentError>,
    },
}

/// `:line:col` of a position, or nothing (the pneuflex file-error convention `file:line:col: key: message`).
fn at_pos(at: &Option<Position>) -> String {
    at.map_or_else(String::new, |p| format!(":{p}"))
}

impl ComponentError {
    /// The OS error behind this error, if any (also through `Referenced`).
    pub fn os_error(&self) -> Option<&std::io::Error> {
        match self {
            ComponentError::Io { os_error, .. } => Some(os_error),
            ComponentError::Input(pneuflex_files::InputError::Io { os_error, .. }) => {
                Some(os_error)
            }
            ComponentError::Referenced { error, .. } => error.os_error(),
            _ => None,
        }
    }
}

impl From<pneuflex_files::InputError> for ComponentError {
    fn from(e: pneuflex_files::InputError) -> Self {
        match e {
            pneuflex_files::InputError::Io { path, os_error } => ComponentError::Io {
                file: path,
                os_error,
            },
            other => ComponentError::Input(other),
        }
    }
}

/// Reads a sheet: a regular file of at most `InputKind::Sheet.max_bytes()` (a FIFO or `/dev/zero` is an
/// error, never a hang or an unbounded read).
fn read(path: &Path) -> Result<String, ComponentError> {
    Ok(pneuflex_files::read_text(
        path,
        pneuflex_files::InputKind::Sheet,
    )?)
}

/// Texts that stand in for files when a sheet is loaded ([`ActuatorSheet::load_overlaid`]), by path.
pub type FileOverlay = std::collections::BTreeMap<PathBuf, String>;

/// Line and column of a dotted key in TOML text (of its table when the key is absent).
fn key_at(text: &str, key: &str) -> Option<Position> {
    pneuflex_files::toml_key_position(text, key)
}

fn parse<T: for<'de> Deserialize<'de>>(path: &Path, text: &str) -> Result<T, ComponentError> {
    toml::from_str(text).map_err(|e| ComponentError::Parse {
        file: path.to_path_buf(),
        at: e.span().map(|s| pneuflex_files::line_col(text, s.start)),
        message: e.message().trim().to_string(),
    })
}

/// Field checker bound to one file; errors carry the line of the key.
struct Check<'a> {
    path: &'a Path,
    text: &'a str,
}

impl Check<'_> {
    fn err(&self, field: &str, message: String) -> ComponentError {
        ComponentError::Invalid {
            file: self.path.to_path_buf(),
            at: key_at(self.text, field),
            key: field.to_string(),
            message,
        }
    }
    /// `e` unchanged, unless it says that the file `key` names could not be read: then it also names the key.
    fn referenced(&self, key: &str, e: ComponentError) -> ComponentError {
        match e {
            ComponentError::Io { .. } | ComponentError::Input(_) => ComponentError::Referenced {
                file: self.path.to_path_buf(),
                at: key_at(self.text, key),
                key: key.to_string(),
                error: Box::new(e),
            },
            e => e,
        }
    }
    fn finite(&self, field: &str, v: f64) -> Result<f64, ComponentError> {
        pneuflex_files::check::finite(v).map_err(|m| self.err(field, m))
    }
    fn positive(&self, field: &str, v: f64) -> Result<f64, ComponentError> {
        pneuflex_files::check::positive(v).map_err(|m| self.err(field, m))
    }
    fn non_negative(&self, field: &str, v: f64) -> Result<f64, ComponentError> {
        pneuflex_files::check::non_negative(v).map_err(|m| self.err(field, m))
    }
    fn range(
        &self,
        field: &str,
        v: f64,
        lo: f64,
        hi: f64,
        what: &str,
    ) -> Result<f64, ComponentError> {
        self.finite(field, v)?;
        if v >= lo && v < hi {
            Ok(v)
        } else {
            Err(self.err(field, format!("must be in {what}, got {v}")))
        }
    }
    /// The sign check, then a physical bound `b` (inclusive); the message says what the bound stands for.
    fn bounded(&self, field: &str, v: f64, b: Bound) -> Result<f64, ComponentError> {
        if b.min > 0.0 {
            self.positive(field, v)?;
        } else {
            self.non_negative(field, v)?;
        }
        if v >= b.min && v <= b.max {
            Ok(v)
        } else {
            Err(self.err(
                field,
                format!(
                    "must be in [{}, {}] {} ({}), got {}",
                    num(b.min),
                    num(b.max),
                    b.unit,
                    b.why,
                    num(v)
                ),
            ))
        }
    }
}

/// A number for messages: exponent notation when plain digits would be unreadable (1e300).
fn num(v: f64) -> String {
    if v != 0.0 && (v.abs() >= 1e6 || v.abs() < 1e-3) {
        format!("{v:e}")
    } else {
        format!("{v}")
    }
}

/// Physical range of a sheet value: the model's equations hold and its integration is resolvable only
/// within these (issue 11: a sonic conductance of 1e-3 or a supply of 1e15 Pa ran to -1e67 Pa).
#[derive(Clone, Copy)]
struct Bound {
    min: f64,
    max: f64,
    unit: &'static str,
    why: &'static str,
}

/// Bore: 1 mm (micro cylinders) to 1 m (the largest industrial pneumatic cylinders are ~0.3 m).
const BORE: Bound = Bound {
    min: 1e-3,
    max: 1.0,
    unit: "m",
    why: "pneumatic cylinders are 1 mm to 1 m in bore",
};
/// Stroke: 1 mm to 10 m (rodless cylinders reach ~6 m).
const STROKE: Bound = Bound {
    min: 1e-3,
    max: 10.0,
    unit: "m",
    why: "pneumatic cylinders stroke 1 mm to 10 m",
};
/// Dead volume per chamber: 1 mm^3 to 1 m^3 (ports and tubing).
const DEAD_VOLUME: Bound = Bound {
    min: 1e-9,
    max: 1.0,
    unit: "m^3",
    why: "1 mm^3 to 1 m^3 of ports and tubing",
};
/// ISO 6358 sonic conductance C: valves are ~1e-9..1e-7 m^3/(s Pa) (0.1-10 dm^3/(s bar)); 1e-5 leaves
/// two orders of magnitude.
const SONIC_CONDUCTANCE: Bound = Bound {
    min: 1e-12,
    max: 1e-5,
    unit: "m^3/(s Pa)",
    why: "valves are ~1e-9 to 1e-7 m^3/(s Pa); 1 dm^3/(s bar) = 1e-8",
};
/// Supply: absolute, at most 10 MPa (pneumatics runs at <= 1.6 MPa).
const SUPPLY_PRESSURE_MAX_PA: f64 = 10e6;
/// Atmosphere (exhaust) pressure: 1 kPa (vacuum exhaust) to 200 kPa, absolute.
const ATMOSPHERE_PRESSURE: Bound = Bound {
    min: 1e3,
    max: 2e5,
    unit: "Pa",
    why: "absolute exhaust pressure",
};
/// Gas temperatures: 200-400 K (the ideal-gas, constant-property model of air).
const TEMPERATURE: Bound = Bound {
    min: 200.0,
    max: 400.0,
    unit: "K",
    why: "the range of the constant-property air model",
};
/// Valve time constants: up to 10 s.
const VALVE_TIME: Bound = Bound {
    min: 0.0,
    max: 10.0,
    unit: "s",
    why: "valve response times are ms to s",
};
/// PWM frequency: up to 10 kHz (solenoid valves switch at <= ~500 Hz).
const PWM_FREQUENCY: Bound = Bound {
    min: 1e-3,
    max: 1e4,
    unit: "Hz",
    why: "solenoid valves switch at up to a few hundred Hz",
};
/// Specific gas constant: CO2 (189) to hydrogen (4124) J/(kg K).
const GAS_CONSTANT: Bound = Bound {
    min: 100.0,
    max: 5000.0,
    unit: "J/(kg K)",
    why: "CO2 is 189, air 287, hydrogen 4124",
};
/// Moving mass: 0.1 g to 1 t.
const MOVING_MASS: Bound = Bound {
    min: 1e-4,
    max: 1e3,
    unit: "kg",
    why: "piston, rod and load",
};
/// Viscous friction K_v: up to 1e6 N s/m.
const VISCOUS: Bound = Bound {
    min: 0.0,
    max: 1e6,
    unit: "N s/m",
    why: "seal and guide damping",
};
/// Friction forces: up to 1e5 N (far beyond any pneumatic cylinder's force).
const FRICTION_FORCE: Bound = Bound {
    min: 0.0,
    max: 1e5,
    unit: "N",
    why: "seal and guide friction",
};
/// Friction velocity scales: 1 um/s to 10 m/s.
const FRICTION_VELOCITY: Bound = Bound {
    min: 1e-6,
    max: 10.0,
    unit: "m/s",
    why: "friction velocity scales",
};
/// Gravity: 0 (horizontal test bench in orbit) to 100 m/s^2.
const GRAVITY: Bound = Bound {
    min: 0.0,
    max: 100.0,
    unit: "m/s^2",
    why: "9.80665 on Earth",
};

/// Wall heat transfer coefficient: 0 (adiabatic) to 1e4 W/(m^2 K). Free convection in a cylinder is
/// ~10-100; at 1e4 a 16 mm chamber is isothermal within a millisecond, which the 0.1 ms RK4 step still
/// resolves (docs/pneumatics.md, "Effects beyond the paper").
const HEAT_TRANSFER: Bound = Bound {
    min: 0.0,
    max: 1e4,
    unit: "W/(m^2 K)",
    why: "free convection is ~10-100; 1e4 is isothermal within the 0.1 ms step",
};
/// Leak sonic conductance: 1e-18 (a chamber that holds for days) to 1e-7 m^3/(s Pa) (a valve's).
const LEAK_CONDUCTANCE: Bound = Bound {
    min: 1e-18,
    max: 1e-7,
    unit: "m^3/(s Pa)",
    why: "a seal leak is far below a valve's 1e-9 to 1e-7",
};
/// Line length: 0 to 100 m.
const LINE_LENGTH: Bound = Bound {
    min: 0.0,
    max: 100.0,
    unit: "m",
    why: "tubing between valve and cylinder",
};
/// Speed of sound in a line: 50 to 2000 m/s (air at 20 degC: 343).
const SOUND_SPEED: Bound = Bound {
    min: 50.0,
    max: 2000.0,
    unit: "m/s",
    why: "air at 20 degC is 343 m/s",
};
/// Rise of the Coulomb friction with the pressure difference: up to 1e-3 N/Pa (100 N/bar).
const COULOMB_PRESSURE: Bound = Bound {
    min: 0.0,
    max: 1e-3,
    unit: "N/Pa",
    why: "a 25 mm O-ring seal measures 7.8e-6 (0.78 N/bar)",
};
/// LuGre bristle stiffness sigma0: 1 to 1e8 N/m.
const BRISTLE_STIFFNESS: Bound = Bound {
    min: 1.0,
    max: 1e8,
    unit: "N/m",
    why: "pre-sliding stiffness of seals, ~1e4 to 1e6",
};
/// LuGre bristle damping sigma1: up to 1e6 N s/m.
const BRISTLE_DAMPING: Bound = Bound {
    min: 0.0,
    max: 1e6,
    unit: "N s/m",
    why: "micro-damping of the bristles",
};
/// The ratio of the heat capacities of air, for the lines' default speed of sound `sqrt(k R T)`.
const AIR_HEAT_CAPACITY_RATIO: f64 = 1.4;
/// The critical pressure ratio of a leak or line restriction whose sheet gives none (an assumption: the
/// choked flow that a leak from a pressurised chamber mostly is does not depend on it).
const DEFAULT_RESTRICTION_B: f64 = 0.5;

// ---------------------------------------------------------------- cylinder

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct CylinderFile {
    cylinder: CylinderSection,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct CylinderSection {
    #[serde(default)]
    name: String,
    bore_m: f64,
    rod_m: f64,
    stroke_m: f64,
    dead_volume_a_m3: f64,
    dead_volume_b_m3: f64,
    wall_heat_transfer_w_per_m2_k: Option<f64>,
    wall_temperature_k: Option<f64>,
    leaks: Option<LeaksSection>,
}

/// Optional `[cylinder.leaks.<path>]` tables.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct LeaksSection {
    piston: Option<RestrictionSection>,
    a_atmosphere: Option<RestrictionSection>,
    b_atmosphere: Option<RestrictionSection>,
}

/// An ISO 6358 restriction of a leak or a line: C required, b optional.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RestrictionSection {
    sonic_conductance_m3_per_s_pa: f64,
    critical_pressure_ratio: Option<f64>,
}

/// A cylinder data sheet: `[cylinder]` with `bore_m`, `rod_m`, `stroke_m`, `dead_volume_a_m3`,
/// `dead_volume_b_m3` (all > 0, rod < bore) and an optional `name`; optionally the wall heat transfer
/// (`wall_heat_transfer_w_per_m2_k`, `wall_temperature_k`) and leaks (`[cylinder.leaks.piston]`,
/// `[cylinder.leaks.a_atmosphere]`, `[cylinder.leaks.b_atmosphere]`).
#[derive(Clone, Debug, PartialEq)]
pub struct CylinderSheet {
    /// Model name.
    pub name: String,
    /// Geometry.
    pub cylinder: Cylinder,
    /// Wall heat transfer coefficient h, W/(m^2 K), if given.
    pub wall_heat_transfer_w_per_m2_k: Option<f64>,
    /// Wall temperature, K, if given (default: the atmosphere's).
    pub wall_temperature_k: Option<f64>,
    /// Leaks.
    pub leaks: Leaks,
}

impl CylinderSheet {
    /// Reads and validates a cylinder sheet.
    pub fn load(path: &Path) -> Result<Self, ComponentError> {
        Self::from_str(path, &read(path)?)
    }
    /// Parses and validates cylinder TOML text; `path` is used in messages.
    pub fn from_str(path: &Path, text: &str) -> Result<Self, ComponentError> {
        let f: CylinderFile = parse(path, text)?;
        let c = Check { path, text };
        let s = f.cylinder;
        let bore = c.bounded("cylinder.bore_m", s.bore_m, BORE)?;
        let rod = c.positive("cylinder.rod_m", s.rod_m)?;
        if rod >= bore {
            return Err(c.err(
                "cylinder.rod_m",
                format!("must be smaller than cylinder.bore_m = {bore}, got {rod}"),
            ));
        }
        Ok(Self {
            name: s.name,
            cylinder: Cylinder {
                bore_m: bore,
                rod_m: rod,
                stroke_m: c.bounded("cylinder.stroke_m", s.stroke_m, STROKE)?,
                dead_volume_a_m3: c.bounded(
                    "cylinder.dead_volume_a_m3",
                    s.dead_volume_a_m3,
                    DEAD_VOLUME,
                )?,
                dead_volume_b_m3: c.bounded(
                    "cylinder.dead_volume_b_m3",
                    s.dead_volume_b_m3,
                    DEAD_VOLUME,
                )?,
            },
            wall_heat_transfer_w_per_m2_k: s
                .wall_heat_transfer_w_per_m2_k
                .map(|h| c.bounded("cylinder.wall_heat_transfer_w_per_m2_k", h, HEAT_TRANSFER))
                .transpose()?,
            wall_temperature_k: match (s.wall_temperature_k, s.wall_heat_transfer_w_per_m2_k) {
                (Some(_), None) => {
                    return Err(c.err(
                        "cylinder.wall_temperature_k",
                        "applies only with cylinder.wall_heat_transfer_w_per_m2_k".into(),
                    ));
                }
                (t, _) => t
                    .map(|t| c.bounded("cylinder.wall_temperature_k", t, TEMPERATURE))
                    .transpose()?,
            },
            leaks: leaks(&c, s.leaks)?,
        })
    }
}

/// The `[cylinder.leaks.*]` tables.
fn leaks(c: &Check, s: Option<LeaksSection>) -> Result<Leaks, ComponentError> {
    let mut out = Leaks::default();
    let Some(s) = s else { return Ok(out) };
    for (i, r) in [s.piston, s.a_atmosphere, s.b_atmosphere]
        .into_iter()
        .enumerate()
    {
        if let Some(r) = r {
            let key = format!("cylinder.leaks.{}", LEAKS[i]);
            out.set(i, Some(restriction(c, &key, &r, LEAK_CONDUCTANCE)?));
        }
    }
    Ok(out)
}

/// An ISO 6358 restriction under `key` (C within `bound`, b in [0, 1), default 0.5).
fn restriction(
    c: &Check,
    key: &str,
    r: &RestrictionSection,
    bound: Bound,
) -> Result<Orifice, ComponentError> {
    Ok(Orifice {
        sonic_conductance_m3_per_s_pa: c.bounded(
            &format!("{key}.sonic_conductance_m3_per_s_pa"),
            r.sonic_conductance_m3_per_s_pa,
            bound,
        )?,
        critical_pressure_ratio: c.range(
            &format!("{key}.critical_pressure_ratio"),
            r.critical_pressure_ratio.unwrap_or(DEFAULT_RESTRICTION_B),
            0.0,
            1.0,
            "[0, 1)",
        )?,
    })
}

// ---------------------------------------------------------------- valve

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ValveFile {
    valve: ValveSection,
}

#[derive(Deserialize, Clone, Copy, Debug, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
enum ValveKindName {
    Proportional,
    OnOffPwm,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ValveSection {
    #[serde(default)]
    name: String,
    kind: ValveKindName,
    sonic_conductance_m3_per_s_pa: f64,
    critical_pressure_ratio: f64,
    response_time_s: Option<f64>,
    underlap: Option<f64>,
    pwm_frequency_hz: Option<f64>,
    switching_delay_s: Option<f64>,
    release_delay_s: Option<f64>,
    spool_time_constant_s: Option<f64>,
    release_time_constant_s: Option<f64>,
    dead_time_s: Option<f64>,
    #[serde(default)]
    paths: Option<PathsSection>,
}

/// Optional `[valve.paths.<path>]` tables: a path's own C and/or b (the others take the valve's).
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct PathsSection {
    supply_a: Option<PathSection>,
    a_exhaust: Option<PathSection>,
    supply_b: Option<PathSection>,
    b_exhaust: Option<PathSection>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct PathSection {
    sonic_conductance_m3_per_s_pa: Option<f64>,
    critical_pressure_ratio: Option<f64>,
}

/// A valve data sheet: `[valve]` with `kind` = "proportional" (`response_time_s`, `underlap`) or
/// "on_off_pwm" (`pwm_frequency_hz`, `switching_delay_s`), plus `sonic_conductance_m3_per_s_pa` and
/// `critical_pressure_ratio`; optionally `[valve.paths.supply_a]` (`a_exhaust`, `supply_b`,
/// `b_exhaust`) with either of those two keys for a path whose metering edge differs.
#[derive(Clone, Debug, PartialEq)]
pub struct ValveSheet {
    /// Model name.
    pub name: String,
    /// The valve model.
    pub valve: ValveModel,
    /// Spool dynamics beyond the switching delay / response time (`release_delay_s`,
    /// `spool_time_constant_s`, `release_time_constant_s` on/off; `dead_time_s` proportional), if given.
    pub spool: Option<SpoolDynamics>,
}

impl ValveSheet {
    /// Reads and validates a valve sheet.
    pub fn load(path: &Path) -> Result<Self, ComponentError> {
        Self::from_str(path, &read(path)?)
    }
    /// Parses and validates valve TOML text; `path` is used in messages.
    pub fn from_str(path: &Path, text: &str) -> Result<Self, ComponentError> {
        let f: ValveFile = parse(path, text)?;
        let c = Check { path, text };
        let s = f.valve;
        let orifice = Orifice {
            sonic_conductance_m3_per_s_pa: c.bounded(
                "valve.sonic_conductance_m3_per_s_pa",
                s.sonic_conductance_m3_per_s_pa,
                SONIC_CONDUCTANCE,
            )?,
            critical_pressure_ratio: c.range(
                "valve.critical_pressure_ratio",
                s.critical_pressure_ratio,
                0.0,
                1.0,
                "[0, 1)",
            )?,
        };
        let mut paths = [None; 4];
        if let Some(p) = s.paths {
            let given = [p.supply_a, p.a_exhaust, p.supply_b, p.b_exhaust];
            for (i, g) in given.into_iter().enumerate() {
                let Some(g) = g else { continue };
                let key = |k: &str| format!("valve.paths.{}.{k}", PATHS[i]);
                let mut o = orifice;
                if let Some(v) = g.sonic_conductance_m3_per_s_pa {
                    o.sonic_conductance_m3_per_s_pa =
                        c.bounded(&key("sonic_conductance_m3_per_s_pa"), v, SONIC_CONDUCTANCE)?;
                }
                if let Some(v) = g.critical_pressure_ratio {
                    o.critical_pressure_ratio =
                        c.range(&key("critical_pressure_ratio"), v, 0.0, 1.0, "[0, 1)")?;
                }
                paths[i] = Some(o);
            }
        }
        let not_for = |field: &str, v: Option<f64>, kind: &str| match v {
            Some(_) => Err(c.err(
                field,
                format!("does not apply to kind = \"{kind}\"; remove it"),
            )),
            None => Ok(()),
        };
        let required = |field: &str, v: Option<f64>, kind: &str| {
            v.ok_or_else(|| c.err(field, format!("required for kind = \"{kind}\"")))
        };
        let (underlap, kind) = match s.kind {
            ValveKindName::Proportional => {
                not_for("valve.pwm_frequency_hz", s.pwm_frequency_hz, "proportional")?;
                not_for(
                    "valve.switching_delay_s",
                    s.switching_delay_s,
                    "proportional",
                )?;
                for (k, v) in [
                    ("valve.release_delay_s", s.release_delay_s),
                    ("valve.spool_time_constant_s", s.spool_time_constant_s),
                    ("valve.release_time_constant_s", s.release_time_constant_s),
                ] {
                    not_for(k, v, "proportional")?;
                }
                let tau = c.non_negative(
                    "valve.response_time_s",
                    required("valve.response_time_s", s.response_time_s, "proportional")?,
                )?;
                c.bounded("valve.response_time_s", tau, VALVE_TIME)?;
                let e = c.range(
                    "valve.underlap",
                    s.underlap.unwrap_or(0.0),
                    0.0,
                    1.0,
                    "[0, 1)",
                )?;
                (
                    e,
                    ValveKind::Proportional {
                        response_time_s: tau,
                    },
                )
            }
            ValveKindName::OnOffPwm => {
                not_for("valve.response_time_s", s.response_time_s, "on_off_pwm")?;
                not_for("valve.underlap", s.underlap, "on_off_pwm")?;
                not_for("valve.dead_time_s", s.dead_time_s, "on_off_pwm")?;
                let f_hz = c.positive(
                    "valve.pwm_frequency_hz",
                    required("valve.pwm_frequency_hz", s.pwm_frequency_hz, "on_off_pwm")?,
                )?;
                c.bounded("valve.pwm_frequency_hz", f_hz, PWM_FREQUENCY)?;
                let delay = c.non_negative(
                    "valve.switching_delay_s",
                    s.switching_delay_s.unwrap_or(0.0),
                )?;
                if delay >= 1.0 / f_hz {
                    return Err(c.err(
                        "valve.switching_delay_s",
                        format!(
                            "must be shorter than one PWM period (1/valve.pwm_frequency_hz = {} s), got {delay}",
                            1.0 / f_hz
                        ),
                    ));
                }
                (
                    0.0,
                    ValveKind::OnOffPwm {
                        pwm_frequency_hz: f_hz,
                        switching_delay_s: delay,
                    },
                )
            }
        };
        let time = |k: &str, v: Option<f64>| v.map(|v| c.bounded(k, v, VALVE_TIME)).transpose();
        let spool = SpoolDynamics {
            release_delay_s: time("valve.release_delay_s", s.release_delay_s)?,
            spool_time_constant_s: time("valve.spool_time_constant_s", s.spool_time_constant_s)?
                .unwrap_or(0.0),
            release_time_constant_s: time(
                "valve.release_time_constant_s",
                s.release_time_constant_s,
            )?,
            dead_time_s: time("valve.dead_time_s", s.dead_time_s)?.unwrap_or(0.0),
        };
        let given = [
            s.release_delay_s,
            s.spool_time_constant_s,
            s.release_time_constant_s,
            s.dead_time_s,
        ]
        .iter()
        .any(Option::is_some);
        Ok(Self {
            name: s.name,
            valve: ValveModel {
                orifice,
                paths,
                underlap,
                kind,
            },
            spool: given.then_some(spool),
        })
    }
}

// ---------------------------------------------------------------- supply

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SupplyFile {
    supply: PressureTemp,
    #[serde(default)]
    atmosphere: Option<PressureTemp>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct PressureTemp {
    pressure_abs_pa: f64,
    temperature_k: f64,
}

/// A supply sheet: `[supply]` and optional `[atmosphere]`, each with `pressure_abs_pa` (absolute) and
/// `temperature_k`; atmosphere defaults to 101325 Pa, 293.15 K. Supply must exceed atmosphere.
#[derive(Clone, Debug, PartialEq)]
pub struct SupplySheet {
    /// Supply and exhaust conditions.
    pub supply: Supply,
}

impl SupplySheet {
    /// Reads and validates a supply sheet.
    pub fn load(path: &Path) -> Result<Self, ComponentError> {
        Self::from_str(path, &read(path)?)
    }
    /// Parses and validates supply TOML text; `path` is used in messages.
    pub fn from_str(path: &Path, text: &str) -> Result<Self, ComponentError> {
        let f: SupplyFile = parse(path, text)?;
        let c = Check { path, text };
        let (p_atm, t_atm) = match f.atmosphere {
            Some(a) => (
                c.bounded(
                    "atmosphere.pressure_abs_pa",
                    a.pressure_abs_pa,
                    ATMOSPHERE_PRESSURE,
                )?,
                c.bounded("atmosphere.temperature_k", a.temperature_k, TEMPERATURE)?,
            ),
            None => (crate::actuator::P_ATM, crate::actuator::T_DEFAULT),
        };
        let ps = c.positive("supply.pressure_abs_pa", f.supply.pressure_abs_pa)?;
        if ps <= p_atm {
            return Err(c.err(
                "supply.pressure_abs_pa",
                format!(
                    "must be above the atmosphere ({p_atm} Pa absolute; give absolute pressure, gauge + atmosphere), got {ps}"
                ),
            ));
        }
        if ps > SUPPLY_PRESSURE_MAX_PA {
            return Err(c.err(
                "supply.pressure_abs_pa",
                format!(
                    "must be at most {} Pa absolute (pneumatic supplies are <= 1.6 MPa), got {}",
                    num(SUPPLY_PRESSURE_MAX_PA),
                    num(ps)
                ),
            ));
        }
        Ok(Self {
            supply: Supply {
                supply_pressure_pa: ps,
                supply_temperature_k: c.bounded(
                    "supply.temperature_k",
                    f.supply.temperature_k,
                    TEMPERATURE,
                )?,
                atmosphere_pressure_pa: p_atm,
                atmosphere_temperature_k: t_atm,
            },
        })
    }
}

// ---------------------------------------------------------------- sensors

/// What a sensor measures.
#[derive(Deserialize, Clone, Copy, Debug, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum Quantity {
    /// Pressure difference p_a - p_b, Pa.
    DifferentialPressure,
    /// Flange/piston position x, m.
    Position,
}

/// The electrical output of a sensor.
#[derive(Deserialize, Clone, Copy, Debug, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum SignalKind {
    /// Current loop, mA.
    CurrentMa,
    /// Voltage, V.
    VoltageV,
    /// ADC counts.
    Counts,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SensorFile {
    sensor: SensorSection,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SensorSection {
    #[serde(default)]
    name: String,
    quantity: Quantity,
    range_min_si: f64,
    range_max_si: f64,
    signal: SignalKind,
    signal_min: f64,
    signal_max: f64,
}

/// A linear sensor sheet: `[sensor]` with `quantity`, `range_min_si`/`range_max_si` (Pa or m),
/// `signal` ("current_ma" | "voltage_v" | "counts") and `signal_min`/`signal_max` at the range ends.
#[derive(Clone, Debug, PartialEq)]
pub struct SensorSheet {
    /// Model name.
    pub name: String,
    /// Measured quantity.
    pub quantity: Quantity,
    /// Lower end of the measuring range, SI (Pa or m).
    pub range_min_si: f64,
    /// Upper end of the measuring range, SI.
    pub range_max_si: f64,
    /// Output signal kind.
    pub signal: SignalKind,
    /// Output at `range_min_si` (mA, V or counts).
    pub signal_min: f64,
    /// Output at `range_max_si`.
    pub signal_max: f64,
}

impl SensorSheet {
    /// Reads and validates a sensor sheet.
    pub fn load(path: &Path) -> Result<Self, ComponentError> {
        Self::from_str(path, &read(path)?)
    }
    /// Parses and validates sensor TOML text; `path` is used in messages.
    pub fn from_str(path: &Path, text: &str) -> Result<Self, ComponentError> {
        let f: SensorFile = parse(path, text)?;
        let c = Check { path, text };
        let s = f.sensor;
        let lo = c.finite("sensor.range_min_si", s.range_min_si)?;
        let hi = c.finite("sensor.range_max_si", s.range_max_si)?;
        if hi <= lo {
            return Err(c.err(
                "sensor.range_max_si",
                format!("must be greater than sensor.range_min_si = {lo}, got {hi}"),
            ));
        }
        let smin = c.finite("sensor.signal_min", s.signal_min)?;
        let smax = c.finite("sensor.signal_max", s.signal_max)?;
        if smax == smin {
            return Err(c.err(
                "sensor.signal_max",
                format!("must differ from sensor.signal_min = {smin}"),
            ));
        }
        Ok(Self {
            name: s.name,
            quantity: s.quantity,
            range_min_si: lo,
            range_max_si: hi,
            signal: s.signal,
            signal_min: smin,
            signal_max: smax,
        })
    }

    /// Converts a raw output (mA, V or counts) to the measured quantity, SI (linear, not clamped).
    pub fn to_si(&self, raw: f64) -> f64 {
        self.range_min_si
            + (raw - self.signal_min) * (self.range_max_si - self.range_min_si)
                / (self.signal_max - self.signal_min)
    }

    /// Converts a quantity (SI) to the raw output the sensor would give, clamped to its output range.
    pub fn to_signal(&self, si: f64) -> f64 {
        let v = si.clamp(self.range_min_si, self.range_max_si);
        self.signal_min
            + (v - self.range_min_si) * (self.signal_max - self.signal_min)
                / (self.range_max_si - self.range_min_si)
    }
}

// ---------------------------------------------------------------- actuator sheet

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ActuatorFile {
    #[serde(default)]
    name: String,
    components: ComponentPaths,
    #[serde(default)]
    gas: Option<GasSection>,
    mechanics: MechanicsSection,
    lines: Option<LinesSection>,
}

/// Optional `[lines]`: the tubes between the valve and the ports (both sides alike).
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct LinesSection {
    volume_m3: f64,
    sonic_conductance_m3_per_s_pa: f64,
    critical_pressure_ratio: Option<f64>,
    length_m: Option<f64>,
    speed_of_sound_m_per_s: Option<f64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ComponentPaths {
    cylinder: String,
    valve: String,
    supply: String,
    pressure_sensor: Option<String>,
    position_sensor: Option<String>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct GasSection {
    gas_constant_j_per_kg_k: Option<f64>,
    polytropic_exponent: Option<f64>,
}

#[derive(Deserialize, Clone, Copy, Debug, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
enum FrictionName {
    Smooth,
    StickSlip,
    Lugre,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct MechanicsSection {
    moving_mass_kg: f64,
    viscous_n_s_per_m: f64,
    friction: FrictionName,
    coulomb_n: f64,
    smooth_velocity_m_per_s: Option<f64>,
    static_n: Option<f64>,
    stribeck_velocity_m_per_s: Option<f64>,
    stick_velocity_m_per_s: Option<f64>,
    bristle_stiffness_n_per_m: Option<f64>,
    bristle_damping_n_s_per_m: Option<f64>,
    coulomb_pressure_n_per_pa: Option<f64>,
    coulomb_negative_n: Option<f64>,
    alpha_deg: f64,
    gravity_m_per_s2: Option<f64>,
}

/// An actuator sheet: names the component files (paths relative to the sheet) and adds gas, moving mass,
/// friction and incline. See docs/pneumatics.md for every key, unit and default.
#[derive(Clone, Debug, PartialEq)]
pub struct ActuatorSheet {
    /// Path the sheet was loaded from.
    pub path: PathBuf,
    /// Actuator name.
    pub name: String,
    /// The cylinder sheet.
    pub cylinder: CylinderSheet,
    /// The valve sheet.
    pub valve: ValveSheet,
    /// The supply sheet.
    pub supply: SupplySheet,
    /// Differential pressure transmitter, if given.
    pub pressure_sensor: Option<SensorSheet>,
    /// Position sensor, if given.
    pub position_sensor: Option<SensorSheet>,
    /// Gas properties.
    pub gas: Gas,
    /// Mechanics of eq. (1).
    pub mechanics: Mechanics,
    /// Effects beyond the paper, from the cylinder, valve and actuator sheets (none: the paper's model).
    pub effects: Effects,
}

impl ActuatorSheet {
    /// Reads an actuator sheet and every component file it names, validating all of them.
    pub fn load(path: impl AsRef<Path>) -> Result<Self, ComponentError> {
        Self::load_overlaid(path, &FileOverlay::new())
    }

    /// [`ActuatorSheet::load`] with some files' texts given instead of read: a file whose path (the sheet's
    /// path, or the sheet's folder joined with the component's name as written) is a key of `overlay` is
    /// parsed from that text (a sweep's edited copy), every other one is read. Errors name the file as if
    /// it had been read.
    pub fn load_overlaid(
        path: impl AsRef<Path>,
        overlay: &FileOverlay,
    ) -> Result<Self, ComponentError> {
        let path = path.as_ref();
        let read = |p: &Path| match overlay.get(p) {
            Some(t) => Ok(t.clone()),
            None => read(p),
        };
        let text = read(path)?;
        let f: ActuatorFile = parse(path, &text)?;
        let c = Check { path, text: &text };
        let dir = path.parent().unwrap_or_else(|| Path::new(""));
        // A component that cannot be read is blamed on the key naming it, too.
        let named = |key: &str, e: ComponentError| c.referenced(key, e);
        let cylinder = {
            let p = dir.join(&f.components.cylinder);
            read(&p).and_then(|t| CylinderSheet::from_str(&p, &t))
        }
        .map_err(|e| named("components.cylinder", e))?;
        let valve = {
            let p = dir.join(&f.components.valve);
            read(&p).and_then(|t| ValveSheet::from_str(&p, &t))
        }
        .map_err(|e| named("components.valve", e))?;
        let supply = {
            let p = dir.join(&f.components.supply);
            read(&p).and_then(|t| SupplySheet::from_str(&p, &t))
        }
        .map_err(|e| named("components.supply", e))?;
        let sensor =
            |p: &Option<String>, field: &str, want: Quantity| -> Result<_, ComponentError> {
                match p {
                    None => Ok(None),
                    Some(p) => {
                        let file = dir.join(p);
                        let s = read(&file)
                            .and_then(|t| SensorSheet::from_str(&file, &t))
                            .map_err(|e| named(field, e))?;
                        if s.quantity != want {
                            return Err(c.err(
                                field,
                                format!("{p} measures {:?}, expected {:?}", s.quantity, want),
                            ));
                        }
                        Ok(Some(s))
                    }
                }
            };
        let pressure_sensor = sensor(
            &f.components.pressure_sensor,
            "components.pressure_sensor",
            Quantity::DifferentialPressure,
        )?;
        let position_sensor = sensor(
            &f.components.position_sensor,
            "components.position_sensor",
            Quantity::Position,
        )?;
        let gas = match &f.gas {
            None => Gas::default(),
            Some(g) => {
                let n = g.polytropic_exponent.unwrap_or(1.4);
                c.finite("gas.polytropic_exponent", n)?;
                if !(1.0..=1.67).contains(&n) {
                    return Err(c.err(
                        "gas.polytropic_exponent",
                        format!(
                            "must be in [1, 1.67] (1 = isothermal, 1.4 = adiabatic air), got {n}"
                        ),
                    ));
                }
                Gas {
                    gas_constant_j_per_kg_k: c.bounded(
                        "gas.gas_constant_j_per_kg_k",
                        g.gas_constant_j_per_kg_k.unwrap_or(R_AIR),
                        GAS_CONSTANT,
                    )?,
                    polytropic_exponent: n,
                }
            }
        };
        let m = &f.mechanics;
        let friction = friction(&c, m)?;
        let alpha = c.finite("mechanics.alpha_deg", m.alpha_deg)?;
        if !(-90.0..=90.0).contains(&alpha) {
            return Err(c.err(
                "mechanics.alpha_deg",
                format!("must be in [-90, 90] degrees below the horizontal, got {alpha}"),
            ));
        }
        let mechanics = Mechanics {
            moving_mass_kg: c.bounded("mechanics.moving_mass_kg", m.moving_mass_kg, MOVING_MASS)?,
            viscous_n_s_per_m: c.bounded(
                "mechanics.viscous_n_s_per_m",
                m.viscous_n_s_per_m,
                VISCOUS,
            )?,
            friction,
            alpha_rad: alpha.to_radians(),
            gravity_m_per_s2: c.bounded(
                "mechanics.gravity_m_per_s2",
                m.gravity_m_per_s2.unwrap_or(STANDARD_GRAVITY),
                GRAVITY,
            )?,
        };
        let effects = effects(&c, &f, &cylinder, &valve, &gas, &supply.supply)?;
        Ok(Self {
            path: path.to_path_buf(),
            name: f.name,
            cylinder,
            valve,
            supply,
            pressure_sensor,
            position_sensor,
            gas,
            mechanics,
            effects,
        })
    }

    /// The pneumatic part described by the sheet.
    pub fn actuator(&self) -> Actuator {
        Actuator {
            cylinder: self.cylinder.cylinder,
            gas: self.gas,
            valve: self.valve.valve,
            supply: self.supply.supply,
        }
    }

    /// The full 1-DOF model described by the sheet.
    pub fn model(&self) -> OneDofModel {
        OneDofModel {
            actuator: self.actuator(),
            mechanics: self.mechanics,
            effects: self.effects,
        }
    }

    /// The keys of the effects beyond the paper this sheet gives (wall heat, leaks, lines, spool dynamics,
    /// seal friction, LuGre friction), as its errors spell them; empty for the paper's model. A host that
    /// integrates the paper's model only (the multibody force element, the MuJoCo plugin) refuses a sheet
    /// that gives any, naming them.
    pub fn effects_beyond_paper(&self) -> Vec<String> {
        let mut given = self.effects.given();
        if matches!(self.mechanics.friction, Friction::LuGre { .. }) {
            given.push("mechanics.friction = \"lugre\"".into());
        }
        given
    }
}

/// Friction keys and the laws they apply to (a key given for another law is refused).
const FRICTION_KEYS: [(&str, &[FrictionName]); 6] = [
    ("mechanics.smooth_velocity_m_per_s", &[FrictionName::Smooth]),
    (
        "mechanics.static_n",
        &[FrictionName::StickSlip, FrictionName::Lugre],
    ),
    (
        "mechanics.stribeck_velocity_m_per_s",
        &[FrictionName::StickSlip, FrictionName::Lugre],
    ),
    (
        "mechanics.stick_velocity_m_per_s",
        &[FrictionName::StickSlip],
    ),
    (
        "mechanics.bristle_stiffness_n_per_m",
        &[FrictionName::Lugre],
    ),
    (
        "mechanics.bristle_damping_n_s_per_m",
        &[FrictionName::Lugre],
    ),
];

/// The `[mechanics]` friction law: `friction` and the keys of that law (the others' keys refused).
fn friction(c: &Check, m: &MechanicsSection) -> Result<Friction, ComponentError> {
    let given = [
        m.smooth_velocity_m_per_s,
        m.static_n,
        m.stribeck_velocity_m_per_s,
        m.stick_velocity_m_per_s,
        m.bristle_stiffness_n_per_m,
        m.bristle_damping_n_s_per_m,
    ];
    for ((key, laws), v) in FRICTION_KEYS.iter().zip(given) {
        if v.is_some() && !laws.contains(&m.friction) {
            let names: Vec<String> = laws.iter().map(|l| format!("\"{}\"", l.name())).collect();
            return Err(c.err(
                key,
                format!("applies only to friction = {}", names.join(" or ")),
            ));
        }
    }
    let coulomb = c.bounded("mechanics.coulomb_n", m.coulomb_n, FRICTION_FORCE)?;
    let velocity = |key: &str, v: Option<f64>, default: f64| {
        c.bounded(key, v.unwrap_or(default), FRICTION_VELOCITY)
    };
    if m.friction == FrictionName::Smooth {
        return Ok(Friction::Smooth {
            coulomb_n: coulomb,
            smooth_velocity_m_per_s: velocity(
                "mechanics.smooth_velocity_m_per_s",
                m.smooth_velocity_m_per_s,
                1e-3,
            )?,
        });
    }
    let fs = c.bounded(
        "mechanics.static_n",
        m.static_n.unwrap_or(coulomb),
        FRICTION_FORCE,
    )?;
    if fs < coulomb {
        return Err(c.err(
            "mechanics.static_n",
            format!("must be >= mechanics.coulomb_n = {coulomb}, got {fs}"),
        ));
    }
    let vs = velocity(
        "mechanics.stribeck_velocity_m_per_s",
        m.stribeck_velocity_m_per_s,
        1e-3,
    )?;
    if m.friction == FrictionName::StickSlip {
        return Ok(Friction::StickSlip {
            coulomb_n: coulomb,
            static_n: fs,
            stribeck_velocity_m_per_s: vs,
            stick_velocity_m_per_s: velocity(
                "mechanics.stick_velocity_m_per_s",
                m.stick_velocity_m_per_s,
                1e-4,
            )?,
        });
    }
    if coulomb <= 0.0 {
        return Err(c.err(
            "mechanics.coulomb_n",
            "must be > 0 for friction = \"lugre\" (the bristles relax towards F_c / sigma0)".into(),
        ));
    }
    let required = |key: &str, v: Option<f64>, b: Bound| {
        v.ok_or_else(|| c.err(key, "required for friction = \"lugre\"".into()))
            .and_then(|v| c.bounded(key, v, b))
    };
    Ok(Friction::LuGre {
        coulomb_n: coulomb,
        static_n: fs,
        stribeck_velocity_m_per_s: vs,
        bristle_stiffness_n_per_m: required(
            "mechanics.bristle_stiffness_n_per_m",
            m.bristle_stiffness_n_per_m,
            BRISTLE_STIFFNESS,
        )?,
        bristle_damping_n_s_per_m: required(
            "mechanics.bristle_damping_n_s_per_m",
            m.bristle_damping_n_s_per_m,
            BRISTLE_DAMPING,
        )?,
    })
}

impl FrictionName {
    fn name(self) -> &'static str {
        match self {
            FrictionName::Smooth => "smooth",
            FrictionName::StickSlip => "stick_slip",
            FrictionName::Lugre => "lugre",
        }
    }
}

/// The effects the three sheets give: wall heat and leaks (cylinder), spool dynamics (valve), lines and the
/// pressure term of the friction (actuator sheet). The lines' speed of sound defaults to `sqrt(k R T_s)`
/// with k = 1.4 (air) and the supply temperature; the wall temperature to the atmosphere's.
fn effects(
    c: &Check,
    f: &ActuatorFile,
    cylinder: &CylinderSheet,
    valve: &ValveSheet,
    gas: &Gas,
    supply: &Supply,
) -> Result<Effects, ComponentError> {
    let lines = match &f.lines {
        None => None,
        Some(l) => Some(Lines {
            volume_m3: c.bounded("lines.volume_m3", l.volume_m3, DEAD_VOLUME)?,
            orifice: restriction(
                c,
                "lines",
                &RestrictionSection {
                    sonic_conductance_m3_per_s_pa: l.sonic_conductance_m3_per_s_pa,
                    critical_pressure_ratio: l.critical_pressure_ratio,
                },
                SONIC_CONDUCTANCE,
            )?,
            length_m: c.bounded("lines.length_m", l.length_m.unwrap_or(0.0), LINE_LENGTH)?,
            speed_of_sound_m_per_s: c.bounded(
                "lines.speed_of_sound_m_per_s",
                l.speed_of_sound_m_per_s.unwrap_or_else(|| {
                    (AIR_HEAT_CAPACITY_RATIO
                        * gas.gas_constant_j_per_kg_k
                        * supply.supply_temperature_k)
                        .sqrt()
                }),
                SOUND_SPEED,
            )?,
        }),
    };
    let coulomb_pressure_n_per_pa = f
        .mechanics
        .coulomb_pressure_n_per_pa
        .map(|k| c.bounded("mechanics.coulomb_pressure_n_per_pa", k, COULOMB_PRESSURE))
        .transpose()?;
    let coulomb_negative_n = f
        .mechanics
        .coulomb_negative_n
        .map(|v| c.bounded("mechanics.coulomb_negative_n", v, FRICTION_FORCE))
        .transpose()?;
    if coulomb_negative_n == Some(0.0) && f.mechanics.friction == FrictionName::Lugre {
        return Err(c.err(
            "mechanics.coulomb_negative_n",
            "must be > 0 for friction = \"lugre\" (the bristles relax towards F_c / sigma0)".into(),
        ));
    }
    Ok(Effects {
        wall_heat: cylinder.wall_heat_transfer_w_per_m2_k.map(|h| WallHeat {
            coefficient_w_per_m2_k: h,
            wall_temperature_k: cylinder
                .wall_temperature_k
                .unwrap_or(supply.atmosphere_temperature_k),
        }),
        leaks: cylinder.leaks,
        lines,
        spool: valve.spool,
        coulomb_pressure_n_per_pa,
        coulomb_negative_n,
    })
}

/// The actuator sheet a file refers to: the file itself if it is an actuator sheet (has
/// `[components]`), or the sheet named by `plant.actuator` (relative to the file) in a scene file.
pub fn find_actuator_sheet(path: &Path) -> Result<PathBuf, ComponentError> {
    find_sheet(path).map(|(p, _)| p)
}

/// The sheet's path and, when a scene named it, the scene's line of `plant.actuator`.
fn find_sheet(path: &Path) -> Result<(PathBuf, Option<Option<Position>>), ComponentError> {
    let text = read(path)?;
    let table: toml::Table = parse(path, &text)?;
    if table.contains_key("components") {
        return Ok((path.to_path_buf(), None));
    }
    let named = table
        .get("plant")
        .and_then(|p| p.get("actuator"))
        .and_then(|a| a.as_str());
    let line = key_at(&text, "plant.actuator");
    match named {
        Some(p) => {
            let p = Path::new(p);
            let sheet = if p.is_absolute() {
                p.to_path_buf()
            } else {
                path.parent().unwrap_or_else(|| Path::new("")).join(p)
            };
            Ok((sheet, Some(line)))
        }
        None => Err(ComponentError::Invalid {
            file: path.to_path_buf(),
            at: line,
            key: "plant.actuator".into(),
            message:
                "neither an actuator sheet ([components]) nor a scene naming one (plant.actuator)"
                    .into(),
        }),
    }
}

/// Loads the actuator sheet `path` is or names (see [`find_actuator_sheet`]); a sheet named by a scene
/// that cannot be read is reported at the scene's `plant.actuator` key.
pub fn load_actuator_sheet(path: &Path) -> Result<ActuatorSheet, ComponentError> {
    let (sheet, scene_line) = find_sheet(path)?;
    ActuatorSheet::load(&sheet).map_err(|e| match (e, scene_line) {
        (e @ (ComponentError::Io { .. } | ComponentError::Input(_)), Some(line)) => {
            ComponentError::Referenced {
                file: path.to_path_buf(),
                at: line,
                key: "plant.actuator".into(),
                error: Box::new(e),
            }
        }
        (e, _) => e,
    })
}
