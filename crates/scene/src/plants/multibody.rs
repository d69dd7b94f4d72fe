//! The multibody plant: the paper's rig on the general engine of `pneuflex-multibody` (`CarriageRig`: the
//! URDF as a `Mechanism` with one actuator, compliant wood and iron faces on spring mounts, rigid flange-face
//! contacts, a held carriage that a swap moves along scripted waypoints) driven by the pneumatic force
//! element of the actuator sheet.
//!
//! Either one control tick of `dt_s` is a whole number of Rapier steps of `physics_dt_s`, or one Rapier
//! step spans a whole number n of control ticks (`physics_dt_s = n dt_s`). The valve command is held over
//! the tick (zero-order hold); the chambers are integrated `chamber_substeps` times per physics step or
//! per tick, whichever is shorter, so the chambers and the controller always run at the tick.
//!
//! A physics step of n ticks (docs/scenes.md, "Physics step longer than the tick"): the chambers see the
//! flange of the last physics step (x_s, v_s at t_s) moving on at its velocity,
//!     x(t) = x_s + v_s (t - t_s),  x'(t) = v_s   (held at a stop it would cross, at rest),   (S1)
//! exactly what the force element assumes inside one physics step (one tick per step is the same
//! computation, bit for bit); the sensors read (S1) at the tick and the load cell's last value (the mean
//! contact force of the last physics step, held). After the n-th tick Rapier steps over n dt_s with the
//! mean of the n ticks' force, so the impulse it applies is the chambers' impulse over the step,
//!     F_step = (1/n) sum_j F_j,  F_j = the tick's substep-averaged piston force minus friction.   (S2)
//! Events fall on physics steps (validated at load).
//! Mechanics (mass, K_v, stroke) come from the URDF; the pneumatics and the Coulomb friction law from
//! the actuator sheet (the URDF has only viscous joint damping).

use std::path::PathBuf;

use serde::{Deserialize, Serialize};

use pneuflex_control::{Sensors, Telemetry, ValveCommand};
use pneuflex_multibody::{
    AxialActuator, CarriageRig, ContactParams, MaterialConfig, Measurements, MultibodyError,
    PneumaticForceElement, RigConfig,
};
use pneuflex_pneumatics::{ActuatorSheet, ChamberState, Friction};

use super::{
    ActuatorGeometry, EventSpec, LinearSpring, Plant, PlantSite, Visual, VisualPose, VisualRole,
};
use crate::error::SceneError;
use crate::origin::Check;

/// The pneumatic force element plus the sheet's Coulomb friction, acting between cylinder and flange.
#[derive(Debug, Clone)]
pub struct FlangeDrive {
    /// Chambers and valve (eqs. (2)-(10)).
    pub element: PneumaticForceElement,
    /// Coulomb friction law of eq. (1) (`f`), from the actuator sheet.
    pub friction: Friction,
    /// Gravity along +x on the flange, N (only used as the drive of a stick-slip law).
    pub gravity_force_n: f64,
}

impl AxialActuator for FlangeDrive {
    fn force(&mut self, x: f64, x_dot: f64, dt: f64) -> f64 {
        let f_p = self.element.force(x, x_dot, dt);
        // eq. (1): F_1 - F_2 - f; K_v x' is the URDF joint damping, G_alpha is Rapier's gravity.
        f_p - self.friction.force(x_dot, f_p + self.gravity_force_n)
    }
}

/// The cylinder family of a mechanism scene: its force element's command, sensors, state and invariants.
impl pneuflex_multibody::ActuatorFamily for FlangeDrive {
    fn family(&self) -> &'static str {
        pneuflex_multibody::ActuatorFamily::family(&self.element)
    }
    fn set_command(&mut self, u: f64) {
        self.element.set_command(u)
    }
    fn sensors(&self) -> &'static [pneuflex_multibody::SensorSpec] {
        pneuflex_multibody::ActuatorFamily::sensors(&self.element)
    }
    fn read_sensors(&self, out: &mut [f64]) {
        pneuflex_multibody::ActuatorFamily::read_sensors(&self.element, out)
    }
    fn state(&self) -> Vec<f64> {
        pneuflex_multibody::ActuatorFamily::state(&self.element)
    }
    fn set_state(&mut self, s: &[f64]) -> bool {
        pneuflex_multibody::ActuatorFamily::set_state(&mut self.element, s)
    }
    fn check_invariants(&self, x_m: f64, stroke_m: f64) -> Result<(), String> {
        pneuflex_multibody::ActuatorFamily::check_invariants(&self.element, x_m, stroke_m)
    }
    fn set_supply_pa(&mut self, p: f64) -> bool {
        pneuflex_multibody::ActuatorFamily::set_supply_pa(&mut self.element, p)
    }
    fn supply_pa(&self) -> Option<f64> {
        pneuflex_multibody::ActuatorFamily::supply_pa(&self.element)
    }
}

