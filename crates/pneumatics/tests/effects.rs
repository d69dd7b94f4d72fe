//! Effects beyond the paper (issue 26), each against a closed form or a limit: wall heat transfer
//! (adiabatic at h = 0, isothermal for a large h, the exponential relaxation of a held chamber), leaks
//! (the choked decay of a closed chamber, isothermal and adiabatic; the piston leak), lines (the transport
//! delay, the added capacitance, the equalisation through the line's restriction), seal friction (the
//! pressure term, LuGre's steady state on the Stribeck curve and its bristle relaxation).
mod common;
use common::*;
use pneuflex_pneumatics::flow::{ISO_RHO0_KG_M3, ISO_T0_K};
use pneuflex_pneumatics::*;

const R: f64 = 287.05;

fn shut_valve() -> ValveModel {
    // Underlap 0, spool 0: every path shut.
    proportional(0.0, 0.0)
}

/// The model with gas exponent `n` and effects `e`.
fn with(valve: ValveModel, n: f64, friction: Friction, e: Effects) -> OneDofModel {
    let mut m = model(valve, friction, 0.0);
    m.actuator.gas.polytropic_exponent = n;
    m.effects = e;
    m
}

fn heat(h: f64, tw: f64) -> Effects {
    Effects {
        wall_heat: Some(WallHeat {
            coefficient_w_per_m2_k: h,
            wall_temperature_k: tw,
        }),
        ..Effects::default()
    }
}

fn rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs()
}

/// h = 0 runs the extended model (the effect is given) and is the paper's adiabatic chamber: the same
/// states as the paper's model, step for step, under the PWM valve with its edges located (0.5 s of a
/// varying command, piston moving, stick-slip friction).
#[test]
fn wall_heat_at_zero_is_the_adiabatic_chamber() {
    let friction = Friction::StickSlip {
        coulomb_n: 0.6,
        static_n: 0.9,
        stribeck_velocity_m_per_s: 1e-3,
        stick_velocity_m_per_s: 1e-4,
    };
    let paper = with(pwm(40.0, 0.005), 1.4, friction, Effects::default());
    let zero = with(pwm(40.0, 0.005), 1.4, friction, heat(0.0, 293.15));
    assert!(paper.is_paper_model() && !zero.is_paper_model());
    let start = OneDofState::at_rest(0.025, ChamberState::new(3.0e5, 2.5e5), -1.0);
    let (mut a, mut b) = (start, start);
    let mut worst = 0.0f64;
    for i in 0..5000 {
        let u = 0.4 * (i as f64 * 2e-3).sin();
        paper.step(&mut a, u, -2.0, 1e-4);
        zero.step(&mut b, u, -2.0, 1e-4);
        for (p, q) in [
            (a.chambers.p_a, b.chambers.p_a),
            (a.chambers.p_b, b.chambers.p_b),
            (a.chambers.t_a, b.chambers.t_a),
            (a.chambers.t_b, b.chambers.t_b),
            (a.x, b.x),
        ] {
            worst = worst.max(rel(q, p));
        }
    }
    assert!(worst < 1e-9, "largest relative difference {worst:e}");
    assert!((a.x - start.x).abs() > 1e-3, "the piston did not move");
}

