//! Plants: what the controller drives, one file per kind. Every plant is stepped the same way,
//! `sense → controller.update → actuate → advance(dt)`; [`build_plant`] is the one place a scene's plant
//! spec becomes a plant.

mod chambers;
pub mod ideal;
pub mod linear;
pub mod multibody;
pub mod pneumatic;

use pneuflex_control::{Sensors, Telemetry, ValveCommand};

use crate::error::SceneError;
use crate::schema::{EventSpec, PlantSpec, Scene};
pub use chambers::{PRESSURE_MARGIN, VALVE_SIGNALS, chamber_invariants};
pub use ideal::IdealLoop;
pub use linear::LinearPlant;
pub use multibody::{FlangeDrive, MultibodyPlant};
pub use pneumatic::OneDofPneumatic;

/// Builds the plant a scene describes, at its initial state.
pub fn build_plant(scene: &Scene) -> Result<Box<dyn Plant>, SceneError> {
    let env = spring_at(scene, scene.environment.stiffness_n_per_m);
    match &scene.plant {
        PlantSpec::Ideal {
            omega_rad_per_s,
            zeta,
            x0_m,
        } => Ok(Box::new(IdealLoop::new(
            *omega_rad_per_s,
            *zeta,
            *x0_m,
            env,
        ))),
        PlantSpec::Pneumatic { .. } => Ok(Box::new(OneDofPneumatic::from_scene(scene, env)?)),
        PlantSpec::Multibody(_) => Ok(Box::new(MultibodyPlant::from_scene(scene)?)),
        PlantSpec::Linear { .. } => Ok(Box::new(LinearPlant::from_scene(scene, env)?)),
    }
}

/// The scene's plant against a spring of stiffness `k_e` at the scene's contact position, as the loop
/// analyses take it ([`crate::analysis::loop_margins`], [`crate::analysis::pwm_onset`]): a plant the valve
/// command drives continuously and that linearises. None for the ideal loop and the multibody rig, which
/// they do not analyse.
pub fn linearisable_at(
    scene: &Scene,
    k_e: f64,
) -> Result<Option<Box<dyn Linearisable>>, SceneError> {
    let env = spring_at(scene, k_e);
    Ok(match &scene.plant {
        PlantSpec::Pneumatic { .. } => Some(Box::new(OneDofPneumatic::from_scene(scene, env)?)),
        PlantSpec::Linear { .. } => Some(Box::new(LinearPlant::from_scene(scene, env)?)),
        PlantSpec::Ideal { .. } | PlantSpec::Multibody(_) => None,
    })
}

/// The scene's environment as a spring of stiffness `k_e`.
fn spring_at(scene: &Scene, k_e: f64) -> LinearSpring {
    LinearSpring {
        stiffness_n_per_m: k_e,
        x_e_m: scene.environment.x_e_m,
    }
}

/// What a plant gives the analysis: its continuous state as a vector, and back.
pub trait Linearisable: Plant {
    /// A copy at the same state, for an analysis that tries several linearisations from one point.
    fn boxed_clone(&self) -> Box<dyn Linearisable>;
    /// Whether the plant has the valve saturation and friction the describing-function prediction of a
    /// limit cycle models ([`crate::analysis::loop_margins::limit_cycle_onset`]).
    fn has_valve_and_friction(&self) -> bool {
        false
    }
    /// The state (position first).
    fn state_vector(&self) -> Vec<f64>;
    /// Sets the state from a vector of the same layout.
    fn set_state_vector(&mut self, v: &[f64]);
    /// A perturbation size per state component for the finite differences.
    fn perturbation_scales(&self) -> Vec<f64>;
    /// Whether the valve switches (PWM): then the analysis uses its period-averaged model.
    fn switching(&self) -> bool {
        false
    }
    /// Replaces a switching valve by its average over one PWM period: the spool's duty d = (1 + u)/2 opens
    /// supply→A and B→exhaust for d of the period and the other paths for 1 − d, i.e. a proportional valve
    /// open both ways at the centre (underlap 1), lagging by the switching delay plus half a period.
    fn average_switching(&mut self) {}
    /// For the sampled-data analysis of a switching valve ([`crate::analysis::pwm_onset`]): replaces it by
    /// the valve its latched duty drives over a period — open both ways at the centre as in
    /// [`Linearisable::average_switching`], but without the lag, which the analysis models exactly as the
    /// hold of the duty over the period and the switching delay. Returns (PWM period, switching delay), s;
    /// None for a valve that does not switch.
    fn hold_switching(&mut self) -> Option<(f64, f64)> {
        None
    }
    /// Leaves out Coulomb friction: linearised at rest its tanh or stick band is a steep viscous damping
    /// (F_c/v_s, 600 N·s/m on the shipped sheet) that an oscillation of any size never sees — its describing
    /// function falls as 4 F_c/(π ω A) — so a small-signal margin with it would promise far more than the
    /// loop has. The viscous K_v stays.
    fn without_coulomb_friction(&mut self) {}
    /// The Coulomb friction force F_c, N (0 without), for its describing function.
    fn coulomb_n(&self) -> f64 {
        0.0
    }
    /// Adds a viscous damping c, N·s/m (the describing function of Coulomb friction at an amplitude).
    fn add_viscous(&mut self, _c: f64) {}
}