/// The rig of `pneuflex-multibody` as a scene plant.
pub struct MultibodyPlant {
    scene_file: PathBuf,
    urdf_file: PathBuf,
    robot: urdf_rs::Robot,
    config: RigConfig,
    world: CarriageRig,
    drive0: FlangeDrive,
    drive: FlangeDrive,
    steps_per_tick: u32,
    /// Control ticks per physics step (1, or n when `physics_dt_s = n dt_s`).
    ticks_per_step: u32,
    /// Ticks of the physics step in progress already integrated (0 .. ticks_per_step).
    tick_in_step: u32,
    /// Sum of those ticks' forces on the flange, N (eq. (S2)).
    force_sum_n: f64,
    flange_mass_kg: f64,
    /// The last physics step's sensor reading.
    last: Measurements,
    /// What the sensors read now: `last`, or (S1) between physics steps.
    sensed: Measurements,
}

impl std::fmt::Debug for MultibodyPlant {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("MultibodyPlant")
            .field("urdf", &self.urdf_file)
            .field("config", &self.config)
            .field("steps_per_tick", &self.steps_per_tick)
            .field("last", &self.last)
            .finish_non_exhaustive()
    }
}

impl MultibodyPlant {
    /// The plant a multibody scene describes (URDF and actuator sheet resolved against the scene's
    /// directory). Checks `environment.x_e_m` against the URDF's first-touch position of the initial
    /// material.
    pub fn from_spec(mb: &MultibodySpec, site: &PlantSite<'_>) -> Result<Self, SceneError> {
        let origin = site.origin;
        let sheet_path = origin.resolve(&mb.actuator);
        let sheet = origin
            .load_sheet(&sheet_path)
            .map_err(|e| origin.invalid("plant.actuator", e.to_string()))?;
        // The rig's force element integrates the paper's chambers and friction only.
        let beyond = sheet.effects_beyond_paper();
        if !beyond.is_empty() {
            return Err(origin.invalid(
                "plant.actuator",
                format!(
                    "{} gives {}: the multibody plant models the paper's chambers, valve and friction \
                     only; use plant.kind = \"pneumatic\" (the 1-DOF model) or remove them",
                    sheet_path.display(),
                    beyond.join(", ")
                ),
            ));
        }
        let urdf_file = origin.resolve(&mb.urdf);
        let robot = pneuflex_multibody::urdf_build::read_urdf(&urdf_file)
            .map_err(|e| origin.invalid("plant.urdf", e.to_string()))?;
        let mut config = config_of(mb, &sheet);
        let mb_err = |field: &str, e: MultibodyError| origin.invalid(field, e.to_string());
        // Build once at x = 0 to learn the initial material's contact position.
        let probe = CarriageRig::from_robot(&urdf_file, &robot, &config)
            .map_err(|e| mb_err(&multibody_field(mb, &e), e))?;
        let init = config.initial_material.clone();
        let x_e = probe
            .material_x_e(&init)
            .map_err(|e| mb_err("plant.initial_material", e))?;
        if (x_e - site.environment.x_e_m).abs() > 1e-6 {
            return Err(origin.invalid(
                "environment.x_e_m",
                format!(
                    "must be the flange extension where {} first touches material {init:?}: {x_e:.6} m, got {}",
                    urdf_file.display(),
                    site.environment.x_e_m
                ),
            ));
        }
        let stroke = probe.stroke();
        let x0 = mb.x0_m.unwrap_or(x_e);
        if !(0.0..=stroke).contains(&x0) {
            return Err(origin.invalid(
                if mb.x0_m.is_some() {
                    "plant.x0_m"
                } else {
                    "environment.x_e_m"
                },
                format!(
                    "initial position {x0} m is outside the stroke [0, {stroke}] m of {}",
                    urdf_file.display()
                ),
            ));
        }
        config.initial_x_m = x0;
        let world = CarriageRig::from_robot(&urdf_file, &robot, &config)
            .map_err(|e| mb_err(&multibody_field(mb, &e), e))?;
        let flange_mass_kg = robot
            .links
            .iter()
            .find(|l| l.name == config.flange_link)
            .map_or(0.0, |l| l.inertial.mass.value);
        let gravity_force_n = flange_mass_kg * config.gravity_m_s2 * config.alpha_rad.sin();
        // Initial chambers as on the 1-DOF plant: B at the mean of supply and atmosphere, A at the static
        // balance of eq. (1) with the contact force at x0 (the face is unloaded at x0 = x_e).
        let actuator = sheet.actuator();
        let s = &actuator.supply;
        let p_b = 0.5 * (s.supply_pressure_pa + s.atmosphere_pressure_pa);
        let mut mech_model = sheet.model();
        mech_model.mechanics.moving_mass_kg = flange_mass_kg;
        mech_model.mechanics.alpha_rad = config.alpha_rad;
        let k0 = mb.initial_material().map_or(0.0, |m| m.stiffness_n_per_m);
        let f0 = LinearSpring {
            stiffness_n_per_m: k0,
            x_e_m: x_e,
        }
        .force(x0);
        let p_a = mech_model.static_balance(p_b, -f0);
        let element =
            PneumaticForceElement::new(actuator, ChamberState::new(p_a, p_b), mb.chamber_substeps);
        let drive = FlangeDrive {
            element,
            friction: sheet.mechanics.friction,
            gravity_force_n,
        };
        let last = world.measurements();
        Ok(Self {
            scene_file: origin.source.to_path_buf(),
            urdf_file,
            robot,
            config,
            world,
            drive0: drive.clone(),
            drive,
            steps_per_tick: mb.steps_per_tick(site.dt_s),
            ticks_per_step: mb.ticks_per_step(site.dt_s),
            tick_in_step: 0,
            force_sum_n: 0.0,
            flange_mass_kg,
            last,
            sensed: last,
        })
    }

