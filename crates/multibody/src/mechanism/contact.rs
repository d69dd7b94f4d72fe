//! Compliant contacts: a Kelvin–Voigt pad between the colliders of two links, evaluated by the mechanism
//! itself (Rapier's own rigid contact is off for every collider), so each pair has its own k and c and the
//! contact-force sensor reads exactly the force applied.
//!
//! The pads are implicit in their own stiffness and damping, so a stiff pad on a light body is stable at
//! the control step (docs/multibody.md "Speed"). Over a physics step h, pad i is a spring-damper along its
//! normal n_i between bodies a and b: δ_i the penetration, u_i = δ̇_i, a_i the relative acceleration every
//! other force gives (cylinders, gravity, joints). Rapier's s substeps of h/s move the pair by
//!
//!   u_i⁺ = u_i + h (a_i − Σ_j W_ij F_j),   δ_i⁺ = δ_i + h u_i + γ h (u_i⁺ − u_i),   γ = (s + 1)/(2 s),  (P1)
//!
//! W the pads' mobility: W_ij = Σ over the bodies both pads push of σ_i σ_j w(i, j), σ = +1 on b, −1 on
//! a, with w how the body moves under the push: a body on one slide (or planar joint) to a fixed or held
//! link w = Σ_k (n_i·e_k)(n_j·e_k)/m over its free axes e_k; on one hinge of axis e about the pivot
//! w = (e·(r_i × n_i))(e·(r_j × n_j))/I_e, r from the pivot and I_e = e·I e + m |d × e|², d from the pivot
//! to the centre of mass; otherwise the free body's n_i·M⁻¹ n_j + (r_i × n_i)·I⁻¹ (r_j × n_j), r from the
//! centre of mass (a joint to a moving link only adds inertia, so W is then an upper bound). The force
//! held over the step is the Kelvin–Voigt force at the step's end (backward Euler):
//!
//!   F_i = k_i δ_i⁺ + c_i u_i⁺ = k_i δ_i + (c_i + h k_i) u_i + (c_i + γ h k_i)(u_i⁺ − u_i).           (P2)
//!
//! a is not known before Rapier's joint solver has run; the last step's velocity change gives it,
//! h a_i ≈ (u_i − u_i⁻) + h Σ_j W_ij F_j⁻ (u⁻ from the bodies' last velocities at this step's point and
//! normal, F⁻ the last step's forces). With e_i = h (c_i + γ h k_i), r_i = k_i δ_i + (c_i + h k_i) u_i
//! + (c_i + γ h k_i)(u_i − u_i⁻), (P2) is the symmetric positive definite system
//!
//!   (E⁻¹ + W) F = E⁻¹ r + W F⁻,   F ≥ 0 (a pad pushes, never pulls).                              (P3)
//!
//! At rest (u = u⁻, F = F⁻) it gives F = k δ; for ω h ≪ 1 it is the explicit pad F = k δ + c u; pads on
//! one body (a gripper's two fingers on its object) are solved together, so neither lags the other. The
//! forces are constant over the step: the sensor reads the force the bodies got.

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

/// A body's velocity at the start of the last step: (linear, angular).
type Velocity = (Vector, AngVector);

/// A contact as built: the collider pairs it checks, and its pad.
#[derive(Debug, Clone)]
pub(super) struct BuiltContact {
    pub(super) body_a: RigidBodyHandle,
    pub(super) body_b: RigidBodyHandle,
    /// Every collider of link a against every collider of link b.
    pub(super) pairs: Vec<(ColliderHandle, ColliderHandle)>,
    pub(super) params: ContactParams,
    /// Each pair's force over the last step, N (F⁻ of (P3)).
    last_force_n: Vec<f64>,
    /// Bodies a and b at the start of the last step (u⁻ of (P3)); None before the first step.
    last_velocities: Option<[Velocity; 2]>,
    /// How bodies a and b move under a push.
    freedom: [Freedom; 2],
}

/// How a body moves under a pad's push (w of (P3)).
#[derive(Debug, Clone, Copy)]
enum Freedom {
    /// Fixed or held: not at all.
    Fixed,
    /// Along the free axes of its one joint to a fixed or held link: a slide, a planar joint or a hinge.
    Joint(ImpulseJointHandle),
    /// As a free body.
    Free,
}

impl Freedom {
    fn of(body: RigidBodyHandle, bodies: &RigidBodySet, joints: &ImpulseJointSet) -> Self {
        if !bodies[body].is_dynamic() {
            return Self::Fixed;
        }
        let mut held_by = joints.iter().filter(|(_, j)| j.body2() == body);
        match (held_by.next(), held_by.next()) {
            (Some((h, j)), None) if !bodies[j.body1()].is_dynamic() => {
                let locked = j.data.locked_axes;
                let hinge = locked.contains(JointAxesMask::LIN_AXES)
                    && (locked & JointAxesMask::ANG_AXES).bits().count_ones() == 2;
                if locked.contains(JointAxesMask::ANG_AXES) || hinge {
                    Self::Joint(h)
                } else {
                    Self::Free
                }
            }
            _ => Self::Free,
        }
    }
}

