//! Any URDF with any number of pneumatic actuators: each cylinder mounted along a prismatic joint or
//! between two anchor points (a lever), compliant Kelvin–Voigt contacts between named links, and the
//! sensors a controller closes its loop on (a contact force, a joint position, a cylinder's stroke).
//!
//! Besides pads, a contact can be rigid (Rapier's own solver, for a face on a compliant mount: `rigid`),
//! a held link can move along scripted waypoints and gravity can turn (`scripted`): the paper's rig, with
//! its carriage that swaps the wood for the iron and its incline, is one mechanism among the others.

mod config;
mod contact;
mod mount;
mod rig;
mod rigid;
mod scripted;

use std::path::Path;

use rapier3d_f64::prelude::*;

pub use config::{ActuatorConfig, ContactConfig, MechanismConfig, Mount, SpringConfig};
use contact::BuiltContact;
pub use contact::{ContactParams, ContactReading, PadIntegration};
use mount::BuiltMount;
pub use mount::MountState;
pub use rig::{CarriageRig, MaterialConfig, Measurements, RigConfig};
pub use rigid::RigidContactConfig;

use crate::actuator::AxialActuator;
use crate::error::MultibodyError;
use crate::urdf_build::{self, BuildOptions, BuiltRig, LinkView};

/// An actuator as built.
#[derive(Debug, Clone)]
struct Actuator {
    name: String,
    mount: BuiltMount,
    stroke_m: f64,
}

/// A contact as built.
#[derive(Debug, Clone)]
struct Contact {
    name: String,
    built: BuiltContact,
}

/// A spring as built.
#[derive(Debug, Clone)]
struct Spring {
    name: String,
    joint: ImpulseJointHandle,
    axis: JointAxis,
    /// Set point that holds the child at q = 0 under its weight, times k (N or N m): q0 = this / k.
    weight_along_n: f64,
    child: RigidBodyHandle,
    params: ContactParams,
}

/// A URDF in Rapier with pneumatic actuators and compliant contacts.
pub struct Mechanism {
    rig: BuiltRig,
    actuators: Vec<Actuator>,
    contacts: Vec<Contact>,
    springs: Vec<Spring>,
    /// Dynamic bodies that get forces: theirs are reset before every step (Rapier keeps them otherwise).
    loaded: Vec<RigidBodyHandle>,
    time_s: f64,
    /// Each actuator's state at the start of the coming step.
    states: Vec<MountState>,
    /// Each actuator's force over the last step, N.
    forces: Vec<f64>,
    /// Each contact over the last step.
    readings: Vec<ContactReading>,
    /// Rigid contacts (Rapier's solver) and their readings.
    rigid: rigid::RigidContacts,
    /// Held links moving along scripted waypoints.
    motions: Vec<scripted::HeldMotion>,
}

impl Mechanism {
    /// Read the URDF at `path` and build the mechanism `config` describes.
    pub fn from_urdf(
        path: impl AsRef<Path>,
        config: &MechanismConfig,
    ) -> Result<Self, MultibodyError> {
        let path = path.as_ref();
        let robot = urdf_build::read_urdf(path)?;
        Self::from_robot(path, &robot, config)
    }

