//! The scene file: one experiment as data (TOML), deserialised strictly and validated, one file per table.
//!
//! Every key is documented with its unit and default in `docs/scenes.md`. Unknown keys, missing keys and
//! out-of-range numbers (negative stiffness, NaN, ...) are rejected with the file name and the key path.

pub mod claims;
pub mod divergence;
pub mod environment;
pub mod events;
pub mod limits;
mod locate;
pub mod plant;
pub mod reference;
pub mod runs;
pub mod windows;

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::error::SceneError;
pub use crate::origin::SceneOrigin;
pub use claims::{CLAIM_METRICS, ClaimSpec};
pub use divergence::DivergenceSpec;
pub use environment::EnvironmentSpec;
pub use events::EventSpec;
pub use limits::{Budget, Limits};
pub use plant::{MaterialSpec, MultibodySpec, PlantSpec};
pub use reference::{ForcePiece, ReferenceSpec};
pub use runs::{
    AdaptiveParams, ControllerKind, FrozenAt, FrozenSpec, FrozenValues, ImpedanceParams, PidParams,
    RunSpec, RunSpecError,
};
pub use windows::{MetricWindow, WindowKind};

/// A complete experiment: plant, environment, references, events, controllers to compare and metric windows.
#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Scene {
    /// Version of the scene format this file is written for (absent = [`SCENE_SCHEMA_VERSION`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub schema_version: Option<u32>,
    /// Scene name; the default output directory is `out/<name>/`.
    pub name: String,
    /// Free text shown in summaries.
    #[serde(default)]
    pub description: String,
    /// Simulated time, s.
    pub duration_s: f64,
    /// Control period (one `sense → update → actuate → advance` tick), s.
    pub dt_s: f64,
    /// Integration method of the plant (only fixed-step RK4 exists).
    #[serde(default)]
    pub integrator: Integrator,
    /// The plant the controllers drive.
    pub plant: PlantSpec,
    /// The environment the flange pushes against.
    pub environment: EnvironmentSpec,
    /// Force and position references.
    pub reference: ReferenceSpec,
    /// Timed changes of the environment.
    #[serde(default)]
    pub events: Vec<EventSpec>,
    /// Named controller runs; each one is simulated from the same initial state.
    pub runs: Vec<RunSpec>,
    /// Time windows over which metrics are computed.
    #[serde(default)]
    pub metrics: Vec<MetricWindow>,
    /// Claims the scene checks: one run better than another on a metric of a window (the paper's claims).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub claims: Vec<ClaimSpec>,
    /// Limits beyond which a run is declared diverged.
    #[serde(default)]
    pub divergence: DivergenceSpec,
    /// Directory of the scene file, for resolving relative paths (not a TOML key).
    #[serde(skip)]
    pub base_dir: PathBuf,
    /// The file the scene was read from, for error messages (not a TOML key).
    #[serde(skip)]
    pub source: PathBuf,
    /// The file's text, to point errors at the line of a key (not a TOML key).
    #[serde(skip)]
    pub text: String,
    /// Texts that stand in for the actuator sheet's files, by resolved path (a sweep's edited copies of
    /// sheet values; empty for a scene read from disk). Not a TOML key.
    #[serde(skip)]
    pub overlay: pneuflex_pneumatics::FileOverlay,
}

/// The scene format version this pneuflex reads and writes.
pub const SCENE_SCHEMA_VERSION: u32 = 1;

/// Largest `duration_s` a scene may ask for, s (about 11.6 days of simulated time).
pub const MAX_DURATION_S: f64 = 1.0e6;

/// Integration method of the plant.
#[derive(Clone, Copy, Debug, Default, Deserialize, Serialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum Integrator {
    /// Classical fourth-order Runge–Kutta with a fixed step (the paper's choice, Section III-B).
    #[default]
    Rk4,
}

/// Why a command that runs one actuator refuses a scene with `[[actuators]]`.
pub const SEVERAL_ACTUATORS: &str = "a scene with several actuators ([[actuators]]) runs with `pneuflex run`, \
     `sweep`, `tune`, `tf --loop`, `rig run --lockstep-truth`, `rig pil` and `compare` (Python: `pneuflex.run`, \
     which returns its Results, and the Gymnasium environments); this call takes a one-actuator scene, with a [plant] \
     table (docs/scenes.md)";

