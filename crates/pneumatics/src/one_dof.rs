//! The step of the 1-DOF model ([`OneDofModel::step`]): the paper's model of eq. (1) with fixed-step RK4,
//! split at every spool edge, and the end stops — or, when the sheet gives effects beyond the paper,
//! [`crate::extended`]'s step. The model's parameters and state are in [`crate::mechanics`].

use crate::actuator::{ChamberState, ChamberStep, Chambers};
use crate::lanes::{Pack, Real};
use crate::mechanics::{Friction, OneDofModel, OneDofState, smooth_coulomb};
use crate::regulator::{PressureRegulator, RegulatedStep};

/// What stays constant over one step of [`OneDofModel::step`].
struct StepConsts<'a, C: Chambers> {
    /// Chamber-equation constants for the held spool (or the regulators' set-points).
    chambers: &'a C,
    /// G_alpha + f_ext, N.
    f_load: f64,
    /// 1 / m, 1/kg.
    inv_mass: f64,
}

#[derive(Clone, Copy)]
struct Deriv {
    x: f64,
    v: f64,
    c: ChamberState,
}

impl OneDofModel {
    #[inline(always)]
    fn rates<C: Chambers>(&self, k: &StepConsts<C>, x: f64, v: f64, c: &ChamberState) -> Deriv {
        let m = &self.mechanics;
        let cs = &k.chambers;
        let drive = cs.piston_force(c) + k.f_load;
        // eq. (1): m x'' = F_1 - F_2 + G_alpha - f - K_v x'.
        let a = (drive - m.friction.force(v, drive) - m.viscous_n_s_per_m * v) * k.inv_mass;
        Deriv {
            x: v,
            v: a,
            c: cs.rates(c, x, v),
        }
    }

    /// One classic RK4 step of length `dt` from `(x0, v0, c0)` with the constants `k` held.
    #[inline(always)]
    fn rk4<C: Chambers>(
        &self,
        k: &StepConsts<C>,
        x0: f64,
        v0: f64,
        c0: ChamberState,
        dt: f64,
    ) -> (f64, f64, ChamberState) {
        let h = 0.5 * dt;
        let k1 = self.rates(k, x0, v0, &c0);
        let k2 = self.stage(k, x0, v0, &c0, h, &k1);
        let k3 = self.stage(k, x0, v0, &c0, h, &k2);
        let k4 = self.stage(k, x0, v0, &c0, dt, &k3);
        rk4_sum(x0, v0, c0, dt, [&k1, &k2, &k3, &k4])
    }

    /// An RK4 stage: the rates at `(x0, v0, c0) + h * prev`.
    #[inline(always)]
    fn stage<C: Chambers>(
        &self,
        k: &StepConsts<C>,
        x0: f64,
        v0: f64,
        c0: &ChamberState,
        h: f64,
        prev: &Deriv,
    ) -> Deriv {
        self.rates(k, x0 + h * prev.x, v0 + h * prev.v, &axpy(c0, h, &prev.c))
    }

    /// Advances the model by one fixed step `dt` under valve command `u` in [-1, 1] and external force
    /// `f_ext` (N, along +x), with classic RK4. The step is split at every spool edge inside it
    /// ([`crate::ValveModel::segment`]: the PWM edges of an on/off valve, delayed by the switching delay):
    /// RK4 up to the edge with the spool before it, then on from the edge with the spool after it, so the
    /// result converges with `dt` (for the proportional valve: one RK4 step with the spool held). The end
    /// stops are hard (inelastic) and applied after the step. Allocation-free.
    pub fn step(&self, state: &mut OneDofState, u: f64, f_ext: f64, dt: f64) {
        self.step_with_gravity(state, u, f_ext, self.mechanics.gravity_force(), dt);
    }

