//! The scene file: one experiment as data (TOML), deserialised strictly and validated.
//!
//! Every key is documented with its unit and default in `docs/scenes.md`. Unknown keys, missing keys and
//! out-of-range numbers (negative stiffness, NaN, ...) are rejected with the file name and the key path.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::error::SceneError;
pub use pneuflex_control::{AdaptiveParams, ImpedanceParams, PidParams};

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

/// What a run may cost before it starts; beyond either limit `run` refuses with the estimate and the flag
/// that raises it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Limits {
    /// Largest number of integration steps per run (RK4 substeps or physics steps, the finest of them).
    pub max_steps_per_run: u64,
    /// Largest memory the traces of all runs may take, bytes.
    pub max_trace_bytes: u64,
}

impl Default for Limits {
    fn default() -> Self {
        // 1e9 steps is ~3 min of the 1-DOF plant or ~3 h of the multibody rig on this project's reference
        // machine; 2 GiB of traces is 24 M rows of 11 columns.
        Self {
            max_steps_per_run: 1_000_000_000,
            max_trace_bytes: 2 << 30,
        }
    }
}

/// The size of a scene's runs, estimated before anything runs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Budget {
    /// Control ticks per run.
    pub ticks_per_run: u64,
    /// Finest integration steps per run (chamber RK4 substeps, or physics steps times chamber substeps).
    pub steps_per_run: u64,
    /// Memory of all runs' traces, bytes.
    pub trace_bytes: u64,
}

/// Integration method of the plant.
#[derive(Clone, Copy, Debug, Default, Deserialize, Serialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum Integrator {
    /// Classical fourth-order Runge–Kutta with a fixed step (the paper's choice, Section III-B).
    #[default]
    Rk4,
}

/// Which plant the controllers drive.
#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
#[serde(tag = "kind", rename_all = "lowercase", deny_unknown_fields)]
pub enum PlantSpec {
    /// x follows the reference position x_r through a stiff second-order loop (an ideal inner loop).
    Ideal {
        /// Natural frequency of the position loop, rad/s.
        omega_rad_per_s: f64,
        /// Damping ratio of the position loop, 1.
        #[serde(default = "one")]
        zeta: f64,
        /// Initial flange position, m.
        #[serde(default)]
        x0_m: f64,
    },
    /// The 1-DOF pneumatic actuator model (pneuflex-pneumatics) driven by the valve command.
    Pneumatic {
        /// Actuator sheet (TOML), relative to the scene file.
        actuator: PathBuf,
        /// RK4 substeps per control period (the chamber dynamics are faster than the controller).
        #[serde(default = "default_substeps")]
        substeps: u32,
        /// Incline of the platform below horizontal, degrees; gravity aids extension by m g sin(alpha).
        /// Absent: the actuator sheet's value.
        #[serde(default)]
        alpha_deg: Option<f64>,
        /// Initial flange position, m. Absent: the actuator sheet's initial state.
        #[serde(default)]
        x0_m: Option<f64>,
    },
    /// The rig as a Rapier multibody world built from URDF (pneuflex-multibody): the pneumatic force
    /// element between cylinder and flange, compliant material faces on a kinematic carriage.
    Multibody(MultibodySpec),
    /// The paper's linear model, eqs. (16)/(17): Y(s)/P_L(s) = K_n / (s (s²/ω_n² + 2 ξ_n s/ω_n + 1)), with the
    /// valve command as a load-pressure command p_L = u · load_pressure_range_pa and the contact force as the
    /// load-pressure disturbance -f_e/S_a (Section III-B's simulation). From an actuator sheet (linearised at
    /// mid-stroke, as `pneuflex tf` prints) or from given numbers.
    Linear {
        /// Actuator sheet to linearise; absent = the numbers below are all given.
        #[serde(default)]
        actuator: Option<PathBuf>,
        /// K_n of eq. (17), m/(Pa·s).
        #[serde(default)]
        k_n_m_per_pa_s: Option<f64>,
        /// ω_n of eq. (17), rad/s.
        #[serde(default)]
        omega_n_rad_per_s: Option<f64>,
        /// ξ_n of eq. (17), 1.
        #[serde(default)]
        zeta_n: Option<f64>,
        /// Piston area S_a, m² (turns the contact force into a load pressure).
        #[serde(default)]
        area_a_m2: Option<f64>,
        /// Load pressure commanded by u = 1, Pa. Absent with a sheet: the supply's gauge pressure.
        #[serde(default)]
        load_pressure_range_pa: Option<f64>,
        /// RK4 substeps per control period.
        #[serde(default = "default_substeps")]
        substeps: u32,
        /// Initial flange position, m. Absent: environment.x_e_m (touching).
        #[serde(default)]
        x0_m: Option<f64>,
    },
}