    /// Build from an already parsed URDF (`path` names it in messages).
    pub fn from_robot(
        path: &Path,
        robot: &urdf_rs::Robot,
        config: &MechanismConfig,
    ) -> Result<Self, MultibodyError> {
        check_settings(config)?;
        for (i, l) in config.held_links.iter().enumerate() {
            if !robot.links.iter().any(|x| &x.name == l) {
                return Err(MultibodyError::BadMechanism {
                    file: path.to_path_buf(),
                    item: format!("held link {i}"),
                    key: "held_links",
                    reason: format!("the URDF has no link named '{l}'"),
                });
            }
        }
        let held: Vec<&str> = config.held_links.iter().map(String::as_str).collect();
        let mut rig = urdf_build::build(
            path,
            robot,
            &BuildOptions {
                kinematic_links: &held,
                friction: 0.0,
            },
        )?;
        let mut actuators = Vec::with_capacity(config.actuators.len());
        for (i, a) in config.actuators.iter().enumerate() {
            if config.actuators[..i].iter().any(|o| o.name == a.name) {
                return Err(bad(
                    &rig,
                    "actuator",
                    &a.name,
                    "name",
                    "is listed twice".into(),
                ));
            }
            actuators.push(build_actuator(&rig, a)?);
        }
        let mut contacts = Vec::with_capacity(config.contacts.len());
        for (i, c) in config.contacts.iter().enumerate() {
            if config.contacts[..i].iter().any(|o| o.name == c.name) {
                return Err(bad(
                    &rig,
                    "contact",
                    &c.name,
                    "name",
                    "is listed twice".into(),
                ));
            }
            contacts.push(Contact {
                name: c.name.clone(),
                built: build_contact(&rig, c)?,
            });
        }
        let mut springs = Vec::with_capacity(config.springs.len());
        for (i, sp) in config.springs.iter().enumerate() {
            if config.springs[..i].iter().any(|o| o.name == sp.name) {
                return Err(bad(
                    &rig,
                    "spring",
                    &sp.name,
                    "name",
                    "is listed twice".into(),
                ));
            }
            springs.push(build_spring(
                &rig,
                sp,
                Vector::from_array(config.gravity_m_s2),
            )?);
        }
        // Rapier's rigid contact is off for every collider: the mechanism's pads are the only contacts.
        let handles: Vec<ColliderHandle> = rig.world.colliders.iter().map(|(h, _)| h).collect();
        for h in handles {
            rig.world.colliders[h].set_enabled(false);
        }
        let mut loaded = Vec::new();
        let bodies = actuators.iter().flat_map(|a| a.mount.bodies()).chain(
            contacts
                .iter()
                .flat_map(|c| [c.built.body_a, c.built.body_b]),
        );
        for b in bodies {
            if rig.world.bodies[b].is_dynamic() && !loaded.contains(&b) {
                loaded.push(b);
            }
        }
        {
            let ip = &mut rig.world.integration_parameters;
            ip.dt = config.dt_s;
            ip.num_solver_iterations = config.solver_iterations;
            ip.warmstart_joints = true;
            if config.pad_integration == PadIntegration::Implicit {
                // The pads and the joints they load are one coupled system, solved by Gauss-Seidel sweeps
                // per substep. A 10 N squeeze of the gripper at 1 ms rests at F/k to 1e-9 relative on
                // 2-20 kN/m pads with 8 sweeps, to 0.2 % on 1 MN/m (16 sweeps: 1e-6); one sweep left 0.1 %
                // on 2 kN/m and a left/right bias of the solver's order. A sweep costs little beside a
                // substep (the gripper's run: 1 and 4 sweeps within 3 %).
                ip.num_internal_pgs_iterations = 8;
            }
        }
        rig.world.gravity = Vector::from_array(config.gravity_m_s2);
        for sp in &springs {
            apply_spring(&mut rig.world, sp);
        }
        if config.pad_integration == PadIntegration::Implicit {
            for c in &mut contacts {
                c.built.add_joints(&mut rig.world.impulse_joints);
            }
        }
        for (name, q) in &config.initial_positions {
            set_prismatic(&mut rig, name, *q)?;
        }
        let states = actuators
            .iter()
            .map(|a| a.mount.state(&rig.world.bodies))
            .collect();
        Ok(Self {
            forces: vec![0.0; actuators.len()],
            readings: vec![ContactReading::default(); contacts.len()],
            rig,
            actuators,
            contacts,
            springs,
            loaded,
            time_s: 0.0,
            states,
            rigid: rigid::RigidContacts::default(),
            motions: Vec::new(),
        })
    }

    /// Physics step, s.
    pub fn dt(&self) -> f64 {
        self.rig.world.integration_parameters.dt
    }

    /// Simulated time, s.
    pub fn time(&self) -> f64 {
        self.time_s
    }

    /// The actuators' names, in configuration order.
    pub fn actuator_names(&self) -> impl Iterator<Item = &str> {
        self.actuators.iter().map(|a| a.name.as_str())
    }

    /// Index of the named actuator.
    pub fn actuator_index(&self, name: &str) -> Result<usize, MultibodyError> {
        self.actuators
            .iter()
            .position(|a| a.name == name)
            .ok_or_else(|| {
                unknown(
                    &self.rig,
                    "actuator",
                    name,
                    self.actuators.iter().map(|a| a.name.as_str()),
                )
            })
    }

    /// Actuator `i`'s stroke, rate and line of force now.
    pub fn actuator_state(&self, i: usize) -> MountState {
        self.states[i]
    }