/// What kind of thing went wrong in a plant.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PlantErrorKind {
    /// The plant has nothing the event could change (a swap on a 1-DOF plant, an incline on the ideal loop).
    Unsupported,
    /// The event's values cannot be applied here (an unknown material, a carriage in motion).
    Rejected,
    /// A physical invariant of the state is violated: the run has diverged.
    Invariant,
    /// The plant's own machinery failed (an exception in a plant written in Python).
    External,
}

/// A plant's error: its kind and a message for people.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("{message}")]
pub struct PlantError {
    /// What kind of failure.
    pub kind: PlantErrorKind,
    /// What happened, with the numbers.
    pub message: String,
}

impl PlantError {
    /// An error of `kind`.
    pub fn new(kind: PlantErrorKind, message: impl Into<String>) -> Self {
        Self {
            kind,
            message: message.into(),
        }
    }
    /// The plant has nothing the event could change.
    pub fn unsupported(message: impl Into<String>) -> Self {
        Self::new(PlantErrorKind::Unsupported, message)
    }
    /// A violated physical invariant.
    pub fn invariant(message: impl Into<String>) -> Self {
        Self::new(PlantErrorKind::Invariant, message)
    }
}

impl From<String> for PlantError {
    fn from(message: String) -> Self {
        Self::new(PlantErrorKind::Rejected, message)
    }
}

impl From<&str> for PlantError {
    fn from(message: &str) -> Self {
        Self::new(PlantErrorKind::Rejected, message)
    }
}

/// Something a controller drives: a simulated plant (integrated) or, later, an adapter to the rig.
pub trait Plant {
    /// Sensor values of the current state (the caller sets `t`).
    fn sense(&self) -> Sensors;
    /// Applies the controller's output for the next period. The ideal plant follows `telemetry.x_r`,
    /// a pneumatic plant the valve `command`.
    fn actuate(&mut self, command: ValveCommand, telemetry: &Telemetry);
    /// Integrates the plant over `dt` seconds with the last command held (zero-order hold).
    fn advance(&mut self, dt: f64);
    /// Applies a scene event; Err explains why this plant cannot.
    fn apply(&mut self, event: &EventSpec) -> Result<(), PlantError>;
    /// Back to the initial state and initial environment.
    fn reset(&mut self);
    /// Checks the physical invariants of the current state (absolute pressures within [0, a margin above
    /// supply], temperatures positive, the piston within its stroke); Err names the variable and its value.
    fn check_invariants(&self) -> Result<(), PlantError> {
        Ok(())
    }
    /// The plant's own recorded signals (beyond what `sense` returns), declared once.
    fn signals(&self) -> &'static [pneuflex_control::Signal] {
        &[]
    }
    /// Writes the values of [`Plant::signals`] at the current state into `out` (same length).
    fn record(&self, _out: &mut [f64]) {}
    /// The plant's bodies as drawn in 3D (name and shape), for viewers; empty for plants without geometry.
    fn visuals(&self) -> Vec<Visual> {
        Vec::new()
    }
    /// World pose of each entry of [`Plant::visuals`], in that order, at the current state.
    fn visual_poses(&self, _pose: &mut dyn FnMut(usize, VisualPose)) {}
    /// The actuator's geometry as a viewer draws it (cylinder, chambers, incline, environment surface);
    /// None for a plant without a pneumatic actuator (the ideal loop).
    fn actuator_geometry(&self) -> Option<ActuatorGeometry> {
        None
    }
    /// The period of the valve's PWM carrier, s (an on/off valve under PWM), which the metrics average
    /// over; None for a proportional valve or a plant without one. The plant knows it once built.
    fn pwm_period_s(&self) -> Option<f64> {
        self.actuator_geometry().and_then(|g| g.pwm_period_s)
    }
}

/// What a drawn shape is to the experiment, set by the plant that builds it: viewers colour by it and
/// attach the chambers to the cylinder and the contact force to the flange.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum VisualRole {
    /// The moving flange (piston rod end) that pushes the environment.
    Flange,
    /// The cylinder body, in which the chambers are.
    Cylinder,
    /// The environment the flange pushes (faces and their blocks).
    Environment,
    /// Anything else (platform, carriage, ...).
    #[default]
    Other,
}

/// The actuator's geometry for viewers (SI), at the plant's initial state.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ActuatorGeometry {
    /// Piston stroke, m.
    pub stroke_m: f64,
    /// Cylinder bore, m.
    pub bore_m: f64,
    /// Incline of the actuator axis below the horizontal, rad.
    pub alpha_rad: f64,
    /// Flange extension at which the environment is first touched, m.
    pub x_e_m: f64,
    /// Period of the valve's PWM carrier, s (an on/off valve under PWM); None for a proportional valve.
    pub pwm_period_s: Option<f64>,
}

