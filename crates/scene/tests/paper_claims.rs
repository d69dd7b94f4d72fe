//! The paper's claims (Section III-E, Figs. 3–4) as thresholds on paper-fig3, on the ideal inner loop and on
//! the 1-DOF pneumatic plant: against impedance control, adaptive impedance control has a lower RMS force
//! error and less phase lag on the sine, and after the stiffness change (700 → 1400 N/m at 6 s) a smaller
//! recovery overshoot and a shorter settling time; both runs stay bounded.
//!
//! Settling after the event is measured back to the steady tracking level (`settling_time_to_tracking_s`):
//! the reference after 6 s is a sine, whose tracking error never enters a plain 2% band for either
//! controller (`settling_time_s` is null for both; see docs/scenes.md).

use std::path::Path;
use std::sync::OnceLock;

use pneuflex_scene::{RunResult, Scene, WindowMetrics, run_scene};

fn run(file: &str) -> Vec<RunResult> {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../scenes")
        .join(file);
    let scene = Scene::load(&path).unwrap_or_else(|e| panic!("{e}"));
    run_scene(&scene, &mut |_| {}).unwrap_or_else(|e| panic!("{e}"))
}

fn ideal() -> &'static [RunResult] {
    static R: OnceLock<Vec<RunResult>> = OnceLock::new();
    R.get_or_init(|| run("paper-fig3-ideal.toml"))
}

fn pneumatic() -> &'static [RunResult] {
    static R: OnceLock<Vec<RunResult>> = OnceLock::new();
    R.get_or_init(|| run("paper-fig3.toml"))
}

fn window<'a>(res: &'a [RunResult], run: &str, window: &str) -> &'a WindowMetrics {
    let r = res
        .iter()
        .find(|r| r.name == run)
        .unwrap_or_else(|| panic!("no run {run}"));
    assert!(r.diverged.is_none(), "{run} diverged: {:?}", r.diverged);
    r.window(window)
        .unwrap_or_else(|| panic!("no window {window}"))
}

fn bounded(res: &[RunResult]) {
    for r in res {
        assert!(
            r.diverged.is_none(),
            "{} diverged: {:?}",
            r.name,
            r.diverged
        );
        // Bounded: the force never exceeds three times the largest reference (12 N), and x stays finite.
        let f_max = r.trace.f_e().iter().fold(0.0_f64, |m, f| m.max(f.abs()));
        assert!(f_max < 36.0, "{}: peak |f_e| = {f_max} N", r.name);
        assert!(r.trace.x().iter().all(|x| x.is_finite()));
    }
}

fn lower_rms_on_sine(res: &[RunResult]) {
    let (a, i) = (
        window(res, "adaptive", "sine"),
        window(res, "impedance", "sine"),
    );
    assert!(
        a.rms_force_error_n < i.rms_force_error_n,
        "RMS force error on the sine: adaptive {:.4} N, impedance {:.4} N",
        a.rms_force_error_n,
        i.rms_force_error_n
    );
}

fn less_lag_on_sine(res: &[RunResult]) {
    let (a, i) = (
        window(res, "adaptive", "sine"),
        window(res, "impedance", "sine"),
    );
    let (la, li) = (a.phase_lag_deg.unwrap(), i.phase_lag_deg.unwrap());
    assert!(
        la >= 0.0 && la < li,
        "phase lag on the sine: adaptive {la:.2}°, impedance {li:.2}°"
    );
}

fn smaller_recovery_overshoot(res: &[RunResult]) {
    let a = window(res, "adaptive", "stiffness_change").event.unwrap();
    let i = window(res, "impedance", "stiffness_change").event.unwrap();
    assert!(
        a.recovery_overshoot_n < i.recovery_overshoot_n,
        "recovery overshoot after the stiffness change: adaptive {:.3} N, impedance {:.3} N",
        a.recovery_overshoot_n,
        i.recovery_overshoot_n
    );
}

fn shorter_settling(res: &[RunResult]) {
    let a = window(res, "adaptive", "stiffness_change").event.unwrap();
    let i = window(res, "impedance", "stiffness_change").event.unwrap();
    let ta = a
        .settling_time_to_tracking_s
        .expect("adaptive settles back to its tracking level");
    // Impedance not settling at all also satisfies the claim.
    if let Some(ti) = i.settling_time_to_tracking_s {
        assert!(
            ta < ti,
            "settling time after the stiffness change: adaptive {ta:.3} s, impedance {ti:.3} s"
        );
    }
}

#[test]
fn ideal_both_bounded() {
    bounded(ideal());
}
#[test]
fn ideal_adaptive_lower_rms_force_error_on_sine() {
    lower_rms_on_sine(ideal());
}
#[test]
fn ideal_adaptive_less_phase_lag_on_sine() {
    less_lag_on_sine(ideal());
}
#[test]
fn ideal_adaptive_smaller_recovery_overshoot() {
    smaller_recovery_overshoot(ideal());
}
#[test]
fn ideal_adaptive_shorter_settling() {
    shorter_settling(ideal());
}

#[test]
fn pneumatic_both_bounded() {
    bounded(pneumatic());
}
#[test]
fn pneumatic_adaptive_lower_rms_force_error_on_sine() {
    lower_rms_on_sine(pneumatic());
}
#[test]
fn pneumatic_adaptive_less_phase_lag_on_sine() {
    less_lag_on_sine(pneumatic());
}
#[test]
#[ignore = "does not hold with the defaults: adaptive 5.44 N vs impedance 4.18 N recovery overshoot on the \
            pneumatic plant (the 40 Hz PWM ripple of about ±1.3 N dominates the peak); reported, not tuned"]
fn pneumatic_adaptive_smaller_recovery_overshoot() {
    smaller_recovery_overshoot(pneumatic());
}
#[test]
fn pneumatic_adaptive_shorter_settling() {
    shorter_settling(pneumatic());
}

#[test]
fn lyapunov_field_is_present_and_non_increasing() {
    for res in [ideal(), pneumatic()] {
        let a = res.iter().find(|r| r.name == "adaptive").unwrap();
        let l = a.lyapunov.expect("adaptive runs carry the Lyapunov check");
        assert!(l.non_increasing && l.v_end <= l.v0, "{l:?}");
        assert!(
            res.iter()
                .find(|r| r.name == "impedance")
                .unwrap()
                .lyapunov
                .is_none()
        );
    }
}