/// A large h makes the chambers isothermal at the wall temperature: closed chambers compressed and
/// expanded by a slow free oscillation keep `p V = M R T_w` (M = p0 V0 / (R T0), closed) and T = T_w, where
/// the adiabatic run (h = 0) swings by kelvins and departs from p V = const by percent.
#[test]
fn large_wall_heat_is_the_isothermal_chamber() {
    let run = |h: f64| {
        let mut m = with(shut_valve(), 1.4, no_coulomb(), heat(h, 293.15));
        m.mechanics.moving_mass_kg = 100.0;
        m.mechanics.viscous_n_s_per_m = 0.0;
        let mut st = OneDofState::at_rest(0.025, ChamberState::new(3.0e5, 3.0e5), 0.0);
        st.x_dot = 0.05;
        let (va0, vb0) = m.actuator.cylinder.volumes(st.x);
        let (pva0, pvb0) = (3.0e5 * va0, 3.0e5 * vb0);
        let (mut dev_pv, mut dev_t, mut travel) = (0.0f64, 0.0f64, 0.0f64);
        for _ in 0..20_000 {
            m.step(&mut st, 0.0, 0.0, 1e-4);
            let (va, vb) = m.actuator.cylinder.volumes(st.x);
            let c = &st.chambers;
            dev_pv = dev_pv.max(rel(c.p_a * va, pva0)).max(rel(c.p_b * vb, pvb0));
            dev_t = dev_t
                .max((c.t_a - 293.15).abs())
                .max((c.t_b - 293.15).abs());
            travel = travel.max((st.x - 0.025).abs());
        }
        (dev_pv, dev_t, travel)
    };
    let (pv, t, travel) = run(1e4);
    assert!(travel > 5e-3, "the piston travelled only {travel} m");
    assert!(pv < 2e-3, "p V departs by {pv:e} with h = 1e4");
    assert!(t < 0.5, "T departs by {t} K with h = 1e4");
    let (pv0, t0, _) = run(0.0);
    assert!(pv0 > 0.05 && t0 > 10.0, "adiabatic: {pv0}, {t0} K");
    // Convergence to the limit: ten times h, about a tenth of the departure.
    let (pv3, _, _) = run(1e3);
    assert!(pv3 > 5.0 * pv, "h = 1e3: {pv3:e}, h = 1e4: {pv:e}");
}

/// A chamber held at constant volume (piston on its stop) at T0 != T_w relaxes by Newton cooling:
/// M c_v T' = h A_w (T_w - T) with M constant gives `T - T_w = (T0 - T_w) exp(-t/tau)`,
/// `tau = M c_v / (h A_w)`, `c_v = R/(k - 1)`, and p = M R T / V follows T. The wall area at x = 0:
/// `A_w,a = 2 S_a + pi D V_a0/S_a`, `A_w,b = 2 S_b + pi (D + d)(L + V_b0/S_b)`.
#[test]
fn held_chamber_relaxes_to_the_wall_temperature() {
    let (h, tw, t0) = (100.0, 293.15, 350.0);
    let m = with(shut_valve(), 1.4, no_coulomb(), heat(h, tw));
    let c = m.actuator.cylinder;
    let mut st = OneDofState::at_rest(0.0, ChamberState::with_temperature(3.0e5, 2.0e5, t0), 0.0);
    let (va, vb) = c.volumes(0.0);
    let pi = std::f64::consts::PI;
    let aw_a = 2.0 * c.area_a() + pi * c.bore_m * c.dead_volume_a_m3 / c.area_a();
    let aw_b = 2.0 * c.area_b()
        + pi * (c.bore_m + c.rod_m) * (c.stroke_m + c.dead_volume_b_m3 / c.area_b());
    let cv = R / 0.4;
    let (ma, mb) = (3.0e5 * va / (R * t0), 2.0e5 * vb / (R * t0));
    let (tau_a, tau_b) = (ma * cv / (h * aw_a), mb * cv / (h * aw_b));
    let dt = 1e-4;
    for i in 1..=3000 {
        // The piston pressed onto its stop at x = 0.
        m.step(&mut st, 0.0, -1e4, dt);
        assert_eq!(st.x, 0.0);
        if i % 500 == 0 {
            let t = i as f64 * dt;
            let want_a = tw + (t0 - tw) * (-t / tau_a).exp();
            let want_b = tw + (t0 - tw) * (-t / tau_b).exp();
            assert!(rel(st.chambers.t_a, want_a) < 1e-9, "T_a at {t}");
            assert!(rel(st.chambers.t_b, want_b) < 1e-9, "T_b at {t}");
            assert!(
                rel(st.chambers.p_a, ma * R * want_a / va) < 1e-9,
                "p_a at {t}"
            );
        }
    }
    assert!(tau_a > 0.01 && tau_a < 0.3, "tau_a = {tau_a} s");
}

fn leak(c: f64, b: f64) -> Orifice {
    Orifice {
        sonic_conductance_m3_per_s_pa: c,
        critical_pressure_ratio: b,
    }
}