    /// Actuator `i`'s stroke length, m.
    pub fn actuator_stroke(&self, i: usize) -> f64 {
        self.actuators[i].stroke_m
    }

    /// The force actuator `i` applied over the last step, N (+ extends).
    pub fn actuator_force(&self, i: usize) -> f64 {
        self.forces[i]
    }

    /// Index of the named contact.
    pub fn contact_index(&self, name: &str) -> Result<usize, MultibodyError> {
        self.contacts
            .iter()
            .position(|c| c.name == name)
            .ok_or_else(|| {
                unknown(
                    &self.rig,
                    "contact",
                    name,
                    self.contacts.iter().map(|c| c.name.as_str()),
                )
            })
    }

    /// What contact `i` did over the last step: its normal force is the contact-force sensor.
    pub fn contact(&self, i: usize) -> ContactReading {
        self.readings[i]
    }

    /// Event: change contact `i`'s stiffness and damping now (an object that stiffens: foam, then rubber).
    pub fn set_contact(&mut self, i: usize, params: ContactParams) -> Result<(), MultibodyError> {
        check_pad(&self.rig, "contact", &self.contacts[i].name, &params)?;
        self.contacts[i].built.params = params;
        Ok(())
    }

    /// Index of the named spring.
    pub fn spring_index(&self, name: &str) -> Result<usize, MultibodyError> {
        self.springs
            .iter()
            .position(|s| s.name == name)
            .ok_or_else(|| {
                unknown(
                    &self.rig,
                    "spring",
                    name,
                    self.springs.iter().map(|s| s.name.as_str()),
                )
            })
    }

    /// Event: change spring `i`'s stiffness and damping now (the environment behind a face stiffens).
    pub fn set_spring(&mut self, i: usize, params: ContactParams) -> Result<(), MultibodyError> {
        check_pad(&self.rig, "spring", &self.springs[i].name, &params)?;
        self.springs[i].params = params;
        apply_spring(&mut self.rig.world, &self.springs[i]);
        Ok(())
    }

    /// Spring `i`'s stiffness and damping.
    pub fn spring_params(&self, i: usize) -> ContactParams {
        self.springs[i].params
    }

    /// Contact `i`'s stiffness and damping.
    pub fn contact_params(&self, i: usize) -> ContactParams {
        self.contacts[i].built.params
    }

    /// Position (m or rad) and velocity of the named prismatic, revolute or continuous joint: the child's
    /// frame relative to the parent's, along or about the joint axis.
    pub fn joint_position(&self, name: &str) -> Result<(f64, f64), MultibodyError> {
        let ji = self.rig.joint_index(name, "joint")?;
        let j = &self.rig.joints[ji];
        let Some(handle) = j.handle else {
            return Err(bad_joint(
                &self.rig,
                name,
                "is not simulated (fixed, floating or merged)",
            ));
        };
        let joint = self.rig.world.impulse_joints.get(handle).expect("built");
        let bodies = &self.rig.world.bodies;
        let (b1, b2) = (&bodies[joint.body1()], &bodies[joint.body2()]);
        let p1 = *b1.position() * joint.data.local_frame1;
        let p2 = *b2.position() * joint.data.local_frame2;
        let axis = p1.rotation * Vector::X;
        match j.kind {
            urdf_rs::JointType::Prismatic => Ok((
                (p2.translation - p1.translation).dot(axis),
                (b2.velocity_at_point(p2.translation) - b1.velocity_at_point(p2.translation))
                    .dot(axis),
            )),
            urdf_rs::JointType::Revolute | urdf_rs::JointType::Continuous => {
                // The twist about x of the relative rotation (the other two are locked).
                let rel = p1.rotation.inverse() * p2.rotation;
                let angle = 2.0 * rel.x.atan2(rel.w);
                let angle = if angle > core::f64::consts::PI {
                    angle - 2.0 * core::f64::consts::PI
                } else if angle <= -core::f64::consts::PI {
                    angle + 2.0 * core::f64::consts::PI
                } else {
                    angle
                };
                Ok((angle, (b2.angvel() - b1.angvel()).dot(axis)))
            }
            _ => Err(bad_joint(
                &self.rig,
                name,
                "has no single position (only prismatic, revolute and continuous joints do)",
            )),
        }
    }

