//! The PWM valve's limit-cycle onset as `tf --loop` predicts it (the sampled-data model of the duty held
//! over each period, `pneuflex_scene::analysis::pwm_onset`) against the onset in simulation, at each
//! stiffness the scene meets: the smallest kp at which the scene's impedance run, on the full switching
//! model with the stiffness held, no longer settles (a sustained oscillation in its second half, or a
//! divergence), found by raising kp 3 % a step from half the prediction. Issue 25 asks for ±25 % on every
//! shipped PWM scene and on rigs made by `new rig`.

use std::path::Path;

use pneuflex_datasheet::{Datasheet, ValveKind, new_rig};
use pneuflex_scene::Scene;
use pneuflex_scene::analysis::loop_margins::stiffnesses;
use pneuflex_scene::analysis::pwm_onset::pwm_onset_at;
use pneuflex_scene::schema::{MetricWindow, WindowKind};

/// Run `run` alone at stiffness `k_e` held for the whole run (no events), judged by one event-kind window
/// over its second half: does it settle into the reference's periodic steady state?
fn at_stiffness(scene: &Scene, run: usize, k_e: f64) -> Scene {
    let mut one = scene.one_run(run, scene.duration_s);
    one.events.clear();
    one.environment.stiffness_n_per_m = k_e;
    one.metrics = vec![MetricWindow {
        name: "steady".into(),
        t0_s: 0.5 * one.duration_s,
        t1_s: one.duration_s,
        kind: WindowKind::Event,
    }];
    one
}

/// Whether `scene`'s only run at `kp` fails to settle, or diverges.
fn oscillates(scene: &Scene, kp: f64) -> bool {
    let mut one = scene.clone();
    one.runs[0].inner.kp_per_m = kp;
    let r = pneuflex_scene::run_scene(&one, &mut |_| {})
        .expect("runs")
        .remove(0);
    r.diverged.is_some()
        || r.windows
            .iter()
            .any(|w| w.event.as_ref().is_some_and(|e| !e.settled))
}

/// The simulated onset: the first kp from `from` up, 3 % a step, that oscillates (None up to `to`).
fn simulated(scene: &Scene, from: f64, to: f64) -> Option<f64> {
    let mut kp = from;
    while kp <= to {
        if oscillates(scene, kp) {
            return Some(kp);
        }
        kp *= 1.03;
    }
    None
}

/// The rows of one scene's impedance run, one per stiffness it meets, and whether each is within 25 %.
fn check(label: &str, scene: &Scene) -> Vec<(String, bool)> {
    let run = scene.run_index("impedance").expect("an impedance run");
    stiffnesses(scene)
        .into_iter()
        .map(|k| {
            let p = pwm_onset_at(scene, run, k)
                .expect("analysed")
                .expect("a switching valve");
            let held = at_stiffness(scene, run, k);
            let kp = p.kp_per_m;
            assert!(
                !oscillates(&held, 0.5 * kp),
                "{label} at {k} N/m: oscillates at half the predicted onset"
            );
            let s = simulated(&held, 0.5 * kp, 2.0 * kp).unwrap_or_else(|| {
                panic!("{label} at {k} N/m: no onset up to twice the predicted {kp}")
            });
            let err = (kp - s) / s;
            let row = format!(
                "| {label} | {k} | {kp:.1} at {:.1} Hz | {s:.1} | {:+.0} % |",
                p.frequency_hz,
                100.0 * err
            );
            (row, err.abs() <= 0.25)
        })
        .collect()
}

#[test]
fn the_sampled_data_onset_is_within_25_percent_of_the_simulated_one() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let mut rows = Vec::new();
    for name in ["paper-fig3", "tuning-pwm", "robustness-pwm"] {
        let scene = Scene::load(&root.join("scenes").join(format!("{name}.toml"))).unwrap();
        rows.extend(check(name, &scene));
    }
    let tmp = tempfile::tempdir().unwrap();
    for (name, bore_mm, stroke_mm, supply_bar) in [
        ("r10", 10.0, 50.0, 6.0),
        ("r25", 25.0, 100.0, 6.0),
        ("r40", 40.0, 80.0, 4.0),
    ] {
        let dir = tmp.path().join(name);
        let ds = Datasheet {
            bore_m: Some(bore_mm * 1e-3),
            stroke_m: Some(stroke_mm * 1e-3),
            supply_gauge_pa: Some(supply_bar * 1e5),
            valve: Some(ValveKind::Pwm),
            ..Default::default()
        };
        new_rig(&ds, &dir, "test").expect("the rig is written");
        let scene = Scene::load(&dir.join("scene.toml")).unwrap();
        rows.extend(check(
            &format!("new rig {bore_mm}x{stroke_mm} mm, {supply_bar} bar"),
            &scene,
        ));
    }
    let table: Vec<&str> = rows.iter().map(|(r, _)| r.as_str()).collect();
    let table = format!(
        "| scene | k_e (N/m) | predicted onset kp (1/m) | simulated | error |\n|---|---|---|---|---|\n{}",
        table.join("\n")
    );
    eprintln!("{table}");
    assert!(rows.iter().all(|(_, ok)| *ok), "{table}");
}
