//! Each run's limit-cycle onset as `tf --loop` predicts it (`pneuflex_scene::analysis::run_onset`: the whole
//! loop, the adaptive law's p and d at their projection bounds) against the onset in simulation, per run and
//! per stiffness. The simulated onset: the run alone with the stiffness held for the whole run (no events),
//! judged by one event-kind window over its second half (settled, no sustained oscillation: the scene's own
//! oscillation metric); kp (ki, kd as in the scene) bracketed between a kp that settles and one that does not,
//! from the run's kp (or half the prediction, if lower) and twice the prediction, then bisected until the bracket is 2 % wide; the onset is its upper end.
//!
//! Quick form (CI): paper-fig3's adaptive run at 1400 N/m and the 63 × 100 mm rig's at 6700 N/m (the one
//! whose onset is the PWM's flip at half its rate). Full form (issue 44's table: paper-fig3,
//! paper-fig3-proportional, the 25 and 63 mm rigs from `new rig`, and two held out from the method's
//! development, 40 × 80 mm at 4 bar and 50 × 100 mm; every run and stiffness, under a minute in a dev
//! build; it fails on the 25 mm rig's adaptive run at 2000 N/m, docs/scenes.md):
//!     cargo test -p pneuflex-datasheet --test adaptive_onset -- --ignored --nocapture

use std::path::Path;

use pneuflex_datasheet::{Datasheet, ValveKind, new_rig};
use pneuflex_scene::Scene;
use pneuflex_scene::analysis::loop_margins::stiffnesses;
use pneuflex_scene::analysis::run_onset::run_onset;
use pneuflex_scene::schema::{MetricWindow, WindowKind};

