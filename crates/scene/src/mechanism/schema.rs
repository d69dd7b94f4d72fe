//! The mechanism scene file: a URDF, its named actuators (sheet, mount, sensor, force reference), its
//! compliant contacts, contact events, the controller runs compared, metric windows and claims.
//! docs/multibody.md "Your own URDF" describes every key.

use std::path::{Path, PathBuf};

use serde::Deserialize;

use crate::error::SceneError;
use crate::schema::{ForcePiece, RunSpec};

/// How the pads' forces enter a physics step (`pads = "explicit" | "implicit"`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum PadSpec {
    /// Their force at the step's start, over the step.
    #[default]
    Explicit,
    /// Implicit in their own stiffness and damping.
    Implicit,
}

/// A scene of any URDF with several pneumatic actuators.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MechanismScene {
    /// Scene name (the default output directory `out/<name>/`).
    pub name: String,
    /// One line for people.
    #[serde(default)]
    pub description: String,
    /// Simulated time, s.
    pub duration_s: f64,
    /// Control period, s.
    pub dt_s: f64,
    /// The URDF, relative to the scene file.
    pub urdf: PathBuf,
    /// Physics steps per control period (the pads are explicit: a stiff pad needs a short step).
    #[serde(default = "default_physics_steps")]
    pub physics_steps_per_tick: u32,
    /// Rapier solver iterations per step.
    #[serde(default = "default_iterations")]
    pub solver_iterations: usize,
    /// Chamber and valve substeps per physics step.
    #[serde(default = "default_substeps")]
    pub chamber_substeps: u32,
    /// How the pads enter a physics step: `explicit` (their force at the step's start; a stiff pad on a
    /// light body needs a short step, ω h < 2) or `implicit` (in their own stiffness and damping, stable at
    /// any step).
    #[serde(default)]
    pub pads: PadSpec,
    /// Gravity in the URDF's root frame, m/s².
    #[serde(default = "default_gravity")]
    pub gravity_m_s2: [f64; 3],
    /// The actuators, each with its own valve, sensor and reference.
    pub actuators: Vec<ActuatorSpec>,
    /// Compliant contacts between links.
    #[serde(default)]
    pub contacts: Vec<ContactSpec>,
    /// Spring-dampers on joints.
    #[serde(default)]
    pub springs: Vec<SpringSpec>,
    /// Links held where the URDF puts them (a carriage, a fixture), with everything fixed to them.
    #[serde(default)]
    pub held_links: Vec<String>,
    /// Contact and spring stiffness changes during the run.
    #[serde(default)]
    pub events: Vec<ContactEvent>,
    /// The controller runs compared; each run puts its controller on every actuator.
    pub runs: Vec<RunSpec>,
    /// Thresholds that stop a run as diverged, as a one-actuator scene's `[divergence]` (each actuator's
    /// position and force).
    #[serde(default)]
    pub divergence: crate::schema::DivergenceSpec,
    /// Metric windows.
    #[serde(default)]
    pub metrics: Vec<WindowSpec>,
    /// Claims: a metric of one run against another's, per actuator.
    #[serde(default)]
    pub claims: Vec<ClaimSpec>,
    /// The scene file.
    #[serde(skip)]
    pub source: PathBuf,
    /// Its text (for the lines of keys in errors).
    #[serde(skip)]
    pub text: String,
    /// Edited copies of the sheets it names, read in place of the files (a sweep's point).
    #[serde(skip)]
    pub overlay: pneuflex_pneumatics::FileOverlay,
}

fn default_physics_steps() -> u32 {
    1
}
fn default_iterations() -> usize {
    4
}
fn default_substeps() -> u32 {
    10
}
fn default_gravity() -> [f64; 3] {
    [0.0, 0.0, -pneuflex_multibody::STANDARD_GRAVITY]
}