/// The multibody plant: URDF rig, actuator sheet, physics step and the environment materials.
#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct MultibodySpec {
    /// URDF of the rig, relative to the scene file.
    pub urdf: PathBuf,
    /// Actuator sheet (TOML) of the pneumatic force element, relative to the scene file.
    pub actuator: PathBuf,
    /// Rapier physics step, s: `dt_s` is a whole number of physics steps, or a physics step is a whole
    /// number of control periods (the chambers and the controller still run at `dt_s`).
    pub physics_dt_s: f64,
    /// Rapier solver iterations per physics step.
    #[serde(default = "default_solver_iterations")]
    pub solver_iterations: usize,
    /// Chamber (valve + thermodynamics) substeps per physics step, or per control period when a
    /// physics step spans several.
    #[serde(default = "default_chamber_substeps")]
    pub chamber_substeps: u32,
    /// Incline of the actuator axis below horizontal, degrees. Absent: the actuator sheet's value.
    #[serde(default)]
    pub alpha_deg: Option<f64>,
    /// Initial flange extension, m. Absent: `environment.x_e_m` (touching the initial material).
    #[serde(default)]
    pub x0_m: Option<f64>,
    /// Material facing the flange at t = 0. Absent: the first material.
    #[serde(default)]
    pub initial_material: Option<String>,
    /// Coulomb friction coefficient of the flange-face contacts, 1.
    #[serde(default = "default_contact_friction")]
    pub contact_friction: f64,
    /// Environment materials on the carriage (at least one).
    pub materials: Vec<MaterialSpec>,
}

impl MultibodySpec {
    /// The material facing the flange at t = 0.
    pub fn initial_material(&self) -> Option<&MaterialSpec> {
        match &self.initial_material {
            Some(n) => self.materials.iter().find(|m| &m.name == n),
            None => self.materials.first(),
        }
    }

    /// Physics steps per control period `dt_s` (rounded; validation requires a whole number; 1 when a
    /// physics step spans several control periods).
    pub fn steps_per_tick(&self, dt_s: f64) -> u32 {
        (dt_s / self.physics_dt_s).round().max(1.0) as u32
    }

    /// Control periods per physics step (rounded; validation requires a whole number; 1 when a control
    /// period holds one or more physics steps).
    pub fn ticks_per_step(&self, dt_s: f64) -> u32 {
        (self.physics_dt_s / dt_s).round().max(1.0) as u32
    }

    /// The chamber substep, s: `chamber_substeps` per physics step or per control period, the shorter.
    pub fn chamber_substep_s(&self, dt_s: f64) -> f64 {
        self.physics_dt_s.min(dt_s) / f64::from(self.chamber_substeps)
    }
}

/// One environment material of the multibody rig: its compliant mount joint in the URDF, k and c.
#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct MaterialSpec {
    /// Material name used by events ("wood", "iron").
    pub name: String,
    /// Prismatic URDF joint that carries the material's contact face on the carriage.
    pub mount_joint: String,
    /// Mount stiffness k_e of eq. (21), N/m.
    pub stiffness_n_per_m: f64,
    /// Mount damping, N·s/m.
    #[serde(default)]
    pub damping_n_s_per_m: f64,
}

fn default_solver_iterations() -> usize {
    4
}

fn default_chamber_substeps() -> u32 {
    10
}

fn default_contact_friction() -> f64 {
    0.3
}

fn one() -> f64 {
    1.0
}

fn default_substeps() -> u32 {
    10
}

/// A linear-spring environment, eq. (21): f_e = k_e (x - x_e) while x > x_e, 0 otherwise.
#[derive(Clone, Copy, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct EnvironmentSpec {
    /// Environment stiffness k_e, N/m.
    pub stiffness_n_per_m: f64,
    /// Position of the environment surface x_e along the flange axis, m.
    #[serde(default)]
    pub x_e_m: f64,
}

/// Force reference schedule and desired position.
#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ReferenceSpec {
    /// Desired (free-space) position x_d, m (constant).
    #[serde(default)]
    pub x_d_m: f64,
    /// Pieces of the force reference f_r; each holds from its start time until the next piece starts.
    pub force: Vec<ForcePiece>,
}

/// One piece of the force reference schedule.
#[derive(Clone, Copy, Debug, Deserialize, Serialize, PartialEq)]
#[serde(tag = "kind", rename_all = "lowercase", deny_unknown_fields)]
pub enum ForcePiece {
    /// Constant force from `start_s` on.
    Step {
        /// Start time, s.
        start_s: f64,
        /// Force, N.
        value_n: f64,
    },
    /// bias + amplitude · sin(2π f (t - start) + phase).
    Sine {
        /// Start time, s.
        start_s: f64,
        /// Bias, N.
        bias_n: f64,
        /// Amplitude, N.
        amplitude_n: f64,
        /// Frequency, Hz.
        frequency_hz: f64,
        /// Phase at the start time, rad.
        #[serde(default)]
        phase_rad: f64,
    },
    /// value0 + slope · (t - start).
    Ramp {
        /// Start time, s.
        start_s: f64,
        /// Force at the start time, N.
        value0_n: f64,
        /// Slope, N/s.
        slope_n_per_s: f64,
    },
}

impl ForcePiece {
    /// Start time of the piece, s.
    pub fn start_s(&self) -> f64 {
        match *self {
            ForcePiece::Step { start_s, .. }
            | ForcePiece::Sine { start_s, .. }
            | ForcePiece::Ramp { start_s, .. } => start_s,
        }
    }
}