/// One drawable collision shape of a plant's link.
#[derive(Clone, Debug, PartialEq)]
pub struct Visual {
    /// Link name (with `/<i>` for a link's i-th shape when it has several).
    pub name: String,
    /// The shape, centred on its pose.
    pub shape: VisualShape,
    /// What the shape is to the experiment.
    pub role: VisualRole,
}

/// A shape for viewers (SI).
#[derive(Clone, Debug, PartialEq)]
pub enum VisualShape {
    /// Box with half edge lengths along its x, y, z, m.
    Box {
        /// Half edge lengths, m.
        half_extents_m: [f64; 3],
    },
    /// Cylinder along its z axis, m.
    Cylinder {
        /// Radius, m.
        radius_m: f64,
        /// Half length, m.
        half_length_m: f64,
    },
    /// Sphere, m.
    Sphere {
        /// Radius, m.
        radius_m: f64,
    },
    /// A triangle mesh (a URDF mesh's convex hull): vertices, m, and triangles, indices into them.
    Mesh {
        /// Vertices, m.
        vertices_m: Vec<[f64; 3]>,
        /// Triangles, counter-clockwise seen from outside.
        triangles: Vec<[u32; 3]>,
    },
}

impl VisualShape {
    /// How a URDF collision shape is drawn (the one conversion: every plant and scene with a URDF uses it).
    pub fn of(shape: &pneuflex_multibody::LinkShape) -> Self {
        use pneuflex_multibody::LinkShape;
        match shape.clone() {
            LinkShape::Box { size_m } => VisualShape::Box {
                half_extents_m: size_m.map(|v| 0.5 * v),
            },
            LinkShape::Cylinder { radius_m, length_m } => VisualShape::Cylinder {
                radius_m,
                half_length_m: 0.5 * length_m,
            },
            // Drawn as its cylinder part plus the caps' length.
            LinkShape::Capsule { radius_m, length_m } => VisualShape::Cylinder {
                radius_m,
                half_length_m: 0.5 * length_m + radius_m,
            },
            LinkShape::Sphere { radius_m } => VisualShape::Sphere { radius_m },
            LinkShape::ConvexHull(hull) => VisualShape::Mesh {
                vertices_m: hull.vertices,
                triangles: hull.triangles,
            },
        }
    }
}

/// The drawn shapes of a URDF's links: each collision shape (`<link>`, or `<link>/<i>` for a link's i-th of
/// several), then each visual mesh (`<link>/visual/<i>`); `role` says what a link is to the experiment.
pub fn drawn_links<'a>(
    links: impl Iterator<Item = pneuflex_multibody::LinkView<'a>>,
    role: impl Fn(&str) -> VisualRole,
) -> Vec<Visual> {
    let mut out = Vec::new();
    for l in links {
        for (j, g) in l.collisions.iter().enumerate() {
            out.push(Visual {
                name: if l.collisions.len() == 1 {
                    l.name.to_string()
                } else {
                    format!("{}/{j}", l.name)
                },
                shape: VisualShape::of(&g.shape),
                role: role(l.name),
            });
        }
        for (j, (_, mesh)) in l.visual_meshes.iter().enumerate() {
            out.push(Visual {
                name: format!("{}/visual/{j}", l.name),
                shape: VisualShape::Mesh {
                    vertices_m: mesh.vertices.clone(),
                    triangles: mesh.triangles.clone(),
                },
                role: role(l.name),
            });
        }
    }
    out
}

/// The pose of each of [`drawn_links`]' shapes now, in that order, in the frame `world` takes the URDF's
/// root frame to.
pub fn drawn_poses<'a>(
    links: impl Iterator<Item = pneuflex_multibody::LinkView<'a>>,
    world: pneuflex_multibody::Pose,
    pose: &mut dyn FnMut(usize, VisualPose),
) {
    let mut i = 0;
    for l in links {
        let origins = l.collisions.iter().map(|g| g.origin);
        for origin in origins.chain(l.visual_meshes.iter().map(|(o, _)| *o)) {
            let p = world * l.pose * origin;
            let (t, q) = (p.translation, p.rotation);
            pose(
                i,
                VisualPose {
                    translation_m: [t.x, t.y, t.z],
                    rotation_xyzw: [q.x, q.y, q.z, q.w],
                },
            );
            i += 1;
        }
    }
}

/// Pose of a shape in the world: translation (m) and unit quaternion [x, y, z, w].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VisualPose {
    /// Translation, m.
    pub translation_m: [f64; 3],
    /// Rotation as a unit quaternion [x, y, z, w].
    pub rotation_xyzw: [f64; 4],
}

/// Linear-spring environment of eq. (21): f_e = k_e (x - x_e) while x > x_e; no contact (0) otherwise.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LinearSpring {
    /// Stiffness k_e, N/m.
    pub stiffness_n_per_m: f64,
    /// Surface position x_e, m.
    pub x_e_m: f64,
}

impl LinearSpring {
    /// Contact force f_e >= 0 on the environment (positive = the flange pushes), N. eq. (21)
    pub fn force(&self, x: f64) -> f64 {
        let d = x - self.x_e_m;
        if d > 0.0 {
            self.stiffness_n_per_m * d
        } else {
            0.0
        }
    }
}