    /// One physics step with each actuator's force element giving its force from its own stroke and rate
    /// (`elements[i]` drives actuator `i`).
    pub fn step<A: AxialActuator>(&mut self, elements: &mut [A]) {
        assert_eq!(
            elements.len(),
            self.actuators.len(),
            "one force element per actuator"
        );
        let dt = self.dt();
        let mut forces = std::mem::take(&mut self.forces);
        for ((f, el), s) in forces.iter_mut().zip(elements.iter_mut()).zip(&self.states) {
            *f = el.force(s.x_m, s.x_dot_m_s, dt);
        }
        self.advance(&forces);
        self.forces = forces;
    }

    /// One physics step with given actuator forces, N (+ extends), in actuator order.
    pub fn step_with_forces(&mut self, forces_n: &[f64]) {
        assert_eq!(
            forces_n.len(),
            self.actuators.len(),
            "one force per actuator"
        );
        self.advance(forces_n);
        self.forces.copy_from_slice(forces_n);
    }

    fn advance(&mut self, forces_n: &[f64]) {
        let world = &mut self.rig.world;
        for &b in &self.loaded {
            let body = &mut world.bodies[b];
            body.reset_forces(false);
            body.reset_torques(false);
        }
        for ((a, s), &f) in self.actuators.iter().zip(&self.states).zip(forces_n) {
            a.mount.apply(&mut world.bodies, s, f);
        }
        for (c, r) in self.contacts.iter_mut().zip(self.readings.iter_mut()) {
            if c.built.joints.is_empty() {
                *r = c.built.apply(&mut world.bodies, &world.colliders);
            } else {
                c.built
                    .arm(&world.bodies, &world.colliders, &mut world.impulse_joints);
            }
        }
        if !self.rigid.built.is_empty() {
            // Recycled contact points are stale after a held link's slide: only while nothing moves.
            world.integration_parameters.contact_recycling = self.motions.is_empty();
        }
        scripted::advance(
            world,
            &mut self.motions,
            self.time_s + world.integration_parameters.dt,
        );
        world.step();
        self.time_s += world.integration_parameters.dt;
        let substep_s = world.integration_parameters.dt
            / world.integration_parameters.num_solver_iterations as f64;
        for (c, r) in self.contacts.iter().zip(self.readings.iter_mut()) {
            if !c.built.joints.is_empty() {
                *r = c.built.read_implicit(&world.impulse_joints, substep_s);
            }
        }
        if !self.rigid.built.is_empty() {
            self.rigid.read(world);
        }
        for (a, s) in self.actuators.iter().zip(self.states.iter_mut()) {
            *s = a.mount.state(&world.bodies);
        }
    }

    /// Whether every anchored cylinder is within its stroke (a joint mount's stroke is its joint's limits,
    /// which Rapier keeps): Err names the actuator and its length.
    pub fn check_strokes(&self) -> Result<(), String> {
        self.check_travel(|_, x, stroke| {
            let slack = 1e-3 * stroke;
            (-slack..=stroke + slack).contains(&x)
        })
    }

    /// Whether every anchored actuator's stroke is one its family admits
    /// ([`crate::actuator::ActuatorFamily::admits_stroke`]: a cylinder between its end stops, a muscle
    /// also slack); `elements[i]` is actuator `i`'s.
    pub fn check_families<A: crate::actuator::ActuatorFamily>(
        &self,
        elements: &[A],
    ) -> Result<(), String> {
        self.check_travel(|i, x, stroke| elements[i].admits_stroke(x, stroke))
    }

    fn check_travel(&self, admits: impl Fn(usize, f64, f64) -> bool) -> Result<(), String> {
        for (i, (a, s)) in self.actuators.iter().zip(&self.states).enumerate() {
            if matches!(a.mount, BuiltMount::Joint { .. }) {
                continue;
            }
            if !admits(i, s.x_m, a.stroke_m) {
                return Err(format!(
                    "actuator '{}': stroke {:.6} m is outside [0, {}] m: the mechanism pulls the actuator \
                     past its end stop (limit the joint it turns)",
                    a.name, s.x_m, a.stroke_m
                ));
            }
        }
        Ok(())
    }

    /// Every link as viewers draw it: name, pose now, collision shapes and visual meshes.
    pub fn link_views(&self) -> impl Iterator<Item = LinkView<'_>> + '_ {
        self.rig.link_views()
    }

