//! The 1-DOF model with the effects beyond the paper (issue 26, [`crate::Effects`]), integrated like the
//! paper's model (classic RK4, the step split where the spool's schedule changes) on the state
//! `(x, x', p_a, p_b, T_a, T_b, p_la, T_la, p_lb, T_lb, z)`: the lines' gas and the LuGre bristle
//! deflection on top of the paper's state.
//!
//! Every gas node (chamber or line) obeys the energy and mass balance of an ideal gas with exponent n
//! (eqs. 2-3, 9-10 generalised), with the wall heat Q' (W) added to the energy balance:
//!
//! ```text
//! dp/dt = n/V (R H - p V') + (n - 1)/V Q'      (U = p V/(k-1), dU/dt = c_p H - p V' + Q', n = k)
//! dT/dt = (T/p) (p' + (p V' - R T M')/V)       (M = p V/(R T) changes by the net inflow M')
//! Q'    = h A_w (T_w - T)                      (Newton cooling)
//! A_w,a = 2 S_a + pi D (x + V_a0/S_a),   A_w,b = 2 S_b + pi (D + d) (L - x + V_b0/S_b)
//! ```
//!
//! The wall area is that of the chamber as a cylinder (an annulus on the rod side) of its own volume: both
//! end faces and the barrel, the dead volume counted as barrel length (tubing's own wall is not in it: an
//! effective h absorbs it). With the wall heat, n must be the heat-capacity ratio k (1.4 for air): the
//! balance is then adiabatic at h = 0 and isothermal (T -> T_w) for h A_w much larger than M c_v's rate.
//!
//! Flows: the valve's paths connect the supply and the exhaust to the valve-side nodes (the lines, or the
//! chambers without lines); each line reaches its chamber through its own ISO 6358 restriction; the leaks
//! are ISO 6358 restrictions between A and B and from each chamber to the atmosphere (eq. 11 for every one,
//! the upstream node's temperature). Friction: the sheet's law with `F_c` (and `F_s`) raised by
//! `k_p |p_a - p_b|`, or LuGre ([`crate::Friction::LuGre`]).

use crate::actuator::{Actuator, ChamberState, ChamberStep, P_FLOOR, T_FLOOR};
use crate::flow::{ISO_T0_K, OrificeStep};
use crate::mechanics::{Friction, OneDofModel, OneDofState};
use crate::spool::{self, SpoolLaw, Timing};

/// Wall-heat constants of a step.
#[derive(Clone, Copy)]
struct Heat {
    /// h, W/(m^2 K).
    h: f64,
    /// T_w, K.
    tw: f64,
    /// End faces of A and B, 2 S_a and 2 S_b, m^2.
    faces: (f64, f64),
    /// Wetted perimeters of A and B, pi D and pi (D + d), m.
    perimeter: (f64, f64),
    /// Barrel lengths of the dead volumes, V_a0/S_a and V_b0/S_b, m.
    dead_length: (f64, f64),
    /// Stroke L, m.
    stroke: f64,
}

impl Heat {
    /// Heat flows into A and B, W, at extension `x` and gas temperatures `ta`, `tb`.
    #[inline(always)]
    fn inflows(&self, x: f64, ta: f64, tb: f64) -> (f64, f64) {
        let xc = x.clamp(0.0, self.stroke);
        let area_a = self.faces.0 + self.perimeter.0 * (xc + self.dead_length.0);
        let area_b = self.faces.1 + self.perimeter.1 * (self.stroke - xc + self.dead_length.1);
        (
            self.h * area_a * (self.tw - ta),
            self.h * area_b * (self.tw - tb),
        )
    }
}

/// An ISO 6358 restriction's step constants and its full-opening gain C rho0 (kg/(s Pa)).
type Restriction = (OrificeStep, f64);