/// One actuator: a cylinder and valve, or a muscle and its valve or regulator, from a sheet (the sheet says
/// which family), mounted along a joint (a cylinder) or between anchors.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ActuatorSpec {
    /// Its name: the prefix of its trace columns (`left.f_e`).
    pub name: String,
    /// The pneumatic actuator sheet (cylinder, valve, supply, friction) or a muscle sheet (a `[muscle]`
    /// table: docs/muscles.md), relative to the scene file.
    pub sheet: PathBuf,
    /// Mounted along this prismatic URDF joint (its limits are the stroke) ...
    #[serde(default)]
    pub joint: Option<String>,
    /// ... or between these two anchor points (the sheet's stroke).
    #[serde(default)]
    pub anchors: Option<AnchorsSpec>,
    /// Where its joint starts, m (a prismatic `joint` mount only; the URDF's zero when absent).
    #[serde(default)]
    pub initial_position_m: Option<f64>,
    /// What the actuator's controller closes its force loop on: a contact's name (the force across it),
    /// or `"load_cell"` (a load cell on the rod: the force the cylinder applies).
    pub force_sensor: String,
    /// A prismatic or revolute joint whose position (m or rad) and rate the controller's position loop
    /// closes on; the cylinder's stroke when absent. The trace's `x`, `x_dot` and `x_d_m` are then in the
    /// joint's units.
    #[serde(default)]
    pub position_sensor: Option<String>,
    /// Desired free-space stroke x_d of the impedance law, m.
    #[serde(default)]
    pub x_d_m: f64,
    /// The force reference f_r: pieces, each from its start until the next.
    pub force: Vec<ForcePiece>,
    /// This actuator's own gains, in place of the run's for every run (the run still picks the kind):
    /// a small finger and a large arm on one rig need different ones.
    #[serde(default)]
    pub gains: Option<GainsSpec>,
}

/// An actuator's own gains: each given table replaces the run's.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GainsSpec {
    /// Target impedance m_d, b_d, k_d.
    #[serde(default)]
    pub impedance: Option<crate::schema::ImpedanceParams>,
    /// Inner position loop.
    #[serde(default)]
    pub inner: Option<crate::schema::PidParams>,
    /// Adaptive law (used by adaptive runs).
    #[serde(default)]
    pub adaptive: Option<crate::schema::AdaptiveParams>,
}

impl MechanismScene {
    /// The controller spec of run `run` for actuator `actuator`: the run's, with the actuator's own gains
    /// in place of those it gives.
    pub fn actuator_run(&self, run: usize, actuator: usize) -> RunSpec {
        let mut spec = self.runs[run].clone();
        if let Some(g) = &self.actuators[actuator].gains {
            if let Some(i) = g.impedance {
                spec.impedance = i;
            }
            if let Some(p) = g.inner {
                spec.inner = p;
            }
            if g.adaptive.is_some() && spec.adaptive.is_some() {
                spec.adaptive = g.adaptive;
            }
        }
        spec
    }

    /// Run `run`'s controller on each actuator, in actuator order (an error names the run's key).
    pub fn run_controllers(
        &self,
        run: usize,
    ) -> Result<Vec<Box<dyn pneuflex_control::Controller + Send + Sync>>, SceneError> {
        (0..self.actuators.len())
            .map(|a| {
                self.actuator_run(run, a)
                    .build()
                    .map_err(|e| self.invalid(&format!("runs[{run}].{}", e.key), e.message))
            })
            .collect()
    }
}

/// A cylinder between a clevis on one link and a rod eye on another.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AnchorsSpec {
    /// Link of the clevis.
    pub link_a: String,
    /// Clevis point in `link_a`'s frame, m.
    pub point_a_m: [f64; 3],
    /// Link of the rod eye.
    pub link_b: String,
    /// Rod-eye point in `link_b`'s frame, m.
    pub point_b_m: [f64; 3],
    /// Pin-to-pin length at the retracted stop, m (a cylinder's; a muscle's sheet gives its lengths).
    #[serde(default)]
    pub retracted_length_m: Option<f64>,
}

/// A compliant contact (Kelvin–Voigt pad) between two links' colliders.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ContactSpec {
    /// Its name (an actuator's `force_sensor`, events).
    pub name: String,
    /// One link.
    pub link_a: String,
    /// The other link.
    pub link_b: String,
    /// Normal stiffness, N/m.
    pub stiffness_n_per_m: f64,
    /// Normal damping, N s/m.
    #[serde(default)]
    pub damping_n_s_per_m: f64,
}

/// At `t_s` the named contact or spring takes a new stiffness (and damping): foam, then rubber.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ContactEvent {
    /// When, s (on a control tick).
    pub t_s: f64,
    /// Which contact (or give `spring`).
    #[serde(default)]
    pub contact: Option<String>,
    /// Which spring (or give `contact`).
    #[serde(default)]
    pub spring: Option<String>,
    /// New stiffness, N/m.
    pub stiffness_n_per_m: f64,
    /// New damping, N s/m (unchanged when absent).
    #[serde(default)]
    pub damping_n_s_per_m: Option<f64>,
}