/// Closed chamber A (piston on its stop, valve shut) leaking to the atmosphere through an ISO 6358
/// orifice, choked while p_atm/p <= b (eq. 11, phi = 1): `M' = -C rho0 p sqrt(T0/T)`.
/// Isothermal (n = 1, T = T0): `V p' = R T M'` gives `p = p0 exp(-k t)`, `k = C rho0 R T0 / V`.
/// Adiabatic (n = k = 1.4): the gas left in the chamber expands isentropically, T = T0 (p/p0)^((k-1)/k),
/// and `V p' = k R T M'` gives `p' = -kappa p (p/p0)^beta` with `kappa = k C rho0 R T0 / V`,
/// `beta = (k-1)/(2k)`, so `(p/p0)^-beta = 1 + beta kappa t`: `p = p0 (1 + beta kappa t)^(-1/beta)`.
#[test]
fn closed_chamber_leak_decays_as_the_choked_closed_form() {
    let (c, p0) = (1e-11, 8.0e5);
    for n in [1.0, 1.4] {
        let e = Effects {
            leaks: Leaks {
                a_atmosphere: Some(leak(c, 0.5)),
                ..Leaks::default()
            },
            ..Effects::default()
        };
        let m = with(shut_valve(), n, no_coulomb(), e);
        let v = m.actuator.cylinder.volumes(0.0).0;
        let mut st = OneDofState::at_rest(0.0, ChamberState::new(p0, 1.5e5), 0.0);
        let k = c * ISO_RHO0_KG_M3 * R * ISO_T0_K / v;
        let beta = (n - 1.0) / (2.0 * n);
        let dt = 1e-3;
        let mut t = 0.0;
        for i in 1..=3000 {
            m.step(&mut st, 0.0, -1e4, dt);
            t = i as f64 * dt;
            let want = if n == 1.0 {
                p0 * (-k * t).exp()
            } else {
                p0 * (1.0 + beta * n * k * t).powf(-1.0 / beta)
            };
            assert!(
                rel(st.chambers.p_a, want) < 1e-8,
                "n {n}, t {t}: {} vs {want}",
                st.chambers.p_a
            );
            assert_eq!(st.chambers.p_b, 1.5e5, "B has no leak");
        }
        // Still choked at the end, and the chamber lost a good part of its gas.
        assert!(st.chambers.p_a > P_ATM / 0.5 && st.chambers.p_a < 0.6 * p0);
        assert!(t == 3.0);
    }
}

/// A choked piston leak A -> B (isothermal): A decays as `p_a0 exp(-k_a t)`, `k_a = C rho0 R T0 / V_a`,
/// while p_b/p_a <= b, and B gains what A loses: `p_b = p_b0 + (V_a/V_b)(p_a0 - p_a)` (mass conserved).
#[test]
fn piston_leak_moves_the_gas_from_a_to_b() {
    let c = 5e-12;
    let e = Effects {
        leaks: Leaks {
            piston: Some(leak(c, 0.5)),
            ..Leaks::default()
        },
        ..Effects::default()
    };
    let m = with(shut_valve(), 1.0, no_coulomb(), e);
    let (va, vb) = m.actuator.cylinder.volumes(0.0);
    let (pa0, pb0) = (8.0e5, 1.0e5);
    let mut st = OneDofState::at_rest(0.0, ChamberState::new(pa0, pb0), 0.0);
    let k = c * ISO_RHO0_KG_M3 * R * ISO_T0_K / va;
    for i in 1..=2000 {
        m.step(&mut st, 0.0, -1e4, 1e-3);
        let t = i as f64 * 1e-3;
        let pa = pa0 * (-k * t).exp();
        assert!(st.chambers.p_b / st.chambers.p_a <= 0.5, "no longer choked");
        assert!(rel(st.chambers.p_a, pa) < 1e-8, "p_a at {t}");
        assert!(
            rel(st.chambers.p_b, pb0 + va / vb * (pa0 - pa)) < 1e-8,
            "p_b at {t}"
        );
    }
    assert!(st.chambers.p_a < 0.8 * pa0);
}

fn lines(volume: f64, c: f64, length: f64) -> Lines {
    Lines {
        volume_m3: volume,
        orifice: leak(c, 0.5),
        length_m: length,
        speed_of_sound_m_per_s: 343.0,
    }
}

