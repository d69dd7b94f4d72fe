//! Independent checks of the building blocks against closed forms.
use pneuflex_control::*;

fn close(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol * (1.0 + b.abs())
}

/// Step response of m x'' + b x' + k x = E (underdamped k > 0, and k = 0) vs the closed form.
#[test]
fn filter_step_matches_closed_form() {
    let dt = 1e-3;
    let e = 10.0;
    // Underdamped: m = 2, b = 20, k = 800 -> ω = 20, ζ = 0.25.
    let (m, b, k): (f64, f64, f64) = (2.0, 20.0, 800.0);
    let mut f = ImpedanceFilter::new(ImpedanceParams {
        m_d_kg: m,
        b_d_ns_per_m: b,
        k_d_n_per_m: k,
    })
    .unwrap();
    let w: f64 = (k / m).sqrt();
    let z = b / (2.0 * (m * k).sqrt());
    let wd = w * (1.0 - z * z).sqrt();
    for n in 1..=3000 {
        let x = f.step(e, dt);
        let t = n as f64 * dt;
        let cf =
            e / k * (1.0 - (-z * w * t).exp() * ((wd * t).cos() + z * w / wd * (wd * t).sin()));
        assert!((x - cf).abs() < 1e-12, "t={t} {x} vs {cf}");
    }
    // k = 0 (the default): x = (E/b)(t - (m/b)(1 - e^{-bt/m})).
    let p = ImpedanceParams::default();
    let mut f = ImpedanceFilter::new(p).unwrap();
    let (m, b) = (p.m_d_kg, p.b_d_ns_per_m);
    for n in 1..=3000 {
        let x = f.step(e, dt);
        let t = n as f64 * dt;
        let cf = e / b * (t - m / b * (1.0 - (-b * t / m).exp()));
        assert!((x - cf).abs() < 1e-12, "t={t} {x} vs {cf}");
    }
}

/// Retuned mid-run (k_d 800 -> 200 N/m at 1 s under a held error), the filter goes on from its state:
/// the closed form of the new system from (x_f, ẋ_f) at the switch; bad parameters leave it unchanged.
#[test]
fn retuned_filter_continues_from_its_state() {
    let (dt, e, m, b) = (1e-3, 10.0, 2.0, 20.0);
    let params = |k| ImpedanceParams {
        m_d_kg: m,
        b_d_ns_per_m: b,
        k_d_n_per_m: k,
    };
    let mut f = ImpedanceFilter::new(params(800.0)).unwrap();
    for _ in 0..1000 {
        f.step(e, dt);
    }
    let (x1, v1) = (f.x_f(), f.v_f());
    let before = f;
    assert!(f.set_params(params(f64::NAN)).is_err());
    assert!(
        f.set_params(ImpedanceParams {
            m_d_kg: 0.0,
            ..params(200.0)
        })
        .is_err()
    );
    assert_eq!(f, before, "a refused retune changes nothing");
    f.set_params(params(200.0)).unwrap();
    let k: f64 = 200.0;
    let w = (k / m).sqrt();
    let z = b / (2.0 * (m * k).sqrt());
    let wd = w * (1.0 - z * z).sqrt();
    let a = x1 - e / k;
    let bb = (v1 + z * w * a) / wd;
    for n in 1..=3000 {
        let x = f.step(e, dt);
        let t = n as f64 * dt;
        let cf = e / k + (-z * w * t).exp() * (a * (wd * t).cos() + bb * (wd * t).sin());
        assert!((x - cf).abs() < 1e-12, "t={t} {x} vs {cf}");
    }
}

