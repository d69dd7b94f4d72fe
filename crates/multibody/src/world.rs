//! The rig world: the URDF rig in Rapier, the axial force element, the load-cell reading and the
//! scene events (environment swap, stiffness change, incline change).

use std::path::Path;

use rapier3d_f64::parry::query::{ShapeCastOptions, cast_shapes};
use rapier3d_f64::prelude::*;

use crate::actuator::AxialActuator;
use crate::error::MultibodyError;
use crate::urdf_build::{self, BuildOptions, BuiltRig, LinkView};

/// Standard gravity, m/s^2.
pub const STANDARD_GRAVITY: f64 = 9.80665;

/// Contact stiffness and damping of one environment material.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MaterialParams {
    /// Environment stiffness k_e of eq. (21), N/m.
    pub stiffness_n_per_m: f64,
    /// Environment damping c_e (the mount's viscous term), N s/m.
    pub damping_n_s_per_m: f64,
}

impl MaterialParams {
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
    pub params: MaterialParams,
}

/// Everything the rig world needs besides the URDF: which links and joints play which role, and the
/// simulation settings.
#[derive(Debug, Clone, PartialEq)]
pub struct MultibodyConfig {
    /// Link of the moving flange (piston rod + flange plate).
    pub flange_link: String,
    /// Link of the cylinder body (the force element's reaction side).
    pub cylinder_link: String,
    /// Prismatic joint between cylinder and flange; its lower limit is the retracted stop (x = 0).
    pub flange_joint: String,
    /// Link of the environment carriage, driven kinematically.
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
    /// Coulomb friction coefficient of all contacts, -.
    pub friction: f64,
}

impl MultibodyConfig {
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
                    params: MaterialParams::PAPER_WOOD,
                },
                MaterialConfig {
                    name: "iron".into(),
                    mount_joint: "iron_mount".into(),
                    params: MaterialParams::PAPER_IRON,
                },
            ],
            initial_material: "wood".into(),
            alpha_rad: 0.0,
            dt_s: 1.0e-3,
            solver_iterations: 4,
            initial_x_m: 0.0,
            gravity_m_s2: STANDARD_GRAVITY,
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
        if !(self.alpha_rad.is_finite() && self.alpha_rad.abs() <= core::f64::consts::FRAC_PI_2) {
            return bad(
                "alpha_rad",
                format!("must be within [-pi/2, pi/2], got {}", self.alpha_rad),
            );
        }
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

fn check_params(p: &MaterialParams) -> Result<(), MultibodyError> {
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
    /// Contact force the flange exerts on the environment along the axis (load cell), N, >= 0 pushing.
    pub f_e: f64,
    /// Whether the flange presses on the environment (a positive normal impulse this step).
    pub contact: bool,
    /// Force the actuator applied on the flange during the step, N.
    pub actuator_force_n: f64,
}

/// A material as built: its mount joint, face body and contact geometry.
#[derive(Debug, Clone)]
struct Material {
    name: String,
    params: MaterialParams,
    joint: ImpulseJointHandle,
    face_body: RigidBodyHandle,
    face_mass_kg: f64,
    /// Mount axis in the rig frame.
    mount_axis: Vector,
    /// Flange extension at first touch when this face is aligned and unloaded, m.
    x_e_m: f64,
    /// Carriage transverse offset (from its URDF pose) that aligns this face with the flange, m.
    align_offset_m: f64,
    /// URDF link of the face (its colliders are the contact geometry).
    face_link: usize,
    /// Other materials whose faces the flange can touch within its stroke while this one faces it.
    in_reach: Vec<usize>,
}

/// A kinematic carriage move in progress: retreat along the axis, slide across, come back.
#[derive(Debug, Clone, Copy)]
struct CarriageMove {
    t0_s: f64,
    duration_s: f64,
    from_m: f64,
    to_m: f64,
    retreat_m: f64,
    target: usize,
}