/// A spring-damper on a prismatic or revolute joint: a compliant mount behind a contact face, a return
/// spring. It rests at the URDF's zero (a prismatic joint's child under its own weight).
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SpringSpec {
    /// Its name (events).
    pub name: String,
    /// The joint.
    pub joint: String,
    /// Stiffness, N/m (N m/rad on a revolute joint).
    pub stiffness_n_per_m: f64,
    /// Damping, N s/m (N m s/rad).
    #[serde(default)]
    pub damping_n_s_per_m: f64,
}

/// A named time window for metrics.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WindowSpec {
    /// Its name.
    pub name: String,
    /// Start, s.
    pub t0_s: f64,
    /// End, s.
    pub t1_s: f64,
}

/// "`better` has a lower `metric` than `than` in `window`", for every actuator (or the one named).
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ClaimSpec {
    /// What is claimed, for people.
    pub statement: String,
    /// The window.
    pub window: String,
    /// The metric (lower is better): `rms_force_error_n`, `max_abs_force_error_n`, `force_imbalance_n`.
    pub metric: String,
    /// The run claimed better.
    pub better: String,
    /// The run it is compared with.
    pub than: String,
    /// Only this actuator (all when absent; ignored by `force_imbalance_n`, which spans them).
    #[serde(default)]
    pub actuator: Option<String>,
    /// Smallest difference that counts, % of the larger value: as a one-actuator scene's claim (default 2).
    #[serde(default = "two_percent")]
    pub margin_pct: f64,
}

fn two_percent() -> f64 {
    2.0
}

/// The `force_sensor` of a load cell on the cylinder's rod.
pub const LOAD_CELL: &str = "load_cell";

/// The metrics a window reports, lower is better.
pub const METRICS: [&str; 3] = [
    "rms_force_error_n",
    "max_abs_force_error_n",
    "force_imbalance_n",
];

impl MechanismScene {
    /// Whether the TOML text is a mechanism scene (it lists `[[actuators]]`) rather than a one-actuator
    /// scene with a `[plant]`.
    pub fn is_mechanism(text: &str) -> bool {
        text.parse::<toml::Table>()
            .is_ok_and(|t| t.contains_key("actuators") && !t.contains_key("plant"))
    }

    /// Reads, parses and checks a mechanism scene.
    pub fn load(path: &Path) -> Result<Self, SceneError> {
        let text = pneuflex_files::read_text(path, pneuflex_files::InputKind::Scene)?;
        Self::from_toml_str(&text, path)
    }

    /// Parses and checks mechanism scene text; `path` names it in errors and its folder resolves the files
    /// it names (a sweep's edited copy of a scene is read this way).
    pub fn from_toml_str(text: &str, path: &Path) -> Result<Self, SceneError> {
        let de = toml::Deserializer::parse(text).map_err(|e| SceneError::Parse {
            file: path.to_path_buf(),
            at: e.span().map(|s| pneuflex_files::line_col(text, s.start)),
            key: String::new(),
            message: e.message().trim().to_string(),
        })?;
        let text = text.to_string();
        let mut scene: Self = serde_path_to_error::deserialize(de).map_err(|e| {
            let key = e.path().to_string();
            let key = if key == "." { String::new() } else { key };
            let inner = e.into_inner();
            SceneError::Parse {
                file: path.to_path_buf(),
                at: pneuflex_files::toml_key_position(&text, &key).or_else(|| {
                    inner
                        .span()
                        .map(|s| pneuflex_files::line_col(&text, s.start))
                }),
                key,
                message: inner.message().trim().to_string(),
            }
        })?;
        scene.source = path.to_path_buf();
        scene.text = text;
        scene.check()?;
        Ok(scene)
    }

    /// A file the scene names, resolved against the scene's folder.
    pub fn resolve(&self, p: &Path) -> PathBuf {
        if p.is_absolute() {
            p.to_path_buf()
        } else {
            self.source
                .parent()
                .map_or_else(|| p.to_path_buf(), |d| d.join(p))
        }
    }