/// A one-period pulse: by superposition x(t) = s(t) - s(t - dt) with s the step response; and a
/// large period (0.5 s, ω dt = 10) stays exact and stable where explicit Euler would diverge.
#[test]
fn filter_pulse_and_large_step_exact() {
    let (m, b, k): (f64, f64, f64) = (2.0, 20.0, 800.0);
    let e = 5.0;
    let w: f64 = (k / m).sqrt();
    let z = b / (2.0 * (m * k).sqrt());
    let wd = w * (1.0 - z * z).sqrt();
    let s = |t: f64| {
        if t <= 0.0 {
            0.0
        } else {
            e / k * (1.0 - (-z * w * t).exp() * ((wd * t).cos() + z * w / wd * (wd * t).sin()))
        }
    };
    for dt in [1e-3, 0.5] {
        let mut f = ImpedanceFilter::new(ImpedanceParams {
            m_d_kg: m,
            b_d_ns_per_m: b,
            k_d_n_per_m: k,
        })
        .unwrap();
        let mut x = f.step(e, dt);
        assert!((x - s(dt)).abs() < 1e-12);
        for n in 2..=40 {
            x = f.step(0.0, dt);
            let t = n as f64 * dt;
            assert!((x - (s(t) - s(t - dt))).abs() < 1e-12, "dt={dt} t={t}");
        }
    }
}

/// Clamping: the integrator stops growing while the output saturates; recovery after the error
/// reverses takes the closed-form time (frozen integral / (k_i |e|) ), not the wound-up one.
#[test]
fn pid_clamping_anti_windup() {
    let params = PidParams {
        kp_per_m: 50.0,
        ki_per_m_s: 50.0,
        kd_s_per_m: 0.0,
        ..PidParams::default()
    };
    let mut pid = Pid::new(params).unwrap();
    let dt = 1e-3;
    // Blocked actuator: y = 0, r = 0.01 -> P = 0.5, integral grows 0.5/s and saturates at t ≈ 1 s.
    let mut t_sat = None;
    for n in 0..3000 {
        let u = pid.update(0.01, 0.0, dt);
        if t_sat.is_none() && pid.saturated() {
            t_sat = Some(n);
        }
        assert!(u <= 1.0);
    }
    let i_frozen = pid.integral();
    assert!(
        (i_frozen - 0.5).abs() < 2.0 * 50.0 * 0.01 * dt,
        "integral {i_frozen}"
    );
    assert!(t_sat.unwrap() >= 995 && t_sat.unwrap() <= 1005);
    // Error reverses: r - y = -0.002 -> P = -0.1; u = 0.5 - 0.1 - 0.1 t crosses 0 at t = 4 s.
    let mut t_cross = None;
    for n in 1..20000 {
        let u = pid.update(0.0, 0.002, dt);
        if u < 0.0 {
            t_cross = Some(n as f64 * dt);
            break;
        }
    }
    let tc = t_cross.unwrap();
    assert!((tc - 4.0).abs() < 0.01, "recovery {tc}");
}

/// Back-calculation: the integral settles where u_unsat - u_max = k_i e T_t (bounded), and the
/// output leaves saturation right after the error reverses.
#[test]
fn pid_back_calculation_bounded() {
    let tt = 0.05;
    let params = PidParams {
        kp_per_m: 50.0,
        ki_per_m_s: 50.0,
        kd_s_per_m: 0.0,
        anti_windup: AntiWindup::BackCalculation {
            tracking_time_s: tt,
        },
        ..PidParams::default()
    };
    let mut pid = Pid::new(params).unwrap();
    for _ in 0..5000 {
        pid.update(0.01, 0.0, 1e-3);
    }
    // Steady state of I' = k_i e + (u_max - (P + I))/T_t = 0 -> I = u_max - P + k_i e T_t.
    let expect = 1.0 - 0.5 + 50.0 * 0.01 * tt;
    assert!(
        (pid.integral() - expect).abs() < 1e-3,
        "{} vs {expect}",
        pid.integral()
    );
    // Reverse: P = -0.1, I decays from 0.525 at rate ≈ 0.1/s -> crossing at ≈ 4.25 s (no windup beyond).
    let mut n = 0;
    while pid.update(0.0, 0.002, 1e-3) >= 0.0 {
        n += 1;
        assert!(n < 6000);
    }
    assert!((n as f64 * 1e-3 - 4.25).abs() < 0.05, "{n}");
}