    /// [`Self::step`] with the gravity component G_alpha = m g sin(alpha) (N, eq. 1) given: a caller that
    /// steps many substeps at one incline computes the sine once, not once per substep (it was 4 % of the
    /// main job's CPU). `gravity_n` must be [`Mechanics::gravity_force`] for the result to be [`Self::step`]'s.
    pub fn step_with_gravity(
        &self,
        state: &mut OneDofState,
        u: f64,
        f_ext: f64,
        gravity_n: f64,
        dt: f64,
    ) {
        if !self.is_paper_model() {
            return crate::extended::step(self, state, u, f_ext, gravity_n, dt);
        }
        let inv_mass = 1.0 / self.mechanics.moving_mass_kg;
        let mut held = Held::NONE;
        self.paper_step(state, u, f_ext, gravity_n, inv_mass, dt, &mut held);
    }

    /// `substeps` steps of [`Self::step_with_gravity`], each `dt / substeps` long, the external force
    /// `f_ext(x)` (N) evaluated at the start of each and held over it: a control period of a plant that
    /// substeps. The result is bit-for-bit that of the steps taken one by one; the chamber constants of a
    /// spool position are evaluated once for the period rather than once per substep.
    pub fn advance(
        &self,
        state: &mut OneDofState,
        u: f64,
        gravity_n: f64,
        dt: f64,
        substeps: u32,
        mut f_ext: impl FnMut(f64) -> f64,
    ) {
        let h = dt / f64::from(substeps.max(1));
        if !self.is_paper_model() {
            let mut stepper = crate::extended::Stepper::new(self);
            for _ in 0..substeps.max(1) {
                let f = f_ext(state.x);
                stepper.step(state, u, gravity_n + f, h);
            }
            return;
        }
        let inv_mass = 1.0 / self.mechanics.moving_mass_kg;
        let mut held = Held::NONE;
        for _ in 0..substeps.max(1) {
            let f = f_ext(state.x);
            self.paper_step(state, u, f, gravity_n, inv_mass, h, &mut held);
        }
    }

    /// [`Self::advance`] behind a pressure regulator in front of each chamber ([`crate::regulator`], the valve's
    /// paths fully open as its flow limits) at set-points `set_pa` (A, B; Pa absolute) in place of the valve:
    /// `substeps` RK4 steps of eq. (1) and the chambers, `f_ext(x)` evaluated at the start of each and held
    /// over it, with the end stops and the sticking of [`Self::step`]. The valve's state is not touched. The
    /// paper's model only: a model with effects beyond it ([`Self::is_paper_model`] false) is integrated
    /// without them, so a host refuses it where it fits the regulators.
    #[allow(clippy::too_many_arguments)]
    pub fn advance_regulated(
        &self,
        state: &mut OneDofState,
        reg: &PressureRegulator,
        set_pa: (f64, f64),
        gravity_n: f64,
        dt: f64,
        substeps: u32,
        mut f_ext: impl FnMut(f64) -> f64,
    ) {
        let h = dt / f64::from(substeps.max(1));
        let inv_mass = 1.0 / self.mechanics.moving_mass_kg;
        let chambers = RegulatedStep::new(&self.actuator, reg, set_pa.0, set_pa.1);
        let stroke = self.actuator.cylinder.stroke_m;
        for _ in 0..substeps.max(1) {
            let f_load = gravity_n + f_ext(state.x);
            let k = StepConsts {
                chambers: &chambers,
                f_load,
                inv_mass,
            };
            let (mut x, mut v, c) = self.rk4(&k, state.x, state.x_dot, state.chambers, h);
            // End stops and sticking as in `paper_step`.
            if x <= 0.0 {
                x = 0.0;
                v = v.max(0.0);
            } else if x >= stroke {
                x = stroke;
                v = v.min(0.0);
            }
            if let crate::mechanics::Friction::StickSlip {
                static_n,
                stick_velocity_m_per_s,
                ..
            } = self.mechanics.friction
                && v.abs() < stick_velocity_m_per_s
                && (chambers.piston_force(&c) + f_load).abs() <= static_n
            {
                v = 0.0;
            }
            state.x = x;
            state.x_dot = v;
            state.chambers = c;
            state.t += h;
        }
    }