    /// The files the scene reads, with their roles: the scene, the URDF and each actuator's sheet.
    pub fn input_files(&self) -> Vec<(&'static str, PathBuf)> {
        let mut v = vec![
            ("scene", self.source.clone()),
            ("urdf", self.resolve(&self.urdf)),
        ];
        for a in &self.actuators {
            let p = self.resolve(&a.sheet);
            if !v.iter().any(|(_, q)| *q == p) {
                v.push(("actuator", p));
            }
        }
        v
    }

    /// An error about the value at the dotted `key`, with its line.
    pub fn invalid(&self, key: &str, message: String) -> SceneError {
        SceneError::Invalid {
            file: self.source.clone(),
            at: pneuflex_files::toml_key_position(&self.text, key),
            key: key.to_string(),
            message,
        }
    }

    /// Number of control ticks.
    pub fn n_steps(&self) -> usize {
        (self.duration_s / self.dt_s).round() as usize
    }

    fn number(
        &self,
        key: &str,
        x: f64,
        check: fn(f64) -> Result<f64, String>,
    ) -> Result<(), SceneError> {
        check(x).map(drop).map_err(|m| self.invalid(key, m))
    }

    /// The checks no single type can make: ranges, names that refer to each other, the time grid.
    fn check(&self) -> Result<(), SceneError> {
        self.check_time_grid()?;
        self.check_actuators()?;
        self.check_springs_and_contacts()?;
        self.check_events()?;
        self.check_runs()?;
        self.check_windows_and_claims()?;
        Ok(())
    }

    /// The run's length, the tick, the physics and chamber steps, gravity.
    fn check_time_grid(&self) -> Result<(), SceneError> {
        use pneuflex_files::check::{finite, positive};
        self.number("duration_s", self.duration_s, positive)?;
        self.number("dt_s", self.dt_s, positive)?;
        if self.dt_s > 0.01 {
            return Err(self.invalid(
                "dt_s",
                format!(
                    "must be <= 0.01 s (one physics step per tick), got {}",
                    self.dt_s
                ),
            ));
        }
        if self.n_steps() > 10_000_000 {
            return Err(self.invalid(
                "duration_s",
                format!(
                    "{} ticks exceed the 10 million a run may take",
                    self.n_steps()
                ),
            ));
        }
        // Rapier's solver converges in a few iterations: past 100 each only costs time.
        if !(1..=100).contains(&self.solver_iterations) {
            return Err(self.invalid(
                "solver_iterations",
                format!("must be within 1..=100, got {}", self.solver_iterations),
            ));
        }
        if !(1..=1000).contains(&self.physics_steps_per_tick) {
            return Err(self.invalid(
                "physics_steps_per_tick",
                format!(
                    "must be within 1..=1000, got {}",
                    self.physics_steps_per_tick
                ),
            ));
        }
        // The chambers' RK4 is stable at ~0.1 ms substeps; 1000 per physics step is 1 µs substeps on a 1 ms one.
        if !(1..=1000).contains(&self.chamber_substeps) {
            return Err(self.invalid(
                "chamber_substeps",
                format!("must be within 1..=1000, got {}", self.chamber_substeps),
            ));
        }
        self.number(
            "divergence.max_abs_position_m",
            self.divergence.max_abs_position_m,
            positive,
        )?;
        self.number(
            "divergence.max_abs_force_n",
            self.divergence.max_abs_force_n,
            positive,
        )?;
        for (i, g) in self.gravity_m_s2.iter().enumerate() {
            self.number(&format!("gravity_m_s2[{i}]"), *g, finite)?;
        }
        Ok(())
    }