/// Derivative on the measurement: a setpoint step changes u by exactly k_p Δr (no kick).
#[test]
fn pid_no_derivative_kick() {
    let params = PidParams {
        kp_per_m: 20.0,
        ki_per_m_s: 0.0,
        kd_s_per_m: 50.0,
        ..PidParams::default()
    };
    let mut pid = Pid::new(params).unwrap();
    let u0 = pid.update(0.0, 0.0, 1e-3);
    let u1 = pid.update(0.0, 0.0, 1e-3);
    let u2 = pid.update(0.01, 0.0, 1e-3);
    assert_eq!(u0, 0.0);
    assert_eq!(u1, 0.0);
    assert!((u2 - 0.2).abs() < 1e-15);
    // A measurement move does act through the derivative: opposite sign, filtered.
    let u3 = pid.update(0.01, 0.001, 1e-3);
    let alpha = 1e-3 / (0.002 + 1e-3);
    let expect: f64 = 20.0 * 0.009 - 50.0 * alpha * 1.0;
    assert!(
        (u3 - expect.clamp(-1.0, 1.0)).abs() < 1e-12,
        "{u3} vs {expect}"
    );
}

/// Sine value and phase; step time; ramp; schedule switching at the declared times.
#[test]
fn references_and_schedule() {
    let s = Reference::Sine {
        bias: 10.0,
        amplitude: 2.0,
        frequency_hz: 0.8,
        phase_rad: 0.3,
    };
    for t in [0.0, 0.1, 0.77, 1.9] {
        let expect = 10.0 + 2.0 * (std::f64::consts::TAU * 0.8 * t + 0.3).sin();
        assert!((s.value(t) - expect).abs() < 1e-12);
    }
    // Quarter period after τ = 0 with phase 0: the peak.
    let s0 = Reference::Sine {
        bias: 1.0,
        amplitude: 2.0,
        frequency_hz: 2.0,
        phase_rad: 0.0,
    };
    assert!((s0.value(0.125) - 3.0).abs() < 1e-12);
    let st = Reference::Step {
        initial: 1.0,
        final_value: 4.0,
        t_step_s: 0.5,
    };
    assert_eq!(st.value(0.499), 1.0);
    assert_eq!(st.value(0.5), 4.0);
    let r = Reference::Ramp {
        start: 2.0,
        slope_per_s: -3.0,
    };
    assert!((r.value(2.0) + 4.0).abs() < 1e-12);

    let sp = SetpointSchedule::paper_fig3(0.002).unwrap();
    assert_eq!(sp.at(2.999).f_ref, 10.0);
    assert!((sp.at(3.0).f_ref - 10.0).abs() < 1e-12);
    assert!((sp.at(3.25).f_ref - 12.0).abs() < 1e-12);
    assert!((sp.at(3.75).f_ref - 8.0).abs() < 1e-12);
    assert_eq!(sp.at(5.0).x_d, 0.002);
    assert_eq!(sp.force_n.active_segment(2.999), Some(0));
    assert_eq!(sp.force_n.active_segment(3.0), Some(1));

    let mut sch: Schedule<2> = Schedule::new();
    sch.push(0.0, Reference::Constant { value: 1.0 }).unwrap();
    assert!(matches!(
        sch.push(0.0, Reference::Constant { value: 1.0 }),
        Err(ParamError::ScheduleOrder { .. })
    ));
    sch.push(1.0, Reference::Constant { value: 2.0 }).unwrap();
    assert_eq!(
        sch.push(2.0, Reference::Constant { value: 3.0 }),
        Err(ParamError::ScheduleFull { capacity: 2 })
    );
    assert_eq!(sch.value(-1.0), 1.0);
    assert_eq!(sch.value(1.5), 2.0);
}

