//! The muscle against closed forms and hand calculations (docs/muscles.md (M1)-(M12)): isometric force,
//! zero-force contraction, bladder volume, a closed chamber stretched, the valve-fed chamber's mass
//! balance, and the muscle-mass-spring plant settling where an independent bisection puts it.

use core::f64::consts::PI;

use pneuflex_muscle::{
    Braid, BraidFriction, ChamberState, Feed, Load, Muscle, MuscleChamber, MusclePlant,
    NEUTRAL_BRAID_ANGLE_RAD, PlantState, Port,
};
use pneuflex_pneumatics::{Gas, Orifice, P_ATM, Supply, ValveKind, ValveModel};

/// The test muscle: D_rest = 10 mm (r0 = 5 mm), L0 = 200 mm, alpha0 = 30 deg, k = 1.25. With alpha0 = 30 deg
/// Tondu & Lopez's coefficients are round: a = 3 / tan^2(30) = 3 / (1/3) = 9, b = 1 / sin^2(30) = 4.
fn braid(k: f64) -> Braid {
    Braid {
        rest_diameter_m: 0.010,
        rest_length_m: 0.200,
        rest_braid_angle_rad: 30f64.to_radians(),
        end_effect_factor: k,
    }
}

fn muscle(k: f64, friction: BraidFriction) -> Muscle {
    Muscle {
        braid: braid(k),
        friction,
        stretch_stiffness_n_per_m: 2.0e4,
        dead_volume_m3: 3.0e-6,
    }
}

fn supply() -> Supply {
    Supply {
        supply_pressure_pa: 6.0e5 + P_ATM,
        supply_temperature_k: 293.15,
        atmosphere_pressure_pa: P_ATM,
        atmosphere_temperature_k: 293.15,
    }
}

fn chamber(k: f64, friction: BraidFriction, n: f64) -> MuscleChamber {
    MuscleChamber {
        muscle: muscle(k, friction),
        gas: Gas {
            polytropic_exponent: n,
            ..Gas::default()
        },
        supply: supply(),
    }
}

fn rel(got: f64, want: f64) -> f64 {
    (got - want).abs() / want.abs()
}

/// Isometric force at several gauge pressures and contractions against the hand calculation of
/// F = pi r0^2 p [a (1 - k eps)^2 - b] with a = 9, b = 4, k = 1.25, pi r0^2 = 7.853981634e-5 m^2.
#[test]
fn isometric_force_matches_hand_calculation() {
    let b = braid(1.25);
    let (a, bb) = b.tondu_lopez_coefficients();
    assert!(rel(a, 9.0) < 1e-14 && rel(bb, 4.0) < 1e-14, "a {a}, b {bb}");
    // (p gauge [Pa], eps, F [N]) worked by hand:
    let table = [
        // 1 bar, eps 0: 7.853981634 N x (9 x 1 - 4) = 39.26990817 N
        (1.0e5, 0.0, 39.269_908_169_872_42),
        // 3 bar, eps 0.10: (1 - 0.125)^2 = 0.765625; 9 x 0.765625 - 4 = 2.890625; 23.56194490 x 2.890625
        (3.0e5, 0.10, 68.108_746_982_122_47),
        // 5 bar, eps 0.20: (1 - 0.25)^2 = 0.5625; 5.0625 - 4 = 1.0625; 39.26990817 x 1.0625
        (5.0e5, 0.20, 41.724_277_430_489_44),
        // 6 bar, eps 0.05: (1 - 0.0625)^2 = 0.87890625; 7.91015625 - 4 = 3.91015625; 47.12388980 x 3.91015625
        (6.0e5, 0.05, 184.261_772_240_823_2),
        // 2 bar, stretched 2 %: (1 + 0.025)^2 = 1.050625; 9.455625 - 4 = 5.455625; 15.70796327 x 5.455625
        (2.0e5, -0.02, 85.696_757_103_704_07),
    ];
    for (p, eps, want) in table {
        let got = b.pressure_force(p, eps);
        assert!(
            rel(got, want) < 1e-12,
            "p {p}, eps {eps}: {got} N vs {want} N"
        );
    }
    // The muscle adds the braid's stretch stiffness past L0 (M8): 2 % of 0.2 m at 2e4 N/m = 80 N.
    let m = muscle(1.25, BraidFriction::NONE);
    let got = m.static_tension(2.0e5, 0.204);
    assert!(rel(got, 85.696_757_103_704_07 + 80.0) < 1e-12, "{got}");
}

