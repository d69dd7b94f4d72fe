//! Muscle sheets as TOML (`pneumatics/*-muscle.toml`): the muscle as a catalogue gives it, its gas, and the
//! supply and valve sheets it names (paths relative to the sheet), or a pressure regulator. Unknown keys
//! are refused; every error names the file, the line and the key. docs/muscles.md lists every key.

use std::path::{Path, PathBuf};

use pneuflex_files::Position;
use pneuflex_pneumatics::{ComponentError, Gas, R_AIR, SupplySheet, ValveSheet};
use serde::Deserialize;

use crate::braid::{
    Braid, BraidFriction, Muscle, NEUTRAL_BRAID_ANGLE_RAD, geometric_max_contraction,
};
use crate::chamber::MuscleChamber;
use crate::plant::Feed;

/// Why a muscle sheet was not loaded.
#[derive(Debug, thiserror::Error)]
pub enum SheetError {
    /// Not readable, not a regular file, too large, or not UTF-8.
    #[error(transparent)]
    Input(pneuflex_files::InputError),
    /// Not valid TOML, or a key unknown, missing or of the wrong type.
    #[error("{}{}: {message}", file.display(), at_pos(at))]
    Parse {
        /// The sheet.
        file: PathBuf,
        /// Line and column, when known.
        at: Option<Position>,
        /// The parser's message (names the key).
        message: String,
    },
    /// A value out of range, or keys that contradict each other.
    #[error("{}{}: {key}: {message}", file.display(), at_pos(at))]
    Invalid {
        /// The sheet.
        file: PathBuf,
        /// Line and column of the key (of its table when absent), when known.
        at: Option<Position>,
        /// Dotted key, e.g. `muscle.braid_angle_deg`.
        key: String,
        /// What was expected and what was found.
        message: String,
    },
    /// A supply or valve sheet the muscle sheet names could not be loaded.
    #[error("{}{}: {key}: {error}", file.display(), at_pos(at))]
    Component {
        /// The muscle sheet.
        file: PathBuf,
        /// Line and column of the key naming the component, when known.
        at: Option<Position>,
        /// `components.supply` or `components.valve`.
        key: String,
        /// The component's own error (names its file, line and key).
        error: Box<ComponentError>,
    },
}

