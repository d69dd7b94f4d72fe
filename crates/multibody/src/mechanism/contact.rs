//! Compliant contacts: a Kelvin–Voigt pad between the colliders of two links, evaluated by the mechanism
//! itself (Rapier's own rigid contact is off for every collider), so each pair has its own k and c and the
//! contact-force sensor reads exactly the force applied.

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

/// A contact as built: the collider pairs it checks, and its pad.
#[derive(Debug, Clone)]
pub(super) struct BuiltContact {
    pub(super) body_a: RigidBodyHandle,
    pub(super) body_b: RigidBodyHandle,
    /// Every collider of link a against every collider of link b.
    pub(super) pairs: Vec<(ColliderHandle, ColliderHandle)>,
    pub(super) params: ContactParams,
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
