//! Scripted changes of a mechanism while it runs: a held link moved along waypoints (a carriage that
//! swaps the face in front of an actuator), placed at set-up, gravity turned (an incline), and the
//! geometric query that says where two links first touch.

use rapier3d_f64::parry::query::{ShapeCastOptions, cast_shapes};
use rapier3d_f64::prelude::*;

use super::{Mechanism, apply_spring};
use crate::error::MultibodyError;

/// A held link moving through waypoints: each leg takes an equal share of the duration with the smooth
/// (C¹) profile s(u) = u² (3 − 2u), so the link starts and stops every leg at rest.
#[derive(Debug, Clone)]
pub(super) struct HeldMotion {
    body: RigidBodyHandle,
    /// The held body's pose when the motion started.
    start: Pose,
    t0_s: f64,
    duration_s: f64,
    /// Translations from `start`, in the root frame, m; the motion ends at the last.
    waypoints: Vec<Vector>,
}

/// The motions in progress; each is removed on the step that reaches its end.
pub(super) fn advance(world: &mut PhysicsWorld, motions: &mut Vec<HeldMotion>, t_end_s: f64) {
    let h = world.integration_parameters.dt;
    motions.retain(|m| {
        let elapsed = t_end_s - m.t0_s;
        // Finish on the step that reaches the end (within half a step: time is a sum of steps).
        let s = if elapsed >= m.duration_s - 0.5 * h {
            1.0
        } else {
            (elapsed / m.duration_s).clamp(0.0, 1.0)
        };
        let n = m.waypoints.len();
        let leg = ((s * n as f64).floor() as usize).min(n - 1);
        let u = (s * n as f64 - leg as f64).clamp(0.0, 1.0);
        let from = if leg == 0 {
            Vector::ZERO
        } else {
            m.waypoints[leg - 1]
        };
        let smooth = u * u * (3.0 - 2.0 * u);
        let at = from + (m.waypoints[leg] - from) * smooth;
        world.bodies[m.body].set_next_kinematic_position(Pose::from_translation(at) * m.start);
        s < 1.0
    });
}

impl Mechanism {
    /// Moves held link `name` from where it is now through `waypoints` (translations from its pose now,
    /// root frame, m) over `duration_s` from now, each leg an equal share; the bodies jointed below it
    /// ride along. Replaces a motion of the same link in progress.
    pub fn move_held_link(
        &mut self,
        name: &str,
        waypoints: &[Vector],
        duration_s: f64,
    ) -> Result<(), MultibodyError> {
        let body = self.held_body(name)?;
        let err = |reason: String| MultibodyError::BadConfig {
            field: "held link motion",
            reason,
        };
        if !(duration_s.is_finite() && duration_s > 0.0) {
            return Err(err(format!(
                "duration must be finite and > 0 s, got {duration_s}"
            )));
        }
        if waypoints.is_empty() || waypoints.iter().any(|w| !w.is_finite()) {
            return Err(err(format!(
                "needs at least one finite waypoint, got {waypoints:?}"
            )));
        }
        self.motions.retain(|m| m.body != body);
        self.motions.push(HeldMotion {
            body,
            start: *self.rig.world.bodies[body].position(),
            t0_s: self.time_s,
            duration_s,
            waypoints: waypoints.to_vec(),
        });
        Ok(())
    }

    /// Whether held link `name` is moving (a motion of [`Mechanism::move_held_link`] in progress).
    pub fn held_link_moving(&self, name: &str) -> Result<bool, MultibodyError> {
        let body = self.held_body(name)?;
        Ok(self.motions.iter().any(|m| m.body == body))
    }

    /// Set-up: translates held link `name` and every link below it by `offset` (root frame, m) at once.
    pub fn place_held_link(&mut self, name: &str, offset: Vector) -> Result<(), MultibodyError> {
        let body = self.held_body(name)?;
        let li = self.rig.link_index(name, "held_links")?;
        let shift = Pose::from_translation(offset);
        let mut moved = vec![body];
        let p = shift * *self.rig.world.bodies[body].position();
        self.rig.world.bodies[body].set_position(p, true);
        for l in 0..self.rig.links.len() {
            let b = self.rig.links[l].body;
            if !moved.contains(&b) && self.below(l, li) {
                let p = shift * *self.rig.world.bodies[b].position();
                self.rig.world.bodies[b].set_position(p, true);
                moved.push(b);
            }
        }
        for (a, s) in self.actuators.iter().zip(self.states.iter_mut()) {
            *s = a.mount.state(&self.rig.world.bodies);
        }
        Ok(())
    }