    /// One step of the paper's model; `held` keeps, between calls, the chamber constants of the last
    /// spool position (they depend on nothing else) and how long the spool holds (while it does, the
    /// valve's [`crate::ValveModel::segment`] would change nothing and is not called).
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn paper_step(
        &self,
        state: &mut OneDofState,
        u: f64,
        f_ext: f64,
        gravity_n: f64,
        inv_mass: f64,
        dt: f64,
        held: &mut Held,
    ) {
        // f_load = G_alpha + f_ext is held over the step.
        let f_load = gravity_n + f_ext;
        let start = (state.x, state.x_dot, state.chambers);
        self.finish_step(
            state,
            u,
            f_load,
            inv_mass,
            dt,
            held,
            Some((state.t, dt)),
            start,
        );
    }

    /// The first piece of a step from `tau` with `rest` of it left: the spool held over it (its chamber
    /// constants put in `held`), the piece's length, and the spool edge that ends it before the step does.
    #[inline(always)]
    fn piece(
        &self,
        state: &mut OneDofState,
        u: f64,
        tau: f64,
        rest: f64,
        held: &mut Held,
    ) -> (f64, Option<f64>) {
        let valve = &self.actuator.valve;
        let (spool, edge) = if held.spool.covers(tau, rest) {
            (state.valve.spool, None)
        } else {
            let piece = valve.segment(&mut state.valve, u, tau, rest);
            held.spool = valve.hold(&state.valve, tau);
            piece
        };
        // The spool is held over the piece: openings, areas and flow constants are evaluated once.
        match &held.consts {
            Some((s, _)) if s.to_bits() == spool.to_bits() => {}
            _ => held.consts = Some((spool, self.actuator.step_consts(spool))),
        }
        (edge.map_or(rest, |e| e - tau), edge)
    }

    /// The rest of a step of length `dt` from `end` (x, x', chambers), its next piece starting at `next`
    /// (time, and how much of the step is left): RK4 over the pieces from there, then the end stops and the
    /// sticking; the state written. The whole step from its start, or what is left after a first piece
    /// ([`advance_together`]'s).
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn finish_step(
        &self,
        state: &mut OneDofState,
        u: f64,
        f_load: f64,
        inv_mass: f64,
        dt: f64,
        held: &mut Held,
        mut next: Option<(f64, f64)>,
        end: (f64, f64, ChamberState),
    ) {
        let (mut x, mut v, mut c) = end;
        let t_end = state.t + dt;
        while let Some((tau, rest)) = next {
            let (h, edge) = self.piece(state, u, tau, rest, held);
            let k = held.step_consts(f_load, inv_mass);
            (x, v, c) = self.rk4(&k, x, v, c, h);
            next = after(edge, t_end);
        }
        // End stops: inelastic, the stop absorbs any velocity into it.
        let stroke = self.actuator.cylinder.stroke_m;
        if x <= 0.0 {
            x = 0.0;
            v = v.max(0.0);
        } else if x >= stroke {
            x = stroke;
            v = v.min(0.0);
        }
        // Karnopp sticking: inside the band with the drive below break-away, the piston is at rest.
        if let crate::mechanics::Friction::StickSlip {
            static_n,
            stick_velocity_m_per_s,
            ..
        } = self.mechanics.friction
            && v.abs() < stick_velocity_m_per_s
            && held
                .consts
                .as_ref()
                .is_some_and(|(_, k)| (k.piston_force(&c) + f_load).abs() <= static_n)
        {
            v = 0.0;
        }
        state.x = x;
        state.x_dot = v;
        state.chambers = c;
        state.t += dt;
    }
}

/// Plants per pack of [`advance_together`]: eight f64, one AVX-512 register (two AVX2 ones).
pub const PACK: usize = 8;

