//! The paper's rig as one mechanism: an actuator along a prismatic joint (cylinder -> flange) pushing
//! against compliant faces on a held carriage (Fig. 1, Section IV). Each material's face sits on a
//! spring-damper of its mount joint (the environment's k_e, eq. (21)) and touches the flange through a rigid
//! contact (Rapier's solver); a swap moves the carriage along scripted waypoints, an incline turns gravity.
//! Everything physical is the general engine's ([`Mechanism`]); this file names the roles, finds where the
//! flange first touches each face, and scripts the swap.

use std::path::Path;

use rapier3d_f64::prelude::*;

use super::{
    ActuatorConfig, ContactParams, Mechanism, MechanismConfig, Mount, RigidContactConfig,
    SpringConfig,
};
use crate::actuator::AxialActuator;
use crate::error::MultibodyError;
use crate::urdf_build::{self, LinkView};

impl ContactParams {
    /// The paper's wood: k_e = 700 N/m (Section III simulation), light damping.
    pub const PAPER_WOOD: Self = Self {
        stiffness_n_per_m: 700.0,
        damping_n_s_per_m: 2.0,
    };
    /// The paper's iron: k_e = 1400 N/m ("two times" the wood, Section III), light damping.
    pub const PAPER_IRON: Self = Self {
        stiffness_n_per_m: 1400.0,
        damping_n_s_per_m: 2.0,
    };
    /// Realistic variant: a steel flange pad on a pine block, ~2e5 N/m lumped contact stiffness.
    pub const REALISTIC_WOOD: Self = Self {
        stiffness_n_per_m: 2.0e5,
        damping_n_s_per_m: 40.0,
    };
    /// Realistic variant: a steel flange pad on an iron block, ~2e7 N/m lumped contact stiffness.
    pub const REALISTIC_IRON: Self = Self {
        stiffness_n_per_m: 2.0e7,
        damping_n_s_per_m: 400.0,
    };
}

/// One environment material: its name in the scene, its compliant mount joint in the URDF, k and c.
#[derive(Debug, Clone, PartialEq)]
pub struct MaterialConfig {
    /// Scene name of the material ("wood", "iron").
    pub name: String,
    /// Prismatic URDF joint carrying the material's contact face (its child link) on the carriage.
    pub mount_joint: String,
    /// Stiffness and damping of the mount.
    pub params: ContactParams,
}

/// Everything the rig needs besides the URDF: which links and joints play which role, and the
/// simulation settings.
#[derive(Debug, Clone, PartialEq)]
pub struct RigConfig {
    /// Link of the moving flange (piston rod + flange plate).
    pub flange_link: String,
    /// Link of the cylinder body (the force element's reaction side).
    pub cylinder_link: String,
    /// Prismatic joint between cylinder and flange; its lower limit is the retracted stop (x = 0).
    pub flange_joint: String,
    /// Link of the environment carriage, held and moved by a swap.
    pub carriage_link: String,
    /// Environment materials on the carriage.
    pub materials: Vec<MaterialConfig>,
    /// Material facing the flange at t = 0.
    pub initial_material: String,
    /// Incline of the actuator axis below the horizontal, rad (gravity aids extension).
    pub alpha_rad: f64,
    /// Physics step, s.
    pub dt_s: f64,
    /// Rapier solver iterations per step.
    pub solver_iterations: usize,
    /// Flange extension at t = 0, m.
    pub initial_x_m: f64,
    /// Magnitude of gravity, m/s^2.
    pub gravity_m_s2: f64,
    /// Coulomb friction coefficient of the flange-face contacts, -.
    pub friction: f64,
}

impl RigConfig {
    /// The configuration matching `urdf/rig.urdf` with the paper's k_e (wood 700 N/m, iron 1400 N/m),
    /// horizontal axis, dt = 1 ms, 4 solver iterations, flange retracted.
    pub fn paper_rig() -> Self {
        Self {
            flange_link: "flange".into(),
            cylinder_link: "cylinder".into(),
            flange_joint: "flange_slide".into(),
            carriage_link: "carriage".into(),
            materials: vec![
                MaterialConfig {
                    name: "wood".into(),
                    mount_joint: "wood_mount".into(),
                    params: ContactParams::PAPER_WOOD,
                },
                MaterialConfig {
                    name: "iron".into(),
                    mount_joint: "iron_mount".into(),
                    params: ContactParams::PAPER_IRON,
                },
            ],
            initial_material: "wood".into(),
            alpha_rad: 0.0,
            dt_s: 1.0e-3,
            solver_iterations: 4,
            initial_x_m: 0.0,
            gravity_m_s2: crate::STANDARD_GRAVITY,
            friction: 0.3,
        }
    }