    /// Each actuator: its name, one mount, its force sensor, its force reference's pieces, its start.
    fn check_actuators(&self) -> Result<(), SceneError> {
        use pneuflex_files::check::{finite, positive};
        if self.actuators.is_empty() {
            return Err(self.invalid("actuators", "needs at least one actuator".into()));
        }
        for (i, a) in self.actuators.iter().enumerate() {
            let at = |k: &str| format!("actuators[{i}].{k}");
            if a.name.is_empty() || a.name.contains(['.', ',', '"', '/']) {
                return Err(self.invalid(
                    &at("name"),
                    format!(
                        "must be a non-empty name without . , \" or /, got {:?}",
                        a.name
                    ),
                ));
            }
            if self.actuators[..i].iter().any(|o| o.name == a.name) {
                return Err(self.invalid(&at("name"), format!("{:?} is listed twice", a.name)));
            }
            match (&a.joint, &a.anchors) {
                (Some(_), None) | (None, Some(_)) => {}
                _ => {
                    return Err(self.invalid(
                        &at("joint"),
                        "give exactly one mount: `joint` (a prismatic joint) or `anchors`".into(),
                    ));
                }
            }
            if a.force_sensor != LOAD_CELL
                && !self.contacts.iter().any(|c| c.name == a.force_sensor)
            {
                return Err(self.invalid(
                    &at("force_sensor"),
                    format!(
                        "no contact named {:?} (contacts: {}; or \"{LOAD_CELL}\")",
                        a.force_sensor,
                        self.contact_names()
                    ),
                ));
            }
            self.number(&at("x_d_m"), a.x_d_m, finite)?;
            if a.force.is_empty() {
                return Err(self.invalid(&at("force"), "needs at least one piece".into()));
            }
            let mut last = f64::NEG_INFINITY;
            for (j, p) in a.force.iter().enumerate() {
                let key = format!("actuators[{i}].force[{j}]");
                let start = p.start_s();
                if !(start.is_finite() && start >= 0.0 && start > last) {
                    return Err(self.invalid(
                        &format!("{key}.start_s"),
                        format!(
                            "must be finite, >= 0 and after the previous piece's start, got {start}"
                        ),
                    ));
                }
                last = start;
                if let ForcePiece::Sine { frequency_hz, .. } = p {
                    self.number(&format!("{key}.frequency_hz"), *frequency_hz, positive)?;
                }
            }
            if let Some(q) = a.initial_position_m {
                self.number(&at("initial_position_m"), q, finite)?;
                if a.joint.is_none() {
                    return Err(self.invalid(&at("initial_position_m"), "only a `joint` mount starts away from the URDF's zero: move the anchors' link instead".into()));
                }
            }
            if let Some(r) = a.anchors.as_ref().and_then(|an| an.retracted_length_m) {
                self.number(&at("anchors.retracted_length_m"), r, positive)?;
            }
        }
        Ok(())
    }

    /// The joint springs and the contact pads: their names and numbers.
    fn check_springs_and_contacts(&self) -> Result<(), SceneError> {
        use pneuflex_files::check::{non_negative, positive};
        for (i, sp) in self.springs.iter().enumerate() {
            let at = |k: &str| format!("springs[{i}].{k}");
            self.number(&at("stiffness_n_per_m"), sp.stiffness_n_per_m, positive)?;
            self.number(&at("damping_n_s_per_m"), sp.damping_n_s_per_m, non_negative)?;
        }
        for (i, c) in self.contacts.iter().enumerate() {
            let at = |k: &str| format!("contacts[{i}].{k}");
            if c.name == LOAD_CELL {
                return Err(self.invalid(
                    &at("name"),
                    format!(
                        "\"{LOAD_CELL}\" names the rod's load cell: call the contact otherwise"
                    ),
                ));
            }
            if self.contacts[..i].iter().any(|o| o.name == c.name) {
                return Err(self.invalid(&at("name"), format!("{:?} is listed twice", c.name)));
            }
            self.number(&at("stiffness_n_per_m"), c.stiffness_n_per_m, positive)?;
            self.number(&at("damping_n_s_per_m"), c.damping_n_s_per_m, non_negative)?;
        }
        Ok(())
    }

    /// Each event: its time within the run and the one contact or spring it changes.
    fn check_events(&self) -> Result<(), SceneError> {
        use pneuflex_files::check::{non_negative, positive};
        for (i, e) in self.events.iter().enumerate() {
            let at = |k: &str| format!("events[{i}].{k}");
            if !(e.t_s.is_finite() && (0.0..=self.duration_s).contains(&e.t_s)) {
                return Err(self.invalid(
                    &at("t_s"),
                    format!(
                        "must be within the run [0, {}] s, got {}",
                        self.duration_s, e.t_s
                    ),
                ));
            }
            match (&e.contact, &e.spring) {
                (Some(c), None) if !self.contacts.iter().any(|x| &x.name == c) => {
                    return Err(self.invalid(
                        &at("contact"),
                        format!(
                            "no contact named {c:?} (contacts: {})",
                            self.contact_names()
                        ),
                    ));
                }
                (None, Some(sp)) if !self.springs.iter().any(|x| &x.name == sp) => {
                    let names: Vec<&str> = self.springs.iter().map(|x| x.name.as_str()).collect();
                    return Err(self.invalid(
                        &at("spring"),
                        format!("no spring named {sp:?} (springs: {})", names.join(", ")),
                    ));
                }
                (Some(_), None) | (None, Some(_)) => {}
                _ => {
                    return Err(self.invalid(
                        &at("t_s"),
                        "name exactly one of `contact` or `spring`".into(),
                    ));
                }
            }
            self.number(&at("stiffness_n_per_m"), e.stiffness_n_per_m, positive)?;
            if let Some(c) = e.damping_n_s_per_m {
                self.number(&at("damping_n_s_per_m"), c, non_negative)?;
            }
        }
        Ok(())
    }