/// With e = 0 and ẋ = 0 the adaptive states decay as exp(-σ t) (leakage) or grow as
/// exp(+σ1 t) (the printed σ1 sign), exactly, at any period.
#[test]
fn adaptive_sigma_decay_closed_form() {
    for dt in [1e-3, 0.01, 0.37] {
        let a = AdaptiveParams {
            sigma1: 0.1,
            sigma2: 0.2,
            sigma3: 0.3,
            ..AdaptiveParams::default()
        };
        let mut law = AdaptiveLaw::with_initial(a, 1.0, -2.0, 3.0).unwrap();
        let mut printed = AdaptiveLaw::with_initial(
            a.with_signs(LambdaDSign::FromEdot, Sigma1Sign::AsPrinted),
            1.0,
            0.0,
            0.0,
        )
        .unwrap();
        let n = (10.0 / dt) as usize;
        for _ in 0..n {
            let dx = law.update(0.0, 0.0, dt);
            assert!((dx - law.g()).abs() < 1e-15);
            printed.update(0.0, 0.0, dt);
        }
        let t = n as f64 * dt;
        assert!(
            close(law.g(), (-0.1 * t).exp(), 1e-12),
            "{} {}",
            law.g(),
            (-0.1 * t).exp()
        );
        assert!(close(law.p(), -2.0 * (-0.2 * t).exp(), 1e-12));
        assert!(close(law.d(), 3.0 * (-0.3 * t).exp(), 1e-12));
        assert!(close(printed.g(), (0.1 * t).exp(), 1e-12));
    }
}

/// One adaptive step with constant e, ẋ matches the exact solution of q' = -σ q + u.
#[test]
fn adaptive_forced_step_exact() {
    let a = AdaptiveParams::default();
    let mut law = AdaptiveLaw::new(a).unwrap();
    let (e, v, dt) = (2.0, 0.01, 0.5);
    let dx = law.update(e, v, dt);
    let chi = -(a.lambda_p * e - a.lambda_d * v);
    let k = (1.0 - (-0.1 * dt).exp()) / 0.1;
    let g = -a.mu1 * chi * k;
    let p = -a.mu2 * chi * e * k;
    let d = -a.mu3 * chi * v * k;
    assert!(close(law.g(), g, 1e-14) && close(law.p(), p, 1e-14) && close(law.d(), d, 1e-14));
    assert!(close(dx, g + p * e + d * v, 1e-14));
    // Units: the same gains read in mm give Δx_f from scaled signals, returned in metres.
    let mut mm = AdaptiveLaw::new(a.with_units(1.0, 1e-3)).unwrap();
    let dx_mm = mm.update(e, v, dt);
    let vs = v / 1e-3;
    let chi = -(e - 8.0 * vs);
    let (g, p, d) = (-0.01 * chi * k, -1e-4 * chi * e * k, -0.01 * chi * vs * k);
    assert!(close(dx_mm, (g + p * e + d * vs) * 1e-3, 1e-14));
}

/// P solves A_mᵀP + PA_m = -Q to ~1e-12; V is non-increasing along the simulated unmodified
/// MRAC law, and V(0) - V(T) equals ∫½E_eᵀQE_e dt (the identity V̇ = -½E_eᵀQE_e).
#[test]
fn lyapunov_solution_and_v_decrease() {
    let q = [[3.0, 0.5], [0.5, 2.0]];
    let p = lyapunov::solve_lyapunov(12.0, 150.0, &q).unwrap();
    let r = lyapunov::lyapunov_residual(12.0, 150.0, &p, &q);
    for row in r {
        for v in row {
            assert!(v.abs() < 1e-12, "residual {v}");
        }
    }
    assert!(
        p[0][0] > 0.0 && p[0][0] * p[1][1] - p[0][1] * p[1][0] > 0.0,
        "P positive definite"
    );

    let rep = lyapunov_check(&LyapunovCheckParams::default()).unwrap();
    println!("lyapunov default: {rep:?}");
    assert!(rep.residual < 1e-12);
    assert!(rep.v_end < rep.v0);
    assert!(
        rep.non_increasing(1e-12),
        "max ΔV {} (V0 {})",
        rep.max_delta_v,
        rep.v0
    );
    let balance = (rep.v0 - rep.v_end - rep.dissipated).abs() / rep.v0;
    assert!(balance < 1e-6, "energy balance {balance}");

    // An initial state with a large parameter error and Q ≠ I.
    let params = LyapunovCheckParams {
        q,
        a_m: 12.0,
        b_m: 150.0,
        beta0: 0.5,
        beta1: 2.0,
        beta2: 0.1,
        initial: MracState {
            e: 3.0,
            e_dot: -20.0,
            e_m: 0.0,
            e_m_dot: 0.0,
            a_p: 1.0,
            b_p: 900.0,
            w_p: -40.0,
        },
        ..LyapunovCheckParams::default()
    };
    let rep = lyapunov_check(&params).unwrap();
    assert!(
        rep.non_increasing(1e-12),
        "max ΔV {} (V0 {})",
        rep.max_delta_v,
        rep.v0
    );
    assert!((rep.v0 - rep.v_end - rep.dissipated).abs() / rep.v0 < 1e-6);
}

