//! Compliant contacts: a Kelvin–Voigt pad between the colliders of two links, evaluated by the mechanism
//! itself (Rapier's own rigid contact is off for every collider), so each pair has its own k and c and the
//! contact-force sensor reads exactly the force applied.
//!
//! Two ways into the step ([`PadIntegration`]): explicit, the force at the step's start applied over it
//! (stable only while ω h < 2 on the lightest body it touches), or implicit in the pad's own k and c: a
//! pair in contact at the step's start is a joint whose force-based motor along the contact normal is the
//! pad, which Rapier's solver takes implicitly, F⁺ = k δ + (c + k h) δ̇⁺ over each of its substeps h, so a
//! stiff pad on a light body keeps the control step.

use rapier3d_f64::parry::query;
use rapier3d_f64::prelude::*;

/// Stiffness and damping of a compliant contact.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContactParams {
    /// Normal stiffness k, N/m.
    pub stiffness_n_per_m: f64,
    /// Normal damping c, N s/m.
    pub damping_n_s_per_m: f64,
}

/// How a pad's force enters a physics step.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum PadIntegration {
    /// The force at the step's start, applied over the step.
    #[default]
    Explicit,
    /// Implicit in the pad's own stiffness and damping (Rapier's force-based joint motor).
    Implicit,
}

/// A contact as built: the collider pairs it checks, and its pad.
#[derive(Debug, Clone)]
pub(super) struct BuiltContact {
    pub(super) body_a: RigidBodyHandle,
    pub(super) body_b: RigidBodyHandle,
    /// Every collider of link a against every collider of link b.
    pub(super) pairs: Vec<(ColliderHandle, ColliderHandle)>,
    pub(super) params: ContactParams,
    /// Implicit pads: one joint per collider pair, enabled for a step while its pair touches.
    pub(super) joints: Vec<ImpulseJointHandle>,
    /// Implicit pads: the deepest penetration at the last step's start, m.
    pub(super) armed_depth_m: f64,
}

/// What a contact did over the last step.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ContactReading {
    /// Normal force between the two links, N (≥ 0; the sum over their touching collider pairs).
    pub force_n: f64,
    /// Deepest penetration, m (0 apart).
    pub penetration_m: f64,
}

/// One touching collider pair: where and how hard.
struct Push {
    /// Midway between the two surface points: both bodies get the force there, so the pair exerts no
    /// spurious couple.
    point: Vector,
    /// Unit normal from a towards b.
    normal: Vector,
    force_n: f64,
}

impl BuiltContact {
    /// Evaluates the pads at the current poses and adds their forces to the bodies (the caller resets
    /// forces every step). F = max(0, k δ + c δ̇): a pad pushes, never pulls.
    pub(super) fn apply(
        &self,
        bodies: &mut RigidBodySet,
        colliders: &ColliderSet,
    ) -> ContactReading {
        let mut reading = ContactReading::default();
        for &(ha, hb) in &self.pairs {
            let Some(push) = self.push(bodies, colliders, ha, hb, &mut reading) else {
                continue;
            };
            let f = push.force_n * push.normal;
            bodies[self.body_b].add_force_at_point(f, push.point, true);
            let a = &mut bodies[self.body_a];
            if a.is_dynamic() {
                a.add_force_at_point(-f, push.point, true);
            }
        }
        reading
    }

    /// Implicit pads: one joint per collider pair between the two bodies, built disabled.
    pub(super) fn add_joints(&mut self, joints: &mut ImpulseJointSet) {
        self.joints = (0..self.pairs.len())
            .map(|_| {
                let mut j = GenericJoint::default();
                j.set_motor_model(JointAxis::LinX, MotorModel::ForceBased);
                j.set_enabled(false);
                joints.insert(self.body_a, self.body_b, j, false)
            })
            .collect();
    }