/// What stays constant over one step.
struct Fixed {
    heat: Option<Heat>,
    /// Leaks piston, A -> atmosphere, B -> atmosphere.
    leaks: [Option<Restriction>; 3],
    /// The lines' restriction and 1 / V_line.
    line: Option<(Restriction, f64)>,
    /// k_p, N/Pa (0 without the pressure term).
    k_p: f64,
    /// F_c- - F_c, N: what the Coulomb and break-away forces gain for motion towards -x (0: symmetric).
    negative_shift: f64,
    /// G_alpha + f_ext, N.
    f_load: f64,
    /// 1 / m, 1/kg.
    inv_mass: f64,
}

impl Fixed {
    fn new(m: &OneDofModel, f_load: f64) -> Self {
        let e = &m.effects;
        let c = &m.actuator.cylinder;
        let restriction = |o: &crate::Orifice| {
            let s = OrificeStep::new(o);
            (s, s.gain(1.0))
        };
        let pi = core::f64::consts::PI;
        Self {
            heat: e
                .wall_heat
                .filter(|w| w.coefficient_w_per_m2_k > 0.0)
                .map(|w| Heat {
                    h: w.coefficient_w_per_m2_k,
                    tw: w.wall_temperature_k,
                    faces: (2.0 * c.area_a(), 2.0 * c.area_b()),
                    perimeter: (pi * c.bore_m, pi * (c.bore_m + c.rod_m)),
                    dead_length: (
                        c.dead_volume_a_m3 / c.area_a(),
                        c.dead_volume_b_m3 / c.area_b(),
                    ),
                    stroke: c.stroke_m,
                }),
            leaks: std::array::from_fn(|i| e.leaks.get(i).map(|o| restriction(&o))),
            line: e
                .lines
                .map(|l| (restriction(&l.orifice), 1.0 / l.volume_m3)),
            k_p: e.coulomb_pressure_n_per_pa.unwrap_or(0.0),
            negative_shift: e
                .coulomb_negative_n
                .map_or(0.0, |n| n - m.mechanics.friction.coulomb_n()),
            f_load,
            inv_mass: 1.0 / m.mechanics.moving_mass_kg,
        }
    }
}

/// The full state integrated by RK4.
#[derive(Clone, Copy)]
struct Full {
    x: f64,
    v: f64,
    c: ChamberState,
    /// The lines (unused without lines).
    l: ChamberState,
    z: f64,
}

impl Full {
    #[inline(always)]
    fn axpy(&self, h: f64, d: &Self) -> Self {
        Self {
            x: self.x + h * d.x,
            v: self.v + h * d.v,
            c: axpy(&self.c, h, &d.c),
            l: axpy(&self.l, h, &d.l),
            z: self.z + h * d.z,
        }
    }
}

#[inline(always)]
fn axpy(c: &ChamberState, h: f64, d: &ChamberState) -> ChamberState {
    ChamberState {
        p_a: c.p_a + h * d.p_a,
        p_b: c.p_b + h * d.p_b,
        t_a: c.t_a + h * d.t_a,
        t_b: c.t_b + h * d.t_b,
    }
}

/// The chamber constants along one piece: held, or rebuilt from the spool's law at each stage.
struct PieceSpool<'a> {
    actuator: &'a Actuator,
    law: SpoolLaw,
    held: Option<ChamberStep>,
}

impl<'a> PieceSpool<'a> {
    /// The piece of `law`; a held spool's constants come from `last` when it holds the same position (they
    /// depend on the spool alone), and are kept there.
    fn new(actuator: &'a Actuator, law: SpoolLaw, last: &mut Option<(f64, ChamberStep)>) -> Self {
        let held = law.is_held().then(|| {
            let spool = law.at(0.0);
            match last {
                Some((at, cs)) if at.to_bits() == spool.to_bits() => *cs,
                _ => {
                    let cs = actuator.step_consts(spool);
                    *last = Some((spool, cs));
                    cs
                }
            }
        });
        Self {
            actuator,
            law,
            held,
        }
    }
    #[inline(always)]
    fn at(&self, t: f64) -> ChamberStep {
        match self.held {
            Some(cs) => cs,
            None => self.actuator.step_consts(self.law.at(t)),
        }
    }
}