    /// The rig on the general engine.
    pub fn world(&self) -> &CarriageRig {
        &self.world
    }

    /// The force element (chambers, valve, friction).
    pub fn drive(&self) -> &FlangeDrive {
        &self.drive
    }

    /// The world configuration the plant was built with.
    pub fn config(&self) -> &RigConfig {
        &self.config
    }

    /// Physics steps per control tick (1 when a physics step spans several ticks).
    pub fn steps_per_tick(&self) -> u32 {
        self.steps_per_tick
    }

    /// Control ticks per physics step (1 when a tick holds one or more physics steps).
    pub fn ticks_per_step(&self) -> u32 {
        self.ticks_per_step
    }

    /// Flange mass from the URDF, kg.
    pub fn flange_mass_kg(&self) -> f64 {
        self.flange_mass_kg
    }

    /// Viscous damping K_v of the flange joint from the URDF (`<dynamics damping>`), N·s/m.
    pub fn flange_damping_n_s_per_m(&self) -> f64 {
        self.robot
            .joints
            .iter()
            .find(|j| j.name == self.config.flange_joint)
            .map_or(0.0, |j| j.dynamics.as_ref().map_or(0.0, |d| d.damping))
    }

    /// The last load-cell and flange reading (between physics steps: eq. (S1) and the held load cell).
    pub fn measurements(&self) -> Measurements {
        self.sensed
    }

    /// What a link is to the experiment, from the configuration's link roles: the flange link, the
    /// cylinder link, and everything mounted on the environment carriage (faces and blocks).
    pub fn link_role(&self, link: &str) -> VisualRole {
        if link == self.config.flange_link {
            VisualRole::Flange
        } else if link == self.config.cylinder_link {
            VisualRole::Cylinder
        } else if self.carried_by_carriage(link) {
            VisualRole::Environment
        } else {
            VisualRole::Other
        }
    }

    /// Whether `link` hangs (through any joints) below the carriage link, the carriage itself excluded.
    fn carried_by_carriage(&self, link: &str) -> bool {
        let mut at = link;
        // A URDF is a tree: at most one parent per link; the bound guards against a malformed loop.
        for _ in 0..=self.robot.joints.len() {
            match self.robot.joints.iter().find(|j| j.child.link == at) {
                Some(j) if j.parent.link == self.config.carriage_link => return true,
                Some(j) => at = &j.parent.link,
                None => return false,
            }
        }
        false
    }

    /// The flange `tau` seconds after the last physics step, eq. (S1), held at its stops: an
    /// extrapolation that leaves [0, stroke] stops at the end it crosses, at rest (the joint limit holds
    /// the flange there); a stop Rapier's own step has overshot stays where Rapier put it.
    fn between_steps(&self, tau: f64) -> (f64, f64) {
        let (x_s, v_s) = self.world.flange_state();
        let x = x_s + v_s * tau;
        let (lo, hi) = (x_s.min(0.0), x_s.max(self.world.stroke()));
        if x < lo || x > hi {
            (x.clamp(lo, hi), 0.0)
        } else {
            (x, v_s)
        }
    }