/// The pneumatic rig as a Rapier world: flange on a prismatic joint in a cylinder, an environment carriage
/// with compliant material faces, an axial force element, and a load cell on the flange.
pub struct RigWorld {
    rig: BuiltRig,
    flange_body: RigidBodyHandle,
    cylinder_body: RigidBodyHandle,
    /// Flange joint frames in the cylinder body and in the flange body; x axis = the actuator axis.
    joint_frame1: Pose,
    joint_frame2: Pose,
    lower_limit_m: f64,
    stroke_m: f64,
    flange_colliders: Vec<ColliderHandle>,
    carriage_body: RigidBodyHandle,
    carriage_home: Pose,
    /// Bodies that ride with the carriage (its dynamic descendants), moved with it at set-up.
    carriage_riders: Vec<RigidBodyHandle>,
    /// Actuator axis and transverse (carriage) axis in the rig frame.
    axis: Vector,
    transverse: Vector,
    up: Vector,
    materials: Vec<Material>,
    active: Option<usize>,
    carriage_offset_m: f64,
    carriage_retreat_m: f64,
    swap_retreat_m: f64,
    motion: Option<CarriageMove>,
    /// A carriage move ended this step: take the faces out of reach out of the simulation after it.
    settle_faces: bool,
    alpha_rad: f64,
    gravity_m_s2: f64,
    time_s: f64,
    last: Measurements,
}

impl RigWorld {
    /// Read the URDF at `path` and build the rig world described by `config`.
    pub fn from_urdf(
        path: impl AsRef<Path>,
        config: &MultibodyConfig,
    ) -> Result<Self, MultibodyError> {
        let path = path.as_ref();
        let robot = urdf_build::read_urdf(path)?;
        Self::from_robot(path, &robot, config)
    }

    /// Build the rig world from an already parsed URDF (`path` is only used in messages).
    pub fn from_robot(
        path: &Path,
        robot: &urdf_rs::Robot,
        config: &MultibodyConfig,
    ) -> Result<Self, MultibodyError> {
        config.validate()?;
        check_names(path, robot, config)?;
        let kinematic = [config.carriage_link.as_str()];
        let mut rig = urdf_build::build(
            path,
            robot,
            &BuildOptions {
                kinematic_links: &kinematic,
                friction: config.friction,
            },
        )?;
        let flange = flange_of(&rig, config)?;

        // The carriage: a kinematic body; everything dynamic below it rides along.
        let carriage_link = rig.link_index(&config.carriage_link, "carriage_link")?;
        let carriage_body = rig.links[carriage_link].body;
        let carriage_home = *rig.world.bodies[carriage_body].position();
        let carriage_riders = riders_of(&rig, carriage_link, carriage_body);

        let mut materials = materials_of(&rig, config, carriage_link, &flange)?;
        mark_faces_in_reach(&rig, &mut materials, &flange);
        isolate_flange_and_faces(&mut rig, config, &flange.colliders);
        let min_xe = materials
            .iter()
            .map(|m| m.x_e_m)
            .fold(f64::INFINITY, f64::min);
        // Retreat far enough that the fully extended flange clears every face during the slide.
        let swap_retreat_m = (flange.stroke_m - min_xe).max(0.0) + 0.01;

        set_integration(&mut rig.world.integration_parameters, config);

        let mut w = Self {
            rig,
            flange_body: flange.body,
            cylinder_body: flange.cylinder_body,
            joint_frame1: flange.joint_frame1,
            joint_frame2: flange.joint_frame2,
            lower_limit_m: flange.lower,
            stroke_m: flange.stroke_m,
            flange_colliders: flange.colliders,
            carriage_body,
            carriage_home,
            carriage_riders,
            axis: flange.axis,
            transverse: flange.transverse,
            up: flange.up,
            materials,
            active: None,
            carriage_offset_m: 0.0,
            carriage_retreat_m: 0.0,
            swap_retreat_m,
            motion: None,
            settle_faces: false,
            alpha_rad: config.alpha_rad,
            gravity_m_s2: config.gravity_m_s2,
            time_s: 0.0,
            last: Measurements::default(),
        };
        // Place the flange at its initial extension.
        {
            let shift = (flange.lower + config.initial_x_m) * flange.axis;
            let b = &mut w.rig.world.bodies[flange.body];
            let p = Pose::from_translation(shift) * *b.position();
            b.set_position(p, true);
        }
        // Align the initial material with the flange (carriage and riders move together).
        let init = w
            .materials
            .iter()
            .position(|m| m.name == config.initial_material)
            .expect("validated");
        w.place_carriage(w.materials[init].align_offset_m, 0.0);
        w.active = Some(init);
        w.simulate_only_face(Some(init));
        w.apply_gravity();
        w.last = w.read_sensors(0.0);
        Ok(w)
    }