/// Signed flow node 1 -> node 2 (kg/s) through a restriction of gain `k`, and its enthalpy carrier
/// q T_upstream (kg K/s), eq. (11).
#[inline(always)]
fn between(r: &Restriction, p1: f64, t1: f64, p2: f64, t2: f64) -> (f64, f64) {
    let (or, k) = r;
    if p1 >= p2 {
        let q = or.flow(*k, ISO_T0_K / t1, p1, p2);
        (q, q * t1)
    } else {
        let q = or.flow(*k, ISO_T0_K / t2, p2, p1);
        (-q, -q * t2)
    }
}

/// Pressure and temperature rates of a gas node (module doc): volume 1/`inv_v`, volume rate `dv`, net mass
/// inflow `m_in`, enthalpy carrier `h_in`, heat inflow `q_heat`.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn node(
    n: f64,
    r: f64,
    p: f64,
    t: f64,
    inv_v: f64,
    dv: f64,
    m_in: f64,
    h_in: f64,
    q_heat: f64,
) -> (f64, f64) {
    // eq. (9)/(10): dp/dt = n/V (R H - p V'), and the wall heat (n - 1) Q'/V.
    let mut dp = n * inv_v * (r * h_in - p * dv);
    if q_heat != 0.0 {
        dp += (n - 1.0) * inv_v * q_heat;
    }
    // eqs. (2)-(3): M = pV/(RT), dM/dt = M'.
    let dt = t / p * (dp + inv_v * (p * dv - r * t * m_in));
    (dp, dt)
}

/// The friction law at chambers `c` for motion towards -x (`negative`) or +x: the sheet's, its forces
/// raised by the pressure term `k_p |p_a - p_b|` and, towards -x, by `F_c- - F_c`.
#[inline(always)]
fn law_at(f: &Friction, fx: &Fixed, c: &ChamberState, negative: bool) -> Friction {
    let extra = if fx.k_p > 0.0 {
        fx.k_p * (c.p_a - c.p_b).abs()
    } else {
        0.0
    } + if negative { fx.negative_shift } else { 0.0 };
    if extra != 0.0 {
        f.with_normal_force(extra)
    } else {
        *f
    }
}

/// Friction force and bristle rate at velocity `v`, drive `drive`, chambers `c` and deflection `z`. The
/// direction is the velocity's (the drive's at rest, where Karnopp's sticking force balances it).
#[inline(always)]
fn friction(f: &Friction, fx: &Fixed, c: &ChamberState, v: f64, drive: f64, z: f64) -> (f64, f64) {
    let negative = if v != 0.0 { v < 0.0 } else { drive < 0.0 };
    let law = law_at(f, fx, c, negative);
    law.lugre(v, z)
        .unwrap_or_else(|| (law.force(v, drive), 0.0))
}