/// With k = 1 the force is Chou & Hannaford's (pi D0^2 p / 4)(3 cos^2 theta - 1), D0 = b / (n pi) from the
/// fibre's length b and turns n, and equals the virtual work -p dV/dL of the bladder volume (M2), here by
/// a central difference of the volume.
#[test]
fn ideal_braid_force_is_chou_hannaford_and_virtual_work() {
    let br = braid(1.0);
    let alpha0 = 30f64.to_radians();
    // b = L0 / cos(alpha0) = 0.2 / 0.8660254 = 0.23094011 m; n = b sin(alpha0) / (pi D_rest) = 3.67552 turns.
    let fibre = 0.2 / alpha0.cos();
    let turns = fibre * alpha0.sin() / (PI * 0.010);
    assert!(rel(br.fibre_length_m(), fibre) < 1e-14 && rel(br.turns(), turns) < 1e-14);
    let d0 = fibre / (turns * PI);
    for p in [1.0e5, 4.0e5, 7.0e5] {
        for eps in [-0.03, 0.0, 0.07, 0.15, 0.25, 0.3] {
            let cos_t = (1.0 - eps) * alpha0.cos();
            let ch = PI * d0 * d0 * p / 4.0 * (3.0 * cos_t * cos_t - 1.0);
            let tl = br.pressure_force(p, eps);
            assert!(
                (tl - ch).abs() < 1e-12 * ch.abs().max(1.0),
                "p {p}, eps {eps}: {tl} vs {ch}"
            );
            // -p dV/dL, dL = -L0 d eps: central difference over +-1 um.
            let h = 1.0e-6 / 0.2;
            let dv_dl = (br.bladder_volume_m3(eps - h) - br.bladder_volume_m3(eps + h)) / 2.0e-6;
            let work = -p * dv_dl;
            assert!(
                (work - ch).abs() < 1e-6 * ch.abs().max(1.0),
                "p {p}, eps {eps}: {work} vs {ch}"
            );
        }
    }
}

/// The force is zero at eps_max = (1 - 1 / (sqrt(3) cos alpha0)) / k at every pressure: with alpha0 = 30
/// deg, sqrt(3) cos(30) = 3/2, so eps_max = (1 - 2/3) / k = 1/3 / 1.25 = 4/15 = 0.266667. Below it the
/// muscle pulls; at and beyond it the muscle is slack and pulls nothing.
#[test]
fn zero_force_contraction() {
    let m = muscle(1.25, BraidFriction::NONE);
    let eps_max = m.braid.max_contraction();
    assert!((eps_max - 4.0 / 15.0).abs() < 1e-14, "{eps_max}");
    for p in [0.5e5, 2.0e5, 6.0e5] {
        let f0 = m.braid.pressure_force(p, 0.0);
        assert!(
            m.braid.pressure_force(p, 4.0 / 15.0).abs() < 1e-12 * f0,
            "p {p}"
        );
        assert!(m.braid.pressure_force(p, 4.0 / 15.0 - 1e-3) > 0.0);
        assert!(m.braid.pressure_force(p, 4.0 / 15.0 + 1e-3) < 0.0);
        let l_max = 0.2 * (1.0 - 4.0 / 15.0);
        assert!(m.static_tension(p, l_max - 1e-4) == 0.0 && m.is_slack(l_max - 1e-4));
        assert!(m.static_tension(p, l_max + 1e-4) > 0.0 && !m.is_slack(l_max + 1e-4));
    }
    // k = 1: the ideal braid stops where theta reaches 54.7356 deg, eps = 1/3.
    assert!((braid(1.0).max_contraction() - 1.0 / 3.0).abs() < 1e-14);
}