/// A command step reaches the port `L / c` later: with a 2 m line at 343 m/s, the line's gas is untouched
/// until 5.83 ms after the valve opened (proportional valve, no spool lag) and fills from then on; the
/// chamber behind the line's restriction follows.
#[test]
fn a_line_delays_the_valve_by_its_length_over_the_speed_of_sound() {
    let e = Effects {
        lines: Some(lines(2e-6, 1e-8, 2.0)),
        ..Effects::default()
    };
    let m = with(proportional(0.0, 0.0), 1.4, no_coulomb(), e);
    let delay = 2.0 / 343.0;
    let mut st = OneDofState::at_rest(0.0, ChamberState::new(P_ATM, P_ATM), 0.0);
    let dt = 1e-5;
    let mut first = None;
    for i in 1..=1000 {
        m.step(&mut st, 1.0, -1e4, dt);
        let t = i as f64 * dt;
        let line_a = st.extra.lines.expect("the lines have a state").p_a;
        if t <= delay - dt {
            assert_eq!(line_a, P_ATM, "line moved at {t} s, before the delay");
            assert_eq!(st.chambers.p_a, P_ATM);
        } else if first.is_none() && line_a > P_ATM {
            first = Some(t);
        }
    }
    let first = first.expect("the line filled");
    assert!(first - delay < 1.5 * dt, "the line filled from {first} s");
    assert!(st.chambers.p_a > 1.2 * P_ATM, "chamber A did not fill");
}

/// The line adds its volume to the chamber's capacitance: filled from the supply through the choked valve
/// (isothermal, n = 1, T = T_s), the gas mass grows at the constant `q = C rho0 p_s`, so the volume-weighted
/// pressure rises as `(p_l V_l + p_a V_a)/(V_l + V_a) = p0 + q R T t / (V_l + V_a)`: a step's initial rise
/// is `V_a / (V_a + V_l)` of the chamber's alone (here 3.5 / 7). With the valve shut, line and chamber end
/// at the mass-weighted mean of their starting pressures through the line's restriction.
#[test]
fn a_line_adds_capacitance_and_equalises_through_its_restriction() {
    let vl = 3.5e-6;
    let e = Effects {
        lines: Some(lines(vl, 2e-8, 0.0)),
        ..Effects::default()
    };
    let m = with(proportional(0.0, 0.0), 1.0, no_coulomb(), e);
    let va = m.actuator.cylinder.volumes(0.0).0;
    let q = 5e-9 * ISO_RHO0_KG_M3 * P_S;
    let mut st = OneDofState::at_rest(0.0, ChamberState::new(P_ATM, P_ATM), 0.0);
    let dt = 1e-6;
    for i in 1..=400 {
        m.step(&mut st, 1.0, -1e4, dt);
        let t = i as f64 * dt;
        let l = st.extra.lines.unwrap();
        assert!(l.p_a <= 0.3 * P_S, "the valve is no longer choked");
        let mean = (l.p_a * vl + st.chambers.p_a * va) / (vl + va);
        let want = P_ATM + q * R * 293.15 * t / (vl + va);
        assert!(rel(mean, want) < 1e-9, "t {t}: {mean} vs {want}");
    }
    // The restriction: the chamber lags behind its line while it fills.
    assert!(st.chambers.p_a < st.extra.lines.unwrap().p_a);
    // Equalisation with the valve shut: the mass-weighted mean of the start.
    let mut st = OneDofState::at_rest(0.0, ChamberState::new(2.0e5, P_ATM), 0.0);
    st.extra.lines = Some(ChamberState::new(5.0e5, P_ATM));
    for _ in 0..20_000 {
        m.step(&mut st, 0.0, -1e4, 1e-5);
    }
    let want = (5.0e5 * vl + 2.0e5 * va) / (vl + va);
    assert!(rel(st.chambers.p_a, want) < 1e-6, "{}", st.chambers.p_a);
    assert!(rel(st.extra.lines.unwrap().p_a, want) < 1e-6);
}