/// A timed change of the scene, applied at the first control tick at or after `t_s`.
#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum EventSpec {
    /// The environment stiffness k_e becomes a new value (on the multibody plant: one material's mount).
    Stiffness {
        /// Time of the event, s.
        t_s: f64,
        /// New stiffness, N/m.
        stiffness_n_per_m: f64,
        /// Multibody plant only: the material to change; absent = the one facing the flange.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        material: Option<String>,
        /// Multibody plant only: new mount damping, N·s/m; absent = unchanged.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        damping_n_s_per_m: Option<f64>,
    },
    /// Multibody plant only: the carriage brings another material in front of the flange (Fig. 7):
    /// it retreats beyond the flange's reach, slides across and comes back, over `duration_s`.
    SwapEnvironment {
        /// Time the carriage starts moving, s.
        t_s: f64,
        /// Material that faces the flange afterwards.
        to: String,
        /// Duration of the whole carriage move, s.
        duration_s: f64,
    },
    /// The incline alpha of the actuator axis changes (gravity aids extension by m g sin(alpha)).
    Alpha {
        /// Time of the event, s.
        t_s: f64,
        /// New incline below horizontal, degrees, in [-90, 90].
        alpha_deg: f64,
    },
}

impl EventSpec {
    /// Time of the event, s.
    pub fn t_s(&self) -> f64 {
        match *self {
            EventSpec::Stiffness { t_s, .. }
            | EventSpec::SwapEnvironment { t_s, .. }
            | EventSpec::Alpha { t_s, .. } => t_s,
        }
    }

    /// The event's `kind` as written in the scene file.
    pub fn kind(&self) -> &'static str {
        match self {
            EventSpec::Stiffness { .. } => "stiffness",
            EventSpec::SwapEnvironment { .. } => "swap_environment",
            EventSpec::Alpha { .. } => "alpha",
        }
    }
}

/// One named controller run.
#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct RunSpec {
    /// Run name: a directory `<out>/<name>/` and a legend entry.
    pub name: String,
    /// Which controller.
    pub controller: ControllerKind,
    /// Target impedance m_d, b_d, k_d (the control crate's parameters, as the file writes them).
    pub impedance: ImpedanceParams,
    /// Adaptive law gains (required for, and only allowed with, `controller = "adaptive"`).
    #[serde(default)]
    pub adaptive: Option<AdaptiveParams>,
    /// Inner position loop.
    pub inner: PidParams,
}

/// Why a run's controller cannot be built: the key inside the run's table and what is wrong.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("{key}: {message}")]
pub struct RunSpecError {
    /// Key relative to the run (`adaptive`, `inner.kp_per_m`, ...).
    pub key: String,
    /// What is wrong.
    pub message: String,
}

impl RunSpec {
    /// The controller this run describes, with validated parameters: the one way every caller (the
    /// scene runner, the rig, Python, the cross-validation) builds a controller.
    pub fn build(
        &self,
    ) -> Result<Box<dyn pneuflex_control::Controller + Send + Sync>, RunSpecError> {
        use pneuflex_control::{AdaptiveImpedanceController, ImpedanceController, ParamError};
        let bad = |table: &str| {
            let table = table.to_string();
            move |e: ParamError| RunSpecError {
                key: match e.field() {
                    Some(f) => format!("{table}.{f}"),
                    None => table.clone(),
                },
                message: e.reason().to_string(),
            }
        };
        self.impedance.validate().map_err(bad("impedance"))?;
        self.inner.validate().map_err(bad("inner"))?;
        match (self.controller, self.adaptive) {
            (ControllerKind::Impedance, None) => Ok(Box::new(
                ImpedanceController::new(self.impedance, self.inner).map_err(bad("impedance"))?,
            )),
            (ControllerKind::Adaptive, Some(a)) => {
                a.validate().map_err(bad("adaptive"))?;
                Ok(Box::new(
                    AdaptiveImpedanceController::new(self.impedance, a, self.inner)
                        .map_err(bad("adaptive"))?,
                ))
            }
            (ControllerKind::Adaptive, None) => Err(RunSpecError {
                key: "adaptive".into(),
                message: "missing: controller = \"adaptive\" needs the adaptive gains".into(),
            }),
            (ControllerKind::Impedance, Some(_)) => Err(RunSpecError {
                key: "adaptive".into(),
                message: "only allowed with controller = \"adaptive\"".into(),
            }),
        }
    }
}

/// The controller of a run.
#[derive(Clone, Copy, Debug, Deserialize, Serialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum ControllerKind {
    /// Position-based impedance control, eqs. (19)–(24), with the inner position PID.
    Impedance,
    /// Model-reference adaptive impedance control, eqs. (25)–(36), with the inner position PID.
    Adaptive,
}

impl ControllerKind {
    /// `"impedance"` or `"adaptive"`.
    pub fn name(self) -> &'static str {
        match self {
            ControllerKind::Impedance => "impedance",
            ControllerKind::Adaptive => "adaptive",
        }
    }
}

/// What a metric window measures.
#[derive(Clone, Copy, Debug, Deserialize, Serialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum WindowKind {
    /// A sine reference: RMS error and phase lag of f_e behind f_ref.
    Sine,
    /// A step (constant) reference: RMS error and steady-state error.
    Step,
    /// After an event: peak force, recovery overshoot, 2% settling time.
    Event,
}

/// A named time window for metrics.
#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct MetricWindow {
    /// Window name (a key in summary.json).
    pub name: String,
    /// Window start, s (for `event`: the event time).
    pub t0_s: f64,
    /// Window end, s.
    pub t1_s: f64,
    /// What to measure.
    pub kind: WindowKind,
}