    /// World pose of the named link now.
    pub fn link_pose(&self, name: &str) -> Result<Pose, MultibodyError> {
        Ok(self.rig.link_pose(self.rig.link_index(name, "link")?))
    }

    /// The underlying Rapier world (read-only), for diagnostics.
    pub fn physics(&self) -> &PhysicsWorld {
        &self.rig.world
    }
}

/// Moves the child of prismatic joint `name` (and every link below it) to joint position `q` (m) from
/// the URDF's zero configuration: the start of a run with a finger already near its object.
fn set_prismatic(rig: &mut BuiltRig, name: &str, q: f64) -> Result<(), MultibodyError> {
    let err = |reason: String| MultibodyError::BadMechanism {
        file: rig.file.clone(),
        item: format!("initial position of joint '{name}'"),
        key: "initial_x_m",
        reason,
    };
    let Some(ji) = rig.joints.iter().position(|j| j.name == name) else {
        return Err(err("the URDF has no such joint".into()));
    };
    let j = rig.joints[ji].clone();
    if j.kind != urdf_rs::JointType::Prismatic || j.handle.is_none() {
        return Err(err(
            "only a prismatic joint to a moving link can start away from zero".into(),
        ));
    }
    if let Some([lo, hi]) = j.limits
        && !(lo..=hi).contains(&q)
    {
        return Err(err(format!(
            "{q} m is outside the joint's limits [{lo}, {hi}] m"
        )));
    }
    if !q.is_finite() {
        return Err(err(format!("must be finite, got {q}")));
    }
    let axis = rig.link_pose(j.parent).rotation * (j.origin.rotation * j.axis);
    let shift = Pose::from_translation(q * axis);
    let mut moved = Vec::new();
    for li in 0..rig.links.len() {
        let below = {
            let mut l = li;
            loop {
                if l == j.child {
                    break true;
                }
                match rig.joints.iter().find(|jj| jj.child == l) {
                    Some(jj) => l = jj.parent,
                    None => break false,
                }
            }
        };
        let body = rig.links[li].body;
        if below && !moved.contains(&body) {
            let b = &mut rig.world.bodies[body];
            let p = shift * *b.position();
            b.set_position(p, true);
            moved.push(body);
        }
    }
    Ok(())
}

fn check_settings(config: &MechanismConfig) -> Result<(), MultibodyError> {
    let bad =
        |field: &'static str, reason: String| Err(MultibodyError::BadConfig { field, reason });
    if !(config.dt_s.is_finite() && config.dt_s > 0.0) {
        return bad(
            "dt_s",
            format!("must be a finite step > 0 s, got {}", config.dt_s),
        );
    }
    if config.solver_iterations == 0 {
        return bad("solver_iterations", "must be >= 1".into());
    }
    if !config.gravity_m_s2.iter().all(|g| g.is_finite()) {
        return bad(
            "gravity_m_s2",
            format!(
                "must be three finite numbers, got {:?}",
                config.gravity_m_s2
            ),
        );
    }
    if config.actuators.is_empty() {
        return bad(
            "actuators",
            "a mechanism needs at least one actuator".into(),
        );
    }
    Ok(())
}

fn bad(
    rig: &BuiltRig,
    kind: &str,
    name: &str,
    key: &'static str,
    reason: String,
) -> MultibodyError {
    MultibodyError::BadMechanism {
        file: rig.file.clone(),
        item: format!("{kind} '{name}'"),
        key,
        reason,
    }
}

fn bad_joint(rig: &BuiltRig, joint: &str, reason: &str) -> MultibodyError {
    MultibodyError::BadJoint {
        file: rig.file.clone(),
        joint: joint.to_owned(),
        reason: reason.to_owned(),
    }
}

fn unknown<'a>(
    rig: &BuiltRig,
    kind: &str,
    name: &str,
    known: impl Iterator<Item = &'a str>,
) -> MultibodyError {
    let known: Vec<&str> = known.collect();
    bad(
        rig,
        kind,
        name,
        "name",
        format!("no such {kind} (known: {})", known.join(", ")),
    )
}

/// The link named `name` for `key` of an actuator or contact, or an error naming both.
fn link(
    rig: &BuiltRig,
    kind: &str,
    item: &str,
    key: &'static str,
    name: &str,
) -> Result<usize, MultibodyError> {
    rig.links
        .iter()
        .position(|l| l.name == name)
        .ok_or_else(|| {
            bad(
                rig,
                kind,
                item,
                key,
                format!("the URDF has no link named '{name}'"),
            )
        })
}