    fn validate(&self) -> Result<(), MultibodyError> {
        let bad =
            |field: &'static str, reason: String| Err(MultibodyError::BadConfig { field, reason });
        if !(self.dt_s.is_finite() && self.dt_s > 0.0) {
            return bad(
                "dt_s",
                format!("must be a finite step > 0 s, got {}", self.dt_s),
            );
        }
        if self.solver_iterations == 0 {
            return bad("solver_iterations", "must be >= 1".into());
        }
        check_alpha(self.alpha_rad)?;
        if !(self.gravity_m_s2.is_finite() && self.gravity_m_s2 >= 0.0) {
            return bad(
                "gravity_m_s2",
                format!("must be finite and >= 0, got {}", self.gravity_m_s2),
            );
        }
        if !(self.friction.is_finite() && self.friction >= 0.0) {
            return bad(
                "friction",
                format!("must be finite and >= 0, got {}", self.friction),
            );
        }
        if !self.initial_x_m.is_finite() {
            return bad("initial_x_m", "must be finite".into());
        }
        if self.materials.is_empty() {
            return bad("materials", "at least one material is needed".into());
        }
        for (i, m) in self.materials.iter().enumerate() {
            check_params(&m.params)?;
            if self.materials[..i].iter().any(|o| o.name == m.name) {
                return bad(
                    "materials",
                    format!("material '{}' is listed twice", m.name),
                );
            }
            if let Some(o) = self.materials[..i]
                .iter()
                .find(|o| o.mount_joint == m.mount_joint)
            {
                // One face, one spring: two materials on one mount would fight over its stiffness.
                return bad(
                    "materials.mount_joint",
                    format!(
                        "materials '{}' and '{}' both use mount joint '{}'",
                        o.name, m.name, m.mount_joint
                    ),
                );
            }
        }
        if !self
            .materials
            .iter()
            .any(|m| m.name == self.initial_material)
        {
            return bad(
                "initial_material",
                format!("'{}' is not one of the materials", self.initial_material),
            );
        }
        Ok(())
    }
}

fn check_alpha(alpha_rad: f64) -> Result<(), MultibodyError> {
    if !(alpha_rad.is_finite() && alpha_rad.abs() <= core::f64::consts::FRAC_PI_2) {
        return Err(MultibodyError::BadConfig {
            field: "alpha_rad",
            reason: format!("must be within [-pi/2, pi/2], got {alpha_rad}"),
        });
    }
    Ok(())
}

fn check_params(p: &ContactParams) -> Result<(), MultibodyError> {
    if !(p.stiffness_n_per_m.is_finite() && p.stiffness_n_per_m > 0.0) {
        return Err(MultibodyError::BadConfig {
            field: "stiffness_n_per_m",
            reason: format!("must be finite and > 0 N/m, got {}", p.stiffness_n_per_m),
        });
    }
    if !(p.damping_n_s_per_m.is_finite() && p.damping_n_s_per_m >= 0.0) {
        return Err(MultibodyError::BadConfig {
            field: "damping_n_s_per_m",
            reason: format!("must be finite and >= 0 N s/m, got {}", p.damping_n_s_per_m),
        });
    }
    Ok(())
}

/// What the rig's sensors read after a step.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Measurements {
    /// Simulated time, s.
    pub t_s: f64,
    /// Flange extension from the retracted stop along the axis, m.
    pub x: f64,
    /// Flange velocity along the axis, m/s.
    pub x_dot: f64,
    /// Contact force the flange exerts on the faces along the axis (load cell), N, >= 0 pushing.
    pub f_e: f64,
    /// Whether the flange presses on a face (a positive normal impulse this step).
    pub contact: bool,
    /// Force the actuator applied on the flange during the step, N.
    pub actuator_force_n: f64,
}

/// One material as built: its spring (mount) and rigid contact in the mechanism, where it touches.
#[derive(Debug, Clone)]
struct Material {
    name: String,
    spring: usize,
    contact: usize,
    /// The face's link.
    face: String,
    /// Flange extension at first touch when this face is aligned and unloaded, m.
    x_e_m: f64,
    /// Carriage offset along the transverse axis (from its URDF pose) that aligns the face with the
    /// flange, m.
    align_offset_m: f64,
    /// Other materials whose faces the flange can touch within its stroke while this one faces it.
    in_reach: Vec<usize>,
}