/// Rates of the full state.
#[inline(always)]
fn rates(m: &OneDofModel, f: &Fixed, cs: &ChamberStep, s: &Full) -> Full {
    let (n, r) = (cs.n, cs.r);
    let floor = |c: &ChamberState| {
        (
            c.p_a.max(P_FLOOR),
            c.t_a.max(T_FLOOR),
            c.p_b.max(P_FLOOR),
            c.t_b.max(T_FLOOR),
        )
    };
    let (pa, ta, pb, tb) = floor(&s.c);
    // The valve feeds the lines, or the chambers without lines.
    let (pf, (ha, hb)) = cs.flows_enthalpy(if f.line.is_some() { &s.l } else { &s.c });
    let (mut ma, mut ea, mut mb, mut eb) = (pf.into_a(), ha, pf.into_b(), hb);
    let mut dl = ChamberState::with_temperature(0.0, 0.0, 0.0);
    if let Some((line, inv_vl)) = &f.line {
        let (pla, tla, plb, tlb) = floor(&s.l);
        let (qa, qta) = between(line, pla, tla, pa, ta);
        let (qb, qtb) = between(line, plb, tlb, pb, tb);
        (dl.p_a, dl.t_a) = node(n, r, pla, tla, *inv_vl, 0.0, ma - qa, ea - qta, 0.0);
        (dl.p_b, dl.t_b) = node(n, r, plb, tlb, *inv_vl, 0.0, mb - qb, eb - qtb, 0.0);
        (ma, ea, mb, eb) = (qa, qta, qb, qtb);
    }
    if let Some(leak) = &f.leaks[0] {
        let (q, qt) = between(leak, pa, ta, pb, tb);
        (ma, ea, mb, eb) = (ma - q, ea - qt, mb + q, eb + qt);
    }
    if let Some(leak) = &f.leaks[1] {
        let (q, qt) = between(leak, pa, ta, cs.pr, cs.tr);
        (ma, ea) = (ma - q, ea - qt);
    }
    if let Some(leak) = &f.leaks[2] {
        let (q, qt) = between(leak, pb, tb, cs.pr, cs.tr);
        (mb, eb) = (mb - q, eb - qt);
    }
    let (va, vb, dva, dvb) = cs.volumes(s.x, s.v);
    let (qa_heat, qb_heat) = f.heat.map_or((0.0, 0.0), |h| h.inflows(s.x, ta, tb));
    let (dpa, dta) = node(n, r, pa, ta, 1.0 / va, dva, ma, ea, qa_heat);
    let (dpb, dtb) = node(n, r, pb, tb, 1.0 / vb, dvb, mb, eb, qb_heat);
    // eq. (1): m x'' = F_1 - F_2 + G_alpha - f - K_v x'.
    let mech = &m.mechanics;
    let drive = cs.piston_force(&s.c) + f.f_load;
    let (fr, dz) = friction(&mech.friction, f, &s.c, s.v, drive, s.z);
    Full {
        x: s.v,
        v: (drive - fr - mech.viscous_n_s_per_m * s.v) * f.inv_mass,
        c: ChamberState {
            p_a: dpa,
            p_b: dpb,
            t_a: dta,
            t_b: dtb,
        },
        l: dl,
        z: dz,
    }
}

