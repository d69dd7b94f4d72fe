//! An actuator's mount as built: where its stroke is read and where its force acts.

use rapier3d_f64::prelude::*;

/// A mount resolved to bodies and frames.
#[derive(Debug, Clone)]
pub(super) enum BuiltMount {
    /// Along a prismatic joint (see [`super::Mount::Joint`]).
    Joint {
        parent: RigidBodyHandle,
        child: RigidBodyHandle,
        /// Joint frames in the parent and child bodies; x = the joint axis.
        frame1: Pose,
        frame2: Pose,
        /// Joint position at the retracted stop, m.
        lower_m: f64,
    },
    /// Between two anchor points (see [`super::Mount::Anchors`]).
    Anchors {
        body_a: RigidBodyHandle,
        /// Clevis point in `body_a`'s frame, m.
        local_a: Vector,
        body_b: RigidBodyHandle,
        /// Rod-eye point in `body_b`'s frame, m.
        local_b: Vector,
        retracted_length_m: f64,
    },
}

/// Where an actuator is now: stroke, rate and line of force.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MountState {
    /// Stroke from the retracted stop, m.
    pub x_m: f64,
    /// Stroke rate, m/s.
    pub x_dot_m_s: f64,
    /// The clevis end (cylinder side) in the root frame, m.
    pub end_a: Vector,
    /// The rod end in the root frame, m.
    pub end_b: Vector,
    /// Unit line of force from `end_a` towards `end_b` (the direction the rod extends).
    pub axis: Vector,
}

impl BuiltMount {
    /// The mount's stroke, rate and line of force at the bodies' current poses and velocities.
    pub(super) fn state(&self, bodies: &RigidBodySet) -> MountState {
        match self {
            Self::Joint {
                parent,
                child,
                frame1,
                frame2,
                lower_m,
            } => {
                let (pb, cb) = (&bodies[*parent], &bodies[*child]);
                let p1 = *pb.position() * *frame1;
                let p2 = *cb.position() * *frame2;
                let axis = p1.rotation * Vector::X;
                let q = (p2.translation - p1.translation).dot(axis);
                let v = (cb.velocity_at_point(p2.translation)
                    - pb.velocity_at_point(p2.translation))
                .dot(axis);
                MountState {
                    x_m: q - lower_m,
                    x_dot_m_s: v,
                    end_a: p1.translation,
                    end_b: p2.translation,
                    axis,
                }
            }
            Self::Anchors {
                body_a,
                local_a,
                body_b,
                local_b,
                retracted_length_m,
            } => {
                let (ba, bb) = (&bodies[*body_a], &bodies[*body_b]);
                let pa = ba.position().transform_point(*local_a);
                let pb = bb.position().transform_point(*local_b);
                let d = pb - pa;
                let length = d.length();
                // Anchors never coincide on a built mount (checked at build, and the stroke check keeps
                // the length above the retracted one), so n is always defined.
                let axis = d / length;
                let rate = (bb.velocity_at_point(pb) - ba.velocity_at_point(pa)).dot(axis);
                MountState {
                    x_m: length - retracted_length_m,
                    x_dot_m_s: rate,
                    end_a: pa,
                    end_b: pb,
                    axis,
                }
            }
        }
    }

    /// Adds the piston force `force_n` (N, + extends) to the bodies: +F along the line on the rod side,
    /// −F on the cylinder side. Forces persist in Rapier until reset: the caller resets them every step.
    pub(super) fn apply(&self, bodies: &mut RigidBodySet, state: &MountState, force_n: f64) {
        let f = force_n * state.axis;
        match self {
            Self::Joint { parent, child, .. } => {
                // Along a prismatic joint the joint takes any moment: the force acts at the centre of mass.
                bodies[*child].add_force(f, true);
                let p = &mut bodies[*parent];
                if p.is_dynamic() {
                    p.add_force(-f, true);
                }
            }
            Self::Anchors { body_a, body_b, .. } => {
                // At the anchors: the moment about a pivot is F × r(θ), the lever arm the geometry gives.
                bodies[*body_b].add_force_at_point(f, state.end_b, true);
                let a = &mut bodies[*body_a];
                if a.is_dynamic() {
                    a.add_force_at_point(-f, state.end_a, true);
                }
            }
        }
    }

    /// The bodies whose forces this mount sets.
    pub(super) fn bodies(&self) -> [RigidBodyHandle; 2] {
        match self {
            Self::Joint { parent, child, .. } => [*parent, *child],
            Self::Anchors { body_a, body_b, .. } => [*body_a, *body_b],
        }
    }
}