impl Scene {
    /// Reads, parses and validates a scene file.
    pub fn load(path: &Path) -> Result<Scene, SceneError> {
        let text = pneuflex_files::read_text(path, pneuflex_files::InputKind::Scene)?;
        let base = path.parent().map(Path::to_path_buf).unwrap_or_default();
        Scene::from_toml_str(&text, path, &base)
    }

    /// Parses and validates scene text; `file` names it in errors and `base_dir` resolves relative paths.
    pub fn from_toml_str(text: &str, file: &Path, base_dir: &Path) -> Result<Scene, SceneError> {
        let de = toml::Deserializer::parse(text).map_err(|e| SceneError::Parse {
            file: file.to_path_buf(),
            at: e.span().map(|s| pneuflex_files::line_col(text, s.start)),
            key: String::new(),
            message: e.message().trim().to_string(),
        })?;
        // Frozen runs copy another run's controller before the file is read into a Scene (rare: most
        // scenes are read straight from the text, with its spans).
        let mut doc = match text.contains("frozen").then(|| text.parse::<toml::Table>()) {
            Some(Ok(doc)) if runs::copy_frozen_controllers_needed(&doc) => Some(doc),
            _ => None,
        };
        if let Some(doc) = doc.as_mut() {
            runs::copy_frozen_controllers(doc).map_err(|(key, message)| SceneError::Invalid {
                file: file.to_path_buf(),
                at: pneuflex_files::toml_key_position(text, &key),
                key,
                message,
            })?;
        }
        let read = match doc {
            Some(doc) => serde_path_to_error::deserialize(toml::Value::Table(doc)),
            None => serde_path_to_error::deserialize(de),
        };
        let mut scene: Scene = read.map_err(|e| {
            let path = e.path().to_string();
            let inner = e.into_inner();
            let path = if path == "." { String::new() } else { path };
            let mut message = inner.message().trim().to_string();
            // A several-actuator scene given to a command that takes one actuator: say so, not "unknown field".
            if message.starts_with("unknown field `actuators`") {
                message = SEVERAL_ACTUATORS.to_string();
            }
            let path = locate::blame_inside_tagged(text, &path, &message);
            let at = match inner.span() {
                // A span on an internally tagged table covers the whole table: the key is more precise.
                Some(s) if path.is_empty() => Some(pneuflex_files::line_col(text, s.start)),
                _ => pneuflex_files::toml_key_position(text, &path),
            };
            SceneError::Parse {
                file: file.to_path_buf(),
                at,
                key: path,
                message,
            }
        })?;
        scene.base_dir = base_dir.to_path_buf();
        scene.source = file.to_path_buf();
        scene.text = text.to_string();
        scene.validate()?;
        Ok(scene)
    }

    /// Number of control ticks in the run (the trace has one more row: t = 0 .. duration inclusive).
    pub fn n_steps(&self) -> usize {
        (self.duration_s / self.dt_s).round() as usize
    }

