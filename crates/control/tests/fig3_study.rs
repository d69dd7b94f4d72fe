//! The paper's Fig. 3 experiment on the ideal-loop plant: impedance vs adaptive impedance,
//! with the units conventions and sign choices of the adaptive law side by side.
mod common;
use common::*;
use pneuflex_control::*;

const DT: f64 = 1e-3;

fn fig3<C: Controller>(c: &mut C) -> Vec<Sample> {
    let sched = SetpointSchedule::paper_fig3(0.0).unwrap();
    run(c, &sched, 700.0, 1400.0, 6.0, 10.0, DT)
}

struct Metrics {
    rms_all: f64,
    rms_sine: f64,
    lag: f64,
    overshoot: f64,
    settle: Option<f64>,
    rms_after: f64,
    bounded: bool,
}

fn metrics(tr: &[Sample]) -> Metrics {
    Metrics {
        rms_all: rms_error(tr, 0.0, 10.0),
        rms_sine: rms_error(tr, 4.0, 6.0),
        lag: lag_deg(tr, 4.0, 6.0, 1.0),
        overshoot: max_overshoot(tr, 6.0, 7.0),
        settle: settle_time(tr, 6.0, 10.0, 0.2),
        rms_after: rms_error(tr, 6.0, 10.0),
        bounded: bounded(tr),
    }
}

fn print(name: &str, m: &Metrics) {
    println!(
        "{name:<40} rms[0,10]={:8.4} rms_sine[4,6]={:8.4} lag={:7.2}° overshoot[6,7]={:8.4} settle(0.2N)={:?} rms[6,10]={:8.4} bounded={}",
        m.rms_all, m.rms_sine, m.lag, m.overshoot, m.settle, m.rms_after, m.bounded
    );
}

fn adaptive(a: AdaptiveParams) -> Vec<Sample> {
    let mut c =
        AdaptiveImpedanceController::new(ImpedanceParams::default(), a, PidParams::default())
            .unwrap();
    fig3(&mut c)
}

#[test]
fn fig3_table() {
    let mut imp =
        ImpedanceController::new(ImpedanceParams::default(), PidParams::default()).unwrap();
    let mi = metrics(&fig3(&mut imp));
    print("impedance", &mi);
    let base = AdaptiveParams::paper_si_as_printed();
    for (fu, xu, unit) in [
        (1.0, 1.0, "SI"),
        (1.0, 1e-3, "N,mm"),
        (1.0, 1e-2, "N,cm"),
        (10.0, 1.0, "10N,m"),
    ] {
        for ls in [LambdaDSign::FromEdot, LambdaDSign::AsPrinted] {
            for ss in [Sigma1Sign::Leakage, Sigma1Sign::AsPrinted] {
                let a = base.with_units(fu, xu).with_signs(ls, ss);
                let tr = adaptive(a);
                print(&format!("adaptive {unit} {ls:?} {ss:?}"), &metrics(&tr));
                let l = tr.last().unwrap();
                println!(
                    "    final g={:.4e} m p={:.4e} m/N d={:.4e} s",
                    l.g, l.p, l.d
                );
            }
        }
    }
}

#[test]
fn stiff_switch_table() {
    // A harsher event than the paper's: 700 -> 7000 N/m (wood -> iron-like), same schedule.
    let sched = SetpointSchedule::paper_fig3(0.0).unwrap();
    let mut imp =
        ImpedanceController::new(ImpedanceParams::default(), PidParams::default()).unwrap();
    print(
        "stiff impedance",
        &metrics(&run(&mut imp, &sched, 700.0, 7000.0, 6.0, 10.0, DT)),
    );
    for ls in [LambdaDSign::FromEdot, LambdaDSign::AsPrinted] {
        for ss in [Sigma1Sign::Leakage, Sigma1Sign::AsPrinted] {
            let a = AdaptiveParams::paper_si_as_printed().with_signs(ls, ss);
            let mut c = AdaptiveImpedanceController::new(
                ImpedanceParams::default(),
                a,
                PidParams::default(),
            )
            .unwrap();
            let tr = run(&mut c, &sched, 700.0, 7000.0, 6.0, 10.0, DT);
            print(&format!("stiff adaptive SI {ls:?} {ss:?}"), &metrics(&tr));
        }
    }
}

/// The paper's Section III-E claims on the ideal plant with the defaults: adaptive has lower RMS
/// force error and less lag on the sine, recovers with lower RMS error after 700 -> 1400 N/m,
/// and both stay bounded. (The peak-overshoot claim does NOT hold here: see docs/control.md.)
#[test]
fn fig3_adaptive_beats_impedance_on_ideal_plant() {
    let mut imp =
        ImpedanceController::new(ImpedanceParams::default(), PidParams::default()).unwrap();
    let mi = metrics(&fig3(&mut imp));
    let ma = metrics(&adaptive(AdaptiveParams::default()));
    assert!(mi.bounded && ma.bounded);
    assert!(
        ma.rms_sine < 0.8 * mi.rms_sine,
        "rms sine {} vs {}",
        ma.rms_sine,
        mi.rms_sine
    );
    assert!(ma.lag < mi.lag - 5.0, "lag {} vs {}", ma.lag, mi.lag);
    assert!(
        ma.rms_after < 0.7 * mi.rms_after,
        "rms after {} vs {}",
        ma.rms_after,
        mi.rms_after
    );
}

