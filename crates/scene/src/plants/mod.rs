//! Plants: what the controller drives, one file per kind, and the `[plant]` table that says which. Every
//! plant is stepped the same way, `sense → controller.update → actuate → advance(dt)` ([`Plant`]). This file
//! is the registry: a kind's `mod` line, its [`PlantSpec`] variant with its keys and checks, and one arm in
//! each dispatch ([`PlantSpec::build`], [`PlantSpec::linearisable`]). The plants see the scene through a
//! [`PlantSite`], never the scene itself, so that the scene's file format can hold a `PlantSpec`.

mod chambers;
pub mod events;
pub mod ideal;
pub mod linear;
pub mod multibody;
pub mod plant;
pub mod pneumatic;
pub mod visual;

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::error::SceneError;
use crate::origin::{Check, SceneOrigin};
pub use chambers::{PRESSURE_MARGIN, VALVE_SIGNALS, chamber_invariants};
pub use events::EventSpec;
pub use ideal::IdealLoop;
pub use linear::LinearPlant;
pub use multibody::{FlangeDrive, MaterialSpec, MultibodyPlant, MultibodySpec};
pub use plant::{LinearSpring, Linearisable, Plant, PlantError, PlantErrorKind};
pub use pneumatic::OneDofPneumatic;
pub use visual::{
    ActuatorGeometry, Visual, VisualPose, VisualRole, VisualShape, drawn_links, drawn_poses,
};

/// What a plant is checked and built against: the scene around it, as the plants see it.
#[derive(Clone, Copy)]
pub struct PlantSite<'a> {
    /// The scene's file, text, folder and overlay: where an error is placed and a path resolved.
    pub origin: SceneOrigin<'a>,
    /// The control period, s.
    pub dt_s: f64,
    /// The environment at t = 0: `environment.stiffness_n_per_m` at `environment.x_e_m`.
    pub environment: LinearSpring,
    /// The scene's events (a physics step of several ticks must not fall between them).
    pub events: &'a [EventSpec],
}

impl PlantSite<'_> {
    /// The checks of the plant's values, blamed on their keys in the scene file.
    pub(crate) fn check(&self) -> Check<'_> {
        Check {
            origin: self.origin,
        }
    }
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

    /// The plant this spec describes, at its initial state, against the environment `env`.
    pub fn build(
        &self,
        site: &PlantSite<'_>,
        env: LinearSpring,
    ) -> Result<Box<dyn Plant>, SceneError> {
        Ok(match self {
            PlantSpec::Ideal {
                omega_rad_per_s,
                zeta,
                x0_m,
            } => Box::new(IdealLoop::new(*omega_rad_per_s, *zeta, *x0_m, env)),
            PlantSpec::Pneumatic { .. } => Box::new(OneDofPneumatic::from_spec(self, site, env)?),
            PlantSpec::Multibody(mb) => Box::new(MultibodyPlant::from_spec(mb, site)?),
            PlantSpec::Linear { .. } => Box::new(LinearPlant::from_spec(self, site, env)?),
        })
    }

    /// The plant against the spring `env` as the loop analyses take it ([`crate::analysis::loop_margins`],
    /// [`crate::analysis::pwm_onset`]): a plant the valve command drives continuously and that linearises.
    /// None for the ideal loop and the multibody rig, which they do not analyse.
    pub fn linearisable(
        &self,
        site: &PlantSite<'_>,
        env: LinearSpring,
    ) -> Result<Option<Box<dyn Linearisable>>, SceneError> {
        Ok(match self {
            PlantSpec::Pneumatic { .. } => {
                Some(Box::new(OneDofPneumatic::from_spec(self, site, env)?))
            }
            PlantSpec::Linear { .. } => Some(Box::new(LinearPlant::from_spec(self, site, env)?)),
            PlantSpec::Ideal { .. } | PlantSpec::Multibody(_) => None,
        })
    }

    /// Checks the plant's keys: every number of its kind, and the multibody rig's materials and physics
    /// step against the scene around it.
    pub(crate) fn check(&self, site: &PlantSite<'_>) -> Result<(), SceneError> {
        let v = &site.check();
        match self {
            PlantSpec::Ideal {
                omega_rad_per_s,
                zeta,
                x0_m,
            } => {
                v.positive("plant.omega_rad_per_s", *omega_rad_per_s)?;
                v.non_negative("plant.zeta", *zeta)?;
                v.finite("plant.x0_m", *x0_m)?;
                // RK4 is stable for |λ dt| below ~2.8; keep well inside.
                if omega_rad_per_s * site.dt_s > 1.0 {
                    return Err(v.err(
                        "plant.omega_rad_per_s",
                        format!(
                            "omega * dt_s must be <= 1 for an accurate fixed-step RK4, got {} (dt_s = {})",
                            omega_rad_per_s * site.dt_s,
                            site.dt_s
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
            PlantSpec::Multibody(mb) => multibody::check(mb, site)?,
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
}

fn one() -> f64 {
    1.0
}

fn default_substeps() -> u32 {
    10
}