/// What a contact did over the last step.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ContactReading {
    /// Normal force between the two links, N (≥ 0; the sum over their touching collider pairs).
    pub force_n: f64,
    /// Deepest penetration, m (0 apart).
    pub penetration_m: f64,
    /// The stiffest touching pair's natural frequency times the physics step, ω h = h √(k W_ii) with
    /// W_ii its mobility of (P3) (0 apart): a pad rings faster than its step can follow when this is
    /// well above 1, and its force then depends on the step (the pad is unresolved).
    pub omega_h: f64,
}

/// The step the pads are integrated over: h and Rapier's substeps s.
#[derive(Debug, Clone, Copy)]
struct PadStep {
    dt_s: f64,
    substeps: usize,
}

/// One touching collider pair this step: where, how deep, how fast, and its force once solved.
#[derive(Debug, Clone, Copy)]
struct Push {
    /// Its contact and collider pair.
    contact: usize,
    pair: usize,
    body_a: RigidBodyHandle,
    body_b: RigidBodyHandle,
    freedom: [Freedom; 2],
    /// Midway between the two surface points: both bodies get the force there, so the pair exerts no
    /// spurious couple.
    point: Vector,
    /// Unit normal from a towards b.
    normal: Vector,
    /// 1/e_i and E⁻¹ r_i + Σ_j W_ij F_j⁻ of (P3), then the force.
    inv_e: f64,
    rhs: f64,
    force_n: f64,
}

/// The pads' scratch, kept between steps so that a step allocates nothing.
#[derive(Debug, Clone, Default)]
pub(super) struct PadSolver {
    pushes: Vec<Push>,
    /// (E⁻¹ + W) of (P3), row-major, and its factor.
    matrix: Vec<f64>,
    factor: Vec<f64>,
    active: Vec<bool>,
}

impl BuiltContact {
    pub(super) fn new(
        world: &PhysicsWorld,
        body_a: RigidBodyHandle,
        body_b: RigidBodyHandle,
        pairs: Vec<(ColliderHandle, ColliderHandle)>,
        params: ContactParams,
    ) -> Self {
        let freedom = |b| Freedom::of(b, &world.bodies, &world.impulse_joints);
        Self {
            body_a,
            body_b,
            last_force_n: vec![0.0; pairs.len()],
            pairs,
            params,
            last_velocities: None,
            freedom: [freedom(body_a), freedom(body_b)],
        }
    }

    /// Pair `pair` if its colliders overlap: its geometry, 1/e and E⁻¹ r of (P3) (the W F⁻ part is added
    /// by the caller).
    fn touch(
        &self,
        bodies: &RigidBodySet,
        colliders: &ColliderSet,
        contact: usize,
        pair: usize,
        step: PadStep,
        reading: &mut ContactReading,
    ) -> Option<Push> {
        let (ha, hb) = self.pairs[pair];
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
        let rate = |va: Vector, vb: Vector| -(vb - va).dot(normal);
        let u = rate(ba.velocity_at_point(point), bb.velocity_at_point(point));
        let u_last = match self.last_velocities {
            Some([(la, wa), (lb, wb)]) => {
                let at = |b: &RigidBody, lin: Vector, ang: AngVector| {
                    lin + ang.cross(point - b.center_of_mass())
                };
                rate(at(ba, la, wa), at(bb, lb, wb))
            }
            None => u,
        };
        let (k, c) = (self.params.stiffness_n_per_m, self.params.damping_n_s_per_m);
        let h = step.dt_s;
        let s = step.substeps.max(1) as f64;
        let gamma = (s + 1.0) / (2.0 * s);
        let e = h * (c + gamma * h * k);
        let r = k * depth + (c + h * k) * u + (c + gamma * h * k) * (u - u_last);
        reading.penetration_m = reading.penetration_m.max(depth);
        Some(Push {
            contact,
            pair,
            body_a: self.body_a,
            body_b: self.body_b,
            freedom: self.freedom,
            point,
            normal,
            inv_e: 1.0 / e,
            rhs: r / e,
            force_n: 0.0,
        })
    }
}