fn finite_point(p: &[f64; 3]) -> Option<Vector> {
    p.iter()
        .all(|v| v.is_finite())
        .then(|| Vector::from_array(*p))
}

fn build_actuator(rig: &BuiltRig, a: &ActuatorConfig) -> Result<Actuator, MultibodyError> {
    let err = |key: &'static str, reason: String| bad(rig, "actuator", &a.name, key, reason);
    match &a.mount {
        Mount::Joint { joint } => {
            let ji = rig
                .joints
                .iter()
                .position(|j| &j.name == joint)
                .ok_or_else(|| err("joint", format!("the URDF has no joint named '{joint}'")))?;
            let j = &rig.joints[ji];
            let Some(handle) = j.handle.filter(|_| j.kind == urdf_rs::JointType::Prismatic) else {
                return Err(err(
                    "joint",
                    format!("'{joint}' must be a prismatic joint to a moving link"),
                ));
            };
            let Some([lower, upper]) = j.limits.filter(|[lo, hi]| hi > lo) else {
                return Err(err(
                    "joint",
                    format!(
                        "'{joint}' needs a finite <limit lower upper> with upper > lower (the stroke)"
                    ),
                ));
            };
            let data = &rig.world.impulse_joints.get(handle).expect("built").data;
            Ok(Actuator {
                name: a.name.clone(),
                mount: BuiltMount::Joint {
                    parent: rig.links[j.parent].body,
                    child: rig.links[j.child].body,
                    frame1: data.local_frame1,
                    frame2: data.local_frame2,
                    lower_m: lower,
                },
                stroke_m: upper - lower,
            })
        }
        Mount::Anchors {
            link_a,
            point_a_m,
            link_b,
            point_b_m,
            retracted_length_m,
            stroke_m,
        } => {
            let la = link(rig, "actuator", &a.name, "link_a", link_a)?;
            let lb = link(rig, "actuator", &a.name, "link_b", link_b)?;
            let pa = finite_point(point_a_m).ok_or_else(|| {
                err(
                    "point_a",
                    format!("must be three finite numbers, got {point_a_m:?}"),
                )
            })?;
            let pb = finite_point(point_b_m).ok_or_else(|| {
                err(
                    "point_b",
                    format!("must be three finite numbers, got {point_b_m:?}"),
                )
            })?;
            if rig.links[la].body == rig.links[lb].body {
                return Err(err(
                    "link_b",
                    format!(
                        "'{link_a}' and '{link_b}' are one rigid body (joined by fixed joints): the cylinder could never move"
                    ),
                ));
            }
            if !(retracted_length_m.is_finite() && *retracted_length_m > 0.0) {
                return Err(err(
                    "retracted_length",
                    format!("must be a finite length > 0 m, got {retracted_length_m}"),
                ));
            }
            if !(stroke_m.is_finite() && *stroke_m > 0.0) {
                return Err(err(
                    "stroke",
                    format!("must be a finite length > 0 m, got {stroke_m}"),
                ));
            }
            let (la_info, lb_info) = (&rig.links[la], &rig.links[lb]);
            let mount = BuiltMount::Anchors {
                body_a: la_info.body,
                local_a: la_info.body_from_link.transform_point(pa),
                body_b: lb_info.body,
                local_b: lb_info.body_from_link.transform_point(pb),
                retracted_length_m: *retracted_length_m,
            };
            // The URDF's zero configuration must put the cylinder within its stroke.
            let length = (rig.link_pose(lb).transform_point(pb)
                - rig.link_pose(la).transform_point(pa))
            .length();
            if !(*retracted_length_m..=retracted_length_m + stroke_m).contains(&length) {
                return Err(err(
                    "retracted_length",
                    format!(
                        "the anchors are {length:.6} m apart in the URDF's zero configuration, outside the \
                         cylinder's [{retracted_length_m}, {}] m",
                        retracted_length_m + stroke_m
                    ),
                ));
            }
            Ok(Actuator {
                name: a.name.clone(),
                mount,
                stroke_m: *stroke_m,
            })
        }
    }
}