    /// Where the scene's values come from: its file, text, folder and overlay.
    pub fn origin(&self) -> SceneOrigin<'_> {
        SceneOrigin {
            source: &self.source,
            text: &self.text,
            base_dir: &self.base_dir,
            overlay: &self.overlay,
        }
    }

    /// The actuator sheet at `resolved` (a path from [`Scene::resolve`]), with the scene's
    /// [`Scene::overlay`] texts standing in for the files they name.
    pub fn load_sheet(
        &self,
        resolved: &Path,
    ) -> Result<pneuflex_pneumatics::ActuatorSheet, pneuflex_pneumatics::ComponentError> {
        self.origin().load_sheet(resolved)
    }

    /// Path of the pneumatic actuator sheet, resolved against the scene's directory.
    pub fn resolve(&self, p: &Path) -> PathBuf {
        self.origin().resolve(p)
    }

    /// The scene's input files, resolved: the scene itself, then the files its plant names (the actuator
    /// sheet, the URDF), each with its role.
    pub fn input_files(&self) -> Vec<(&'static str, PathBuf)> {
        let mut v = vec![("scene", self.source.clone())];
        for (key, p) in self.plant.files() {
            let role = if key == "plant.urdf" {
                "urdf"
            } else {
                "actuator"
            };
            v.push((role, self.resolve(p)));
        }
        v
    }

    /// The actuator sheet the plant runs, resolved against the scene's folder, if it has one.
    pub fn actuator_sheet_path(&self) -> Option<PathBuf> {
        self.plant.actuator_sheet().map(|a| self.resolve(a))
    }

    /// An error about the value at `path` (a dotted key path), with the line of that key when the text
    /// of the file is known.
    pub fn invalid(&self, path: &str, message: String) -> SceneError {
        self.origin().invalid(path, message)
    }

    /// Checks every number and cross-reference, table by table; the error names the file, the line and
    /// the key path.
    pub fn validate(&self) -> Result<(), SceneError> {
        let v = crate::origin::Check {
            origin: self.origin(),
        };
        if let Some(version) = self.schema_version
            && version != SCENE_SCHEMA_VERSION
        {
            return Err(v.err(
                "schema_version",
                format!(
                    "this pneuflex reads scene schema version {SCENE_SCHEMA_VERSION}, the file is written for version {version}"
                ),
            ));
        }
        if self.name.trim().is_empty() {
            return Err(v.err("name", "must not be empty".into()));
        }
        if self.name.contains(['/', '\\']) || self.name == "." || self.name == ".." {
            return Err(v.err(
                "name",
                format!("must be usable as a directory name, got {:?}", self.name),
            ));
        }
        v.positive("duration_s", self.duration_s)?;
        if self.duration_s > MAX_DURATION_S {
            return Err(v.err(
                "duration_s",
                format!(
                    "must be at most {MAX_DURATION_S:e} s, got {}",
                    self.duration_s
                ),
            ));
        }
        v.positive("dt_s", self.dt_s)?;
        if self.dt_s > self.duration_s {
            return Err(v.err(
                "dt_s",
                format!(
                    "must not exceed duration_s ({}), got {}",
                    self.duration_s, self.dt_s
                ),
            ));
        }
        plant::validate(self, &v)?;
        environment::validate(self, &v)?;
        reference::validate(self, &v)?;
        events::validate(self, &v)?;
        runs::validate(self, &v)?;
        windows::validate(self, &v)?;
        claims::validate(self, &v)?;
        divergence::validate(self, &v)
    }

    /// The scene reduced to run `index` and cut at `end_s` (what one run on the rig or on the board
    /// describes): windows ending after `end_s` and events after it are left out, and the claims, which
    /// compare two runs. A recording of N ticks covers N·dt: give that, not its last tick's time.
    pub fn one_run(&self, index: usize, end_s: f64) -> Scene {
        self.some_runs(&[index], end_s)
    }

    /// [`Scene::one_run`] for the runs `indices` (in that order): the claims between two of them stay.
    pub fn some_runs(&self, indices: &[usize], end_s: f64) -> Scene {
        let mut s = self.clone();
        s.runs = indices.iter().map(|&i| self.runs[i].clone()).collect();
        s.duration_s = self.duration_s.min(end_s);
        s.metrics.retain(|w| w.t1_s <= s.duration_s + 0.5 * s.dt_s);
        s.events.retain(|e| e.t_s() < s.duration_s);
        let kept = |name: &str| s.runs.iter().any(|r| r.name == name);
        let window = |name: &str| s.metrics.iter().any(|w| w.name == name);
        let claims = std::mem::take(&mut s.claims);
        s.claims = claims
            .into_iter()
            .filter(|c| c.better != c.than && kept(&c.better) && kept(&c.than) && window(&c.window))
            .collect();
        s
    }

    /// The index of the run named `name`; the error lists the runs there are.
    pub fn run_index(&self, name: &str) -> Result<usize, SceneError> {
        self.runs
            .iter()
            .position(|r| r.name == name)
            .ok_or_else(|| {
                let names: Vec<&str> = self.runs.iter().map(|r| r.name.as_str()).collect();
                self.invalid(
                    "runs",
                    format!("no run named {name:?}, expected one of {names:?}"),
                )
            })
    }
}