/// A claim: run `better` has a lower `metric` than run `than` over window `window` (every metric here is
/// better when lower; a run that did not settle has an infinite settling time).
#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ClaimSpec {
    /// The claim in words, as the paper makes it.
    pub statement: String,
    /// Metric window the claim is read on.
    pub window: String,
    /// Which metric: one of [`CLAIM_METRICS`].
    pub metric: String,
    /// The run claimed to be better.
    pub better: String,
    /// The run it is compared with.
    pub than: String,
    /// Smallest difference that counts, % of the larger value (default 2: a single run of the PWM loop moves
    /// its metrics by about that much under a halved step or a 1 µm change of x0; closer is too close to
    /// call, and the claim does not hold).
    #[serde(default = "two_percent")]
    pub margin_pct: f64,
}

fn two_percent() -> f64 {
    2.0
}

/// Metrics a claim can compare, with the window kinds that have them.
pub const CLAIM_METRICS: [(&str, &[WindowKind]); 8] = [
    (
        "rms_force_error_n",
        &[WindowKind::Sine, WindowKind::Step, WindowKind::Event],
    ),
    ("phase_lag_deg", &[WindowKind::Sine]),
    ("steady_state_error_n", &[WindowKind::Step]),
    ("peak_force_n", &[WindowKind::Event]),
    ("jump_n", &[WindowKind::Event]),
    ("recovery_overshoot_n", &[WindowKind::Event]),
    ("recovery_overshoot_pct", &[WindowKind::Event]),
    ("settling_time_s", &[WindowKind::Event]),
];

/// Thresholds that stop a run as diverged.
#[derive(Clone, Copy, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct DivergenceSpec {
    /// Largest admissible |x|, m.
    #[serde(default = "default_max_position")]
    pub max_abs_position_m: f64,
    /// Largest admissible |f_e|, N.
    #[serde(default = "default_max_force")]
    pub max_abs_force_n: f64,
}

fn default_max_position() -> f64 {
    10.0
}

fn default_max_force() -> f64 {
    1.0e5
}