/// The paper's rig on the general engine: a flange on a prismatic joint in a cylinder, a held carriage
/// with compliant material faces, an axial force element, and a load cell on the flange.
pub struct CarriageRig {
    mechanism: Mechanism,
    carriage_link: String,
    materials: Vec<Material>,
    /// Actuator axis, transverse (carriage) axis and up, root frame.
    axis: Vector,
    transverse: Vector,
    up: Vector,
    stroke_m: f64,
    /// How far the carriage retreats along the axis during a swap: the extended flange clears every face.
    swap_retreat_m: f64,
    /// The material facing the flange (None while the carriage moves) and the one a swap goes to.
    active: Option<usize>,
    swapping_to: Option<usize>,
    /// The carriage's transverse offset from its URDF pose, m.
    carriage_offset_m: f64,
    alpha_rad: f64,
    gravity_m_s2: f64,
    last: Measurements,
}

impl CarriageRig {
    /// Read the URDF at `path` and build the rig `config` describes.
    pub fn from_urdf(path: impl AsRef<Path>, config: &RigConfig) -> Result<Self, MultibodyError> {
        let path = path.as_ref();
        let robot = urdf_build::read_urdf(path)?;
        Self::from_robot(path, &robot, config)
    }

    /// Build the rig from an already parsed URDF (`path` is only used in messages).
    pub fn from_robot(
        path: &Path,
        robot: &urdf_rs::Robot,
        config: &RigConfig,
    ) -> Result<Self, MultibodyError> {
        config.validate()?;
        let (stroke, lower) = check_roles(path, robot, config)?;
        if !(0.0..=stroke).contains(&config.initial_x_m) {
            return Err(MultibodyError::BadConfig {
                field: "initial_x_m",
                reason: format!(
                    "must be within the stroke [0, {stroke}] m, got {}",
                    config.initial_x_m
                ),
            });
        }
        let mc = MechanismConfig {
            actuators: vec![ActuatorConfig {
                name: config.flange_link.clone(),
                mount: Mount::Joint {
                    joint: config.flange_joint.clone(),
                },
            }],
            contacts: Vec::new(),
            gravity_m_s2: [0.0, 0.0, -config.gravity_m_s2],
            dt_s: config.dt_s,
            solver_iterations: config.solver_iterations,
            pad_integration: super::PadIntegration::Explicit,
            initial_positions: vec![(config.flange_joint.clone(), lower + config.initial_x_m)],
            springs: config
                .materials
                .iter()
                .map(|m| SpringConfig {
                    name: m.name.clone(),
                    joint: m.mount_joint.clone(),
                    stiffness: m.params.stiffness_n_per_m,
                    damping: m.params.damping_n_s_per_m,
                })
                .collect(),
            held_links: vec![config.carriage_link.clone()],
        };
        let mut mechanism = Mechanism::from_robot(path, robot, &mc)?;
        let bad_joint = |joint: &str, reason: String| MultibodyError::BadJoint {
            file: path.to_path_buf(),
            joint: joint.to_owned(),
            reason,
        };
        let state = mechanism.actuator_state(0);
        let axis = state.axis;
        let up = Vector::Z;
        if axis.dot(up).abs() > 1e-9 {
            return Err(bad_joint(
                &config.flange_joint,
                "the actuator axis must be horizontal (normal to z) in the URDF: alpha comes from the scene"
                    .into(),
            ));
        }
        let transverse = up.cross(axis);
        let flange_pose = mechanism.link_pose(&config.flange_link)?;
        if mechanism.rig.links[mechanism
            .rig
            .link_index(&config.flange_link, "flange_link")?]
        .colliders
        .is_empty()
        {
            return Err(MultibodyError::BadGeometry {
                file: path.to_path_buf(),
                link: config.flange_link.clone(),
                reason:
                    "the flange needs at least one <collision> element to touch the environment"
                        .into(),
            });
        }
        let mut materials = Vec::with_capacity(config.materials.len());
        for m in &config.materials {
            let j = robot
                .joints
                .iter()
                .find(|j| j.name == m.mount_joint)
                .expect("checked");
            let moving = mechanism
                .rig
                .joints
                .iter()
                .any(|b| b.name == j.name && b.handle.is_some());
            if j.joint_type != urdf_rs::JointType::Prismatic || !moving {
                return Err(bad_joint(
                    &j.name,
                    "a material mount must be a prismatic joint to a moving face".into(),
                ));
            }
            if !descends_from(robot, &j.child.link, &config.carriage_link) {
                return Err(bad_joint(
                    &j.name,
                    format!(
                        "the material face must ride on the carriage '{}'",
                        config.carriage_link
                    ),
                ));
            }
            let face = j.child.link.clone();
            let parent = mechanism.link_pose(&j.parent.link)?;
            let origin = urdf_build::urdf_pose(&j.origin);
            let mount_axis = (parent * origin).rotation * Vector::from_array(j.axis.xyz.0);
            if mount_axis.normalize_or_zero().dot(axis) < 1.0 - 1e-9 {
                return Err(bad_joint(
                    &j.name,
                    "the material mount axis must point along the actuator axis (away from the flange)"
                        .into(),
                ));
            }
            let face_pose = mechanism.link_pose(&face)?;
            let align_offset_m = (flange_pose.translation - face_pose.translation).dot(transverse);
            // First touch: cast the flange along the axis onto the aligned, unloaded face.
            let touch = mechanism
                .first_touch(
                    &config.flange_link,
                    &face,
                    axis,
                    transverse * align_offset_m,
                )?
                .ok_or_else(|| MultibodyError::BadGeometry {
                    file: path.to_path_buf(),
                    link: face.clone(),
                    reason: "the flange never touches this face when it faces the flange".into(),
                })?;
            let spring = mechanism.spring_index(&m.name)?;
            let contact = mechanism.add_rigid_contact(&RigidContactConfig {
                name: m.name.clone(),
                link_a: config.flange_link.clone(),
                link_b: face.clone(),
                friction: config.friction,
            })?;
            materials.push(Material {
                name: m.name.clone(),
                spring,
                contact,
                face,
                x_e_m: state.x_m + touch,
                align_offset_m,
                in_reach: Vec::new(),
            });
        }
        for i in 0..materials.len() {
            let shift = transverse * materials[i].align_offset_m;
            for k in 0..materials.len() {
                let touch =
                    mechanism.first_touch(&config.flange_link, &materials[k].face, axis, shift)?;
                if k != i && touch.is_some_and(|t| state.x_m + t <= stroke) {
                    materials[i].in_reach.push(k);
                }
            }
        }
        let min_xe = materials
            .iter()
            .map(|m| m.x_e_m)
            .fold(f64::INFINITY, f64::min);
        let initial = materials
            .iter()
            .position(|m| m.name == config.initial_material)
            .expect("validated");
        let offset = materials[initial].align_offset_m;
        let mut rig = Self {
            mechanism,
            carriage_link: config.carriage_link.clone(),
            materials,
            axis,
            transverse,
            up,
            stroke_m: stroke,
            // Far enough that the fully extended flange clears every face during the slide.
            swap_retreat_m: (stroke - min_xe).max(0.0) + 0.01,
            active: Some(initial),
            swapping_to: None,
            carriage_offset_m: offset,
            alpha_rad: config.alpha_rad,
            gravity_m_s2: config.gravity_m_s2,
            last: Measurements::default(),
        };
        // Align the initial material with the flange (the carriage and every face ride together).
        rig.mechanism
            .place_held_link(&config.carriage_link, transverse * offset)?;
        rig.simulate_only_face(Some(initial))?;
        rig.mechanism.set_gravity(rig.gravity())?;
        rig.last = rig.read_sensors();
        Ok(rig)
    }