/// Seal friction rising with the pressure difference, `F_c = F_c0 + k_p |p_a - p_b|`: a piston driven by
/// constant chamber pressures (1 m^3 chambers: the stroke changes them by 1e-6) reaches the terminal
/// velocity `v = (F_p - F_c0 - k_p |p_a - p_b|) / K_v` of eq. (1) with the smooth law (|v| >> v_s).
#[test]
fn coulomb_friction_rises_with_the_pressure_difference() {
    let e = Effects {
        coulomb_pressure_n_per_pa: Some(1e-5),
        ..Effects::default()
    };
    let friction = Friction::Smooth {
        coulomb_n: 2.0,
        smooth_velocity_m_per_s: 1e-3,
    };
    let mut m = with(shut_valve(), 1.4, friction, e);
    m.mechanics.viscous_n_s_per_m = 200.0;
    m.actuator.cylinder.dead_volume_a_m3 = 1.0;
    m.actuator.cylinder.dead_volume_b_m3 = 1.0;
    let c = ChamberState::new(5.0e5, 1.0e5);
    let f_p = m.actuator.piston_force(&c);
    let f_c = 2.0 + 1e-5 * 4.0e5;
    assert!((friction.with_normal_force(4.0).coulomb_n() - f_c).abs() < 1e-12);
    let mut st = OneDofState::at_rest(0.005, c, 0.0);
    for _ in 0..400 {
        m.step(&mut st, 0.0, 0.0, 1e-4);
    }
    let want = (f_p - f_c) / 200.0;
    assert!(rel(st.x_dot, want) < 1e-4, "{} vs {want}", st.x_dot);
    // Without the pressure term, the paper's model: F_c0 only.
    m.effects = Effects::default();
    let mut st = OneDofState::at_rest(0.005, c, 0.0);
    for _ in 0..400 {
        m.step(&mut st, 0.0, 0.0, 1e-4);
    }
    assert!(rel(st.x_dot, (f_p - 2.0) / 200.0) < 1e-4);
}

/// Stick-slip with the pressure term: the break-away force is raised by as much, so a drive between
/// F_s0 and F_s0 + k_p |p_a - p_b| holds the piston, one above moves it.
#[test]
fn break_away_rises_with_the_pressure_difference() {
    let friction = Friction::StickSlip {
        coulomb_n: 2.0,
        static_n: 3.0,
        stribeck_velocity_m_per_s: 1e-3,
        stick_velocity_m_per_s: 1e-4,
    };
    let e = Effects {
        coulomb_pressure_n_per_pa: Some(1e-5),
        ..Effects::default()
    };
    let mut m = with(shut_valve(), 1.4, friction, e);
    m.actuator.cylinder.dead_volume_a_m3 = 1.0;
    m.actuator.cylinder.dead_volume_b_m3 = 1.0;
    let c = ChamberState::new(3.0e5, 2.0e5);
    // F_s = 3 + 1e-5 * 1e5 = 4 N.
    let f_p = m.actuator.piston_force(&c);
    for (load, moves) in [(3.5, false), (4.5, true)] {
        let mut st = OneDofState::at_rest(0.02, c, 0.0);
        for _ in 0..1000 {
            m.step(&mut st, 0.0, load - f_p, 1e-4);
        }
        assert_eq!((st.x - 0.02).abs() > 1e-6, moves, "drive {load} N");
    }
}

fn lugre() -> Friction {
    Friction::LuGre {
        coulomb_n: 2.0,
        static_n: 3.0,
        stribeck_velocity_m_per_s: 0.01,
        bristle_stiffness_n_per_m: 1e5,
        bristle_damping_n_s_per_m: 300.0,
    }
}