/// One classic RK4 step of length `dt` from `s0` at time `t`. LuGre's bristles are not RK4's: each stage,
/// and the step's end, takes z from the exact solution of its linear ODE with the velocity held
/// ([`Friction::lugre_bristle_after`]) over the displacement RK4 gives that stage (`tau k.x`, the velocity
/// that carried x there) and, at the end, over the step's own displacement; the stiff bristles
/// (sigma0 |v| / g up to 1e5 1/s at 1.6e5 N/m) then cannot make the step diverge.
fn rk4(m: &OneDofModel, f: &Fixed, sp: &PieceSpool, t: f64, s0: Full, dt: f64) -> Full {
    let h = 0.5 * dt;
    let lugre = matches!(m.mechanics.friction, Friction::LuGre { .. }).then(|| {
        (
            law_at(&m.mechanics.friction, f, &s0.c, false),
            law_at(&m.mechanics.friction, f, &s0.c, true),
        )
    });
    let bristle = |dx: f64, tau: f64| {
        lugre.map_or(s0.z, |(up, down)| {
            let law = if dx < 0.0 { down } else { up };
            law.lugre_bristle_after(s0.z, dx, tau).unwrap_or(s0.z)
        })
    };
    // The stage state at `tau` along `k`: RK4's, with the bristles' exact deflection.
    let stage = |tau: f64, k: &Full| {
        let mut s = s0.axpy(tau, k);
        if lugre.is_some() {
            s.z = bristle(tau * k.x, tau);
        }
        s
    };
    // The chamber constants by reference: a held spool's once for the four stages, a moving one's once per
    // stage time (k2 and k3 share t + h). They are ~40 numbers; copies of them were a tenth of a fit's time.
    let (k1, k2, k3, k4);
    if let Some(cs) = &sp.held {
        k1 = rates(m, f, cs, &s0);
        k2 = rates(m, f, cs, &stage(h, &k1));
        k3 = rates(m, f, cs, &stage(h, &k2));
        k4 = rates(m, f, cs, &stage(dt, &k3));
    } else {
        k1 = rates(m, f, &sp.at(t), &s0);
        let mid = sp.at(t + h);
        k2 = rates(m, f, &mid, &stage(h, &k1));
        k3 = rates(m, f, &mid, &stage(h, &k2));
        k4 = rates(m, f, &sp.at(t + dt), &stage(dt, &k3));
    }
    let w = dt / 6.0;
    let comb = |a: f64, b: f64, c: f64, d: f64, y: f64| y + w * (a + 2.0 * b + 2.0 * c + d);
    let chambers = |y: &ChamberState,
                    a: &ChamberState,
                    b: &ChamberState,
                    c: &ChamberState,
                    d: &ChamberState| {
        ChamberState {
            p_a: comb(a.p_a, b.p_a, c.p_a, d.p_a, y.p_a),
            p_b: comb(a.p_b, b.p_b, c.p_b, d.p_b, y.p_b),
            t_a: comb(a.t_a, b.t_a, c.t_a, d.t_a, y.t_a),
            t_b: comb(a.t_b, b.t_b, c.t_b, d.t_b, y.t_b),
        }
    };
    Full {
        x: comb(k1.x, k2.x, k3.x, k4.x, s0.x),
        v: comb(k1.v, k2.v, k3.v, k4.v, s0.v),
        c: chambers(&s0.c, &k1.c, &k2.c, &k3.c, &k4.c),
        l: chambers(&s0.l, &k1.l, &k2.l, &k3.l, &k4.l),
        z: if lugre.is_some() {
            bristle(w * (k1.x + 2.0 * k2.x + 2.0 * k3.x + k4.x), dt)
        } else {
            comb(k1.z, k2.z, k3.z, k4.z, s0.z)
        },
    }
}

/// [`OneDofModel::step_with_gravity`] for a model with effects: RK4 pieces between the spool's scheduled
/// moves ([`crate::spool`]), then the paper's end stops and Karnopp sticking (with the break-away force
/// raised by the pressure term).
pub(crate) fn step(
    model: &OneDofModel,
    state: &mut OneDofState,
    u: f64,
    f_ext: f64,
    gravity_n: f64,
    dt: f64,
) {
    Stepper::new(model).step(state, u, gravity_n + f_ext, dt);
}

/// What [`step`] needs of the model, made once for the substeps of a control period
/// ([`OneDofModel::advance`]): the spool's timing, the effects' constants, and the last held spool's chamber
/// constants. Its steps are bit for bit [`step`]'s.
pub(crate) struct Stepper<'a> {
    model: &'a OneDofModel,
    timing: Timing,
    fixed: Fixed,
    last: Option<(f64, ChamberStep)>,
}

impl<'a> Stepper<'a> {
    pub(crate) fn new(model: &'a OneDofModel) -> Self {
        Self {
            model,
            timing: Timing::of(&model.actuator.valve, &model.effects),
            fixed: Fixed::new(model, 0.0),
            last: None,
        }
    }

    /// One step of `dt` under the load `f_load` = G_alpha + f_ext (N).
    pub(crate) fn step(&mut self, state: &mut OneDofState, u: f64, f_load: f64, dt: f64) {
        self.fixed.f_load = f_load;
        step_with(
            self.model,
            &self.timing,
            &self.fixed,
            &mut self.last,
            state,
            u,
            dt,
        );
    }
}