/// Bladder volume against contraction: the cylinder pi D^2 L / 4 with D = D_rest sin(theta) / sin(alpha0)
/// (the braid keeps its fibre length and turns) and L = L0 (1 - eps); pi r0^2 L0 at rest; its maximum at
/// theta = atan(sqrt 2) = 54.7356 deg, where dV/dL = 0.
#[test]
fn bladder_volume_against_contraction() {
    let br = braid(1.25);
    let alpha0 = 30f64.to_radians();
    let v0 = PI * 0.005 * 0.005 * 0.2;
    assert!(rel(br.bladder_volume_m3(0.0), v0) < 1e-13);
    for eps in [-0.05, 0.0, 0.1, 0.2, 1.0 / 3.0, 0.4] {
        let theta = ((1.0 - eps) * alpha0.cos()).acos();
        let d = 0.010 * theta.sin() / alpha0.sin();
        let want = PI * d * d / 4.0 * 0.2 * (1.0 - eps);
        let got = br.bladder_volume_m3(eps);
        assert!(rel(got, want) < 1e-12, "eps {eps}: {got} vs {want}");
    }
    // The largest volume on a 1e-5 grid of eps: its braid angle is 54.7356 deg to the grid's resolution.
    let (mut best, mut v_best) = (0.0, 0.0);
    for i in 0..=50_000 {
        let eps = i as f64 * 1e-5;
        let v = br.bladder_volume_m3(eps);
        if v > v_best {
            (best, v_best) = (eps, v);
        }
    }
    let theta = ((1.0 - best) * alpha0.cos()).acos();
    assert!(
        (theta.to_degrees() - 54.735_610_317).abs() < 2e-3,
        "volume largest at {} deg",
        theta.to_degrees()
    );
    assert!((NEUTRAL_BRAID_ANGLE_RAD - 2f64.sqrt().atan()).abs() < 1e-15);
    assert!(br.volume_per_length_m2(1.0 / 3.0).abs() < 1e-18);
    // The muscle's chamber: the dead volume added; a slack muscle keeps its volume at eps_max.
    let m = muscle(1.25, BraidFriction::NONE);
    let (v, _) = m.chamber_volume(0.2 * (1.0 - 0.1), 0.0);
    assert!(rel(v, 3.0e-6 + br.bladder_volume_m3(0.1)) < 1e-14);
    let (v_slack, rate) = m.chamber_volume(0.1, -0.5);
    assert!(rel(v_slack, 3.0e-6 + br.bladder_volume_m3(4.0 / 15.0)) < 1e-14 && rate == 0.0);
}

/// Integrates the chamber with RK4 while the muscle is moved from `l1` to `l2` in `duration` at constant
/// speed, fed through `port`; returns the end state.
fn move_chamber(
    c: &MuscleChamber,
    s: ChamberState,
    port: &Port,
    (l1, l2, duration): (f64, f64, f64),
    steps: usize,
) -> ChamberState {
    let v = (l2 - l1) / duration;
    let dt = duration / steps as f64;
    let mut s = s;
    let add = |s: &ChamberState, h: f64, k: &(f64, f64)| ChamberState {
        pressure_pa: s.pressure_pa + h * k.0,
        temperature_k: s.temperature_k + h * k.1,
    };
    let f = |s: &ChamberState, t: f64| {
        let r = c.rates(s, l1 + v * t, v, port);
        (r.pressure_pa_per_s, r.temperature_k_per_s)
    };
    for i in 0..steps {
        let t = i as f64 * dt;
        let k1 = f(&s, t);
        let k2 = f(&add(&s, 0.5 * dt, &k1), t + 0.5 * dt);
        let k3 = f(&add(&s, 0.5 * dt, &k2), t + 0.5 * dt);
        let k4 = f(&add(&s, dt, &k3), t + dt);
        s.pressure_pa += dt / 6.0 * (k1.0 + 2.0 * k2.0 + 2.0 * k3.0 + k4.0);
        s.temperature_k += dt / 6.0 * (k1.1 + 2.0 * k2.1 + 2.0 * k3.1 + k4.1);
    }
    s
}