    fn event_error(&self, e: MultibodyError) -> crate::plants::PlantError {
        format!("{} (URDF {})", e, self.urdf_file.display()).into()
    }
}

/// The world configuration of a multibody scene: the link and joint roles the scene names (the paper rig's
/// names where it names none), its materials, step, iterations and incline.
fn config_of(mb: &MultibodySpec, sheet: &ActuatorSheet) -> RigConfig {
    let mut c = RigConfig::paper_rig();
    for (name, role) in [
        (&mb.flange_link, &mut c.flange_link),
        (&mb.flange_joint, &mut c.flange_joint),
        (&mb.cylinder_link, &mut c.cylinder_link),
        (&mb.carriage_link, &mut c.carriage_link),
    ] {
        if let Some(n) = name {
            role.clone_from(n);
        }
    }
    c.materials = mb
        .materials
        .iter()
        .map(|m| MaterialConfig {
            name: m.name.clone(),
            mount_joint: m.mount_joint.clone(),
            params: ContactParams {
                stiffness_n_per_m: m.stiffness_n_per_m,
                damping_n_s_per_m: m.damping_n_s_per_m,
            },
        })
        .collect();
    c.initial_material = mb
        .initial_material()
        .map(|m| m.name.clone())
        .unwrap_or_default();
    c.alpha_rad = mb
        .alpha_deg
        .map_or(sheet.mechanics.alpha_rad, f64::to_radians);
    c.dt_s = mb.physics_dt_s;
    c.solver_iterations = mb.solver_iterations;
    c.friction = mb.contact_friction;
    c.gravity_m_s2 = sheet.mechanics.gravity_m_per_s2;
    c
}

/// The scene key a multibody build error belongs to.
fn multibody_field(mb: &MultibodySpec, e: &MultibodyError) -> String {
    match e {
        MultibodyError::MissingJoint { field, joint, .. } if field.starts_with("materials") => {
            match mb.materials.iter().position(|m| &m.mount_joint == joint) {
                Some(i) => format!("plant.materials[{i}].mount_joint"),
                None => "plant.materials".into(),
            }
        }
        MultibodyError::BadConfig { field, .. } => format!("plant ({field})"),
        // A role's link or joint the URDF lacks: the scene's key when the scene names it.
        MultibodyError::MissingLink { field, .. } | MultibodyError::MissingJoint { field, .. } => {
            let key = match *field {
                "flange_link" => Some(("plant.flange_link", &mb.flange_link)),
                "flange_joint" => Some(("plant.flange_joint", &mb.flange_joint)),
                "cylinder_link" => Some(("plant.cylinder_link", &mb.cylinder_link)),
                "carriage_link" | "kinematic link" => {
                    Some(("plant.carriage_link", &mb.carriage_link))
                }
                _ => None,
            };
            match key {
                Some((key, Some(_))) => key.into(),
                _ => "plant.urdf".into(),
            }
        }
        _ => "plant.urdf".into(),
    }
}