fn step_with(
    model: &OneDofModel,
    timing: &Timing,
    fixed: &Fixed,
    last: &mut Option<(f64, ChamberStep)>,
    state: &mut OneDofState,
    u: f64,
    dt: f64,
) {
    let mut s = Full {
        x: state.x,
        v: state.x_dot,
        c: state.chambers,
        l: state.extra.lines.unwrap_or(state.chambers),
        z: state.extra.bristle_m,
    };
    let t_end = state.t + dt;
    let (mut tau, mut rest) = (state.t, dt);
    loop {
        let (law, edge) = spool::piece(timing, &mut state.valve, u, tau, rest);
        let h = edge.map_or(rest, |e| e - tau);
        let sp = PieceSpool::new(&model.actuator, law, last);
        s = rk4(model, fixed, &sp, tau, s, h);
        state.valve.spool = law.at(tau + h);
        match edge {
            Some(e) if e < t_end => {
                tau = e;
                rest = t_end - e;
            }
            _ => break,
        }
    }
    let stroke = model.actuator.cylinder.stroke_m;
    // End stops: inelastic, the stop absorbs any velocity into it.
    if s.x <= 0.0 {
        s.x = 0.0;
        s.v = s.v.max(0.0);
    } else if s.x >= stroke {
        s.x = stroke;
        s.v = s.v.min(0.0);
    }
    // Karnopp sticking: inside the band with the drive below break-away (raised by the pressure term).
    if let Friction::StickSlip {
        static_n,
        stick_velocity_m_per_s,
        ..
    } = model.mechanics.friction
    {
        let drive = model.actuator.piston_force(&s.c) + fixed.f_load;
        let break_away = static_n
            + fixed.k_p * (s.c.p_a - s.c.p_b).abs()
            + if drive < 0.0 {
                fixed.negative_shift
            } else {
                0.0
            };
        if s.v.abs() < stick_velocity_m_per_s && drive.abs() <= break_away {
            s.v = 0.0;
        }
    }
    state.x = s.x;
    state.x_dot = s.v;
    state.chambers = s.c;
    state.extra.lines = fixed.line.map(|_| s.l);
    state.extra.bristle_m = s.z;
    state.t += dt;
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{ActuatorSheet, ValveKind, ValveState};

    /// The shipped actuator with LuGre bristles of `sigma0` N/m (F_c 0.6 N, F_s 0.9 N, v_s 5 mm/s,
    /// sigma1 100 N s/m) and its valve shut (a proportional spool held at 0): the chambers are gas springs.
    fn lugre_model(sigma0: f64) -> OneDofModel {
        let sheet = ActuatorSheet::load(
            std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
                .join("../../pneumatics/paper-actuator.toml"),
        )
        .unwrap();
        let mut m = sheet.model();
        m.mechanics.friction = Friction::LuGre {
            coulomb_n: 0.6,
            static_n: 0.9,
            stribeck_velocity_m_per_s: 0.005,
            bristle_stiffness_n_per_m: sigma0,
            bristle_damping_n_s_per_m: 100.0,
        };
        m.actuator.valve.kind = ValveKind::Proportional {
            response_time_s: 0.0,
        };
        m.actuator.valve.underlap = 0.0;
        m
    }

    /// A 20 Hz external force of 30 N: the piston swings +-3 mm at up to 0.4 m/s and reverses every 25 ms
    /// (pre-sliding at each reversal, sigma0 |v| / g up to 1e5 1/s in between).
    fn f_ext(t: f64) -> f64 {
        30.0 * (2.0 * core::f64::consts::PI * 20.0 * t).sin()
    }

    const T_END: f64 = 0.1;

    /// Classic RK4 on every state, z included (the step before the exact bristles), with steps of `dt`.
    fn explicit(m: &OneDofModel, dt: f64) -> Full {
        let cs = m.actuator.step_consts(0.0);
        let gravity = m.mechanics.gravity_force();
        let c0 = ChamberState::new(3.0e5, 3.0e5);
        let mut s = Full {
            x: 0.025,
            v: 0.0,
            c: c0,
            l: c0,
            z: 0.0,
        };
        let steps = (T_END / dt).round() as usize;
        for i in 0..steps {
            let t = i as f64 * dt;
            let at = |tau: f64| Fixed::new(m, gravity + f_ext(tau));
            let (f0, fh, f1) = (at(t), at(t + 0.5 * dt), at(t + dt));
            let k1 = rates(m, &f0, &cs, &s);
            let k2 = rates(m, &fh, &cs, &s.axpy(0.5 * dt, &k1));
            let k3 = rates(m, &fh, &cs, &s.axpy(0.5 * dt, &k2));
            let k4 = rates(m, &f1, &cs, &s.axpy(dt, &k3));
            let w = dt / 6.0;
            s = s
                .axpy(w, &k1)
                .axpy(2.0 * w, &k2)
                .axpy(2.0 * w, &k3)
                .axpy(w, &k4);
        }
        s
    }

    /// The model's own step (exact bristles) with steps of `dt`, the force held over each step at its
    /// middle.
    fn stepped(m: &OneDofModel, dt: f64) -> OneDofState {
        let mut st = OneDofState::at_rest(0.025, ChamberState::new(3.0e5, 3.0e5), 0.0);
        st.valve = ValveState::at_spool(0.0);
        let steps = (T_END / dt).round() as usize;
        for i in 0..steps {
            let t = i as f64 * dt;
            step(
                m,
                &mut st,
                0.0,
                f_ext(t + 0.5 * dt),
                m.mechanics.gravity_force(),
                dt,
            );
        }
        st
    }

    /// The bristle step against the closed form at a constant velocity: `z(t) = z_ss + (z0 - z_ss)
    /// exp(-sigma0 |v| t / g(v))`, `z_ss = sign(v) g(v) / sigma0`, over one step of any length.
    #[test]
    fn the_bristle_step_is_the_closed_form_at_a_held_velocity() {
        let law = lugre_model(1.6e5).mechanics.friction;
        for (v, t, z0) in [
            (0.4, 1e-4, -5e-6),
            (-0.02, 3e-3, 2e-6),
            (1e-4, 1e-4, 0.0),
            (0.003, 0.01, 5.6e-6),
        ] {
            let g = 0.6 + 0.3 * (-(v / 0.005f64).powi(2)).exp();
            let z_ss = v.signum() * g / 1.6e5;
            let want = z_ss + (z0 - z_ss) * (-1.6e5 * v.abs() * t / g).exp();
            let got = law.lugre_bristle_after(z0, v * t, t).unwrap();
            assert!(
                (got - want).abs() < 1e-12 * z_ss.abs(),
                "v {v} t {t}: {got} vs {want}"
            );
        }
    }

    /// Stiff bristles (2e4 to 1.6e5 N/m, a real seal's, docs/identification.md) at the emulator's step of
    /// 0.1 ms follow a fine explicit reference (RK4 at 1 us, where sigma0 |v| dt / g <= 0.11) within 0.5 %
    /// of the swing and 1 % of the velocity's; the same explicit RK4 at 0.1 ms diverges for 4e4 N/m and
    /// stiffer; and halving the step halves the error at least (the step converges).
    #[test]
    fn stiff_bristles_follow_a_fine_explicit_reference_at_the_emulators_step() {
        for sigma0 in [2e4, 4e4, 1.6e5] {
            let m = lugre_model(sigma0);
            let reference = explicit(&m, 1e-6);
            assert!(reference.x.is_finite() && (reference.x - 0.025).abs() < 0.02);
            let err = |dt: f64| {
                let s = stepped(&m, dt);
                (
                    (s.x - reference.x).abs(),
                    (s.x_dot - reference.v).abs(),
                    (s.extra.bristle_m - reference.z).abs(),
                )
            };
            let (ex, ev, ez) = err(1e-4);
            let (ex2, ev2, _) = err(5e-5);
            eprintln!(
                "sigma0 {sigma0:e}: x {:.4} mm v {:.4} m/s z {:.3e} m; error x {ex:.2e} m v {ev:.2e} m/s z {ez:.2e} m; \
                 at half the step x {ex2:.2e} v {ev2:.2e}",
                reference.x * 1e3,
                reference.v,
                reference.z
            );
            assert!(
                ex < 1e-6 && ev < 1e-4,
                "sigma0 {sigma0}: x {ex} m, v {ev} m/s"
            );
            assert!(ez < 0.05 * 0.9 / sigma0, "sigma0 {sigma0}: z {ez} m");
            assert!(
                ex2 < 0.6 * ex.max(1e-9) && ev2 < 0.6 * ev.max(1e-9),
                "no convergence: {ex} -> {ex2}, {ev} -> {ev2}"
            );
            let old = explicit(&m, 1e-4);
            if sigma0 >= 4e4 {
                // Diverged: off by more than 1 mm, or not a number at all.
                let off = (old.x - reference.x).abs();
                assert!(
                    off.is_nan() || off > 1e-3,
                    "explicit at 0.1 ms: x {}",
                    old.x
                );
            }
        }
    }
}