fn check_pad(
    rig: &BuiltRig,
    kind: &str,
    name: &str,
    p: &ContactParams,
) -> Result<(), MultibodyError> {
    if !(p.stiffness_n_per_m.is_finite() && p.stiffness_n_per_m > 0.0) {
        return Err(bad(
            rig,
            kind,
            name,
            "stiffness",
            format!("must be finite and > 0 N/m, got {}", p.stiffness_n_per_m),
        ));
    }
    if !(p.damping_n_s_per_m.is_finite() && p.damping_n_s_per_m >= 0.0) {
        return Err(bad(
            rig,
            kind,
            name,
            "damping",
            format!("must be finite and >= 0 N s/m, got {}", p.damping_n_s_per_m),
        ));
    }
    Ok(())
}

fn build_contact(rig: &BuiltRig, c: &ContactConfig) -> Result<BuiltContact, MultibodyError> {
    let la = link(rig, "contact", &c.name, "link_a", &c.link_a)?;
    let lb = link(rig, "contact", &c.name, "link_b", &c.link_b)?;
    for (key, l) in [("link_a", la), ("link_b", lb)] {
        if rig.links[l].colliders.is_empty() {
            return Err(bad(
                rig,
                "contact",
                &c.name,
                key,
                format!(
                    "link '{}' has no <collision> element to touch with",
                    rig.links[l].name
                ),
            ));
        }
    }
    if rig.links[la].body == rig.links[lb].body {
        return Err(bad(
            rig,
            "contact",
            &c.name,
            "link_b",
            format!(
                "'{}' and '{}' are one rigid body: they cannot touch",
                c.link_a, c.link_b
            ),
        ));
    }
    let params = ContactParams {
        stiffness_n_per_m: c.stiffness_n_per_m,
        damping_n_s_per_m: c.damping_n_s_per_m,
    };
    check_pad(rig, "contact", &c.name, &params)?;
    let pairs = rig.links[la]
        .colliders
        .iter()
        .flat_map(|&a| rig.links[lb].colliders.iter().map(move |&b| (a, b)))
        .collect();
    Ok(BuiltContact {
        body_a: rig.links[la].body,
        body_b: rig.links[lb].body,
        pairs,
        params,
        joints: Vec::new(),
        armed_depth_m: 0.0,
    })
}

fn build_spring(
    rig: &BuiltRig,
    sp: &SpringConfig,
    gravity: Vector,
) -> Result<Spring, MultibodyError> {
    let err = |key: &'static str, reason: String| bad(rig, "spring", &sp.name, key, reason);
    let Some(j) = rig.joints.iter().find(|j| j.name == sp.joint) else {
        return Err(err(
            "joint",
            format!("the URDF has no joint named '{}'", sp.joint),
        ));
    };
    let axis = match j.kind {
        urdf_rs::JointType::Prismatic => JointAxis::LinX,
        urdf_rs::JointType::Revolute | urdf_rs::JointType::Continuous => JointAxis::AngX,
        _ => {
            return Err(err(
                "joint",
                format!("'{}' must be a prismatic or revolute joint", sp.joint),
            ));
        }
    };
    let Some(handle) = j.handle else {
        return Err(err(
            "joint",
            format!(
                "'{}' moves no simulated link (held, or merged by fixed joints)",
                sp.joint
            ),
        ));
    };
    let params = ContactParams {
        stiffness_n_per_m: sp.stiffness,
        damping_n_s_per_m: sp.damping,
    };
    check_pad(rig, "spring", &sp.name, &params)?;
    // A prismatic child's weight along the joint, which the set point carries so that it rests at q = 0.
    let child = rig.links[j.child].body;
    let weight_along_n = if axis == JointAxis::LinX {
        let joint_axis = (rig.link_pose(j.parent) * j.origin).rotation * j.axis;
        rig.links[j.child].body_mass_kg * gravity.dot(joint_axis)
    } else {
        0.0
    };
    Ok(Spring {
        name: sp.name.clone(),
        joint: handle,
        axis,
        weight_along_n,
        child,
        params,
    })
}

fn apply_spring(world: &mut PhysicsWorld, sp: &Spring) {
    let k = sp.params.stiffness_n_per_m;
    crate::spring::set_joint_spring(
        world,
        sp.joint,
        sp.axis,
        -sp.weight_along_n / k,
        k,
        sp.params.damping_n_s_per_m,
    );
    world.bodies[sp.child].wake_up(true);
}