/// Bad parameters give the named error.
#[test]
fn validation_errors() {
    let bad_m = ImpedanceParams {
        m_d_kg: 0.0,
        ..ImpedanceParams::default()
    };
    assert_eq!(
        bad_m.validate(),
        Err(ParamError::NotPositive {
            name: "m_d_kg",
            value: 0.0
        })
    );
    let bad_b = ImpedanceParams {
        b_d_ns_per_m: -1.0,
        ..ImpedanceParams::default()
    };
    assert_eq!(
        bad_b.validate(),
        Err(ParamError::Negative {
            name: "b_d_ns_per_m",
            value: -1.0
        })
    );
    let nan = ImpedanceParams {
        k_d_n_per_m: f64::NAN,
        ..ImpedanceParams::default()
    };
    assert!(matches!(
        nan.validate(),
        Err(ParamError::NotFinite {
            name: "k_d_n_per_m",
            ..
        })
    ));
    assert!(ImpedanceController::new(bad_m, PidParams::default()).is_err());

    let a = AdaptiveParams {
        mu1: -0.01,
        ..AdaptiveParams::default()
    };
    assert_eq!(
        a.validate(),
        Err(ParamError::Negative {
            name: "mu1",
            value: -0.01
        })
    );
    let a = AdaptiveParams {
        position_unit_m: 0.0,
        ..AdaptiveParams::default()
    };
    assert!(matches!(
        a.validate(),
        Err(ParamError::NotPositive {
            name: "position_unit_m",
            ..
        })
    ));
    let a = AdaptiveParams {
        sigma2: f64::INFINITY,
        ..AdaptiveParams::default()
    };
    assert!(matches!(
        a.validate(),
        Err(ParamError::NotFinite { name: "sigma2", .. })
    ));

    let pid = PidParams {
        u_min: 1.0,
        u_max: -1.0,
        ..PidParams::default()
    };
    assert_eq!(
        pid.validate(),
        Err(ParamError::BadLimits {
            u_min: 1.0,
            u_max: -1.0
        })
    );
    let pid = PidParams {
        anti_windup: AntiWindup::BackCalculation {
            tracking_time_s: 0.0,
        },
        ..PidParams::default()
    };
    assert!(matches!(
        pid.validate(),
        Err(ParamError::NotPositive {
            name: "tracking_time_s",
            ..
        })
    ));

    assert!(matches!(
        lyapunov::solve_lyapunov(-1.0, 10.0, &[[1.0, 0.0], [0.0, 1.0]]),
        Err(ParamError::UnstableReferenceModel { .. })
    ));
    assert_eq!(
        lyapunov::solve_lyapunov(1.0, 10.0, &[[1.0, 2.0], [2.0, 1.0]]),
        Err(ParamError::QNotPositiveDefinite)
    );
    let bad_ref = Reference::Sine {
        bias: 0.0,
        amplitude: 1.0,
        frequency_hz: -1.0,
        phase_rad: 0.0,
    };
    let mut s: Schedule = Schedule::new();
    assert!(matches!(
        s.push(0.0, bad_ref),
        Err(ParamError::Negative {
            name: "frequency_hz",
            ..
        })
    ));
    // Error messages name the field.
    let msg = format!(
        "{}",
        ParamError::Negative {
            name: "mu1",
            value: -0.01
        }
    );
    assert!(msg.contains("mu1") && msg.contains(">= 0"));
}