/// W_ij of (P3): how pad j's force changes pad i's penetration rate, per unit force and time.
fn mobility(bodies: &RigidBodySet, joints: &ImpulseJointSet, i: &Push, j: &Push) -> f64 {
    let mut w = 0.0;
    for ((body, sign_i), freedom) in [(i.body_a, -1.0), (i.body_b, 1.0)]
        .into_iter()
        .zip(i.freedom)
    {
        let sign_j = if body == j.body_b {
            1.0
        } else if body == j.body_a {
            -1.0
        } else {
            continue;
        };
        w += sign_i * sign_j * body_mobility(&bodies[body], freedom, bodies, joints, i, j);
    }
    w
}

/// w of (P3) for one body both pads push.
fn body_mobility(
    b: &RigidBody,
    freedom: Freedom,
    bodies: &RigidBodySet,
    joints: &ImpulseJointSet,
    i: &Push,
    j: &Push,
) -> f64 {
    let mp = b.mass_properties();
    let free = || {
        let rn_i = (i.point - mp.world_com).cross(i.normal);
        let rn_j = (j.point - mp.world_com).cross(j.normal);
        (mp.effective_inv_mass * i.normal).dot(j.normal)
            + rn_i.dot(mp.effective_world_inv_inertia * rn_j)
    };
    match freedom {
        Freedom::Fixed => 0.0,
        Freedom::Free => free(),
        Freedom::Joint(h) => {
            let Some(joint) = joints.get(h) else {
                return free();
            };
            let frame = *bodies[joint.body1()].position() * joint.data.local_frame1;
            let locked = joint.data.locked_axes;
            let axes = [Vector::X, Vector::Y, Vector::Z].map(|e| frame.rotation * e);
            if locked.contains(JointAxesMask::ANG_AXES) {
                // Translation only, along the free axes.
                let lin = [
                    JointAxesMask::LIN_X,
                    JointAxesMask::LIN_Y,
                    JointAxesMask::LIN_Z,
                ];
                let inv_m = mp.local_mprops.inv_mass;
                axes.iter()
                    .zip(lin)
                    .filter(|(_, m)| !locked.contains(*m))
                    .map(|(e, _)| i.normal.dot(*e) * j.normal.dot(*e) * inv_m)
                    .sum()
            } else {
                // A hinge: rotation about the free axis through the pivot.
                let ang = [
                    JointAxesMask::ANG_X,
                    JointAxesMask::ANG_Y,
                    JointAxesMask::ANG_Z,
                ];
                let Some((e, _)) = axes.iter().zip(ang).find(|(_, m)| !locked.contains(*m)) else {
                    return free();
                };
                let pivot = (*b.position() * joint.data.local_frame2).translation;
                let lm = &mp.local_mprops;
                let principal = b.position().rotation * lm.principal_inertia_local_frame;
                let e_p = principal.inverse() * *e;
                let i_com = (lm.principal_inertia() * e_p).dot(e_p);
                let d = mp.world_com - pivot;
                let i_e = i_com + lm.mass() * d.cross(*e).length_squared();
                if i_e <= 0.0 {
                    return free();
                }
                e.dot((i.point - pivot).cross(i.normal)) * e.dot((j.point - pivot).cross(j.normal))
                    / i_e
            }
        }
    }
}

impl PadSolver {
    /// Evaluates every pad at the current poses, solves (P3) and adds the forces to the bodies (the
    /// caller resets forces every step); `readings[c]` gets contact c's force and deepest penetration.
    pub(super) fn apply<C>(
        &mut self,
        contacts: &mut [C],
        built: impl Fn(&mut C) -> &mut BuiltContact,
        readings: &mut [ContactReading],
        world: &mut PhysicsWorld,
    ) {
        let step = PadStep {
            dt_s: world.integration_parameters.dt,
            substeps: world.integration_parameters.num_solver_iterations,
        };
        let (bodies, colliders, joints) =
            (&mut world.bodies, &world.colliders, &world.impulse_joints);
        self.pushes.clear();
        for (ci, (c, r)) in contacts.iter_mut().zip(readings.iter_mut()).enumerate() {
            let c = built(c);
            *r = ContactReading::default();
            for pi in 0..c.pairs.len() {
                if let Some(p) = c.touch(bodies, colliders, ci, pi, step, r) {
                    self.pushes.push(p);
                }
            }
        }
        let n = self.pushes.len();
        if n > 0 {
            self.matrix.clear();
            for i in 0..n {
                for j in 0..n {
                    let w = mobility(bodies, joints, &self.pushes[i], &self.pushes[j]);
                    self.matrix.push(w);
                }
            }
            for i in 0..n {
                let p = &self.pushes[i];
                let k = built(&mut contacts[p.contact]).params.stiffness_n_per_m;
                let omega_h = step.dt_s * (k * self.matrix[i * n + i]).max(0.0).sqrt();
                let r = &mut readings[p.contact];
                r.omega_h = r.omega_h.max(omega_h);
            }
            // The right side: E⁻¹ r + W F⁻, with F⁻ the last force of each pad touching now.
            for i in 0..n {
                let mut wf = 0.0;
                for j in 0..n {
                    let pj = &self.pushes[j];
                    let last = built(&mut contacts[pj.contact]).last_force_n[pj.pair];
                    wf += self.matrix[i * n + j] * last;
                }
                self.pushes[i].rhs += wf;
                self.matrix[i * n + i] += self.pushes[i].inv_e;
            }
            self.solve();
        }
        for c in contacts.iter_mut() {
            let c = built(c);
            c.last_force_n.iter_mut().for_each(|f| *f = 0.0);
        }
        for p in &self.pushes {
            let c = built(&mut contacts[p.contact]);
            c.last_force_n[p.pair] = p.force_n;
            readings[p.contact].force_n += p.force_n;
            let f = p.force_n * p.normal;
            bodies[p.body_b].add_force_at_point(f, p.point, true);
            let a = &mut bodies[p.body_a];
            if a.is_dynamic() {
                a.add_force_at_point(-f, p.point, true);
            }
        }
        for c in contacts.iter_mut() {
            let c = built(c);
            let velocity = |b: &RigidBody| (b.linvel(), b.angvel());
            c.last_velocities = Some([velocity(&bodies[c.body_a]), velocity(&bodies[c.body_b])]);
        }
    }