/// A closed muscle stretched from eps = 0.20 to eps = 0.02 (its volume shrinks, below 54.7 deg): adiabatic
/// p V^1.4 and T V^0.4 constant, isothermal p V constant, with V = V_dead + V_bladder (M2); the same at
/// half the step (converged).
#[test]
fn closed_chamber_stretched_follows_polytropic_law() {
    let (l1, l2) = (0.2 * (1.0 - 0.20), 0.2 * (1.0 - 0.02));
    let s0 = ChamberState {
        pressure_pa: 3.0e5,
        temperature_k: 293.15,
    };
    for n in [1.4, 1.0] {
        let c = chamber(1.25, BraidFriction::NONE, n);
        let (v1, _) = c.muscle.chamber_volume(l1, 0.0);
        let (v2, _) = c.muscle.chamber_volume(l2, 0.0);
        assert!(
            v2 < 0.8 * v1,
            "the stretch must shrink the chamber: {v1} -> {v2}"
        );
        let p2 = 3.0e5 * (v1 / v2).powf(n);
        let t2 = 293.15 * (v1 / v2).powf(n - 1.0);
        for steps in [200, 400] {
            let s = move_chamber(&c, s0, &Port::Closed, (l1, l2, 0.05), steps);
            eprintln!(
                "n {n}, {steps} steps: p {:.3e}, T {:.3e} relative to the closed form",
                rel(s.pressure_pa, p2),
                rel(s.temperature_k, t2)
            );
            assert!(
                rel(s.pressure_pa, p2) < 1e-9,
                "n {n}: {} vs {p2} Pa",
                s.pressure_pa
            );
            assert!(
                rel(s.temperature_k, t2) < 1e-9,
                "n {n}: {} vs {t2} K",
                s.temperature_k
            );
            // No gas came in or left.
            assert!(rel(c.gas_mass_kg(&s, l2), c.gas_mass_kg(&s0, l1)) < 1e-9);
        }
    }
}

/// Behind the regulator the pressure follows p_set + (p0 - p_set) exp(-t / tau) (M11) while the muscle
/// moves, and the gas that came in is the gas mass's change.
#[test]
fn regulated_chamber_follows_first_order_lag() {
    let c = chamber(1.25, BraidFriction::NONE, 1.4);
    let (l1, l2) = (0.2 * (1.0 - 0.02), 0.2 * (1.0 - 0.18));
    let s0 = ChamberState {
        pressure_pa: P_ATM,
        temperature_k: 293.15,
    };
    let (tau, p_set, t_end) = (0.02, P_ATM + 4.0e5, 0.05);
    let port = Port::Regulator {
        time_constant_s: tau,
        set_pressure_pa: p_set,
    };
    let s = move_chamber(&c, s0, &port, (l1, l2, t_end), 1000);
    // 101325 + 4e5 (1 - exp(-2.5)) = 101325 + 4e5 x 0.917915 = 468491.0 Pa
    let want = p_set + (P_ATM - p_set) * (-t_end / tau).exp();
    assert!((want - 468_491.0).abs() < 0.1, "{want}");
    assert!(
        rel(s.pressure_pa, want) < 1e-9,
        "{} vs {want} Pa",
        s.pressure_pa
    );
    // A set pressure above the supply is the supply's.
    let high = Port::Regulator {
        time_constant_s: tau,
        set_pressure_pa: 2.0e6,
    };
    let r = c.rates(&s0, l1, 0.0, &high);
    let want = (c.supply.supply_pressure_pa - P_ATM) / tau;
    assert!(rel(r.pressure_pa_per_s, want) < 1e-12);
}

/// The first instant of filling through the valve, muscle held: the flow is choked (p / p_s = 0.144 < b =
/// 0.3), q = C rho0 p_s sqrt(T0 / T_s) = 5e-9 x 1.185 x 701325 x 1 = 4.15535e-3 kg/s, and
/// dp/dt = n R T_s q / V (M9) with V = 3e-6 + pi r0^2 L0 = 1.870796e-5 m^3 at rest.
#[test]
fn choked_filling_rate() {
    let c = chamber(1.25, BraidFriction::NONE, 1.4);
    let s0 = ChamberState {
        pressure_pa: P_ATM,
        temperature_k: 293.15,
    };
    let v = valve(ValveKind::Proportional {
        response_time_s: 0.0,
    });
    let r = c.rates(
        &s0,
        0.2,
        0.0,
        &Port::Valve {
            valve: v,
            spool: 1.0,
        },
    );
    let q: f64 = 5.0e-9 * 1.185 * 701_325.0;
    assert!((q - 4.155_35e-3).abs() < 1e-8, "{q}");
    let vol: f64 = 3.0e-6 + PI * 0.005 * 0.005 * 0.2;
    assert!((vol - 1.870_796e-5).abs() < 1e-11, "{vol}");
    let dp = 1.4 * 287.05 * 293.15 * q / vol;
    assert!(
        rel(r.mass_flow_kg_per_s, q) < 1e-12,
        "{}",
        r.mass_flow_kg_per_s
    );
    assert!(
        rel(r.pressure_pa_per_s, dp) < 1e-12,
        "{} vs {dp}",
        r.pressure_pa_per_s
    );
    // Supply air at the chamber's temperature heats the chamber: dT/dt = T/p (dp/dt - R T q / V) > 0.
    let dt = 293.15 / P_ATM * (dp - 287.05 * 293.15 * q / vol);
    assert!(rel(r.temperature_k_per_s, dt) < 1e-12 && dt > 0.0);
    // Venting (spool -1) from 3 bar gauge: a_exhaust, choked the other way, q = -C rho0 p sqrt(T0/T).
    let s = ChamberState {
        pressure_pa: P_ATM + 3.0e5,
        temperature_k: 293.15,
    };
    let r = c.rates(
        &s,
        0.2,
        0.0,
        &Port::Valve {
            valve: v,
            spool: -1.0,
        },
    );
    assert!(rel(r.mass_flow_kg_per_s, -5.0e-9 * 1.185 * (P_ATM + 3.0e5)) < 1e-12);
}