/// [`PACK`] plants of the paper's model advanced together ([`advance_together`]).
pub struct Together<'a> {
    /// Each plant's model.
    pub models: [&'a OneDofModel; PACK],
    /// Each plant's state.
    pub states: [&'a mut OneDofState; PACK],
    /// Each plant's valve command in [-1, 1].
    pub u: [f64; PACK],
    /// Each plant's G_alpha = m g sin(alpha), N.
    pub gravity_n: [f64; PACK],
}

/// [`OneDofModel::advance`] of [`PACK`] plants over one control period `dt` in `substeps` steps, `f_ext(i, x)` the
/// external force on plant i (N) at the start of each substep: bit for bit the N calls of `advance` (the
/// same expressions, [`crate::lanes`]), with each RK4 stage computed for all N plants at once in packed
/// arithmetic (AVX-512 or AVX2 where the processor has them). The batched Gymnasium environment steps its plants so
/// (docs/gymnasium.md). Plants whose models have effects beyond the paper's, or different actuators (the
/// valve's timing aside), are advanced one by one. Not generic, so that it is compiled here, optimised as
/// this crate is, whatever the caller's profile (a generic is compiled in its caller's).
pub fn advance_together(
    plants: Together<'_>,
    dt: f64,
    substeps: u32,
    f_ext: &mut dyn FnMut(usize, f64) -> f64,
) {
    let m0 = plants.models[0];
    // One set of chamber constants for all of them but the paths' gains: the same actuator, every field but
    // the valve's timing (`valve.kind`, which only moves the spool's edges). Compared field by field: a
    // copy of each actuator to compare whole showed in a batched environment's profile.
    let same_circuit = |m: &OneDofModel| {
        let (a, b) = (&m.actuator, &m0.actuator);
        let crate::Actuator {
            cylinder,
            gas,
            valve,
            supply,
        } = a;
        let crate::ValveModel {
            orifice,
            paths,
            underlap,
            kind: _,
        } = valve;
        *cylinder == b.cylinder
            && *gas == b.gas
            && *supply == b.supply
            && *orifice == b.valve.orifice
            && *paths == b.valve.paths
            && *underlap == b.valve.underlap
    };
    if plants
        .models
        .iter()
        .any(|m| !m.is_paper_model() || !same_circuit(m))
    {
        let Together {
            models,
            mut states,
            u,
            gravity_n,
        } = plants;
        for (i, (m, s)) in models.iter().zip(states.iter_mut()).enumerate() {
            m.advance(s, u[i], gravity_n[i], dt, substeps, |x| f_ext(i, x));
        }
        return;
    }
    #[cfg(target_arch = "x86_64")]
    {
        // SAFETY (both): the processor has the instructions (checked on the same line).
        if std::is_x86_feature_detected!("avx512f") {
            unsafe { packed_avx512(plants, dt, substeps, f_ext) };
            return;
        }
        if std::is_x86_feature_detected!("avx2") {
            unsafe { packed_avx2(plants, dt, substeps, f_ext) };
            return;
        }
    }
    packed(plants, dt, substeps, f_ext);
}

/// [`packed`] compiled for AVX-512 (eight plants per instruction).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
unsafe fn packed_avx512(
    plants: Together<'_>,
    dt: f64,
    substeps: u32,
    f_ext: &mut dyn FnMut(usize, f64) -> f64,
) {
    packed(plants, dt, substeps, f_ext);
}

/// [`packed`] compiled for AVX2 (four plants per instruction).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn packed_avx2(
    plants: Together<'_>,
    dt: f64,
    substeps: u32,
    f_ext: &mut dyn FnMut(usize, f64) -> f64,
) {
    packed(plants, dt, substeps, f_ext);
}