/// LuGre at constant velocity: `z' = v - sigma0 |v| z / g(v)` is linear in z, so
/// `z(t) = z_ss + (z0 - z_ss) exp(-sigma0 |v| t / g(v))` with `z_ss = g(v) sign(v) / sigma0`, and the
/// steady force `sigma0 z_ss = g(v) sign(v)` is the Stribeck curve `F_c + (F_s - F_c) exp(-(v/v_s)^2)`.
#[test]
fn lugre_relaxes_to_the_stribeck_curve() {
    let f = lugre();
    for v in [-0.05, -0.01, -2e-3, 1e-4, 1e-3, 0.005, 0.01, 0.03, 0.2] {
        let g = 2.0 + (3.0 - 2.0) * (-(v / 0.01f64).powi(2)).exp();
        let z_ss = g * f64::signum(v) / 1e5;
        let rate = 1e5 * f64::abs(v) / g;
        let (mut z, dt) = (0.0, 0.01 / rate);
        for i in 1..=2000 {
            // RK4 of z' at constant v.
            let dz = |z: f64| f.lugre(v, z).unwrap().1;
            let k1 = dz(z);
            let k2 = dz(z + 0.5 * dt * k1);
            let k3 = dz(z + 0.5 * dt * k2);
            let k4 = dz(z + dt * k3);
            z += dt / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4);
            let want = z_ss * (1.0 - (-rate * i as f64 * dt).exp());
            assert!((z - want).abs() < 1e-9 * z_ss.abs(), "v {v}, step {i}");
        }
        let (force, dz) = f.lugre(v, z).unwrap();
        assert!(dz.abs() < 1e-6 * v.abs(), "v {v}: not steady");
        assert!(
            (force - g * v.signum()).abs() < 1e-6 * g,
            "v {v}: {force} vs {g}"
        );
        assert!((f.force(v, 0.0) - g * v.signum()).abs() < 1e-12);
    }
}

/// LuGre in the model: under a constant drive the piston slides at the velocity where eq. (1) balances on
/// the Stribeck curve, `F_p = g(v) + K_v v` (solved by bisection). Below the break-away force it creeps
/// by the pre-sliding displacement and holds: with g = F_s at rest, `dz/dx = 1 - sigma0 z / F_s` along a
/// monotonic (over-damped) approach gives `z = (F_s/sigma0)(1 - exp(-sigma0 x / F_s))`, and the rest at
/// `sigma0 z = F` gives `x = -(F_s/sigma0) ln(1 - F/F_s)`.
#[test]
fn lugre_slides_on_the_stribeck_curve_and_creeps_below_break_away() {
    let mut m = with(shut_valve(), 1.4, lugre(), Effects::default());
    assert!(!m.is_paper_model());
    m.mechanics.viscous_n_s_per_m = 50.0;
    m.actuator.cylinder.dead_volume_a_m3 = 1.0;
    m.actuator.cylinder.dead_volume_b_m3 = 1.0;
    let c = ChamberState::new(2.0e5, 2.0e5);
    let f_p = m.actuator.piston_force(&c);
    let g = |v: f64| 2.0 + (-(v / 0.01f64).powi(2)).exp();
    for drive in [3.5, 5.0] {
        let mut st = OneDofState::at_rest(0.005, c, 0.0);
        for _ in 0..2000 {
            m.step(&mut st, 0.0, drive - f_p, 1e-4);
        }
        let (mut lo, mut hi) = (0.0, 1.0);
        for _ in 0..100 {
            let mid = 0.5 * (lo + hi);
            if g(mid) + 50.0 * mid < drive {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        assert!(
            rel(st.x_dot, lo) < 1e-4,
            "drive {drive}: {} vs {lo}",
            st.x_dot
        );
    }
    // Below F_s, over-damped bristles (sigma1 = 1000 N s/m) and a Stribeck velocity far above the creep.
    m.mechanics.friction = Friction::LuGre {
        coulomb_n: 2.0,
        static_n: 3.0,
        stribeck_velocity_m_per_s: 0.1,
        bristle_stiffness_n_per_m: 1e5,
        bristle_damping_n_s_per_m: 1000.0,
    };
    let mut st = OneDofState::at_rest(0.005, c, 0.0);
    for _ in 0..20_000 {
        m.step(&mut st, 0.0, 1.5 - f_p, 1e-5);
    }
    let want = -(3.0 / 1e5) * (1.0 - 1.5 / 3.0f64).ln();
    let crept = st.x - 0.005;
    assert!(
        rel(crept, want) < 1e-3,
        "crept {crept} m, closed form {want} m"
    );
    assert!(st.x_dot.abs() < 1e-6);
    assert!((st.extra.bristle_m - 1.5 / 1e5).abs() < 1e-9);
}