    /// The general engine the rig runs on.
    pub fn mechanism(&self) -> &Mechanism {
        &self.mechanism
    }

    /// Physics step, s.
    pub fn dt(&self) -> f64 {
        self.mechanism.dt()
    }

    /// Simulated time, s.
    pub fn time(&self) -> f64 {
        self.mechanism.time()
    }

    /// Flange stroke (upper - lower joint limit), m.
    pub fn stroke(&self) -> f64 {
        self.stroke_m
    }

    /// Incline of the actuator axis below the horizontal, rad.
    pub fn alpha(&self) -> f64 {
        self.alpha_rad
    }

    /// The material currently facing the flange (None while the carriage moves).
    pub fn active_material(&self) -> Option<&str> {
        self.active.map(|i| self.materials[i].name.as_str())
    }

    /// Flange extension x_e (m) at which the flange first touches the named material's unloaded face.
    pub fn material_x_e(&self, name: &str) -> Result<f64, MultibodyError> {
        Ok(self.materials[self.material_index(name)?].x_e_m)
    }

    /// Stiffness and damping of the named material.
    pub fn material_params(&self, name: &str) -> Result<ContactParams, MultibodyError> {
        let m = &self.materials[self.material_index(name)?];
        Ok(self.mechanism.spring_params(m.spring))
    }