fn valve(kind: ValveKind) -> ValveModel {
    ValveModel {
        orifice: Orifice {
            sonic_conductance_m3_per_s_pa: 5.0e-9,
            critical_pressure_ratio: 0.3,
        },
        paths: [None; 4],
        underlap: 0.02,
        kind,
    }
}

fn load() -> Load {
    Load {
        mass_kg: 0.5,
        spring_n_per_m: 3000.0,
        spring_free_length_m: 0.21,
        damping_n_s_per_m: 15.0,
        pull_n: 20.0,
    }
}

fn start() -> PlantState {
    PlantState {
        length_m: 0.2,
        velocity_m_per_s: 0.0,
        chamber: ChamberState {
            pressure_pa: P_ATM,
            temperature_k: 293.15,
        },
        inflow_kg: 0.0,
    }
}

/// Runs the plant for `duration` at step `dt` under `command(t)`; calls `each` after every step.
fn run(
    plant: &mut MusclePlant,
    x: &mut PlantState,
    dt: f64,
    duration: f64,
    command: impl Fn(f64) -> f64,
    mut each: impl FnMut(&MusclePlant, &PlantState),
) {
    let steps = (duration / dt).round() as usize;
    for i in 0..steps {
        plant.step(x, command(i as f64 * dt), dt);
        each(plant, x);
    }
}

/// The valve-fed chamber keeps its mass balance: the gas in the muscle, p V / (R T), changes by exactly the
/// mass that came through the valve (the integral of eq. (11)'s flows), while the muscle fills, moves its
/// load and vents, with a proportional and with a PWM on/off valve, and behind the regulator.
#[test]
fn valve_fed_chamber_conserves_mass() {
    let feeds = [
        (
            "proportional",
            Feed::Valve(valve(ValveKind::Proportional {
                response_time_s: 0.005,
            })),
        ),
        (
            "pwm",
            Feed::Valve(ValveModel {
                underlap: 0.0,
                ..valve(ValveKind::OnOffPwm {
                    pwm_frequency_hz: 50.0,
                    switching_delay_s: 0.002,
                })
            }),
        ),
        (
            "regulator",
            Feed::Regulator {
                time_constant_s: 0.02,
            },
        ),
    ];
    let friction = BraidFriction {
        coulomb_n: 1.0,
        coulomb_n_per_pa: 1.0e-5,
        smooth_velocity_m_per_s: 1.0e-3,
    };
    for (name, feed) in feeds {
        let c = chamber(1.25, friction, 1.4);
        let mut plant = MusclePlant::new(c, load(), feed);
        let mut x = start();
        let m0 = c.gas_mass_kg(&x.chamber, x.length_m);
        let (mut worst, mut m_max, mut moved) = (0.0f64, 0.0f64, 0.0f64);
        // Fill, hold, vent halfway, refill: u = sin(2 pi 1.5 t), or set pressures between 1 and 6 bar.
        let command = |t: f64| {
            let u = (2.0 * PI * 1.5 * t).sin();
            if name == "regulator" {
                P_ATM + 3.0e5 * (1.0 + u)
            } else {
                u
            }
        };
        run(&mut plant, &mut x, 1.0e-4, 1.0, command, |p, x| {
            let m = p.chamber.gas_mass_kg(&x.chamber, x.length_m);
            worst = worst.max((m - m0 - x.inflow_kg).abs());
            m_max = m_max.max(m);
            moved = moved.max((x.length_m - 0.2).abs());
        });
        assert!(
            m_max > 3.0 * m0,
            "{name}: the muscle must fill: {m_max} vs {m0} kg"
        );
        assert!(moved > 0.01, "{name}: the load must move: {moved} m");
        eprintln!(
            "{name}: mass balance off by at most {:.3e} of the largest mass",
            worst / m_max
        );
        assert!(
            worst < 1e-9 * m_max,
            "{name}: mass balance off by {worst} kg of {m_max}"
        );
    }
}