/// The substeps of [`advance_together`]: per plant its spool's pieces ([`OneDofModel::piece`]); the first
/// piece's RK4 for all plants at once; the pieces after an edge, the end stops and the sticking per plant
/// ([`OneDofModel::finish_step`]).
#[inline(always)]
fn packed(plants: Together<'_>, dt: f64, substeps: u32, f_ext: &mut dyn FnMut(usize, f64) -> f64) {
    let Together {
        models,
        mut states,
        u,
        gravity_n,
    } = plants;
    let h = dt / f64::from(substeps.max(1));
    let inv_mass = models.map(|m| 1.0 / m.mechanics.moving_mass_kg);
    let viscous = Pack(models.map(|m| m.mechanics.viscous_n_s_per_m));
    let mut smooth = Some((Pack([0.0; PACK]), Pack([0.0; PACK])));
    for (i, m) in models.iter().enumerate() {
        match (m.mechanics.friction, &mut smooth) {
            (
                Friction::Smooth {
                    coulomb_n,
                    smooth_velocity_m_per_s,
                },
                Some((c, inv_v_s)),
            ) => (c.0[i], inv_v_s.0[i]) = (coulomb_n, 1.0 / smooth_velocity_m_per_s),
            _ => smooth = None,
        }
    }
    let mut held: [Held; PACK] = core::array::from_fn(|_| Held::NONE);
    for _ in 0..substeps.max(1) {
        let mut f_load = [0.0; PACK];
        let mut pieces = [(0.0, None); PACK];
        for i in 0..PACK {
            f_load[i] = gravity_n[i] + f_ext(i, states[i].x);
            let t = states[i].t;
            pieces[i] = models[i].piece(states[i], u[i], t, h, &mut held[i]);
        }
        let chambers = held.each_ref().map(|k| k.step_consts(0.0, 0.0).chambers);
        let shared = chambers[0];
        let gains = [
            Pack(chambers.map(|c| c.k_pa)),
            Pack(chambers.map(|c| c.k_ar)),
            Pack(chambers.map(|c| c.k_pb)),
            Pack(chambers.map(|c| c.k_br)),
        ];
        let (load, inv_m) = (Pack(f_load), Pack(inv_mass));
        let start = Point {
            x: Pack(states.each_ref().map(|s| s.x)),
            v: Pack(states.each_ref().map(|s| s.x_dot)),
            c: [
                Pack(states.each_ref().map(|s| s.chambers.p_a)),
                Pack(states.each_ref().map(|s| s.chambers.p_b)),
                Pack(states.each_ref().map(|s| s.chambers.t_a)),
                Pack(states.each_ref().map(|s| s.chambers.t_b)),
            ],
        };
        let mut dt = [0.0; PACK];
        for i in 0..PACK {
            dt[i] = pieces[i].0;
        }
        let rates = PackRates {
            models: &models,
            shared,
            gains,
            load,
            viscous,
            inv_mass: inv_m,
            smooth,
        };
        let end = rk4_point(&start, Pack(dt), &rates);
        for (i, state) in states.iter_mut().enumerate() {
            let t_end = state.t + h;
            let c = ChamberState {
                p_a: end.c[0].0[i],
                p_b: end.c[1].0[i],
                t_a: end.c[2].0[i],
                t_b: end.c[3].0[i],
            };
            let piece_end = (end.x.0[i], end.v.0[i], c);
            models[i].finish_step(
                state,
                u[i],
                f_load[i],
                inv_mass[i],
                h,
                &mut held[i],
                after(pieces[i].1, t_end),
                piece_end,
            );
        }
    }
}

/// The rates of N plants at a point ([`OneDofModel::rates`] lane by lane): eq. (1) with each plant's
/// friction, and the chambers with the shared constants and each plant's gains.
struct PackRates<'a, const N: usize> {
    models: &'a [&'a OneDofModel; N],
    shared: &'a ChamberStep,
    gains: [Pack<N>; 4],
    load: Pack<N>,
    viscous: Pack<N>,
    inv_mass: Pack<N>,
    /// F_c and 1 / v_s when every plant's friction is [`Friction::Smooth`] (then computed packed, else per
    /// plant).
    smooth: Option<(Pack<N>, Pack<N>)>,
}