    /// Physics step, s.
    pub fn dt(&self) -> f64 {
        self.rig.world.integration_parameters.dt
    }

    /// Simulated time, s.
    pub fn time(&self) -> f64 {
        self.time_s
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
    pub fn material_params(&self, name: &str) -> Result<MaterialParams, MultibodyError> {
        Ok(self.materials[self.material_index(name)?].params)
    }

    /// Deflection of the named material's face from its unloaded position along the axis, m.
    pub fn material_deflection(&self, name: &str) -> Result<f64, MultibodyError> {
        let m = &self.materials[self.material_index(name)?];
        let j = self.rig.world.impulse_joints.get(m.joint).expect("built");
        let p1 = *self.rig.world.bodies[j.body1()].position() * j.data.local_frame1;
        let p2 = *self.rig.world.bodies[j.body2()].position() * j.data.local_frame2;
        Ok((p2.translation - p1.translation).dot(m.mount_axis))
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
        let dt = self.dt();
        let f = force_n * self.axis;
        // User forces persist in Rapier until reset: set them afresh each step.
        {
            let b = &mut self.rig.world.bodies[self.flange_body];
            b.reset_forces(false);
            b.add_force(f, true);
        }
        {
            let c = &mut self.rig.world.bodies[self.cylinder_body];
            if c.is_dynamic() {
                c.reset_forces(false);
                c.add_force(-f, true);
            }
        }
        // Contact points are recycled from the last step only while the carriage rests: the pair then moves
        // by µm per step and recomputing its manifold is wasted work (~9 % of the tick); while the
        // carriage moves, stale points survived its slide and pushed across a 1 cm gap, so never then.
        self.rig.world.integration_parameters.contact_recycling = self.motion.is_none();
        self.advance_carriage(self.time_s + dt);
        self.rig.world.step();
        if std::mem::take(&mut self.settle_faces) {
            self.simulate_only_face(self.active);
        }
        self.time_s += dt;
        self.last = self.read_sensors(force_n);
        self.last
    }

    /// Flange extension (m) and velocity (m/s) along the axis, relative to the cylinder body.
    pub fn flange_state(&self) -> (f64, f64) {
        let bodies = &self.rig.world.bodies;
        let c = &bodies[self.cylinder_body];
        let fb = &bodies[self.flange_body];
        let p1 = *c.position() * self.joint_frame1;
        let p2 = *fb.position() * self.joint_frame2;
        let a = p1.rotation * Vector::X;
        let q = (p2.translation - p1.translation).dot(a);
        let v = (fb.velocity_at_point(p2.translation) - c.velocity_at_point(p2.translation)).dot(a);
        (q - self.lower_limit_m, v)
    }

    fn read_sensors(&self, force_n: f64) -> Measurements {
        let (x, x_dot) = self.flange_state();
        let np = &self.rig.world.narrow_phase;
        let mut impulse = 0.0;
        for &ch in &self.flange_colliders {
            for pair in np.contact_pairs_with(ch) {
                if !pair.has_any_active_contact() {
                    continue;
                }
                // total_impulse pushes collider2 along +normal: the flange's push on the other body.
                let sign = if pair.collider1 == ch { 1.0 } else { -1.0 };
                impulse += sign * pair.total_impulse().dot(self.axis);
            }
        }
        let f_e = impulse / self.dt();
        Measurements {
            t_s: self.time_s,
            x,
            x_dot,
            f_e,
            contact: f_e > 0.0,
            actuator_force_n: force_n,
        }
    }

    /// Event: move the carriage so that material `to` faces the flange, over `duration_s` seconds from now.
    /// The carriage retreats along the axis beyond the flange's reach, slides across, and comes back,
    /// each leg a third of the duration with a smooth (C1) profile, so the flange loses and regains contact.
    pub fn swap_environment(&mut self, to: &str, duration_s: f64) -> Result<(), MultibodyError> {
        let target = self.material_index(to)?;
        if !(duration_s.is_finite() && duration_s > 0.0) {
            return Err(MultibodyError::BadConfig {
                field: "swap duration_s",
                reason: format!("must be finite and > 0 s, got {duration_s}"),
            });
        }
        self.motion = Some(CarriageMove {
            t0_s: self.time_s,
            duration_s,
            from_m: self.carriage_offset_m,
            to_m: self.materials[target].align_offset_m,
            retreat_m: self.swap_retreat_m,
            target,
        });
        self.active = None;
        // Every face rides the carriage during the move and any of them may touch the flange.
        self.simulate_only_face(None);
        Ok(())
    }

    /// Event: change the named material's stiffness and damping now.
    pub fn set_material(
        &mut self,
        name: &str,
        params: MaterialParams,
    ) -> Result<(), MultibodyError> {
        check_params(&params)?;
        let i = self.material_index(name)?;
        self.materials[i].params = params;
        self.update_mount(i);
        Ok(())
    }

    /// Event: change the incline alpha (rad). Done by turning gravity in the rig frame, which is the same
    /// as tilting the whole rig about the horizontal transverse axis (nothing in the rig is attached to
    /// the world outside the tilted platform).
    pub fn set_alpha(&mut self, alpha_rad: f64) -> Result<(), MultibodyError> {
        if !(alpha_rad.is_finite() && alpha_rad.abs() <= core::f64::consts::FRAC_PI_2) {
            return Err(MultibodyError::BadConfig {
                field: "alpha_rad",
                reason: format!("must be within [-pi/2, pi/2], got {alpha_rad}"),
            });
        }
        self.alpha_rad = alpha_rad;
        self.apply_gravity();
        Ok(())
    }

    /// Gravity in the rig frame, m/s^2: g (sin(alpha) axis - cos(alpha) up); m g sin(alpha) aids extension,
    /// eq. (1)'s G_alpha.
    pub fn gravity(&self) -> Vector {
        self.gravity_m_s2 * (self.alpha_rad.sin() * self.axis - self.alpha_rad.cos() * self.up)
    }

    /// The tilt that takes the rig frame into a world frame with z up, for viewers.
    pub fn world_from_rig(&self) -> Pose {
        Pose::from_rotation(Rotation::from_axis_angle(self.transverse, self.alpha_rad))
    }

    /// Every link as viewers draw it: name, pose now, collision shapes and visual meshes.
    pub fn link_views(&self) -> impl Iterator<Item = LinkView<'_>> + '_ {
        self.rig.link_views()
    }

    /// The underlying Rapier world (read-only), for diagnostics.
    pub fn physics(&self) -> &PhysicsWorld {
        &self.rig.world
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

    fn apply_gravity(&mut self) {
        self.rig.world.gravity = self.gravity();
        for i in 0..self.materials.len() {
            self.update_mount(i);
        }
    }

    /// The mount is a force-based spring-damper F = k (q0 - q) - c q' ([`crate::spring::set_joint_spring`]).
    /// Its set point q0 absorbs the face's own weight along the mount, so the unloaded face rests at q = 0
    /// at every incline and f_e = k (x - x_e) holds with a fixed x_e (eq. (21)).
    fn update_mount(&mut self, i: usize) {
        let g_axial = self.gravity().dot(self.materials[i].mount_axis);
        let m = &self.materials[i];
        let k = m.params.stiffness_n_per_m;
        let q0 = -m.face_mass_kg * g_axial / k;
        let (joint, face, c) = (m.joint, m.face_body, m.params.damping_n_s_per_m);
        crate::spring::set_joint_spring(&mut self.rig.world, joint, JointAxis::LinX, q0, k, c);
        self.rig.world.bodies[face].wake_up(true);
    }

    fn carriage_pose(&self, offset_m: f64, retreat_m: f64) -> Pose {
        Pose::from_translation(self.transverse * offset_m + self.axis * retreat_m)
            * self.carriage_home
    }

    /// Teleport the carriage and its riders (set-up only).
    fn place_carriage(&mut self, offset_m: f64, retreat_m: f64) {
        let delta = self.transverse * (offset_m - self.carriage_offset_m)
            + self.axis * (retreat_m - self.carriage_retreat_m);
        let pose = self.carriage_pose(offset_m, retreat_m);
        self.rig.world.bodies[self.carriage_body].set_position(pose, true);
        for &b in &self.carriage_riders {
            let body = &mut self.rig.world.bodies[b];
            let p = Pose::from_translation(delta) * *body.position();
            body.set_position(p, true);
        }
        self.carriage_offset_m = offset_m;
        self.carriage_retreat_m = retreat_m;
    }

    /// Set the carriage's kinematic target for time `t_s` (end of the coming step).
    fn advance_carriage(&mut self, t_s: f64) {
        let Some(mv) = self.motion else { return };
        // Finish on the step that reaches the end (within half a step: time is a sum of dt's).
        let elapsed = t_s - mv.t0_s;
        let s = if elapsed >= mv.duration_s - 0.5 * self.dt() {
            1.0
        } else {
            (elapsed / mv.duration_s).clamp(0.0, 1.0)
        };
        let smooth = |u: f64| {
            let u = u.clamp(0.0, 1.0);
            u * u * (3.0 - 2.0 * u)
        };
        let third = 1.0 / 3.0;
        let (offset, retreat) = if s < third {
            (mv.from_m, mv.retreat_m * smooth(s / third))
        } else if s < 2.0 * third {
            (
                mv.from_m + (mv.to_m - mv.from_m) * smooth((s - third) / third),
                mv.retreat_m,
            )
        } else {
            (
                mv.to_m,
                mv.retreat_m * (1.0 - smooth((s - 2.0 * third) / third)),
            )
        };
        let pose = self.carriage_pose(offset, retreat);
        self.rig.world.bodies[self.carriage_body].set_next_kinematic_position(pose);
        self.carriage_offset_m = offset;
        self.carriage_retreat_m = retreat;
        if s >= 1.0 {
            self.active = Some(mv.target);
            self.motion = None;
            // After this step, so that every face rides the carriage's last leg to its rest pose.
            self.settle_faces = true;
        }
    }

    /// Take the faces out of the flange's reach out of the simulation while the carriage rests (`Some(i)`:
    /// material i faces the flange, and only its face and the faces in its `in_reach` stay in; `None`: all
    /// are in). A face the flange cannot touch, on a carriage at rest, only rests on its mount: simulating
    /// it costs a third of the solver's time per step and changes nothing the flange feels. Its pose, mount
    /// stiffness and damping are kept (a stiffness event on it takes effect when it comes back).
    fn simulate_only_face(&mut self, only: Option<usize>) {
        let reach = only.map(|k| (k, self.materials[k].in_reach.clone()));
        for (i, m) in self.materials.iter().enumerate() {
            let on = reach
                .as_ref()
                .is_none_or(|(k, near)| *k == i || near.contains(&i));
            self.rig.world.bodies[m.face_body].set_enabled(on);
            if let Some(j) = self.rig.world.impulse_joints.get_mut(m.joint, on) {
                j.data.set_enabled(on);
            }
        }
    }
}

/// The links and joints the configuration names exist in the URDF: checked first, so that a misspelt
/// name is reported as such rather than as a tree problem.
fn check_names(
    path: &Path,
    robot: &urdf_rs::Robot,
    config: &MultibodyConfig,
) -> Result<(), MultibodyError> {
    let has_link = |n: &str| robot.links.iter().any(|l| l.name == n);
    let has_joint = |n: &str| robot.joints.iter().any(|j| j.name == n);
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
    if !has_joint(&config.flange_joint) {
        return Err(MultibodyError::MissingJoint {
            file: path.to_path_buf(),
            field: "flange_joint",
            joint: config.flange_joint.clone(),
        });
    }
    for m in &config.materials {
        if !has_joint(&m.mount_joint) {
            return Err(MultibodyError::MissingJoint {
                file: path.to_path_buf(),
                field: "materials.mount_joint",
                joint: m.mount_joint.clone(),
            });
        }
    }
    Ok(())
}

/// The flange and its joint as the rig needs them.
struct Flange {
    link: usize,
    body: RigidBodyHandle,
    cylinder_body: RigidBodyHandle,
    joint_frame1: Pose,
    joint_frame2: Pose,
    /// The joint's lower limit (the retracted stop) and its stroke, m.
    lower: f64,
    stroke_m: f64,
    /// The actuator axis, the horizontal transverse to it and up (z), world frame.
    axis: Vector,
    transverse: Vector,
    up: Vector,
    colliders: Vec<ColliderHandle>,
}

/// The flange joint: prismatic, cylinder -> flange, a finite stroke holding the initial extension, a
/// horizontal axis; the flange has a collider to touch with.
fn flange_of(rig: &BuiltRig, config: &MultibodyConfig) -> Result<Flange, MultibodyError> {
    let file = rig.file.clone();
    let bad_joint = |joint: &str, reason: String| MultibodyError::BadJoint {
        file: file.clone(),
        joint: joint.to_owned(),
        reason,
    };
    let fj = rig.joint_index(&config.flange_joint, "flange_joint")?;
    let flange_link = rig.link_index(&config.flange_link, "flange_link")?;
    let cylinder_link = rig.link_index(&config.cylinder_link, "cylinder_link")?;
    let fji = rig.joints[fj].clone();
    if fji.kind != urdf_rs::JointType::Prismatic {
        return Err(bad_joint(
            &fji.name,
            "the flange joint must be prismatic".into(),
        ));
    }
    if fji.child != flange_link || rig.links[fji.parent].body != rig.links[cylinder_link].body {
        return Err(bad_joint(
            &fji.name,
            format!(
                "must connect the cylinder link '{}' (parent) to the flange link '{}' (child)",
                config.cylinder_link, config.flange_link
            ),
        ));
    }
    let Some([lower, upper]) = fji.limits else {
        return Err(bad_joint(
            &fji.name,
            "needs finite <limit lower upper> (the stroke)".into(),
        ));
    };
    let stroke_m = upper - lower;
    if stroke_m.is_nan() || stroke_m <= 0.0 {
        return Err(bad_joint(
            &fji.name,
            format!("stroke upper - lower must be > 0, got {stroke_m}"),
        ));
    }
    if !(0.0..=stroke_m).contains(&config.initial_x_m) {
        return Err(MultibodyError::BadConfig {
            field: "initial_x_m",
            reason: format!(
                "must be within the stroke [0, {stroke_m}] m, got {}",
                config.initial_x_m
            ),
        });
    }
    let flange_body = rig.links[flange_link].body;
    let cylinder_body = rig.links[cylinder_link].body;
    let joint_handle = fji
        .handle
        .expect("a dynamic prismatic child always gets a joint");
    let (joint_frame1, joint_frame2) = {
        let j = &rig
            .world
            .impulse_joints
            .get(joint_handle)
            .expect("just built")
            .data;
        (j.local_frame1, j.local_frame2)
    };
    let cyl_pose = *rig.world.bodies[cylinder_body].position();
    let axis = (cyl_pose * joint_frame1).rotation * Vector::X;
    let up = Vector::Z;
    if axis.dot(up).abs() > 1e-9 {
        return Err(bad_joint(
            &fji.name,
            "the actuator axis must be horizontal (normal to z) in the URDF: alpha comes from the scene"
                .into(),
        ));
    }
    let transverse = up.cross(axis);
    let flange_colliders = rig.links[flange_link].colliders.clone();
    if flange_colliders.is_empty() {
        return Err(MultibodyError::BadGeometry {
            file: file.clone(),
            link: config.flange_link.clone(),
            reason: "the flange needs at least one <collision> element to touch the environment"
                .into(),
        });
    }
    Ok(Flange {
        link: flange_link,
        body: flange_body,
        cylinder_body,
        joint_frame1,
        joint_frame2,
        lower,
        stroke_m,
        axis,
        transverse,
        up,
        colliders: flange_colliders,
    })
}

/// The materials: prismatic mounts under the carriage along the actuator axis, each with where the flange
/// first touches its face and the carriage offset that aligns it with the flange.
fn materials_of(
    rig: &BuiltRig,
    config: &MultibodyConfig,
    carriage_link: usize,
    flange: &Flange,
) -> Result<Vec<Material>, MultibodyError> {
    let Flange {
        link: flange_link,
        axis,
        transverse,
        lower,
        ..
    } = *flange;
    let file = rig.file.clone();
    let bad_joint = |joint: &str, reason: String| MultibodyError::BadJoint {
        file: file.clone(),
        joint: joint.to_owned(),
        reason,
    };
    let mut materials = Vec::with_capacity(config.materials.len());
    let flange_zero = *rig.world.bodies[rig.links[flange_link].body].position();
    for mc in &config.materials {
        let ji = rig.joint_index(&mc.mount_joint, "materials.mount_joint")?;
        let j = rig.joints[ji].clone();
        if j.kind != urdf_rs::JointType::Prismatic || j.handle.is_none() {
            return Err(bad_joint(
                &j.name,
                "a material mount must be a prismatic joint to a moving face".into(),
            ));
        }
        if !descends_from(rig, j.child, carriage_link) {
            return Err(bad_joint(
                &j.name,
                format!(
                    "the material face must ride on the carriage '{}'",
                    config.carriage_link
                ),
            ));
        }
        let face_body = rig.links[j.child].body;
        let handle = j.handle.expect("checked");
        let frame1 = rig
            .world
            .impulse_joints
            .get(handle)
            .expect("built")
            .data
            .local_frame1;
        let parent_pose = *rig.world.bodies[rig.links[j.parent].body].position();
        let mount_axis = (parent_pose * frame1).rotation * Vector::X;
        if mount_axis.dot(axis) < 1.0 - 1e-9 {
            return Err(bad_joint(
                &j.name,
                "the material mount axis must point along the actuator axis (away from the flange)"
                    .into(),
            ));
        }
        let face_pose = *rig.world.bodies[face_body].position();
        let align_offset_m = (flange_zero.translation - face_pose.translation).dot(transverse);
        // First touch: cast the flange along the axis onto the aligned, unloaded face.
        let aligned = Pose::from_translation(transverse * align_offset_m) * face_pose;
        let x_e_m = first_touch(
            rig,
            &rig.links[flange_link].colliders,
            &rig.links[j.child].colliders,
            &aligned,
            axis,
        )
        .ok_or_else(|| MultibodyError::BadGeometry {
            file: file.clone(),
            link: rig.links[j.child].name.clone(),
            reason: "the flange never touches this face when it faces the flange".into(),
        })?;
        let face_mass_kg = rig.links[j.child].body_mass_kg;
        materials.push(Material {
            name: mc.name.clone(),
            params: mc.params,
            joint: handle,
            face_body,
            face_mass_kg,
            mount_axis,
            // x measured from the retracted stop.
            x_e_m: x_e_m - lower,
            align_offset_m,
            face_link: j.child,
            in_reach: Vec::new(),
        });
    }
    Ok(materials)
}

/// The bodies below the carriage that ride along when it moves (the carriage's own body excluded).
fn riders_of(
    rig: &BuiltRig,
    carriage_link: usize,
    carriage_body: RigidBodyHandle,
) -> Vec<RigidBodyHandle> {
    let mut carriage_riders = Vec::new();
    for (li, l) in rig.links.iter().enumerate() {
        if l.body != carriage_body
            && descends_from(rig, li, carriage_link)
            && !carriage_riders.contains(&l.body)
        {
            carriage_riders.push(l.body);
        }
    }

    carriage_riders
}

/// Faces the flange can reach while another material faces it (only a rig with faces closer together
/// than the flange is wide): they stay simulated while that material is active.
fn mark_faces_in_reach(rig: &BuiltRig, materials: &mut [Material], flange: &Flange) {
    let Flange {
        link: flange_link,
        axis,
        transverse,
        lower,
        stroke_m,
        ..
    } = *flange;
    for i in 0..materials.len() {
        let shift = Pose::from_translation(transverse * materials[i].align_offset_m);
        for k in 0..materials.len() {
            let touch = first_touch(
                rig,
                &rig.links[flange_link].colliders,
                &rig.links[materials[k].face_link].colliders,
                &(shift * *rig.world.bodies[materials[k].face_body].position()),
                axis,
            );
            if k != i && touch.is_some_and(|t| t - lower <= stroke_m) {
                materials[i].in_reach.push(k);
            }
        }
    }
}

/// Only the flange and the material faces touch by design: every other collider gets an empty filter so
/// that the broad and narrow phases never pair them (fewer pairs, faster steps).
fn isolate_flange_and_faces(
    rig: &mut BuiltRig,
    config: &MultibodyConfig,
    flange_colliders: &[ColliderHandle],
) {
    let face_colliders: Vec<ColliderHandle> = config
        .materials
        .iter()
        .filter_map(|mc| rig.joints.iter().find(|j| j.name == mc.mount_joint))
        .flat_map(|j| rig.links[j.child].colliders.iter().copied())
        .collect();
    let flange_g = InteractionGroups::new(Group::GROUP_1, Group::GROUP_2, InteractionTestMode::And);
    let face_g = InteractionGroups::new(Group::GROUP_2, Group::GROUP_1, InteractionTestMode::And);
    let other_g = InteractionGroups::new(Group::GROUP_3, Group::NONE, InteractionTestMode::And);
    let handles: Vec<ColliderHandle> = rig.world.colliders.iter().map(|(h, _)| h).collect();
    for h in handles {
        let g = if flange_colliders.contains(&h) {
            flange_g
        } else if face_colliders.contains(&h) {
            face_g
        } else {
            other_g
        };
        rig.world.colliders[h].set_collision_groups(g);
        // Never paired: out of the broad phase altogether (the shape casts of `first_touch` above
        // and the viewers' geometry do not need it enabled; colliders carry no mass).
        if g == other_g {
            rig.world.colliders[h].set_enabled(false);
        }
    }
}

/// Integration parameters: stiff (near-rigid) Rapier contacts, the compliance lives in the mounts.
fn set_integration(ip: &mut IntegrationParameters, config: &MultibodyConfig) {
    ip.dt = config.dt_s;
    ip.num_solver_iterations = config.solver_iterations;
    ip.contact_softness = SpringCoefficients::new(1.0e6, 1.0);
    ip.static_contact_softness = SpringCoefficients::new(1.0e6, 1.0);
    ip.warmstart_joints = true;
    ip.max_ccd_substeps = 0;
    // Recycled (stale) contact points survived the carriage slide and pushed across a gap: off while
    // the carriage moves, on while it rests (set before every step in `step_with_force`).
    ip.contact_recycling = false;
}

/// Whether link `li` is `ancestor` or lies below it in the tree.
fn descends_from(rig: &BuiltRig, mut li: usize, ancestor: usize) -> bool {
    loop {
        if li == ancestor {
            return true;
        }
        match rig.joints.iter().find(|j| j.child == li) {
            Some(j) => li = j.parent,
            None => return false,
        }
    }
}

/// Distance the flange's colliders travel along `axis` from their current pose until they first touch the
/// face colliders placed at `face_pose` (body pose), or None.
fn first_touch(
    rig: &BuiltRig,
    flange: &[ColliderHandle],
    face: &[ColliderHandle],
    face_pose: &Pose,
    axis: Vector,
) -> Option<f64> {
    let cs = &rig.world.colliders;
    let mut best: Option<f64> = None;
    for &fh in flange {
        let fc = &cs[fh];
        for &eh in face {
            let ec = &cs[eh];
            let local = ec.position_wrt_parent().copied().unwrap_or(Pose::IDENTITY);
            let pos2 = *face_pose * local;
            let hit = cast_shapes(
                fc.position(),
                axis,
                fc.shape(),
                &pos2,
                Vector::ZERO,
                ec.shape(),
                ShapeCastOptions::with_max_time_of_impact(10.0),
            )
            .ok()
            .flatten();
            if let Some(h) = hit {
                best = Some(best.map_or(h.time_of_impact, |b: f64| b.min(h.time_of_impact)));
            }
        }
    }
    best
}