/// NaN sensors never open the valve; controllers implement reset.
#[test]
fn nan_sensor_gives_closed_valve_and_reset_clears() {
    let mut c = AdaptiveImpedanceController::new(
        ImpedanceParams::default(),
        AdaptiveParams::default(),
        PidParams::default(),
    )
    .unwrap();
    let sp = Setpoint {
        f_ref: 10.0,
        x_d: 0.0,
    };
    let u = c.update(
        &Sensors {
            x: f64::NAN,
            ..Sensors::default()
        },
        &sp,
        1e-3,
    );
    assert_eq!(u.u, 0.0);
    c.reset();
    assert_eq!(c.telemetry(), Telemetry::default());
    let u = c.update(&Sensors::default(), &sp, 1e-3);
    assert!(u.u > 0.0, "positive force error extends");
}

/// Parameter projection: under a pure velocity ripple ẋ = A sin(ωt) with e = 0 the unbounded d drifts to the
/// closed-form mean -μ3 λd A²/(2 σ3) (eq. 35 with χ = λd ẋ); with d_max it stays in [-d_max, 0]. Under a
/// force ripple p grows (ṗ = μ2 λp e² when ẋ = 0) and the bound holds it in [0, p_max].
#[test]
fn projection_bounds_p_and_d_where_sigma_modification_alone_drifts() {
    let (amp, w, dt): (f64, f64, f64) = (0.3, 2.0 * core::f64::consts::PI * 40.0, 1e-3 / 8.0);
    let free = AdaptiveParams::default();
    let bounded = AdaptiveParams {
        p_max_m_per_n: 3.57e-4,
        d_max_s: 0.005,
        ..AdaptiveParams::default()
    };
    let mut a = AdaptiveLaw::new(free).unwrap();
    let mut b = AdaptiveLaw::new(bounded).unwrap();
    let n = (60.0 / dt) as usize; // 6 time constants of σ3 = 0.1 /s
    let period = (1.0 / 40.0 / dt).round() as usize;
    let mut d_mean = 0.0;
    for k in 0..n {
        let v = amp * (w * k as f64 * dt).sin();
        a.update(0.0, v, dt);
        b.update(0.0, v, dt);
        assert!(
            (-0.005..=0.0).contains(&b.d()),
            "d = {} left [-5 ms, 0]",
            b.d()
        );
        if k >= n - period {
            d_mean += a.d() / period as f64;
        }
    }
    let expect = -free.mu3 * free.lambda_d * amp * amp / (2.0 * free.sigma3);
    assert!(
        (d_mean - expect).abs() <= 0.02 * expect.abs(),
        "unbounded d drifts to {d_mean}, closed form {expect}"
    );
    assert!(b.d() <= -0.0049, "the bound is reached: d = {}", b.d());

    let mut b = AdaptiveLaw::new(bounded).unwrap();
    let mut a = AdaptiveLaw::new(free).unwrap();
    for k in 0..(20.0 / dt) as usize {
        let e = 1.0 + (w * k as f64 * dt).sin();
        a.update(e, 0.0, dt);
        b.update(e, 0.0, dt);
        assert!(
            (0.0..=3.57e-4).contains(&b.p()),
            "p = {} left [0, p_max]",
            b.p()
        );
    }
    assert!(
        a.p() > 3.57e-4,
        "without the bound p grows past it: {}",
        a.p()
    );
}