/// The rates of a point (what RK4 steps).
trait Rates<R> {
    fn at(&self, p: &Point<R>) -> Point<R>;
}

impl<const N: usize> Rates<Pack<N>> for PackRates<'_, N> {
    #[inline(always)]
    fn at(&self, p: &Point<Pack<N>>) -> Point<Pack<N>> {
        let drive = self.shared.force_of(p.c[0], p.c[1]) + self.load;
        let friction = match self.smooth {
            Some((coulomb, inv_smooth_velocity)) => {
                smooth_coulomb(coulomb, inv_smooth_velocity, p.v)
            }
            None => {
                let mut each = [0.0; N];
                for (i, f) in each.iter_mut().enumerate() {
                    *f = self.models[i]
                        .mechanics
                        .friction
                        .force(p.v.0[i], drive.0[i]);
                }
                Pack(each)
            }
        };
        Point {
            x: p.v,
            // eq. (1), as `OneDofModel::rates`.
            v: (drive - friction - self.viscous * p.v) * self.inv_mass,
            c: self.shared.rates_of(self.gains, p.c, p.x, p.v),
        }
    }
}

/// A point of eq. (1) and the chambers: x, x' and [p_a, p_b, t_a, t_b] (of a plant, or a pack of them).
#[derive(Clone, Copy)]
struct Point<R> {
    x: R,
    v: R,
    c: [R; 4],
}

impl<R: Real> Point<R> {
    /// `self + h d`, the argument of an RK4 stage.
    #[inline(always)]
    fn ahead(&self, h: R, d: &Self) -> Self {
        Point {
            x: self.x + h * d.x,
            v: self.v + h * d.v,
            c: [
                self.c[0] + h * d.c[0],
                self.c[1] + h * d.c[1],
                self.c[2] + h * d.c[2],
                self.c[3] + h * d.c[3],
            ],
        }
    }
}

/// RK4's weighted stage sum `a + 2 b + 2 c + d`.
#[inline(always)]
fn stage_sum<R: Real>(a: R, b: R, c: R, d: R) -> R {
    let two = R::splat(2.0);
    a + two * b + two * c + d
}

/// One classic RK4 step of length `dt` from `p0` with the rates `f` (the expressions of
/// [`OneDofModel::rk4`], lane by lane).
#[inline(always)]
fn rk4_point<R: Real>(p0: &Point<R>, dt: R, f: &impl Rates<R>) -> Point<R> {
    let h = R::splat(0.5) * dt;
    let k1 = f.at(p0);
    let k2 = f.at(&p0.ahead(h, &k1));
    let k3 = f.at(&p0.ahead(h, &k2));
    let k4 = f.at(&p0.ahead(dt, &k3));
    let w = dt / R::splat(6.0);
    let c = |j: usize| p0.c[j] + w * stage_sum(k1.c[j], k2.c[j], k3.c[j], k4.c[j]);
    Point {
        x: p0.x + w * stage_sum(k1.x, k2.x, k3.x, k4.x),
        v: p0.v + w * stage_sum(k1.v, k2.v, k3.v, k4.v),
        c: [c(0), c(1), c(2), c(3)],
    }
}

/// The piece after one that ended at `edge` (its time, and the step left after it), if the step goes on.
#[inline(always)]
fn after(edge: Option<f64>, t_end: f64) -> Option<(f64, f64)> {
    match edge {
        Some(e) if e < t_end => Some((e, t_end - e)),
        _ => None,
    }
}

/// What [`OneDofModel::paper_step`] carries from one step to the next within a control period.
struct Held {
    /// The chamber constants of the last spool position.
    consts: Option<(f64, ChamberStep)>,
    /// How long the spool holds after the last call of the valve.
    spool: crate::SpoolHold,
}

impl Held {
    const NONE: Self = Self {
        consts: None,
        spool: crate::SpoolHold::NONE,
    };