fn at_pos(at: &Option<Position>) -> String {
    at.map_or_else(String::new, |p| format!(":{p}"))
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct MuscleFile {
    #[serde(default)]
    name: String,
    muscle: MuscleSection,
    gas: Option<GasSection>,
    components: ComponentsSection,
    regulator: Option<RegulatorSection>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct MuscleSection {
    nominal_diameter_m: f64,
    rest_length_m: f64,
    braid_angle_deg: Option<f64>,
    braid_length_m: Option<f64>,
    braid_turns: Option<f64>,
    end_effect_factor: Option<f64>,
    max_contraction: Option<f64>,
    dead_volume_m3: f64,
    stretch_stiffness_n_per_m: Option<f64>,
    friction: Option<FrictionSection>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FrictionSection {
    coulomb_n: f64,
    coulomb_n_per_pa: Option<f64>,
    smooth_velocity_m_per_s: f64,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct GasSection {
    gas_constant_j_per_kg_k: Option<f64>,
    polytropic_exponent: Option<f64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ComponentsSection {
    supply: String,
    valve: Option<String>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RegulatorSection {
    time_constant_s: f64,
}

/// What feeds the muscle, as the sheet says.
#[derive(Clone, Debug, PartialEq)]
pub enum FeedSheet {
    /// A 3/2 valve: the valve sheet named by `components.valve` (its supply_a and a_exhaust paths).
    Valve(Box<ValveSheet>),
    /// A pressure regulator, `[regulator] time_constant_s`.
    Regulator {
        /// Time constant of the regulated pressure, s.
        time_constant_s: f64,
    },
}

/// A loaded muscle sheet.
#[derive(Clone, Debug, PartialEq)]
pub struct MuscleSheet {
    /// The file it was read from.
    pub path: PathBuf,
    /// The muscle's name.
    pub name: String,
    /// Muscle, gas and supply.
    pub chamber: MuscleChamber,
    /// Valve or regulator.
    pub feed: FeedSheet,
}

/// A value's physical range; the message says what it stands for.
struct Bound {
    min: f64,
    max: f64,
    unit: &'static str,
    why: &'static str,
}

const DIAMETER: Bound = Bound {
    min: 1e-3,
    max: 0.2,
    unit: "m",
    why: "braided muscles are ~5 to 40 mm across",
};
const LENGTH: Bound = Bound {
    min: 5e-3,
    max: 10.0,
    unit: "m",
    why: "catalogue muscles are 30 mm to 9 m long",
};
const DEAD_VOLUME: Bound = Bound {
    min: 1e-9,
    max: 1e-2,
    unit: "m^3",
    why: "fittings and tubing, 1 mm^3 to 10 l",
};
const STIFFNESS: Bound = Bound {
    min: 0.0,
    max: 1e8,
    unit: "N/m",
    why: "the braid's tensile stiffness past the rest length",
};
const FRICTION_FORCE: Bound = Bound {
    min: 0.0,
    max: 1e4,
    unit: "N",
    why: "braid friction",
};
const FRICTION_PER_PA: Bound = Bound {
    min: 0.0,
    max: 1e-3,
    unit: "N/Pa",
    why: "1e-3 N/Pa is 100 N per bar",
};
const FRICTION_VELOCITY: Bound = Bound {
    min: 1e-6,
    max: 10.0,
    unit: "m/s",
    why: "the tanh's velocity scale",
};
const END_EFFECT: Bound = Bound {
    min: 1.0,
    max: 10.0,
    unit: "",
    why: "k = 1 is the ideal cylinder, the end caps only shorten the stroke",
};
const GAS_CONSTANT: Bound = Bound {
    min: 100.0,
    max: 5000.0,
    unit: "J/(kg K)",
    why: "CO2 is 189, air 287, hydrogen 4124",
};
const REGULATOR_TIME: Bound = Bound {
    min: 1e-5,
    max: 10.0,
    unit: "s",
    why: "regulators settle in ms to s",
};

/// Field checks bound to one sheet's text: errors carry the key's line.
struct Check<'a> {
    path: &'a Path,
    text: &'a str,
}

impl Check<'_> {
    fn err(&self, key: &str, message: String) -> SheetError {
        SheetError::Invalid {
            file: self.path.to_path_buf(),
            at: pneuflex_files::toml_key_position(self.text, key),
            key: key.to_string(),
            message,
        }
    }
    fn bounded(&self, key: &str, v: f64, b: Bound) -> Result<f64, SheetError> {
        pneuflex_files::check::finite(v).map_err(|m| self.err(key, m))?;
        if v >= b.min && v <= b.max {
            Ok(v)
        } else {
            let unit = if b.unit.is_empty() {
                String::new()
            } else {
                format!(" {}", b.unit)
            };
            Err(self.err(
                key,
                format!(
                    "must be in [{}, {}]{unit} ({}), got {v}",
                    b.min, b.max, b.why
                ),
            ))
        }
    }
    /// Exactly one of the keys `keys` (under `table`) given: its index and value.
    fn one_of(
        &self,
        table: &str,
        keys: &[(&str, Option<f64>)],
    ) -> Result<(usize, f64), SheetError> {
        let given: Vec<usize> = (0..keys.len()).filter(|&i| keys[i].1.is_some()).collect();
        let names = keys
            .iter()
            .map(|(k, _)| format!("{table}.{k}"))
            .collect::<Vec<_>>()
            .join(", ");
        match given[..] {
            [i] => Ok((i, keys[i].1.unwrap_or_default())),
            [] => Err(self.err(table, format!("give one of {names}"))),
            [_, j, ..] => Err(self.err(
                &format!("{table}.{}", keys[j].0),
                format!("give only one of {names}"),
            )),
        }
    }
}

impl MuscleSheet {
    /// Reads and validates a muscle sheet and the supply and valve sheets it names.
    pub fn load(path: impl AsRef<Path>) -> Result<Self, SheetError> {
        let path = path.as_ref();
        let text = pneuflex_files::read_text(path, pneuflex_files::InputKind::Sheet)
            .map_err(SheetError::Input)?;
        Self::from_str(path, &text)
    }

    /// Parses and validates muscle-sheet text; `path` names it in messages and locates the components.
    pub fn from_str(path: &Path, text: &str) -> Result<Self, SheetError> {
        let f: MuscleFile = toml::from_str(text).map_err(|e| SheetError::Parse {
            file: path.to_path_buf(),
            at: e.span().map(|s| pneuflex_files::line_col(text, s.start)),
            message: e.message().trim().to_string(),
        })?;
        let c = Check { path, text };
        let m = &f.muscle;
        let diameter = c.bounded("muscle.nominal_diameter_m", m.nominal_diameter_m, DIAMETER)?;
        let length = c.bounded("muscle.rest_length_m", m.rest_length_m, LENGTH)?;
        // The rest braid angle, from whichever the catalogue gives: L0 = b cos(alpha0) and
        // tan(alpha0) = n pi D_rest / L0 (M1).
        let (which, v) = c.one_of(
            "muscle",
            &[
                ("braid_angle_deg", m.braid_angle_deg),
                ("braid_length_m", m.braid_length_m),
                ("braid_turns", m.braid_turns),
            ],
        )?;
        let (key, alpha0) = match which {
            0 => ("muscle.braid_angle_deg", v.to_radians()),
            1 => {
                let b = c.bounded("muscle.braid_length_m", v, LENGTH)?;
                if b <= length {
                    return Err(c.err(
                        "muscle.braid_length_m",
                        format!(
                            "must be longer than muscle.rest_length_m ({length} m): L0 = b cos(alpha0), got {b}"
                        ),
                    ));
                }
                ("muscle.braid_length_m", (length / b).acos())
            }
            _ => {
                pneuflex_files::check::positive(v).map_err(|e| c.err("muscle.braid_turns", e))?;
                (
                    "muscle.braid_turns",
                    (v * core::f64::consts::PI * diameter / length).atan(),
                )
            }
        };
        if !(alpha0.is_finite() && alpha0 > 0.0 && alpha0 < NEUTRAL_BRAID_ANGLE_RAD) {
            return Err(c.err(
                key,
                format!(
                    "gives a rest braid angle of {:.4} deg; a muscle contracts only below 54.7356 deg (tan^2 = 2)",
                    alpha0.to_degrees()
                ),
            ));
        }
        let geometric = geometric_max_contraction(alpha0);
        let (which, v) = c.one_of(
            "muscle",
            &[
                ("end_effect_factor", m.end_effect_factor),
                ("max_contraction", m.max_contraction),
            ],
        )?;
        let k = if which == 0 {
            c.bounded("muscle.end_effect_factor", v, END_EFFECT)?
        } else {
            pneuflex_files::check::positive(v).map_err(|e| c.err("muscle.max_contraction", e))?;
            if v > geometric {
                return Err(c.err(
                    "muscle.max_contraction",
                    format!(
                        "must be at most the braid's own limit 1 - 1/(sqrt(3) cos alpha0) = {geometric:.4} at alpha0 = {:.4} deg (end-effect factor k >= 1), got {v}",
                        alpha0.to_degrees()
                    ),
                ));
            }
            // (M6) solved for k.
            c.bounded("muscle.max_contraction", geometric / v, END_EFFECT)
                .map_err(|_| {
                    c.err(
                        "muscle.max_contraction",
                        format!(
                            "gives an end-effect factor k = {} outside [1, 10]",
                            geometric / v
                        ),
                    )
                })?
        };
        let friction = match &m.friction {
            None => BraidFriction::NONE,
            Some(fr) => BraidFriction {
                coulomb_n: c.bounded("muscle.friction.coulomb_n", fr.coulomb_n, FRICTION_FORCE)?,
                coulomb_n_per_pa: c.bounded(
                    "muscle.friction.coulomb_n_per_pa",
                    fr.coulomb_n_per_pa.unwrap_or(0.0),
                    FRICTION_PER_PA,
                )?,
                smooth_velocity_m_per_s: c.bounded(
                    "muscle.friction.smooth_velocity_m_per_s",
                    fr.smooth_velocity_m_per_s,
                    FRICTION_VELOCITY,
                )?,
            },
        };
        let muscle = Muscle {
            braid: Braid {
                rest_diameter_m: diameter,
                rest_length_m: length,
                rest_braid_angle_rad: alpha0,
                end_effect_factor: k,
            },
            friction,
            stretch_stiffness_n_per_m: c.bounded(
                "muscle.stretch_stiffness_n_per_m",
                m.stretch_stiffness_n_per_m.unwrap_or(0.0),
                STIFFNESS,
            )?,
            dead_volume_m3: c.bounded("muscle.dead_volume_m3", m.dead_volume_m3, DEAD_VOLUME)?,
        };
        let gas = match &f.gas {
            None => Gas::default(),
            Some(g) => {
                let n = g.polytropic_exponent.unwrap_or(1.4);
                pneuflex_files::check::within(
                    n,
                    1.0,
                    1.67,
                    "(1 = isothermal, 1.4 = adiabatic air)",
                )
                .map_err(|e| c.err("gas.polytropic_exponent", e))?;
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
        let dir = path.parent().unwrap_or_else(|| Path::new(""));
        let component = |key: &str, e: ComponentError| SheetError::Component {
            file: path.to_path_buf(),
            at: pneuflex_files::toml_key_position(text, key),
            key: key.to_string(),
            error: Box::new(e),
        };
        let supply = SupplySheet::load(&dir.join(&f.components.supply))
            .map_err(|e| component("components.supply", e))?
            .supply;
        let feed = match (&f.components.valve, &f.regulator) {
            (Some(v), None) => {
                let valve =
                    ValveSheet::load(&dir.join(v)).map_err(|e| component("components.valve", e))?;
                if valve.spool.is_some() {
                    return Err(c.err(
                        "components.valve",
                        format!(
                            "{v} gives spool dynamics (delays, time constants) beyond its response time or switching delay: the muscle's valve does not model them"
                        ),
                    ));
                }
                FeedSheet::Valve(Box::new(valve))
            }
            (None, Some(r)) => FeedSheet::Regulator {
                time_constant_s: c.bounded(
                    "regulator.time_constant_s",
                    r.time_constant_s,
                    REGULATOR_TIME,
                )?,
            },
            (Some(_), Some(_)) => {
                return Err(c.err(
                    "regulator",
                    "give a valve (components.valve) or a regulator ([regulator]), not both"
                        .to_string(),
                ));
            }
            (None, None) => {
                return Err(c.err(
                    "components",
                    "give a valve (components.valve) or a regulator ([regulator] time_constant_s)"
                        .to_string(),
                ));
            }
        };
        Ok(Self {
            path: path.to_path_buf(),
            name: f.name,
            chamber: MuscleChamber {
                muscle,
                gas,
                supply,
            },
            feed,
        })
    }

    /// The feed as the plant runs it (a valve at rest at spool 0).
    pub fn plant_feed(&self) -> Feed {
        match &self.feed {
            FeedSheet::Valve(v) => Feed::Valve(v.valve),
            FeedSheet::Regulator { time_constant_s } => Feed::Regulator {
                time_constant_s: *time_constant_s,
            },
        }
    }
}