    /// (P3) with F ≥ 0: solve for the pads still pushing, drop those the solution makes pull, repeat
    /// (at most once per pad; the matrix is symmetric positive definite, so each solve is a Cholesky).
    fn solve(&mut self) {
        let n = self.pushes.len();
        self.active.clear();
        self.active.resize(n, true);
        for _ in 0..=n {
            if n <= 2 {
                self.solve_small();
            } else {
                self.solve_cholesky();
            }
            let mut dropped = false;
            for (p, on) in self.pushes.iter().zip(self.active.iter_mut()) {
                if *on && p.force_n < 0.0 {
                    *on = false;
                    dropped = true;
                }
            }
            if !dropped {
                break;
            }
        }
        for p in &mut self.pushes {
            p.force_n = p.force_n.max(0.0);
        }
    }

    /// One or two pads, by Cramer's rule: symmetric in the two, so two mirrored fingers on one object
    /// get bitwise equal forces (a Cholesky's rounding would seed the object's sideways drift).
    fn solve_small(&mut self) {
        let n = self.pushes.len();
        let a = |i: usize, j: usize| self.matrix[i * n + j];
        match (n, self.active.first().copied(), self.active.get(1).copied()) {
            (2, Some(true), Some(true)) => {
                let (b0, b1) = (self.pushes[0].rhs, self.pushes[1].rhs);
                let det = a(0, 0) * a(1, 1) - a(0, 1) * a(1, 0);
                let f0 = (b0 * a(1, 1) - a(0, 1) * b1) / det;
                let f1 = (a(0, 0) * b1 - a(1, 0) * b0) / det;
                self.pushes[0].force_n = f0;
                self.pushes[1].force_n = f1;
            }
            _ => {
                for i in 0..n {
                    self.pushes[i].force_n = if self.active[i] {
                        self.pushes[i].rhs / a(i, i)
                    } else {
                        0.0
                    };
                }
            }
        }
    }

    fn solve_cholesky(&mut self) {
        let n = self.pushes.len();
        {
            // Cholesky of the active block, in place of the inactive rows an identity.
            self.factor.clear();
            self.factor.resize(n * n, 0.0);
            for i in 0..n {
                for j in 0..=i {
                    let on = self.active[i] && self.active[j];
                    let mut sum = if on {
                        self.matrix[i * n + j]
                    } else if i == j {
                        1.0
                    } else {
                        0.0
                    };
                    for m in 0..j {
                        sum -= self.factor[i * n + m] * self.factor[j * n + m];
                    }
                    self.factor[i * n + j] = if i == j {
                        sum.max(f64::MIN_POSITIVE).sqrt()
                    } else {
                        sum / self.factor[j * n + j]
                    };
                }
            }
            // Forward and back substitution, the forces in `force_n`.
            for i in 0..n {
                let mut sum = if self.active[i] {
                    self.pushes[i].rhs
                } else {
                    0.0
                };
                for m in 0..i {
                    sum -= self.factor[i * n + m] * self.pushes[m].force_n;
                }
                self.pushes[i].force_n = sum / self.factor[i * n + i];
            }
            for i in (0..n).rev() {
                let mut sum = self.pushes[i].force_n;
                for m in i + 1..n {
                    sum -= self.factor[m * n + i] * self.pushes[m].force_n;
                }
                self.pushes[i].force_n = sum / self.factor[i * n + i];
            }
        }
    }
}