    /// The runs: names, no frozen run, and every controller (each actuator's own gains too) builds.
    fn check_runs(&self) -> Result<(), SceneError> {
        if self.runs.is_empty() {
            return Err(self.invalid("runs", "needs at least one run".into()));
        }
        for (i, r) in self.runs.iter().enumerate() {
            if r.name.is_empty() || r.name.contains(['/', '\\']) || r.name == "." || r.name == ".."
            {
                return Err(self.invalid(
                    &format!("runs[{i}].name"),
                    format!("must be a non-empty directory name, got {:?}", r.name),
                ));
            }
            if self.runs[..i].iter().any(|o| o.name == r.name) {
                return Err(self.invalid(
                    &format!("runs[{i}].name"),
                    format!("duplicate run name {:?}", r.name),
                ));
            }
            if r.frozen.is_some() {
                return Err(self.invalid(
                    &format!("runs[{i}].frozen"),
                    "frozen runs are for one-actuator scenes".into(),
                ));
            }
            r.build()
                .map_err(|e| self.invalid(&format!("runs[{i}].{}", e.key), e.message))?;
            // An actuator's own gains build with every run's kind.
            for (j, a) in self.actuators.iter().enumerate() {
                if a.gains.is_some() {
                    self.actuator_run(i, j).build().map_err(|e| {
                        self.invalid(&format!("actuators[{j}].gains.{}", e.key), e.message)
                    })?;
                }
            }
        }
        Ok(())
    }

    /// The metric windows within the run, and each claim's window, metric, runs and actuator.
    fn check_windows_and_claims(&self) -> Result<(), SceneError> {
        for (i, w) in self.metrics.iter().enumerate() {
            let at = |k: &str| format!("metrics[{i}].{k}");
            if !(w.t0_s.is_finite()
                && w.t1_s.is_finite()
                && 0.0 <= w.t0_s
                && w.t0_s < w.t1_s
                && w.t1_s <= self.duration_s)
            {
                return Err(self.invalid(
                    &at("t1_s"),
                    format!(
                        "needs 0 <= t0_s < t1_s <= duration_s = {}, got [{}, {}]",
                        self.duration_s, w.t0_s, w.t1_s
                    ),
                ));
            }
            if self.metrics[..i].iter().any(|o| o.name == w.name) {
                return Err(self.invalid(&at("name"), format!("{:?} is listed twice", w.name)));
            }
        }
        for (i, c) in self.claims.iter().enumerate() {
            let at = |k: &str| format!("claims[{i}].{k}");
            if !self.metrics.iter().any(|w| w.name == c.window) {
                return Err(self.invalid(
                    &at("window"),
                    format!("no metric window named {:?}", c.window),
                ));
            }
            if !METRICS.contains(&c.metric.as_str()) {
                return Err(self.invalid(
                    &at("metric"),
                    format!("unknown metric {:?}, expected one of {METRICS:?}", c.metric),
                ));
            }
            for (key, run) in [("better", &c.better), ("than", &c.than)] {
                if !self.runs.iter().any(|r| &r.name == run) {
                    return Err(self.invalid(&at(key), format!("no run named {run:?}")));
                }
            }
            if let Some(a) = &c.actuator
                && !self.actuators.iter().any(|x| &x.name == a)
            {
                return Err(self.invalid(&at("actuator"), format!("no actuator named {a:?}")));
            }
            self.number(
                &at("margin_pct"),
                c.margin_pct,
                pneuflex_files::check::non_negative,
            )?;
        }
        Ok(())
    }

    fn contact_names(&self) -> String {
        self.contacts
            .iter()
            .map(|c| c.name.as_str())
            .collect::<Vec<_>>()
            .join(", ")
    }
}