    /// The last sensor reading.
    pub fn measurements(&self) -> Measurements {
        self.last
    }

    /// One physics step with the force of `actuator` between cylinder and flange.
    pub fn step(&mut self, actuator: &mut dyn AxialActuator) -> Measurements {
        let (x, x_dot) = self.flange_state();
        let f = actuator.force(x, x_dot, self.dt());
        self.step_with_force(f)
    }

    /// One physics step with a given force on the flange along +x (N), reaction on the cylinder body.
    pub fn step_with_force(&mut self, force_n: f64) -> Measurements {
        self.mechanism.step_with_forces(&[force_n]);
        self.last = self.read_sensors();
        if let Some(to) = self.swapping_to {
            let moving = self
                .mechanism
                .held_link_moving(&self.carriage_link)
                .expect("the carriage is held");
            if !moving {
                self.active = Some(to);
                self.swapping_to = None;
                // After this step, so that every face rode the carriage's last leg to its rest pose.
                self.simulate_only_face(Some(to))
                    .expect("the faces were found at build");
            }
        }
        self.last
    }

    /// Flange extension (m) and velocity (m/s) along the axis, relative to the cylinder body.
    pub fn flange_state(&self) -> (f64, f64) {
        let s = self.mechanism.actuator_state(0);
        (s.x_m, s.x_dot_m_s)
    }

    /// The load cell: the rigid contacts' normal impulse over the last step, summed over the faces.
    fn read_sensors(&self) -> Measurements {
        let m = &self.mechanism;
        let (x, x_dot) = self.flange_state();
        let f_e: f64 = self
            .materials
            .iter()
            .map(|mat| m.rigid_contact(mat.contact).force_n)
            .sum();
        Measurements {
            t_s: m.time(),
            x,
            x_dot,
            f_e,
            contact: f_e > 0.0,
            actuator_force_n: m.actuator_force(0),
        }
    }

    /// Event: move the carriage so that material `to` faces the flange, over `duration_s` seconds from now.
    /// The carriage retreats along the axis beyond the flange's reach, slides across, and comes back,
    /// each leg a third of the duration with a smooth (C1) profile, so the flange loses and regains contact.
    pub fn swap_environment(&mut self, to: &str, duration_s: f64) -> Result<(), MultibodyError> {
        let target = self.material_index(to)?;
        if self.swapping_to.is_some() {
            return Err(MultibodyError::BadConfig {
                field: "swap",
                reason: "the carriage is still moving from the last swap".into(),
            });
        }
        let back = self.axis * self.swap_retreat_m;
        let across =
            self.transverse * (self.materials[target].align_offset_m - self.carriage_offset_m);
        self.mechanism.move_held_link(
            &self.carriage_link,
            &[back, back + across, across],
            duration_s,
        )?;
        // Every face rides the carriage during the move and any of them may touch the flange.
        self.simulate_only_face(None)?;
        self.carriage_offset_m = self.materials[target].align_offset_m;
        self.active = None;
        self.swapping_to = Some(target);
        Ok(())
    }

    /// Event: change the named material's stiffness and damping now.
    pub fn set_material(
        &mut self,
        name: &str,
        params: ContactParams,
    ) -> Result<(), MultibodyError> {
        check_params(&params)?;
        let i = self.material_index(name)?;
        self.mechanism.set_spring(self.materials[i].spring, params)
    }

    /// Event: change the incline alpha (rad). Done by turning gravity in the rig frame, which is the same
    /// as tilting the whole rig about the horizontal transverse axis (nothing in the rig is attached to
    /// the world outside the tilted platform).
    pub fn set_alpha(&mut self, alpha_rad: f64) -> Result<(), MultibodyError> {
        check_alpha(alpha_rad)?;
        self.alpha_rad = alpha_rad;
        self.mechanism.set_gravity(self.gravity())
    }

    /// Gravity in the rig frame, m/s^2: g (sin(alpha) axis - cos(alpha) up); m g sin(alpha) aids extension,
    /// eq. (1)'s G_alpha.
    pub fn gravity(&self) -> [f64; 3] {
        (self.gravity_m_s2 * (self.alpha_rad.sin() * self.axis - self.alpha_rad.cos() * self.up))
            .to_array()
    }

    /// The tilt that takes the rig frame into a world frame with z up, for viewers.
    pub fn world_from_rig(&self) -> Pose {
        Pose::from_rotation(Rotation::from_axis_angle(self.transverse, self.alpha_rad))
    }