impl Plant for MultibodyPlant {
    fn signals(&self) -> &'static [pneuflex_control::Signal] {
        &crate::plants::VALVE_SIGNALS
    }

    fn record(&self, out: &mut [f64]) {
        out[0] = self.drive.element.valve.spool;
    }

    fn sense(&self) -> Sensors {
        let (p_a, p_b) = self.drive.element.pressures();
        Sensors {
            t: 0.0,
            x: self.sensed.x,
            x_dot: self.sensed.x_dot,
            f_e: self.sensed.f_e,
            p_a,
            p_b,
        }
    }

    fn actuate(&mut self, command: ValveCommand, _telemetry: &Telemetry) {
        self.drive.element.set_command(command.u);
    }

    fn set_regulators(
        &mut self,
        _i: usize,
        regulator: Option<pneuflex_pneumatics::PressureRegulator>,
    ) -> Result<(f64, f64), super::PlantError> {
        // The force element integrates the paper's chambers only (a sheet beyond it is refused at load).
        self.drive.element.set_regulator(regulator);
        self.drive0.element.set_regulator(regulator);
        let s = &self.drive.element.actuator.supply;
        Ok((s.atmosphere_pressure_pa, s.supply_pressure_pa))
    }

    fn actuate_pressures(&mut self, _i: usize, p_a_pa: f64, p_b_pa: f64) {
        self.drive.element.set_pressure_command(p_a_pa, p_b_pa);
    }

    fn advance(&mut self, dt: f64) {
        if self.ticks_per_step == 1 {
            // dt_s = steps_per_tick · physics_dt_s (validated at load).
            for _ in 0..self.steps_per_tick {
                self.last = self.world.step(&mut self.drive);
            }
            self.sensed = self.last;
            return;
        }
        // physics_dt_s = n dt_s: this tick's chambers along (S1), Rapier after the n-th tick with (S2).
        let j = f64::from(self.tick_in_step);
        let (x_j, v_j) = self.between_steps(j * dt);
        self.force_sum_n += self.drive.force(x_j, v_j, dt);
        self.tick_in_step += 1;
        if self.tick_in_step == self.ticks_per_step {
            let f = self.force_sum_n / f64::from(self.ticks_per_step);
            self.last = self.world.step_with_force(f);
            self.sensed = self.last;
            self.tick_in_step = 0;
            self.force_sum_n = 0.0;
        } else {
            let (x, x_dot) = self.between_steps((j + 1.0) * dt);
            self.sensed = Measurements {
                t_s: self.last.t_s + (j + 1.0) * dt,
                x,
                x_dot,
                ..self.last
            };
        }
    }

    fn apply(&mut self, event: &EventSpec) -> Result<(), crate::plants::PlantError> {
        match event {
            EventSpec::Stiffness {
                stiffness_n_per_m,
                material,
                damping_n_s_per_m,
                ..
            } => {
                let name = match material {
                    Some(n) => n.clone(),
                    None => self
                        .world
                        .active_material()
                        .ok_or("no material faces the flange (the carriage is moving): name one with `material`")?
                        .to_owned(),
                };
                let old = self
                    .world
                    .material_params(&name)
                    .map_err(|e| self.event_error(e))?;
                let params = ContactParams {
                    stiffness_n_per_m: *stiffness_n_per_m,
                    damping_n_s_per_m: damping_n_s_per_m.unwrap_or(old.damping_n_s_per_m),
                };
                self.world
                    .set_material(&name, params)
                    .map_err(|e| self.event_error(e))
            }
            EventSpec::SwapEnvironment { to, duration_s, .. } => self
                .world
                .swap_environment(to, *duration_s)
                .map_err(|e| self.event_error(e)),
            EventSpec::Alpha { alpha_deg, .. } => {
                let a = alpha_deg.to_radians();
                self.world.set_alpha(a).map_err(|e| self.event_error(e))?;
                self.drive.gravity_force_n =
                    self.flange_mass_kg * self.config.gravity_m_s2 * a.sin();
                Ok(())
            }
        }
    }

    fn visuals(&self) -> Vec<Visual> {
        super::drawn_links(self.world.link_views(), |link| self.link_role(link))
    }

    fn visual_poses(&self, pose: &mut dyn FnMut(usize, VisualPose)) {
        super::drawn_poses(self.world.link_views(), self.world.world_from_rig(), pose)
    }

    fn actuator_geometry(&self) -> Option<ActuatorGeometry> {
        Some(ActuatorGeometry {
            stroke_m: self.world.stroke(),
            bore_m: self.drive.element.actuator.cylinder.bore_m,
            alpha_rad: self.config.alpha_rad,
            x_e_m: self
                .world
                .material_x_e(&self.config.initial_material)
                .unwrap_or(self.config.initial_x_m),
            pwm_period_s: self.drive.element.actuator.valve.pwm_period_s(),
        })
    }

    fn check_invariants(&self) -> Result<(), crate::plants::PlantError> {
        let el = &self.drive.element;
        crate::plants::chamber_invariants(
            &el.chambers,
            &el.actuator.supply,
            self.sensed.x,
            self.world.stroke(),
        )
    }

    fn reset(&mut self) {
        // The rig has no reset: rebuild it from the parsed URDF (it was built from the same inputs).
        match CarriageRig::from_robot(&self.urdf_file, &self.robot, &self.config) {
            Ok(w) => {
                self.last = w.measurements();
                self.sensed = self.last;
                self.world = w;
            }
            Err(e) => unreachable!(
                "{}: the multibody plant rebuilt from unchanged inputs failed: {e}",
                self.scene_file.display()
            ),
        }
        self.drive = self.drive0.clone();
        self.tick_in_step = 0;
        self.force_sum_n = 0.0;
    }
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
    /// The URDF's link that the cylinder pushes (rod and flange). Absent: `flange` (urdf/rig.urdf).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub flange_link: Option<String>,
    /// The prismatic joint between the cylinder and the flange link. Absent: `flange_slide`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub flange_joint: Option<String>,
    /// The URDF's link of the cylinder body (the force's reaction side). Absent: `cylinder`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cylinder_link: Option<String>,
    /// The URDF's link that carries the materials, driven kinematically. Absent: `carriage`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub carriage_link: Option<String>,
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