impl Default for DivergenceSpec {
    fn default() -> Self {
        Self {
            max_abs_position_m: default_max_position(),
            max_abs_force_n: default_max_force(),
        }
    }
}

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
        let mut scene: Scene = serde_path_to_error::deserialize(de).map_err(|e| {
            let path = e.path().to_string();
            let inner = e.into_inner();
            let path = if path == "." { String::new() } else { path };
            let message = inner.message().trim().to_string();
            let path = crate::locate::blame_inside_tagged(text, &path, &message);
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

    /// The actuator sheet at `resolved` (a path from [`Scene::resolve`]), with the scene's
    /// [`Scene::overlay`] texts standing in for the files they name.
    pub fn load_sheet(
        &self,
        resolved: &Path,
    ) -> Result<pneuflex_pneumatics::ActuatorSheet, pneuflex_pneumatics::ComponentError> {
        pneuflex_pneumatics::ActuatorSheet::load_overlaid(resolved, &self.overlay)
    }

    /// Path of the pneumatic actuator sheet, resolved against the scene's directory.
    pub fn resolve(&self, p: &Path) -> PathBuf {
        if p.is_absolute() {
            p.to_path_buf()
        } else {
            self.base_dir.join(p)
        }
    }

    /// An error about the value at `path` (a dotted key path), with the line of that key when the text
    /// of the file is known.
    pub fn invalid(&self, path: &str, message: String) -> SceneError {
        SceneError::Invalid {
            file: self.source.clone(),
            at: pneuflex_files::toml_key_position(&self.text, path),
            key: path.to_string(),
            message,
        }
    }

    /// Estimates the ticks, integration steps and trace memory of the scene's runs.
    pub fn budget(&self) -> Budget {
        let ticks = (self.duration_s / self.dt_s).round().max(0.0);
        let fine_per_tick = match &self.plant {
            PlantSpec::Ideal { .. } => 1.0,
            PlantSpec::Pneumatic { substeps, .. } | PlantSpec::Linear { substeps, .. } => {
                f64::from(*substeps)
            }
            PlantSpec::Multibody(mb) => self.dt_s / mb.chamber_substep_s(self.dt_s),
        };
        // Rows are ticks + 1; 11 columns of f64 for adaptive runs, 8 otherwise.
        let row_bytes: f64 = self
            .runs
            .iter()
            .map(|r| {
                if r.controller == ControllerKind::Adaptive {
                    88.0
                } else {
                    64.0
                }
            })
            .sum();
        let sat = |x: f64| {
            if x >= u64::MAX as f64 {
                u64::MAX
            } else {
                x as u64
            }
        };
        Budget {
            ticks_per_run: sat(ticks),
            steps_per_run: sat(ticks * fine_per_tick),
            trace_bytes: sat((ticks + 1.0) * row_bytes),
        }
    }

    /// Refuses a scene whose runs would exceed `limits`, with the estimate and how to raise the limit.
    pub fn check_budget(&self, limits: &Limits) -> Result<Budget, SceneError> {
        let b = self.budget();
        if b.steps_per_run > limits.max_steps_per_run {
            let key = match &self.plant {
                PlantSpec::Multibody(_) => "plant.physics_dt_s",
                PlantSpec::Pneumatic { .. } | PlantSpec::Linear { .. } => "plant.substeps",
                PlantSpec::Ideal { .. } => "dt_s",
            };
            return Err(self.invalid(
                key,
                format!(
                    "the scene needs {:.3e} integration steps per run (duration_s = {} s, dt_s = {} s, and this key), \
                     more than the limit of {:.3e}; use a coarser step or a shorter duration, or raise the limit with \
                     `--max-steps {}`",
                    b.steps_per_run as f64,
                    self.duration_s,
                    self.dt_s,
                    limits.max_steps_per_run as f64,
                    b.steps_per_run
                ),
            ));
        }
        if b.trace_bytes > limits.max_trace_bytes {
            return Err(self.invalid(
                "duration_s",
                format!(
                    "the traces of {} run(s) of {} ticks need {:.0} MiB, more than the limit of {:.0} MiB; \
                     shorten the run or raise the limit with `--max-trace-mb {}`",
                    self.runs.len(),
                    b.ticks_per_run,
                    b.trace_bytes as f64 / 1048576.0,
                    limits.max_trace_bytes as f64 / 1048576.0,
                    b.trace_bytes.div_ceil(1 << 20)
                ),
            ));
        }
        Ok(b)
    }

    /// Checks every number and cross-reference; the error names the file, the line and the key path.
    pub fn validate(&self) -> Result<(), SceneError> {
        let v = Validator { scene: self };
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
        match &self.plant {
            PlantSpec::Ideal {
                omega_rad_per_s,
                zeta,
                x0_m,
            } => {
                v.positive("plant.omega_rad_per_s", *omega_rad_per_s)?;
                v.non_negative("plant.zeta", *zeta)?;
                v.finite("plant.x0_m", *x0_m)?;
                // RK4 is stable for |λ dt| below ~2.8; keep well inside.
                if omega_rad_per_s * self.dt_s > 1.0 {
                    return Err(v.err(
                        "plant.omega_rad_per_s",
                        format!(
                            "omega * dt_s must be <= 1 for an accurate fixed-step RK4, got {} (dt_s = {})",
                            omega_rad_per_s * self.dt_s,
                            self.dt_s
                        ),
                    ));
                }
            }
            PlantSpec::Pneumatic {
                actuator,
                substeps,
                alpha_deg,
                x0_m,
            } => {
                if *substeps == 0 {
                    return Err(v.err("plant.substeps", "must be >= 1, got 0".into()));
                }
                if actuator.as_os_str().is_empty() {
                    return Err(v.err("plant.actuator", "must name an actuator sheet".into()));
                }
                if let Some(a) = alpha_deg {
                    v.finite("plant.alpha_deg", *a)?;
                    if !(-90.0..=90.0).contains(a) {
                        return Err(
                            v.err("plant.alpha_deg", format!("must be in [-90, 90], got {a}"))
                        );
                    }
                }
                if let Some(x) = x0_m {
                    v.finite("plant.x0_m", *x)?;
                }
            }
            PlantSpec::Multibody(mb) => self.validate_multibody(&v, mb)?,
            PlantSpec::Linear {
                actuator,
                k_n_m_per_pa_s,
                omega_n_rad_per_s,
                zeta_n,
                area_a_m2,
                load_pressure_range_pa,
                substeps,
                x0_m,
            } => {
                if *substeps == 0 {
                    return Err(v.err("plant.substeps", "must be >= 1, got 0".into()));
                }
                let given = [
                    ("plant.k_n_m_per_pa_s", *k_n_m_per_pa_s),
                    ("plant.omega_n_rad_per_s", *omega_n_rad_per_s),
                    ("plant.zeta_n", *zeta_n),
                    ("plant.area_a_m2", *area_a_m2),
                    ("plant.load_pressure_range_pa", *load_pressure_range_pa),
                ];
                for (key, val) in given {
                    match (val, key) {
                        (Some(z), "plant.zeta_n") => v.non_negative(key, z)?,
                        (Some(x), _) => v.positive(key, x)?,
                        (None, _) => {
                            // Without a sheet every number is needed; with one, only the pressure range
                            // has a default and the rest comes from the linearisation.
                            if actuator.is_none() {
                                return Err(v.err(
                                    key,
                                    "missing: give an actuator sheet (plant.actuator) or all of k_n_m_per_pa_s, omega_n_rad_per_s, zeta_n, area_a_m2 and load_pressure_range_pa".into(),
                                ));
                            }
                        }
                    }
                }
                if actuator.is_some() && given[..4].iter().any(|(_, x)| x.is_some()) {
                    return Err(v.err(
                        "plant.actuator",
                        "give either an actuator sheet or K_n, omega_n, zeta_n and S_a, not both"
                            .into(),
                    ));
                }
                if let Some(x) = x0_m {
                    v.finite("plant.x0_m", *x)?;
                }
            }
        }
        v.non_negative(
            "environment.stiffness_n_per_m",
            self.environment.stiffness_n_per_m,
        )?;
        v.finite("environment.x_e_m", self.environment.x_e_m)?;
        v.finite("reference.x_d_m", self.reference.x_d_m)?;
        if self.reference.force.is_empty() {
            return Err(v.err("reference.force", "needs at least one piece".into()));
        }
        if self.reference.force.len() > pneuflex_control::reference::SCHEDULE_CAPACITY {
            return Err(v.err(
                "reference.force",
                format!(
                    "at most {} pieces, got {}",
                    pneuflex_control::reference::SCHEDULE_CAPACITY,
                    self.reference.force.len()
                ),
            ));
        }
        let mut prev = f64::NEG_INFINITY;
        for (i, piece) in self.reference.force.iter().enumerate() {
            let at = |k: &str| format!("reference.force[{i}].{k}");
            v.non_negative(&at("start_s"), piece.start_s())?;
            if piece.start_s() <= prev {
                return Err(v.err(
                    &at("start_s"),
                    format!(
                        "pieces must start in increasing time order, got {} after {prev}",
                        piece.start_s()
                    ),
                ));
            }
            prev = piece.start_s();
            match *piece {
                ForcePiece::Step { value_n, .. } => v.finite(&at("value_n"), value_n)?,
                ForcePiece::Sine {
                    bias_n,
                    amplitude_n,
                    frequency_hz,
                    phase_rad,
                    ..
                } => {
                    v.finite(&at("bias_n"), bias_n)?;
                    v.non_negative(&at("amplitude_n"), amplitude_n)?;
                    v.positive(&at("frequency_hz"), frequency_hz)?;
                    v.finite(&at("phase_rad"), phase_rad)?;
                }
                ForcePiece::Ramp {
                    value0_n,
                    slope_n_per_s,
                    ..
                } => {
                    v.finite(&at("value0_n"), value0_n)?;
                    v.finite(&at("slope_n_per_s"), slope_n_per_s)?;
                }
            }
        }
        for (i, ev) in self.events.iter().enumerate() {
            let at = |k: &str| format!("events[{i}].{k}");
            v.non_negative(&at("t_s"), ev.t_s())?;
            if ev.t_s() > self.duration_s + 0.5 * self.dt_s {
                return Err(v.err(
                    &at("t_s"),
                    format!(
                        "the event would never happen: t_s = {} is after the end of the scene (duration_s = {})",
                        ev.t_s(),
                        self.duration_s
                    ),
                ));
            }
            let mb = match &self.plant {
                PlantSpec::Multibody(mb) => Some(mb),
                _ => None,
            };
            match ev {
                EventSpec::Stiffness {
                    stiffness_n_per_m,
                    material,
                    damping_n_s_per_m,
                    ..
                } => {
                    v.non_negative(&at("stiffness_n_per_m"), *stiffness_n_per_m)?;
                    if let Some(c) = damping_n_s_per_m {
                        v.non_negative(&at("damping_n_s_per_m"), *c)?;
                    }
                    match mb {
                        Some(mb) => {
                            // The mount is a spring: zero stiffness has no rest position.
                            v.positive(&at("stiffness_n_per_m"), *stiffness_n_per_m)?;
                            if let Some(name) = material {
                                v.known_material(&at("material"), mb, name)?;
                            }
                        }
                        None => {
                            if material.is_some() || damping_n_s_per_m.is_some() {
                                return Err(v.err(
                                    &at("material"),
                                    "`material` and `damping_n_s_per_m` need plant.kind = \"multibody\"".into(),
                                ));
                            }
                        }
                    }
                }
                EventSpec::SwapEnvironment { to, duration_s, .. } => {
                    let Some(mb) = mb else {
                        return Err(v.err(
                            &at("kind"),
                            "\"swap_environment\" needs plant.kind = \"multibody\": the 1-DOF plants have one linear-spring environment and no carriage".into(),
                        ));
                    };
                    v.known_material(&at("to"), mb, to)?;
                    v.positive(&at("duration_s"), *duration_s)?;
                    if ev.t_s() + duration_s > self.duration_s + 0.5 * self.dt_s {
                        return Err(v.err(
                            &at("duration_s"),
                            format!(
                                "the swap must end within the scene: t_s + duration_s = {} > duration_s = {}",
                                ev.t_s() + duration_s,
                                self.duration_s
                            ),
                        ));
                    }
                }
                EventSpec::Alpha { alpha_deg, .. } => {
                    v.finite(&at("alpha_deg"), *alpha_deg)?;
                    if !(-90.0..=90.0).contains(alpha_deg) {
                        return Err(v.err(
                            &at("alpha_deg"),
                            format!("must be in [-90, 90], got {alpha_deg}"),
                        ));
                    }
                    if matches!(
                        self.plant,
                        PlantSpec::Ideal { .. } | PlantSpec::Linear { .. }
                    ) {
                        return Err(v.err(
                            &at("kind"),
                            "\"alpha\" has no effect on plant.kind = \"ideal\" or \"linear\" (no gravity in those models)".into(),
                        ));
                    }
                }
            }
        }
        if self.runs.is_empty() {
            return Err(v.err("runs", "needs at least one run".into()));
        }
        for (i, run) in self.runs.iter().enumerate() {
            let at = |k: &str| format!("runs[{i}].{k}");
            if run.name.trim().is_empty()
                || run.name.contains(['/', '\\'])
                || run.name == "."
                || run.name == ".."
            {
                return Err(v.err(
                    &at("name"),
                    format!("must be a non-empty directory name, got {:?}", run.name),
                ));
            }
            if self.runs[..i].iter().any(|r| r.name == run.name) {
                return Err(v.err(&at("name"), format!("duplicate run name {:?}", run.name)));
            }
            match (run.controller, &run.adaptive) {
                (ControllerKind::Adaptive, None) => {
                    return Err(v.err(
                        &at("adaptive"),
                        "missing: controller = \"adaptive\" needs the adaptive gains".into(),
                    ));
                }
                (ControllerKind::Impedance, Some(_)) => {
                    return Err(v.err(
                        &at("adaptive"),
                        "only allowed with controller = \"adaptive\"".into(),
                    ));
                }
                (ControllerKind::Adaptive, Some(a)) => {
                    a.validate().map_err(|e| v.param(&at("adaptive"), e))?;
                }
                (ControllerKind::Impedance, None) => {}
            }
            // The control crate's own checks, blamed on the key they are about.
            run.impedance
                .validate()
                .map_err(|e| v.param(&at("impedance"), e))?;
            run.inner.validate().map_err(|e| v.param(&at("inner"), e))?;
        }
        for (i, w) in self.metrics.iter().enumerate() {
            let at = |k: &str| format!("metrics[{i}].{k}");
            if w.name.trim().is_empty() {
                return Err(v.err(&at("name"), "must not be empty".into()));
            }
            if self.metrics[..i].iter().any(|o| o.name == w.name) {
                return Err(v.err(&at("name"), format!("duplicate window name {:?}", w.name)));
            }
            v.non_negative(&at("t0_s"), w.t0_s)?;
            v.finite(&at("t1_s"), w.t1_s)?;
            if w.t1_s <= w.t0_s || w.t1_s > self.duration_s + 0.5 * self.dt_s {
                return Err(v.err(
                    &at("t1_s"),
                    format!(
                        "must satisfy t0_s < t1_s <= duration_s ({}), got t0_s = {}, t1_s = {}",
                        self.duration_s, w.t0_s, w.t1_s
                    ),
                ));
            }
            if w.kind == WindowKind::Sine && self.sine_in(w.t0_s, w.t1_s).is_none() {
                return Err(v.err(
                    &at("kind"),
                    format!(
                        "\"sine\" needs one sine reference piece covering [{}, {}] s",
                        w.t0_s, w.t1_s
                    ),
                ));
            }
        }
        for (i, c) in self.claims.iter().enumerate() {
            let at = |k: &str| format!("claims[{i}].{k}");
            let Some(w) = self.metrics.iter().find(|w| w.name == c.window) else {
                return Err(v.err(
                    &at("window"),
                    format!("no metric window named {:?}", c.window),
                ));
            };
            match CLAIM_METRICS.iter().find(|(m, _)| *m == c.metric) {
                None => {
                    let known: Vec<&str> = CLAIM_METRICS.iter().map(|(m, _)| *m).collect();
                    return Err(v.err(
                        &at("metric"),
                        format!("unknown metric {:?}, expected one of {known:?}", c.metric),
                    ));
                }
                Some((_, kinds)) if !kinds.contains(&w.kind) => {
                    return Err(v.err(
                        &at("metric"),
                        format!("{:?} is not measured on a {:?} window", c.metric, w.kind),
                    ));
                }
                Some(_) => {}
            }
            v.non_negative(&at("margin_pct"), c.margin_pct)?;
            for (k, run) in [("better", &c.better), ("than", &c.than)] {
                if !self.runs.iter().any(|r| &r.name == run) {
                    return Err(v.err(&at(k), format!("no run named {run:?}")));
                }
            }
        }
        let d = &self.divergence;
        v.positive("divergence.max_abs_position_m", d.max_abs_position_m)?;
        v.positive("divergence.max_abs_force_n", d.max_abs_force_n)?;
        Ok(())
    }

    fn validate_multibody(&self, v: &Validator<'_>, mb: &MultibodySpec) -> Result<(), SceneError> {
        if mb.urdf.as_os_str().is_empty() {
            return Err(v.err("plant.urdf", "must name a URDF file".into()));
        }
        if mb.actuator.as_os_str().is_empty() {
            return Err(v.err("plant.actuator", "must name an actuator sheet".into()));
        }
        v.positive("plant.physics_dt_s", mb.physics_dt_s)?;
        let whole = |r: f64| r >= 1.0 - 1e-9 && (r - r.round()).abs() <= 1e-6 * r.max(1.0);
        let ratio = self.dt_s / mb.physics_dt_s;
        let inverse = mb.physics_dt_s / self.dt_s;
        if !whole(ratio) && !whole(inverse) {
            return Err(v.err(
                "plant.physics_dt_s",
                format!(
                    "must divide dt_s ({}) or be a whole multiple of it, got physics_dt_s / dt_s = {inverse}",
                    self.dt_s
                ),
            ));
        }
        if inverse.round() > 1000.0 {
            return Err(v.err(
                "plant.physics_dt_s",
                format!("must be at most 1000 dt_s, got {inverse} dt_s"),
            ));
        }
        // A physics step of several ticks: an event changes the rig between physics steps only.
        if inverse.round() > 1.0 {
            for (i, e) in self.events.iter().enumerate() {
                let k = e.t_s() / mb.physics_dt_s;
                if (k - k.round()).abs() > 1e-6 * k.abs().max(1.0) {
                    return Err(v.err(
                        &format!("events[{i}].t_s"),
                        format!(
                            "must be a whole number of physics steps (plant.physics_dt_s = {} s) when a physics step spans several control periods, got t_s / physics_dt_s = {k}",
                            mb.physics_dt_s
                        ),
                    ));
                }
            }
        }
        if mb.solver_iterations == 0 || mb.solver_iterations > 1000 {
            return Err(v.err(
                "plant.solver_iterations",
                format!("must be in 1 ..= 1000, got {}", mb.solver_iterations),
            ));
        }
        if mb.chamber_substeps == 0 || mb.chamber_substeps > 10_000 {
            return Err(v.err(
                "plant.chamber_substeps",
                format!("must be in 1 ..= 10000, got {}", mb.chamber_substeps),
            ));
        }
        if let Some(a) = mb.alpha_deg {
            v.finite("plant.alpha_deg", a)?;
            if !(-90.0..=90.0).contains(&a) {
                return Err(v.err("plant.alpha_deg", format!("must be in [-90, 90], got {a}")));
            }
        }
        if let Some(x) = mb.x0_m {
            v.finite("plant.x0_m", x)?;
        }
        v.non_negative("plant.contact_friction", mb.contact_friction)?;
        if mb.materials.is_empty() {
            return Err(v.err("plant.materials", "needs at least one material".into()));
        }
        for (i, m) in mb.materials.iter().enumerate() {
            let at = |k: &str| format!("plant.materials[{i}].{k}");
            if m.name.trim().is_empty() {
                return Err(v.err(&at("name"), "must not be empty".into()));
            }
            if mb.materials[..i].iter().any(|o| o.name == m.name) {
                return Err(v.err(&at("name"), format!("duplicate material {:?}", m.name)));
            }
            if m.mount_joint.trim().is_empty() {
                return Err(v.err(&at("mount_joint"), "must name a URDF joint".into()));
            }
            v.positive(&at("stiffness_n_per_m"), m.stiffness_n_per_m)?;
            v.non_negative(&at("damping_n_s_per_m"), m.damping_n_s_per_m)?;
        }
        let Some(init) = mb.initial_material() else {
            return Err(v.err(
                "plant.initial_material",
                format!(
                    "{:?} is not one of the materials ({})",
                    mb.initial_material.as_deref().unwrap_or(""),
                    material_names(mb)
                ),
            ));
        };
        // [environment] states the initial contact (used by the Lyapunov summary and checked against the
        // URDF's geometry when the plant is built): its stiffness must be the initial material's.
        if (self.environment.stiffness_n_per_m - init.stiffness_n_per_m).abs()
            > 1e-9 * init.stiffness_n_per_m
        {
            return Err(v.err(
                "environment.stiffness_n_per_m",
                format!(
                    "must equal the initial material {:?}'s stiffness_n_per_m ({}) on a multibody plant, got {}",
                    init.name, init.stiffness_n_per_m, self.environment.stiffness_n_per_m
                ),
            ));
        }
        Ok(())
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

    /// The sine reference piece that covers the whole interval [t0, t1], if any.
    pub fn sine_in(&self, t0: f64, t1: f64) -> Option<ForcePiece> {
        let pieces = &self.reference.force;
        for (i, p) in pieces.iter().enumerate() {
            let end = pieces.get(i + 1).map_or(f64::INFINITY, ForcePiece::start_s);
            if matches!(p, ForcePiece::Sine { .. }) && p.start_s() <= t0 && t1 <= end {
                return Some(*p);
            }
        }
        None
    }
}

struct Validator<'a> {
    scene: &'a Scene,
}

impl Validator<'_> {
    fn err(&self, path: &str, message: String) -> SceneError {
        self.scene.invalid(path, message)
    }
    /// A control-crate parameter error at `table` (`runs[1].inner`), blamed on the key it names.
    fn param(&self, table: &str, e: pneuflex_control::ParamError) -> SceneError {
        let path = match e.field() {
            Some(f) => format!("{table}.{f}"),
            None => table.to_string(),
        };
        self.err(&path, e.reason().to_string())
    }
    fn known_material(&self, path: &str, mb: &MultibodySpec, name: &str) -> Result<(), SceneError> {
        if mb.materials.iter().any(|m| m.name == name) {
            Ok(())
        } else {
            Err(self.err(
                path,
                format!(
                    "unknown material {name:?}, expected one of {}",
                    material_names(mb)
                ),
            ))
        }
    }
    fn finite(&self, path: &str, x: f64) -> Result<(), SceneError> {
        if x.is_finite() {
            Ok(())
        } else {
            Err(self.err(path, format!("must be a finite number, got {x}")))
        }
    }
    fn non_negative(&self, path: &str, x: f64) -> Result<(), SceneError> {
        self.finite(path, x)?;
        if x >= 0.0 {
            Ok(())
        } else {
            Err(self.err(path, format!("must be >= 0, got {x}")))
        }
    }
    fn positive(&self, path: &str, x: f64) -> Result<(), SceneError> {
        self.finite(path, x)?;
        if x > 0.0 {
            Ok(())
        } else {
            Err(self.err(path, format!("must be > 0, got {x}")))
        }
    }
}

fn material_names(mb: &MultibodySpec) -> String {
    mb.materials
        .iter()
        .map(|m| format!("{:?}", m.name))
        .collect::<Vec<_>>()
        .join(", ")
}