    /// The step's constants with the held spool's chambers ([`OneDofModel::piece`] put them there).
    #[inline(always)]
    fn step_consts(&self, f_load: f64, inv_mass: f64) -> StepConsts<'_, ChamberStep> {
        let chambers = match &self.consts {
            Some((_, k)) => k,
            None => unreachable!("a piece holds its spool's constants"),
        };
        StepConsts {
            chambers,
            f_load,
            inv_mass,
        }
    }
}

/// RK4's weighted sum of the stages `k` over a step `dt` from `(x0, v0, c0)`.
#[inline(always)]
fn rk4_sum(
    x0: f64,
    v0: f64,
    c0: ChamberState,
    dt: f64,
    k: [&Deriv; 4],
) -> (f64, f64, ChamberState) {
    let [k1, k2, k3, k4] = k;
    let w = dt / 6.0;
    let x = x0 + w * (k1.x + 2.0 * k2.x + 2.0 * k3.x + k4.x);
    let v = v0 + w * (k1.v + 2.0 * k2.v + 2.0 * k3.v + k4.v);
    let mut c = c0;
    c.p_a += w * (k1.c.p_a + 2.0 * k2.c.p_a + 2.0 * k3.c.p_a + k4.c.p_a);
    c.p_b += w * (k1.c.p_b + 2.0 * k2.c.p_b + 2.0 * k3.c.p_b + k4.c.p_b);
    c.t_a += w * (k1.c.t_a + 2.0 * k2.c.t_a + 2.0 * k3.c.t_a + k4.c.t_a);
    c.t_b += w * (k1.c.t_b + 2.0 * k2.c.t_b + 2.0 * k3.c.t_b + k4.c.t_b);
    (x, v, c)
}

#[inline]
fn axpy(c: &ChamberState, h: f64, d: &ChamberState) -> ChamberState {
    ChamberState {
        p_a: c.p_a + h * d.p_a,
        p_b: c.p_b + h * d.p_b,
        t_a: c.t_a + h * d.t_a,
        t_b: c.t_b + h * d.t_b,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The packed step compiled for the baseline instruction set (what a processor without AVX2 runs;
    /// `tests/advance_together.rs` checks the one this processor dispatches to) is each plant's own step.
    #[test]
    fn the_baseline_packed_step_is_each_plants_own() {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../pneumatics/paper-actuator.toml");
        let base = crate::ActuatorSheet::load(path)
            .expect("shipped sheet")
            .model();
        let models: [OneDofModel; 8] = core::array::from_fn(|i| {
            let mut m = base;
            m.mechanics.moving_mass_kg *= 0.7 + 0.1 * i as f64;
            m
        });
        let start = OneDofState::at_rest(0.025, ChamberState::new(3.0e5, 2.8e5), 0.0);
        let (mut alone, mut packed_states) = ([start; 8], [start; 8]);
        let spring = |x: f64| -900.0 * (x - 0.03).max(0.0);
        let gravity = models.map(|m| m.mechanics.gravity_force());
        for k in 0..400u64 {
            let u: [f64; 8] = core::array::from_fn(|i| {
                if (k / 30 + i as u64).is_multiple_of(3) {
                    0.4
                } else {
                    -0.2
                }
            });
            for (i, (m, s)) in models.iter().zip(alone.iter_mut()).enumerate() {
                m.advance(s, u[i], gravity[i], 1e-3, 10, spring);
            }
            let plants = Together {
                models: core::array::from_fn(|i| &models[i]),
                states: packed_states.each_mut(),
                u,
                gravity_n: gravity,
            };
            packed(plants, 1e-3, 10, &mut |_, x| spring(x));
            for i in 0..8 {
                assert_eq!(
                    format!("{:?}", alone[i]),
                    format!("{:?}", packed_states[i]),
                    "plant {i}, period {k}"
                );
            }
        }
    }
}
