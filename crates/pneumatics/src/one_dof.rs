//! The step of the 1-DOF model ([`OneDofModel::step`]): the paper's model of eq. (1) with fixed-step RK4,
//! split at every spool edge, and the end stops — or, when the sheet gives effects beyond the paper,
//! [`crate::extended`]'s step. The model's parameters and state are in [`crate::mechanics`].

use crate::actuator::{ChamberState, ChamberStep, Chambers};
use crate::mechanics::{OneDofModel, OneDofState};
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
        let k2 = self.rates(k, x0 + h * k1.x, v0 + h * k1.v, &axpy(&c0, h, &k1.c));
        let k3 = self.rates(k, x0 + h * k2.x, v0 + h * k2.v, &axpy(&c0, h, &k2.c));
        let k4 = self.rates(k, x0 + dt * k3.x, v0 + dt * k3.v, &axpy(&c0, dt, &k3.c));
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
        let (mut x, mut v, mut c) = (state.x, state.x_dot, state.chambers);
        let t_end = state.t + dt;
        let (mut tau, mut rest) = (state.t, dt);
        loop {
            let valve = &self.actuator.valve;
            let (spool, edge) = if held.spool.covers(tau, rest) {
                (state.valve.spool, None)
            } else {
                let piece = valve.segment(&mut state.valve, u, tau, rest);
                held.spool = valve.hold(&state.valve, tau);
                piece
            };
            // The spool is held over the piece: openings, areas and flow constants are evaluated once.
            let consts = match &mut held.consts {
                Some((s, k)) if s.to_bits() == spool.to_bits() => k,
                consts => &mut consts.insert((spool, self.actuator.step_consts(spool))).1,
            };
            let k = StepConsts {
                chambers: consts,
                f_load,
                inv_mass,
            };
            let h = edge.map_or(rest, |e| e - tau);
            (x, v, c) = self.rk4(&k, x, v, c, h);
            match edge {
                Some(e) if e < t_end => {
                    tau = e;
                    rest = t_end - e;
                }
                _ => break,
            }
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