    /// Takes link `name`'s body and the joint that carries it out of the simulation (`false`) or back in
    /// (`true`); its pose, velocity and spring are kept. A body that rests on a held link out of every
    /// other body's reach changes nothing else while it rests: out, it costs no solver time.
    pub fn set_link_simulated(&mut self, name: &str, on: bool) -> Result<(), MultibodyError> {
        let li = self.rig.link_index(name, "link")?;
        let body = self.rig.links[li].body;
        self.rig.world.bodies[body].set_enabled(on);
        if let Some(handle) = self
            .rig
            .joints
            .iter()
            .find(|j| j.child == li)
            .and_then(|j| j.handle)
            && let Some(j) = self.rig.world.impulse_joints.get_mut(handle, on)
        {
            j.data.set_enabled(on);
        }
        Ok(())
    }

    /// Whether link `name`'s body is simulated.
    pub fn link_simulated(&self, name: &str) -> Result<bool, MultibodyError> {
        let li = self.rig.link_index(name, "link")?;
        Ok(self.rig.world.bodies[self.rig.links[li].body].is_enabled())
    }

    /// Gravity in the URDF's root frame, m/s².
    pub fn gravity(&self) -> [f64; 3] {
        self.rig.world.gravity.to_array()
    }

    /// Event: turns gravity (an incline of the whole mechanism). Each spring's set point follows, so a
    /// prismatic joint's child still rests at q = 0 under its own weight.
    pub fn set_gravity(&mut self, gravity_m_s2: [f64; 3]) -> Result<(), MultibodyError> {
        if !gravity_m_s2.iter().all(|g| g.is_finite()) {
            return Err(MultibodyError::BadConfig {
                field: "gravity_m_s2",
                reason: format!("must be three finite numbers, got {gravity_m_s2:?}"),
            });
        }
        let g = Vector::from_array(gravity_m_s2);
        self.rig.world.gravity = g;
        for i in 0..self.springs.len() {
            let sp = &self.springs[i];
            if sp.axis == JointAxis::LinX
                && let Some(j) = self.rig.joints.iter().find(|j| j.handle == Some(sp.joint))
            {
                let joint_axis = (self.rig.link_pose(j.parent) * j.origin).rotation * j.axis;
                self.springs[i].weight_along_n =
                    self.rig.links[j.child].body_mass_kg * g.dot(joint_axis);
            }
            apply_spring(&mut self.rig.world, &self.springs[i]);
        }
        Ok(())
    }

    /// How far link `moving` travels along the unit `direction` (root frame) from its pose now until its
    /// colliders first touch those of link `other` translated by `other_offset` (m); None if never.
    pub fn first_touch(
        &self,
        moving: &str,
        other: &str,
        direction: Vector,
        other_offset: Vector,
    ) -> Result<Option<f64>, MultibodyError> {
        let (la, lb) = (
            self.rig.link_index(moving, "link")?,
            self.rig.link_index(other, "link")?,
        );
        let (bodies, colliders) = (&self.rig.world.bodies, &self.rig.world.colliders);
        // From the bodies' poses: a disabled collider's own pose is not kept up to date.
        let pose = |l: usize, h: ColliderHandle| {
            *bodies[self.rig.links[l].body].position()
                * colliders[h]
                    .position_wrt_parent()
                    .copied()
                    .unwrap_or(Pose::IDENTITY)
        };
        let mut best: Option<f64> = None;
        for &ha in &self.rig.links[la].colliders {
            for &hb in &self.rig.links[lb].colliders {
                let pb = Pose::from_translation(other_offset) * pose(lb, hb);
                let hit = cast_shapes(
                    &pose(la, ha),
                    direction,
                    colliders[ha].shape(),
                    &pb,
                    Vector::ZERO,
                    colliders[hb].shape(),
                    ShapeCastOptions::with_max_time_of_impact(10.0),
                )
                .ok()
                .flatten();
                if let Some(h) = hit {
                    best = Some(best.map_or(h.time_of_impact, |b: f64| b.min(h.time_of_impact)));
                }
            }
        }
        Ok(best)
    }

    /// The body of held link `name`, refused if the link is not held.
    fn held_body(&self, name: &str) -> Result<RigidBodyHandle, MultibodyError> {
        let li = self.rig.link_index(name, "held_links")?;
        let body = self.rig.links[li].body;
        if !self.rig.world.bodies[body].is_kinematic() {
            return Err(MultibodyError::BadConfig {
                field: "held_links",
                reason: format!("link '{name}' is not held (name it in held_links)"),
            });
        }
        Ok(body)
    }

    /// Whether link `l` is `ancestor` or lies below it in the tree.
    fn below(&self, mut l: usize, ancestor: usize) -> bool {
        loop {
            if l == ancestor {
                return true;
            }
            match self.rig.joints.iter().find(|j| j.child == l) {
                Some(j) => l = j.parent,
                None => return false,
            }
        }
    }
}