/// Bisection on the static balance written out by hand, independent of the crate:
/// pi r0^2 p [a (1 - k eps)^2 - b] = k_s (L_s - L) + F_pull, with a = 9, b = 4, k = 1.25, L0 = 0.2 m.
fn equilibrium_by_bisection(p_gauge: f64, load: &Load) -> f64 {
    let residual = |l: f64| {
        let eps = 1.0 - l / 0.2;
        let s = 1.0 - 1.25 * eps;
        PI * 0.005 * 0.005 * p_gauge * (9.0 * s * s - 4.0)
            - (load.spring_n_per_m * (load.spring_free_length_m - l) + load.pull_n)
    };
    // Tension falls and the load's pull rises as the muscle shortens: one root between eps_max and L0.
    let (mut lo, mut hi) = (0.2 * (1.0 - 4.0 / 15.0), 0.2);
    assert!(residual(lo) < 0.0 && residual(hi) > 0.0);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if residual(mid) > 0.0 {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    0.5 * (lo + hi)
}

/// The muscle-mass-spring plant settles where the bisection puts it: the valve fully open fills the muscle
/// to the supply pressure, the regulator to its set pressure; with braid friction (which vanishes at rest)
/// and the same to 10 nm at half the step (both under the friction's RK4 limit).
#[test]
fn plant_settles_at_static_equilibrium() {
    let friction = BraidFriction {
        coulomb_n: 1.0,
        coulomb_n_per_pa: 1.0e-5,
        smooth_velocity_m_per_s: 1.0e-3,
    };
    let cases = [
        (
            Feed::Valve(valve(ValveKind::Proportional {
                response_time_s: 0.005,
            })),
            1.0,
            6.0e5,
        ),
        (
            Feed::Regulator {
                time_constant_s: 0.02,
            },
            P_ATM + 2.5e5,
            2.5e5,
        ),
    ];
    for (feed, command, p_gauge) in cases {
        let want = equilibrium_by_bisection(p_gauge, &load());
        let mut ends = vec![];
        for dt in [1.0e-4, 5.0e-5] {
            let c = chamber(1.25, friction, 1.4);
            let mut plant = MusclePlant::new(c, load(), feed);
            // 2.785 x 0.5 kg x 1e-3 m/s / (1 N + 1e-5 N/Pa x 6e5 Pa) = 1.99e-4 s; at 2e-4 s the valve
            // case ends 0.46 um off, a friction limit cycle.
            assert!((plant.friction_step_limit_s() - 1.989_285_714e-4).abs() < 1e-12);
            assert!(dt < plant.friction_step_limit_s());
            let mut x = start();
            // The tanh friction is a damper F_f / v_s ~ 7000 N s/m near rest: the last millimetre is a
            // creep with time constant c / k ~ 0.9 s (docs/muscles.md), hence 15 s.
            run(&mut plant, &mut x, dt, 15.0, |_| command, |_, _| {});
            eprintln!(
                "{}: dt {dt} s: {:.9} m, bisection {want:.9} m",
                if command > 1.5 { "regulator" } else { "valve" },
                x.length_m
            );
            let gauge = x.chamber.pressure_pa - P_ATM;
            assert!(
                (gauge - p_gauge).abs() < 1.0,
                "{gauge} Pa gauge, want {p_gauge}"
            );
            assert!(
                (x.length_m - want).abs() < 1e-8,
                "dt {dt}: settled at {} m, bisection {want} m",
                x.length_m
            );
            ends.push(x.length_m);
        }
        assert!((ends[0] - ends[1]).abs() < 1e-8);
    }
}
