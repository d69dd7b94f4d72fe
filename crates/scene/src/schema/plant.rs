//! `[plant]`: which plant the controllers drive, with its keys and their checks, and what the rest of the
//! code asks of a plant's spec (the files it names, the key that sets its step, its integration steps).

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use super::Scene;
use super::check::Check;
use crate::error::SceneError;

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

impl PlantSpec {
    /// The plant's `kind` as the scene file writes it.
    pub fn kind(&self) -> &'static str {
        match self {
            PlantSpec::Ideal { .. } => "ideal",
            PlantSpec::Pneumatic { .. } => "pneumatic",
            PlantSpec::Multibody(_) => "multibody",
            PlantSpec::Linear { .. } => "linear",
        }
    }

    /// The actuator sheet the plant runs, as the scene writes it (relative to the scene), if it has one.
    pub fn actuator_sheet(&self) -> Option<&Path> {
        match self {
            PlantSpec::Pneumatic { actuator, .. } => Some(actuator),
            PlantSpec::Multibody(mb) => Some(&mb.actuator),
            PlantSpec::Linear { actuator, .. } => actuator.as_deref(),
            PlantSpec::Ideal { .. } => None,
        }
    }

    /// Every file the plant names, with its key in the scene, as written: the actuator sheet
    /// (`plant.actuator`) and the URDF (`plant.urdf`).
    pub fn files(&self) -> Vec<(&'static str, &Path)> {
        let mut out: Vec<(&'static str, &Path)> = self
            .actuator_sheet()
            .map(|a| ("plant.actuator", a))
            .into_iter()
            .collect();
        if let PlantSpec::Multibody(mb) = self {
            out.push(("plant.urdf", &mb.urdf));
        }
        out
    }

    /// The finest integration steps the plant takes per control period `dt_s` (RK4 substeps, or chamber
    /// substeps of the physics step).
    pub fn steps_per_tick(&self, dt_s: f64) -> f64 {
        match self {
            PlantSpec::Ideal { .. } => 1.0,
            PlantSpec::Pneumatic { substeps, .. } | PlantSpec::Linear { substeps, .. } => {
                f64::from(*substeps)
            }
            PlantSpec::Multibody(mb) => dt_s / mb.chamber_substep_s(dt_s),
        }
    }

    /// The multibody rig's spec, for a multibody plant.
    pub fn multibody(&self) -> Option<&MultibodySpec> {
        match self {
            PlantSpec::Multibody(mb) => Some(mb),
            PlantSpec::Ideal { .. } | PlantSpec::Pneumatic { .. } | PlantSpec::Linear { .. } => {
                None
            }
        }
    }

    /// The actuator whose force comes from the two-chamber model (the pneumatic and multibody plants): its
    /// sheet as written and the incline the scene sets (None: the sheet's). A force element coupled to
    /// another engine (MuJoCo) simulates this actuator.
    pub fn force_element(&self) -> Option<(&Path, Option<f64>)> {
        match self {
            PlantSpec::Pneumatic {
                actuator,
                alpha_deg,
                ..
            } => Some((actuator, *alpha_deg)),
            PlantSpec::Multibody(mb) => Some((&mb.actuator, mb.alpha_deg)),
            PlantSpec::Ideal { .. } | PlantSpec::Linear { .. } => None,
        }
    }

    /// The chambers' integration step for a plant with chambers: the step h, s, the key that sets it, and
    /// its current number of substeps.
    pub fn chamber_step(&self, dt_s: f64) -> Option<(f64, &'static str, f64)> {
        match self {
            PlantSpec::Pneumatic { substeps, .. } => Some((
                dt_s / f64::from(*substeps),
                "plant.substeps",
                f64::from(*substeps),
            )),
            PlantSpec::Multibody(mb) => Some((
                mb.chamber_substep_s(dt_s),
                "plant.chamber_substeps",
                f64::from(mb.chamber_substeps),
            )),
            PlantSpec::Ideal { .. } | PlantSpec::Linear { .. } => None,
        }
    }

    /// Whether the environment's spring is integrated inside the chambers' substeps (the 1-DOF pneumatic
    /// plant), so that the contact mode must be resolved by that step; the multibody plant leaves contact
    /// to Rapier.
    pub fn contact_in_substeps(&self) -> bool {
        match self {
            PlantSpec::Pneumatic { .. } => true,
            PlantSpec::Ideal { .. } | PlantSpec::Linear { .. } | PlantSpec::Multibody(_) => false,
        }
    }

    /// Whether gravity acts in the plant (an incline event changes something).
    pub fn has_gravity(&self) -> bool {
        match self {
            PlantSpec::Pneumatic { .. } | PlantSpec::Multibody(_) => true,
            PlantSpec::Ideal { .. } | PlantSpec::Linear { .. } => false,
        }
    }

    /// The key that sets the plant's finest step: what to change when a run needs too many steps.
    pub fn step_key(&self) -> &'static str {
        match self {
            PlantSpec::Multibody(_) => "plant.physics_dt_s",
            PlantSpec::Pneumatic { .. } | PlantSpec::Linear { .. } => "plant.substeps",
            PlantSpec::Ideal { .. } => "dt_s",
        }
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

fn one() -> f64 {
    1.0
}

fn default_substeps() -> u32 {
    10
}

/// Checks `[plant]`: every number of the plant kind the scene names, and the multibody rig's materials.
pub(crate) fn validate(scene: &Scene, v: &Check<'_>) -> Result<(), SceneError> {
    match &scene.plant {
        PlantSpec::Ideal {
            omega_rad_per_s,
            zeta,
            x0_m,
        } => {
            v.positive("plant.omega_rad_per_s", *omega_rad_per_s)?;
            v.non_negative("plant.zeta", *zeta)?;
            v.finite("plant.x0_m", *x0_m)?;
            // RK4 is stable for |λ dt| below ~2.8; keep well inside.
            if omega_rad_per_s * scene.dt_s > 1.0 {
                return Err(v.err(
                    "plant.omega_rad_per_s",
                    format!(
                        "omega * dt_s must be <= 1 for an accurate fixed-step RK4, got {} (dt_s = {})",
                        omega_rad_per_s * scene.dt_s,
                        scene.dt_s
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
                v.within("plant.alpha_deg", *a, -90.0, 90.0)?;
            }
            if let Some(x) = x0_m {
                v.finite("plant.x0_m", *x)?;
            }
        }
        PlantSpec::Multibody(mb) => validate_multibody(scene, v, mb)?,
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
    Ok(())
}

fn validate_multibody(scene: &Scene, v: &Check<'_>, mb: &MultibodySpec) -> Result<(), SceneError> {
    if mb.urdf.as_os_str().is_empty() {
        return Err(v.err("plant.urdf", "must name a URDF file".into()));
    }
    if mb.actuator.as_os_str().is_empty() {
        return Err(v.err("plant.actuator", "must name an actuator sheet".into()));
    }
    v.positive("plant.physics_dt_s", mb.physics_dt_s)?;
    let whole = |r: f64| r >= 1.0 - 1e-9 && (r - r.round()).abs() <= 1e-6 * r.max(1.0);
    let ratio = scene.dt_s / mb.physics_dt_s;
    let inverse = mb.physics_dt_s / scene.dt_s;
    if !whole(ratio) && !whole(inverse) {
        return Err(v.err(
            "plant.physics_dt_s",
            format!(
                "must divide dt_s ({}) or be a whole multiple of it, got physics_dt_s / dt_s = {inverse}",
                scene.dt_s
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
        for (i, e) in scene.events.iter().enumerate() {
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
    if (scene.environment.stiffness_n_per_m - init.stiffness_n_per_m).abs()
        > 1e-9 * init.stiffness_n_per_m
    {
        return Err(v.err(
            "environment.stiffness_n_per_m",
            format!(
                "must equal the initial material {:?}'s stiffness_n_per_m ({}) on a multibody plant, got {}",
                init.name, init.stiffness_n_per_m, scene.environment.stiffness_n_per_m
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