/// λd with the printed sign makes the velocity term anti-damping: on a 10x stiffness jump it
/// runs away, while the sign derived from ė = -k_e ẋ stays bounded and settles.
#[test]
fn lambda_d_sign_from_edot_survives_stiff_switch() {
    let sched = SetpointSchedule::paper_fig3(0.0).unwrap();
    let run_sign = |ls| {
        let a = AdaptiveParams::default().with_signs(ls, Sigma1Sign::Leakage);
        let mut c =
            AdaptiveImpedanceController::new(ImpedanceParams::default(), a, PidParams::default())
                .unwrap();
        run(&mut c, &sched, 700.0, 7000.0, 6.0, 10.0, DT)
    };
    let good = run_sign(LambdaDSign::FromEdot);
    let bad = run_sign(LambdaDSign::AsPrinted);
    assert!(bounded(&good));
    assert!(settle_time(&good, 6.0, 10.0, 0.2).is_some_and(|t| t < 1.0));
    assert!(!bounded(&bad) || rms_error(&bad, 6.0, 10.0) > 3.0 * rms_error(&good, 6.0, 10.0));
}

/// Impedance control on the ideal plant matches its linear closed form: zero static force error
/// for k_d = 0, the static error k_d/(k_d+k_e) for k_d > 0, and the sine phase lag of
/// f_e/f_r = k_e H G / (1 + k_e H G) with G = 1/(m_d s² + b_d s + k_d), H = ω²/(s² + 2ζωs + ω²).
#[test]
fn impedance_matches_linear_closed_form() {
    let imp = ImpedanceParams::default();
    // Static: constant 10 N, k_e = 700, x_d = x_e = 0.
    let mut sched = SetpointSchedule::default();
    sched
        .force_n
        .push(0.0, Reference::Constant { value: 10.0 })
        .unwrap();
    sched
        .position_m
        .push(0.0, Reference::Constant { value: 0.0 })
        .unwrap();
    let mut c = ImpedanceController::new(imp, PidParams::default()).unwrap();
    let tr = run(&mut c, &sched, 700.0, 700.0, 1e9, 6.0, DT);
    assert!((tr.last().unwrap().f_e - 10.0).abs() < 1e-6);
    // k_d = 300 N/m, x_d = 5 mm: f_e = (k_e f_r + k_d k_e (x_d - x_e)) / (k_d + k_e).
    let stiff = ImpedanceParams {
        k_d_n_per_m: 300.0,
        ..imp
    };
    let mut sched2 = sched;
    sched2.position_m = Schedule::constant(Reference::Constant { value: 0.005 });
    let mut c = ImpedanceController::new(stiff, PidParams::default()).unwrap();
    let tr = run(&mut c, &sched2, 700.0, 700.0, 1e9, 6.0, DT);
    let expect = (700.0 * 10.0 + 300.0 * 700.0 * 0.005) / 1000.0;
    assert!(
        (tr.last().unwrap().f_e - expect).abs() < 1e-6,
        "{} vs {}",
        tr.last().unwrap().f_e,
        expect
    );
    // Sine at 0.8 Hz (Fig. 2): bias 10, amplitude 2.
    let f = 0.8;
    let mut sched3 = SetpointSchedule::default();
    sched3
        .force_n
        .push(
            0.0,
            Reference::Sine {
                bias: 10.0,
                amplitude: 2.0,
                frequency_hz: f,
                phase_rad: 0.0,
            },
        )
        .unwrap();
    sched3
        .position_m
        .push(0.0, Reference::Constant { value: 0.0 })
        .unwrap();
    let mut c = ImpedanceController::new(imp, PidParams::default()).unwrap();
    // Start at the bias equilibrium would need state injection; run long enough instead.
    let tr = run(&mut c, &sched3, 700.0, 700.0, 1e9, 10.0, DT);
    let lag = lag_deg(&tr, 5.0, 10.0, f);
    let w = std::f64::consts::TAU * f;
    let (wn, z) = (60.0, 1.0);
    // Complex arithmetic by hand: L = k_e H G.
    let cdiv = |a: (f64, f64), b: (f64, f64)| {
        let d = b.0 * b.0 + b.1 * b.1;
        ((a.0 * b.0 + a.1 * b.1) / d, (a.1 * b.0 - a.0 * b.1) / d)
    };
    let cmul = |a: (f64, f64), b: (f64, f64)| (a.0 * b.0 - a.1 * b.1, a.0 * b.1 + a.1 * b.0);
    let h = cdiv((wn * wn, 0.0), (wn * wn - w * w, 2.0 * z * wn * w));
    let g = cdiv(
        (1.0, 0.0),
        (imp.k_d_n_per_m - imp.m_d_kg * w * w, imp.b_d_ns_per_m * w),
    );
    let l = cmul((700.0, 0.0), cmul(h, g));
    let t = cdiv(l, (1.0 + l.0, l.1));
    let lag_cf = -t.1.atan2(t.0).to_degrees();
    println!("impedance lag at {f} Hz: simulated {lag:.3}°, closed form {lag_cf:.3}°");
    assert!(
        (lag - lag_cf).abs() < 0.5,
        "lag {lag} vs closed form {lag_cf}"
    );
}