    /// Implicit pads, before the step: each touching pair's joint is placed at its contact point with its
    /// x axis along the normal (a to b) and its motor set to push b by k (δ₀ − s) − c ṡ, s the anchors'
    /// separation along the normal since the step's start; a pair apart, or pulling already (k δ + c δ̇ ≤
    /// 0), is switched off. A pad pushes, never pulls: it is armed only while it pushes at the step's start.
    pub(super) fn arm(
        &mut self,
        bodies: &RigidBodySet,
        colliders: &ColliderSet,
        joints: &mut ImpulseJointSet,
    ) {
        let mut deepest = 0.0_f64;
        for (i, &(ha, hb)) in self.pairs.iter().enumerate() {
            let mut reading = ContactReading::default();
            let push = self.push(bodies, colliders, ha, hb, &mut reading);
            let Some(joint) = joints.get_mut(self.joints[i], false) else {
                continue;
            };
            let data = &mut joint.data;
            match push {
                Some(push) if push.force_n > 0.0 => {
                    deepest = deepest.max(reading.penetration_m);
                    let at = Pose::from_parts(
                        push.point,
                        Rotation::from_rotation_arc(Vector::X, push.normal),
                    );
                    data.set_local_frame1(bodies[self.body_a].position().inverse() * at);
                    data.set_local_frame2(bodies[self.body_b].position().inverse() * at);
                    let p = self.params;
                    data.set_motor(
                        JointAxis::LinX,
                        reading.penetration_m,
                        0.0,
                        p.stiffness_n_per_m,
                        p.damping_n_s_per_m,
                    );
                    data.set_enabled(true);
                }
                _ => {
                    if data.is_enabled() {
                        data.set_enabled(false);
                        if let Some(m) = data.motors.get_mut(0) {
                            m.impulse = 0.0;
                        }
                    }
                }
            }
        }
        self.armed_depth_m = deepest;
    }

    /// Implicit pads, after the step of `h` s (Rapier's substep): the force each armed pair's motor
    /// applied over the last substep, ≥ 0 (a pull is read as 0).
    pub(super) fn read_implicit(&self, joints: &ImpulseJointSet, substep_s: f64) -> ContactReading {
        let mut force = 0.0;
        for &h in &self.joints {
            let Some(j) = joints.get(h) else { continue };
            if j.data.is_enabled() {
                // The motor's impulse on b along the normal is −λ (Rapier's sign).
                force += (-j.data.motors[0].impulse / substep_s).max(0.0);
            }
        }
        ContactReading {
            force_n: force,
            penetration_m: self.armed_depth_m,
        }
    }

    fn push(
        &self,
        bodies: &RigidBodySet,
        colliders: &ColliderSet,
        ha: ColliderHandle,
        hb: ColliderHandle,
        reading: &mut ContactReading,
    ) -> Option<Push> {
        let (ca, cb) = (&colliders[ha], &colliders[hb]);
        let (ba, bb) = (&bodies[self.body_a], &bodies[self.body_b]);
        // From the bodies' poses: a disabled collider's own pose is not kept up to date.
        let pose = |b: &RigidBody, c: &Collider| {
            *b.position() * c.position_wrt_parent().copied().unwrap_or(Pose::IDENTITY)
        };
        let (pa, pb) = (pose(ba, ca), pose(bb, cb));
        let hit = query::contact(&pa, ca.shape(), &pb, cb.shape(), 0.0).ok()??;
        if hit.dist >= 0.0 {
            return None;
        }
        let depth = -hit.dist;
        let normal = hit.normal1;
        let point = 0.5 * (hit.point1 + hit.point2);
        // Penetration grows as b moves against the normal relative to a.
        let depth_rate = -(bb.velocity_at_point(point) - ba.velocity_at_point(point)).dot(normal);
        let p = self.params;
        let force_n = (p.stiffness_n_per_m * depth + p.damping_n_s_per_m * depth_rate).max(0.0);
        reading.force_n += force_n;
        reading.penetration_m = reading.penetration_m.max(depth);
        Some(Push {
            point,
            normal,
            force_n,
        })
    }
}