/// Run `run` alone at stiffness `k_e` held for the whole run, judged over its second half (a frozen run
/// after its source, which gives it g: the run judged is the last).
fn at_stiffness(scene: &Scene, run: usize, k_e: f64) -> Scene {
    let runs = match &scene.runs[run].frozen {
        Some(f) => vec![scene.run_index(&f.run).expect("the source"), run],
        None => vec![run],
    };
    let mut one = scene.some_runs(&runs, scene.duration_s);
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

/// Whether `scene`'s last run at `kp` (every run at it) fails to settle, or diverges.
fn oscillates(scene: &Scene, kp: f64) -> bool {
    let mut one = scene.clone();
    // A frozen run's inner loop is its source's: both at kp.
    for r in &mut one.runs {
        r.inner.kp_per_m = kp;
    }
    let r = pneuflex_scene::run_scene(&one, &mut |_| {})
        .expect("runs")
        .pop()
        .expect("a result");
    r.diverged.is_some()
        || r.windows
            .iter()
            .any(|w| w.event.as_ref().is_some_and(|e| !e.settled))
}

/// The simulated onset by bisection (see the module's comment); Err says where no bracket was found
/// within [pred/8, 8 pred].
fn simulated(scene: &Scene, pred: f64) -> Result<f64, String> {
    // From the run's own kp when it lies below: under a narrow stable band (an outer loop with little
    // margin) half the prediction can be past its lower edge.
    let kp0 = scene.runs.last().expect("a run").inner.kp_per_m;
    let (mut lo, mut hi) = (if kp0 < pred { kp0 } else { 0.5 * pred }, 2.0 * pred);
    while oscillates(scene, lo) {
        lo *= 0.5;
        if lo < pred / 8.0 {
            return Err(format!("oscillates down to {lo:.2}"));
        }
    }
    while !oscillates(scene, hi) {
        hi *= 2.0;
        if hi > 8.0 * pred {
            return Err(format!("settles up to {hi:.1}"));
        }
    }
    while hi / lo > 1.02 {
        let mid = (lo * hi).sqrt();
        if oscillates(scene, mid) {
            hi = mid
        } else {
            lo = mid
        }
    }
    Ok(hi)
}

/// The rows of `runs` of one scene at each stiffness, and whether each prediction is within 25 %.
fn check(label: &str, scene: &Scene, runs: &[&str], only_k: Option<f64>) -> Vec<(String, bool)> {
    let mut rows = Vec::new();
    for name in runs {
        let run = scene.run_index(name).expect("the run");
        for k in stiffnesses(scene) {
            if only_k.is_some_and(|o| o != k) {
                continue;
            }
            let o = run_onset(scene, run, k)
                .expect("analysed")
                .expect("a pneumatic plant");
            let kp = o
                .kp_per_m
                .unwrap_or_else(|| panic!("{label} `{name}` at {k} N/m: no prediction ({o:?})"));
            let held = at_stiffness(scene, run, k);
            let freq = o.frequency_hz.unwrap_or(f64::NAN);
            let row = match simulated(&held, kp) {
                Ok(s) => {
                    let err = (kp - s) / s;
                    (
                        format!(
                            "| {label} | {name} | {k} | {kp:.1} at {freq:.1} Hz ({}) | {s:.1} | {:+.0} % |",
                            o.method,
                            100.0 * err
                        ),
                        err.abs() <= 0.25,
                    )
                }
                Err(why) => (
                    format!(
                        "| {label} | {name} | {k} | {kp:.1} at {freq:.1} Hz ({}) | {why} | - |",
                        o.method
                    ),
                    false,
                ),
            };
            eprintln!("{}", row.0);
            rows.push(row);
        }
    }
    rows
}

fn table(rows: &[(String, bool)]) -> String {
    let t: Vec<&str> = rows.iter().map(|(r, _)| r.as_str()).collect();
    format!(
        "| scene | run | k_e (N/m) | predicted onset kp (1/m) | simulated | error |\n|---|---|---|---|---|---|\n{}",
        t.join("\n")
    )
}

fn root() -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// The scene `new rig` writes for a `bore_mm` × `stroke_mm` cylinder at `supply_bar` on a PWM valve, and
/// its label.
fn rig(dir: &Path, bore_mm: f64, stroke_mm: f64, supply_bar: f64) -> (String, Scene) {
    let dir = dir.join(format!("r{bore_mm}x{stroke_mm}"));
    let ds = Datasheet {
        bore_m: Some(bore_mm * 1e-3),
        stroke_m: Some(stroke_mm * 1e-3),
        supply_gauge_pa: Some(supply_bar * 1e5),
        valve: Some(ValveKind::Pwm),
        ..Default::default()
    };
    new_rig(&ds, &dir, "test").expect("the rig is written");
    (
        format!("new rig {bore_mm}x{stroke_mm} mm, {supply_bar} bar"),
        Scene::load(&dir.join("scene.toml")).unwrap(),
    )
}

#[test]
fn the_adaptive_runs_onset_on_paper_fig3_and_the_63_mm_rig_is_within_25_percent_of_the_simulated_one()
 {
    let scene = Scene::load(&root().join("scenes/paper-fig3.toml")).unwrap();
    let mut rows = check("paper-fig3", &scene, &["adaptive"], Some(1400.0));
    let tmp = tempfile::tempdir().unwrap();
    let (label, scene) = rig(tmp.path(), 63.0, 100.0, 6.0);
    rows.extend(check(&label, &scene, &["adaptive"], Some(6700.0)));
    let t = table(&rows);
    eprintln!("{t}");
    assert!(rows.iter().all(|(_, ok)| *ok), "{t}");
}

#[test]
#[ignore = "the full table: under a minute in a dev build (see the module's comment); fails on the 25 mm rig's adaptive run at 2000 N/m"]
fn every_runs_onset_is_within_25_percent_of_the_simulated_one() {
    let mut rows = Vec::new();
    for name in ["paper-fig3", "paper-fig3-proportional"] {
        let scene = Scene::load(&root().join("scenes").join(format!("{name}.toml"))).unwrap();
        rows.extend(check(
            name,
            &scene,
            &["impedance", "adaptive", "frozen_bounds"],
            None,
        ));
    }
    let tmp = tempfile::tempdir().unwrap();
    // The 25 and 63 mm rigs the method was developed on, then two held out.
    for (bore_mm, stroke_mm, supply_bar) in [
        (25.0, 100.0, 6.0),
        (63.0, 100.0, 6.0),
        (40.0, 80.0, 4.0),
        (50.0, 100.0, 6.0),
    ] {
        let (label, scene) = rig(tmp.path(), bore_mm, stroke_mm, supply_bar);
        rows.extend(check(&label, &scene, &["impedance", "adaptive"], None));
    }
    let t = table(&rows);
    eprintln!("{t}");
    assert!(rows.iter().all(|(_, ok)| *ok), "{t}");
}

/// The peak-to-peak position per quarter second of `scene`'s last run at `kp` (every run at it), mm.
fn envelope(scene: &Scene, kp: f64) -> Vec<f64> {
    let mut one = scene.clone();
    for r in &mut one.runs {
        r.inner.kp_per_m = kp;
    }
    let r = pneuflex_scene::run_scene(&one, &mut |_| {})
        .expect("runs")
        .pop()
        .expect("a result");
    let x = r.trace.column("x").expect("x is traced");
    x.chunks((0.25 / scene.dt_s).round() as usize)
        .map(|c| {
            let (lo, hi) = c
                .iter()
                .fold((f64::MAX, f64::MIN), |(l, h), v| (l.min(*v), h.max(*v)));
            1e3 * (hi - lo)
        })
        .collect()
}

#[test]
#[ignore = "part of the full form (see the module's comment): eleven runs of 10 s"]
fn the_25_mm_rigs_adaptive_run_holds_a_large_cycle_where_its_settled_contact_is_stable() {
    // Below the predicted onset (the settled contact's), the run from its start sits in a large cycle (the
    // flange leaving the spring, > 30 mm peak to peak) and either keeps it past half-way or falls out of it
    // into the settled ripple (< 15 mm with the reference's moves), which then holds for at least the last
    // second: its simulated onset is where the large cycle lasts past half-way, which no model of the
    // settled contact predicts.
    let tmp = tempfile::tempdir().unwrap();
    let (label, scene) = rig(tmp.path(), 25.0, 100.0, 6.0);
    let run = scene.run_index("adaptive").unwrap();
    for (k, kps) in [
        (1000.0, [56.0, 65.0, 73.0, 76.0, 85.0].as_slice()),
        (2000.0, [56.0, 57.0, 60.0, 65.0, 75.0, 85.0].as_slice()),
    ] {
        let predicted = run_onset(&scene, run, k)
            .unwrap()
            .unwrap()
            .kp_per_m
            .expect("predicted");
        let held = at_stiffness(&scene, run, k);
        let (mut fell, mut held_on) = (Vec::new(), Vec::new());
        for &kp in kps {
            let e = envelope(&held, kp);
            let last_large = e.iter().rposition(|v| *v > 30.0);
            eprintln!(
                "{label}, adaptive at {k} N/m, kp {kp}: peak to peak per 0.25 s (mm) {:?}",
                e.iter().map(|v| format!("{v:.1}")).collect::<Vec<_>>()
            );
            match last_large {
                // The large cycle ends, and the ripple after it holds for at least the last second.
                Some(i) if i + 5 < e.len() && e[i + 2..].iter().all(|v| *v < 15.0) => {
                    fell.push((kp, 0.25 * (i + 1) as f64))
                }
                Some(i) if i >= e.len() / 2 => held_on.push(kp),
                _ => {}
            }
        }
        eprintln!(
            "at {k} N/m: the run's kp {}, predicted onset {predicted:.1} /m; fell into the settled ripple at \
             (kp, s) {fell:?}, large cycle past half-way at {held_on:?}",
            scene.runs[run].inner.kp_per_m
        );
        // Both below the prediction: where the ripple holds after the large cycle the contact is stable at
        // that kp, and where the cycle holds past half-way the run counts as oscillating.
        assert!(
            !fell.is_empty() && !held_on.is_empty(),
            "{k} N/m: fell {fell:?}, held {held_on:?}"
        );
        assert!(
            fell.iter()
                .map(|f| &f.0)
                .chain(&held_on)
                .all(|f| *f < predicted),
            "{k} N/m: {fell:?} {held_on:?} against {predicted}"
        );
    }
}

#[test]
fn an_adaptive_law_without_a_bound_or_a_frozen_run_at_its_means_says_it_is_not_predicted() {
    let mut scene = Scene::load(&root().join("scenes/paper-fig3.toml")).unwrap();
    let means = scene.run_index("frozen_means").unwrap();
    let o = run_onset(&scene, means, 700.0).unwrap().unwrap();
    assert!(o.kp_per_m.is_none(), "{o:?}");
    assert!(
        o.not_predicted
            .as_deref()
            .is_some_and(|w| w.contains("means")),
        "{o:?}"
    );
    let a = scene.run_index("adaptive").unwrap();
    scene.runs[a].adaptive.as_mut().unwrap().p_max_m_per_n = f64::INFINITY;
    let o = run_onset(&scene, a, 700.0).unwrap().unwrap();
    assert!(o.kp_per_m.is_none(), "{o:?}");
    assert!(
        o.not_predicted
            .as_deref()
            .is_some_and(|w| w.contains("p_max_m_per_n")),
        "{o:?}"
    );
    // The impedance run is predicted, with nothing of the adaptive law held.
    let o = run_onset(&scene, scene.run_index("impedance").unwrap(), 700.0)
        .unwrap()
        .unwrap();
    assert!(o.kp_per_m.is_some() && o.not_predicted.is_none(), "{o:?}");
}