    /// Every link as viewers draw it: name, pose now, collision shapes and visual meshes.
    pub fn link_views(&self) -> impl Iterator<Item = LinkView<'_>> + '_ {
        self.mechanism.link_views()
    }

    /// The underlying Rapier world (read-only), for diagnostics.
    pub fn physics(&self) -> &PhysicsWorld {
        self.mechanism.physics()
    }

    fn material_index(&self, name: &str) -> Result<usize, MultibodyError> {
        self.materials
            .iter()
            .position(|m| m.name == name)
            .ok_or_else(|| MultibodyError::UnknownMaterial {
                name: name.to_owned(),
                known: self
                    .materials
                    .iter()
                    .map(|m| m.name.as_str())
                    .collect::<Vec<_>>()
                    .join(", "),
            })
    }

    /// Takes the faces out of the flange's reach out of the simulation while the carriage rests
    /// (`Some(i)`: material i faces the flange, and only its face and the faces in its `in_reach` stay
    /// in; `None`: all are in). A face the flange cannot touch, on a carriage at rest, only rests on its
    /// mount: simulating it costs a third of the solver's time per step and changes nothing the flange
    /// feels. Its pose, mount stiffness and damping are kept (a stiffness event on it takes effect when
    /// it comes back).
    fn simulate_only_face(&mut self, only: Option<usize>) -> Result<(), MultibodyError> {
        for i in 0..self.materials.len() {
            let on = only.is_none_or(|k| k == i || self.materials[k].in_reach.contains(&i));
            self.mechanism
                .set_link_simulated(&self.materials[i].face, on)?;
        }
        Ok(())
    }
}

/// The roles and the mount joints exist in the URDF, and the flange joint is a prismatic joint from the
/// cylinder to the flange with a finite stroke: (stroke, lower limit), m. Checked before the mechanism
/// is built, so that a misspelt name is reported as such rather than as a tree problem.
fn check_roles(
    path: &Path,
    robot: &urdf_rs::Robot,
    config: &RigConfig,
) -> Result<(f64, f64), MultibodyError> {
    let has_link = |n: &str| robot.links.iter().any(|l| l.name == n);
    for (field, name) in [
        ("flange_link", &config.flange_link),
        ("cylinder_link", &config.cylinder_link),
        ("carriage_link", &config.carriage_link),
    ] {
        if !has_link(name) {
            return Err(MultibodyError::MissingLink {
                file: path.to_path_buf(),
                field,
                link: name.clone(),
            });
        }
    }
    let joint =
        |field: &'static str, name: &str| {
            robot.joints.iter().find(|j| j.name == name).ok_or_else(|| {
                MultibodyError::MissingJoint {
                    file: path.to_path_buf(),
                    field,
                    joint: name.to_owned(),
                }
            })
        };
    let fj = joint("flange_joint", &config.flange_joint)?;
    for m in &config.materials {
        joint("materials.mount_joint", &m.mount_joint)?;
    }
    let bad_joint = |reason: String| MultibodyError::BadJoint {
        file: path.to_path_buf(),
        joint: fj.name.clone(),
        reason,
    };
    if fj.joint_type != urdf_rs::JointType::Prismatic {
        return Err(bad_joint("the flange joint must be prismatic".into()));
    }
    if fj.child.link != config.flange_link || fj.parent.link != config.cylinder_link {
        return Err(bad_joint(format!(
            "must connect the cylinder link '{}' (parent) to the flange link '{}' (child)",
            config.cylinder_link, config.flange_link
        )));
    }
    let (lower, upper) = (fj.limit.lower, fj.limit.upper);
    let stroke = upper - lower;
    if !(lower.is_finite() && upper.is_finite()) || stroke.is_nan() || stroke <= 0.0 {
        return Err(bad_joint(format!(
            "needs finite <limit lower upper> with a stroke upper - lower > 0, got [{lower}, {upper}]"
        )));
    }
    Ok((stroke, lower))
}

/// Whether link `link` is `ancestor` or lies below it in the URDF's tree.
fn descends_from(robot: &urdf_rs::Robot, link: &str, ancestor: &str) -> bool {
    let mut at = link;
    for _ in 0..=robot.joints.len() {
        if at == ancestor {
            return true;
        }
        match robot.joints.iter().find(|j| j.child.link == at) {
            Some(j) => at = &j.parent.link,
            None => return false,
        }
    }
    false
}
