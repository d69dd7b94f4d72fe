//! The loop at the valve measured by injection in closed loop (`analysis::injection`, what `tf --loop`
//! gives for a scene of several actuators) against the same loop from the state-space linearisation of
//! `analysis::loop_margins` (`loop_at_valve`: L = P (C_y + C_r k_e / (m_d s² + b_d s + k_d))), on the
//! paper's linear model, where both must agree.

use std::path::Path;

use pneuflex_scene::analysis::injection::{Injection, measure};
use pneuflex_scene::analysis::loop_margins::loop_at_valve;
use pneuflex_scene::{Scene, build_plant};

#[test]
fn the_injected_loop_is_the_linearised_loop_on_the_linear_model() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/paper-fig3-linear.toml");
    let scene = Scene::load(&path).unwrap();
    let run = 0; // impedance
    assert_eq!(scene.runs[run].name, "impedance");
    let mut plant = build_plant(&scene).unwrap();
    let mut controller = scene.controller(run).unwrap();
    let schedule = scene.setpoints().unwrap();
    // The reference held at its first value (10 N against 700 N/m).
    let held = schedule.at(0.0);
    let inj = Injection::default();
    let measured = measure(
        &mut *plant,
        &mut [&mut *controller],
        scene.runs[run].controller,
        &mut |_, _| held,
        scene.dt_s,
        &inj,
        &scene.divergence,
        &|k, m| scene.invalid(k, m),
    )
    .unwrap();
    let freqs: Vec<f64> = measured.response.iter().map(|r| r.0).collect();
    let model = loop_at_valve(&scene, run, 700.0, &freqs).unwrap();
    assert_eq!(model.len(), measured.response.len());
    let mut compared = 0;
    for (m, l) in measured.response.iter().zip(&model) {
        // The model leaves out the impedance filter's zero-order hold: below 20 Hz it is exact to a degree.
        if m.0 > 20.0 {
            continue;
        }
        let (mag_m, mag_l) = (m.1.hypot(m.2), l.1.hypot(l.2));
        let dphase = (m.2.atan2(m.1) - l.2.atan2(l.1)).to_degrees();
        let dphase = (dphase + 540.0).rem_euclid(360.0) - 180.0;
        assert!(
            (mag_m / mag_l - 1.0).abs() < 0.02 && dphase.abs() < 1.0,
            "{:.3} Hz: |L| measured {mag_m:.4} vs model {mag_l:.4}, phase differs by {dphase:.2} deg",
            m.0
        );
        compared += 1;
    }
    assert!(compared >= 14, "{compared} frequencies below 20 Hz");
    // The margins come from the measured response (the crossover lies in the compared band).
    let gc = measured.crossover_hz.expect("|L| crosses 1");
    assert!(gc < 20.0, "crossover {gc} Hz");
    eprintln!(
        "measured: crossover {gc:.2} Hz, phase margin {:?} deg, gain margin {:?} dB",
        measured.phase_margin_deg, measured.gain_margin_db
    );
}