/// The d box follows the sign convention: with λd as printed the law drives d positive (anti-damping, mean
/// +μ3 λd A²/(2 σ3) under a velocity ripple), and the bound [0, d_max] limits it there instead of clamping
/// it to zero — the d term stays on. d_max = 0 switches it off on purpose.
#[test]
fn the_d_bound_limits_the_as_printed_sign_instead_of_switching_the_term_off() {
    let (amp, w, dt): (f64, f64, f64) = (0.3, 2.0 * core::f64::consts::PI * 40.0, 1e-3 / 8.0);
    let printed = AdaptiveParams::paper_si_as_printed()
        .with_signs(LambdaDSign::AsPrinted, Sigma1Sign::Leakage);
    let bounded = AdaptiveParams {
        d_max_s: 0.005,
        ..printed
    };
    let off = AdaptiveParams {
        d_max_s: 0.0,
        ..printed
    };
    let (mut b, mut z) = (
        AdaptiveLaw::new(bounded).unwrap(),
        AdaptiveLaw::new(off).unwrap(),
    );
    for k in 0..(60.0 / dt) as usize {
        let v = amp * (w * k as f64 * dt).sin();
        b.update(0.0, v, dt);
        z.update(0.0, v, dt);
        assert!(
            (0.0..=0.005).contains(&b.d()),
            "d = {} left [0, 5 ms]",
            b.d()
        );
        assert_eq!(z.d(), 0.0);
    }
    assert!(
        b.d() >= 0.0049,
        "d reaches its bound and stays on: {}",
        b.d()
    );
}

/// A frozen law gives Δx_f = g0 + p0 e + d0 ẋ (eq. (36)) at every tick and never moves, whatever e and ẋ
/// do; held at zero, the frozen adaptive controller is the impedance controller tick for tick.
#[test]
fn a_frozen_law_holds_its_values_and_at_zero_is_the_impedance_controller() {
    let a = AdaptiveParams {
        p_max_m_per_n: 3.57e-4,
        d_max_s: 0.005,
        ..AdaptiveParams::default()
    };
    let (g0, p0, d0) = (2.0e-3 / a.position_unit_m, 1.0e-4, -4.0e-3);
    let mut law = AdaptiveLaw::frozen(a, g0, p0, d0).unwrap();
    assert!(law.is_frozen());
    let mut live = AdaptiveLaw::with_initial(a, g0, p0, d0).unwrap();
    let dt = 1e-3;
    for k in 0..2000 {
        let t = k as f64 * dt;
        let (e, v) = (5.0 * (7.0 * t).sin() + 1.0, 0.02 * (3.0 * t).cos());
        let dx = law.update(e, v, dt);
        live.update(e, v, dt);
        let expect =
            (g0 + p0 * e / a.force_unit_n + d0 * v / a.position_unit_m) * a.position_unit_m;
        assert!(
            (dx - expect).abs() <= 1e-15 * (1.0 + expect.abs()),
            "tick {k}: {dx} vs {expect}"
        );
        assert_eq!((law.g(), law.p(), law.d()), (g0, p0, d0));
    }
    assert_ne!(
        (live.g(), live.p(), live.d()),
        (g0, p0, d0),
        "the live law adapts"
    );
    live.reset();
    assert_eq!(
        (live.g(), live.p(), live.d()),
        (g0, p0, d0),
        "reset goes back to g0, p0, d0"
    );

    let (imp, pid) = (ImpedanceParams::default(), PidParams::default());
    let mut frozen = AdaptiveImpedanceController::frozen(imp, a, pid, 0.0, 0.0, 0.0).unwrap();
    let mut plain = ImpedanceController::new(imp, pid).unwrap();
    for k in 0..2000 {
        let t = k as f64 * dt;
        let s = Sensors {
            x: 0.01 * (2.0 * t).sin(),
            x_dot: 0.02 * (2.0 * t).cos(),
            f_e: 20.0 * (1.0 - (-5.0 * t).exp()),
            ..Sensors::default()
        };
        let sp = Setpoint {
            f_ref: 30.0,
            x_d: 0.0,
        };
        assert_eq!(
            frozen.update(&s, &sp, dt),
            plain.update(&s, &sp, dt),
            "tick {k}"
        );
    }
}