#[cfg(test)]
mod direction_tests {
    use super::*;
    use crate::{ActuatorSheet, ValveKind};

    /// Per-direction Coulomb friction: under a constant drive of +-5 N, with chambers too large for the
    /// motion to change their pressure, the piston slides at the velocity where eq. (1) balances,
    /// `5 = F_c(direction) + K_v |v|`: F_c+ = 2 N towards +x, F_c- = 3 N towards -x (K_v = 50 N s/m).
    #[test]
    fn each_direction_slides_against_its_own_coulomb_force() {
        let sheet = ActuatorSheet::load(
            std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
                .join("../../pneumatics/paper-actuator.toml"),
        )
        .unwrap();
        let mut m = sheet.model();
        m.mechanics.friction = Friction::Smooth {
            coulomb_n: 2.0,
            smooth_velocity_m_per_s: 1e-4,
        };
        m.mechanics.viscous_n_s_per_m = 50.0;
        m.effects.coulomb_negative_n = Some(3.0);
        m.actuator.valve.kind = ValveKind::Proportional {
            response_time_s: 0.0,
        };
        m.actuator.valve.underlap = 0.0;
        m.actuator.cylinder.dead_volume_a_m3 = 1.0;
        m.actuator.cylinder.dead_volume_b_m3 = 1.0;
        let c = ChamberState::new(2.0e5, 2.0e5);
        let f_p = m.actuator.piston_force(&c) + m.mechanics.gravity_force();
        for (drive, v) in [(5.0, 0.06), (-5.0, -0.04)] {
            let mut st = OneDofState::at_rest(0.025, c, 0.0);
            for _ in 0..1000 {
                step(
                    &m,
                    &mut st,
                    0.0,
                    drive - f_p,
                    m.mechanics.gravity_force(),
                    1e-4,
                );
            }
            assert!(
                (st.x_dot / v - 1.0).abs() < 1e-3,
                "drive {drive}: {} vs {v}",
                st.x_dot
            );
        }
        // Symmetric without the key: -5 N slides at -0.06 m/s.
        m.effects.coulomb_negative_n = None;
        let mut st = OneDofState::at_rest(0.025, c, 0.0);
        for _ in 0..1000 {
            step(
                &m,
                &mut st,
                0.0,
                -5.0 - f_p,
                m.mechanics.gravity_force(),
                1e-4,
            );
        }
        assert!((st.x_dot / -0.06 - 1.0).abs() < 1e-3, "{}", st.x_dot);
    }
}