/// Checks the multibody plant's keys, its physics step against `dt_s` and the events, and its materials
/// against `[environment]`'s stiffness.
pub(crate) fn check(mb: &MultibodySpec, site: &PlantSite<'_>) -> Result<(), SceneError> {
    let v = &site.check();
    if mb.urdf.as_os_str().is_empty() {
        return Err(v.err("plant.urdf", "must name a URDF file".into()));
    }
    if mb.actuator.as_os_str().is_empty() {
        return Err(v.err("plant.actuator", "must name an actuator sheet".into()));
    }
    v.positive("plant.physics_dt_s", mb.physics_dt_s)?;
    let whole = |r: f64| r >= 1.0 - 1e-9 && (r - r.round()).abs() <= 1e-6 * r.max(1.0);
    let ratio = site.dt_s / mb.physics_dt_s;
    let inverse = mb.physics_dt_s / site.dt_s;
    if !whole(ratio) && !whole(inverse) {
        return Err(v.err(
            "plant.physics_dt_s",
            format!(
                "must divide dt_s ({}) or be a whole multiple of it, got physics_dt_s / dt_s = {inverse}",
                site.dt_s
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
        for (i, e) in site.events.iter().enumerate() {
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
        v.within("plant.alpha_deg", a, -90.0, 90.0)?;
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
    if (site.environment.stiffness_n_per_m - init.stiffness_n_per_m).abs()
        > 1e-9 * init.stiffness_n_per_m
    {
        return Err(v.err(
            "environment.stiffness_n_per_m",
            format!(
                "must equal the initial material {:?}'s stiffness_n_per_m ({}) on a multibody plant, got {}",
                init.name, init.stiffness_n_per_m, site.environment.stiffness_n_per_m
            ),
        ));
    }
    Ok(())
}

/// Refuses a material name the multibody plant does not list, naming the ones it does.
pub(crate) fn known_material(
    v: &Check<'_>,
    path: &str,
    mb: &MultibodySpec,
    name: &str,
) -> Result<(), SceneError> {
    if mb.materials.iter().any(|m| m.name == name) {
        Ok(())
    } else {
        Err(v.err(
            path,
            format!(
                "unknown material {name:?}, expected one of {}",
                material_names(mb)
            ),
        ))
    }
}

fn material_names(mb: &MultibodySpec) -> String {
    mb.materials
        .iter()
        .map(|m| format!("{:?}", m.name))
        .collect::<Vec<_>>()
        .join(", ")
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plants::VisualRole;

    fn plant(scene: &str) -> MultibodyPlant {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../scenes")
            .join(scene);
        MultibodyPlant::from_scene(&crate::schema::Scene::load(&path).unwrap()).unwrap()
    }

    #[test]
    fn visuals_carry_the_roles_of_the_configured_links() {
        let p = plant("paper-fig7-wood-to-iron.toml");
        let role = |name: &str| {
            p.visuals()
                .into_iter()
                .find(|v| v.name == name)
                .unwrap_or_else(|| panic!("no visual {name}"))
                .role
        };
        assert_eq!(role("flange"), VisualRole::Flange);
        assert_eq!(role("cylinder"), VisualRole::Cylinder);
        for env in ["wood_face", "wood_block", "iron_face", "iron_block"] {
            assert_eq!(role(env), VisualRole::Environment, "{env}");
        }
        assert_eq!(role("carriage"), VisualRole::Other);
        assert_eq!(role("platform"), VisualRole::Other);
    }

    #[test]
    fn the_actuator_geometry_is_the_rigs() {
        let p = plant("paper-fig3-multibody.toml");
        let g = p.actuator_geometry().unwrap();
        assert_eq!(g.stroke_m, p.world().stroke());
        assert_eq!(g.bore_m, p.drive().element.actuator.cylinder.bore_m);
        assert_eq!(g.alpha_rad, p.config().alpha_rad);
        assert!((g.x_e_m - 0.02).abs() < 1e-6, "{g:?}");
    }
}
