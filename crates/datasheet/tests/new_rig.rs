//! `new rig` end to end on rigs across the sizes: every generated scene loads, runs, settles after the
//! stiffness change in every run, and carries no warning but the ones its rig deserves; impossible rigs are
//! refused with their option named, before anything is written.

use pneuflex_datasheet::{Datasheet, DesignError, FlowRating, Severity, ValveKind, new_rig};

fn rig(bore_mm: f64, stroke_mm: f64, supply_bar: f64, valve: ValveKind) -> Datasheet {
    Datasheet {
        bore_m: Some(bore_mm * 1e-3),
        stroke_m: Some(stroke_mm * 1e-3),
        supply_gauge_pa: Some(supply_bar * 1e5),
        valve: Some(valve),
        ..Default::default()
    }
}

fn check_scene(dir: &std::path::Path) {
    let scene = pneuflex_scene::Scene::load(&dir.join("scene.toml")).expect("the scene loads");
    let warnings = pneuflex_scene::analysis::advice::warnings(&scene);
    assert!(warnings.is_empty(), "{}: {warnings:?}", dir.display());
    let results = pneuflex_scene::run_scene(&scene, &mut |_| {}).expect("runs");
    for r in &results {
        assert!(r.diverged.is_none(), "{}: {:?}", r.name, r.diverged);
        for w in &r.windows {
            if let Some(e) = &w.event {
                assert!(
                    e.settled,
                    "{} {} {}: {:?}",
                    dir.display(),
                    r.name,
                    w.name,
                    e.not_settled
                );
            }
        }
        // The step is held: the force error at the end of the step is small against the force.
        let step = r.window("step").expect("a step window");
        let f = scene.setpoints().unwrap().at(2.9).f_ref;
        assert!(
            step.rms_force_error_n < 0.1 * f,
            "{} {}: {}",
            dir.display(),
            r.name,
            step.rms_force_error_n
        );
    }
    // Every run's kp at least 6 dB under that run's predicted limit-cycle onset at every stiffness (`new
    // rig` lowers kp to it, rounded down).
    for (i, r) in scene.runs.iter().enumerate() {
        for k in pneuflex_scene::analysis::loop_margins::stiffnesses(&scene) {
            let onset =
                pneuflex_scene::analysis::run_onset::run_onset(&scene, i, k).expect("analyses");
            if let Some(kp) = onset.and_then(|o| o.kp_per_m) {
                let margin_db = 20.0 * (kp / r.inner.kp_per_m).log10();
                assert!(
                    margin_db >= 6.0 - 1e-9,
                    "{} {} at {k} N/m: kp {} is {margin_db:.2} dB under the onset {kp}",
                    dir.display(),
                    r.name,
                    r.inner.kp_per_m
                );
            }
        }
    }
    // The rig file is one `rig emulate` reads.
    pneuflex_rig::rigfile::RigFile::load(&dir.join("rig.toml")).expect("the rig file loads");
}

#[test]
fn five_rigs_from_10_to_63_mm_load_run_and_settle() {
    let tmp = tempfile::tempdir().unwrap();
    let rigs = [
        ("r10", rig(10.0, 50.0, 6.0, ValveKind::Pwm)),
        ("r25", rig(25.0, 100.0, 6.0, ValveKind::Pwm)),
        ("r32", rig(32.0, 160.0, 4.0, ValveKind::Proportional)),
        ("r40", rig(40.0, 80.0, 4.0, ValveKind::Pwm)),
        ("r63", rig(63.0, 200.0, 6.0, ValveKind::Proportional)),
    ];
    for (name, ds) in rigs {
        let dir = tmp.path().join(name);
        let report = new_rig(&ds, &dir, "test").unwrap_or_else(|e| panic!("{name}: {e}"));
        assert!(
            report
                .warnings
                .iter()
                .all(|w| w.severity == Severity::Warning)
        );
        // Every value not given is listed with its option.
        for key in ["--rod", "--mass", "--valve-flow", "--position-range"] {
            assert!(
                report.design.assumptions.iter().any(|a| a.key == key),
                "{name}: {key}"
            );
        }
        for (_, inner, outer) in &report.gains.gain_margins_db {
            assert!(inner.is_none_or(|g| g >= 6.0 - 0.5), "{name}: {inner:?}");
            assert!(outer.is_none_or(|g| g >= 6.0 - 0.5), "{name}: {outer:?}");
        }
        check_scene(&dir);
    }
}

#[test]
fn a_sensor_shorter_than_the_stroke_is_refused_with_its_option_and_nothing_is_written() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("short");
    let ds = Datasheet {
        position_range_m: Some(0.075),
        ..rig(25.0, 100.0, 6.0, ValveKind::Pwm)
    };
    let e = new_rig(&ds, &dir, "test").unwrap_err();
    let msg = e.to_string();
    assert!(matches!(e, DesignError::Checks(_)), "{msg}");
    assert!(
        msg.contains("--position-range")
            && msg.contains("75.0 mm is shorter than the 100.0 mm stroke"),
        "{msg}"
    );
    assert!(
        msg.contains("--position-range 125mm"),
        "a value that works: {msg}"
    );
    assert!(
        std::fs::read_dir(tmp.path()).unwrap().next().is_none(),
        "nothing written"
    );
}

#[test]
fn other_impossible_rigs_name_their_option() {
    let tmp = tempfile::tempdir().unwrap();
    let cases = [
        (
            Datasheet {
                flow: Some(FlowRating::Qn(5.0e-3 / 60.0)),
                ..rig(63.0, 200.0, 6.0, ValveKind::Pwm)
            },
            "--valve-flow",
        ),
        (
            Datasheet {
                pressure_range_pa: Some(4e5),
                ..rig(25.0, 100.0, 6.0, ValveKind::Pwm)
            },
            "--pressure-range",
        ),
        (
            Datasheet {
                moving_mass_kg: Some(20.0),
                incline_deg: Some(60.0),
                ..rig(16.0, 50.0, 6.0, ValveKind::Pwm)
            },
            "--mass",
        ),
        (
            Datasheet {
                force_n: Some(200.0),
                ..rig(25.0, 100.0, 6.0, ValveKind::Pwm)
            },
            "--force",
        ),
        (
            Datasheet {
                switching_delay_s: Some(0.02),
                ..rig(25.0, 100.0, 6.0, ValveKind::Pwm)
            },
            "--pwm-frequency",
        ),
        (
            Datasheet {
                rod_m: Some(0.03),
                ..rig(25.0, 100.0, 6.0, ValveKind::Pwm)
            },
            "--rod",
        ),
        (
            Datasheet {
                iso_bore_mm: Some(33.0),
                ..Datasheet {
                    stroke_m: Some(0.1),
                    ..Default::default()
                }
            },
            "--iso-bore",
        ),
        (
            Datasheet {
                bore_m: Some(0.025),
                ..Default::default()
            },
            "--stroke",
        ),
        (
            Datasheet {
                stroke_m: Some(f64::NAN),
                ..rig(25.0, 100.0, 6.0, ValveKind::Pwm)
            },
            "--stroke",
        ),
    ];
    for (ds, key) in cases {
        let e = new_rig(&ds, &tmp.path().join("x"), "test")
            .unwrap_err()
            .to_string();
        assert!(e.contains(key), "{key}: {e}");
    }
    assert!(
        std::fs::read_dir(tmp.path()).unwrap().next().is_none(),
        "nothing written"
    );
}

#[test]
fn an_existing_directory_is_never_replaced() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("mine");
    std::fs::create_dir(&dir).unwrap();
    std::fs::write(dir.join("notes.txt"), "my notes").unwrap();
    let e = new_rig(&rig(25.0, 100.0, 6.0, ValveKind::Pwm), &dir, "test").unwrap_err();
    assert!(matches!(e, DesignError::Exists(_)), "{e}");
    assert_eq!(
        std::fs::read_to_string(dir.join("notes.txt")).unwrap(),
        "my notes"
    );
    assert_eq!(
        std::fs::read_dir(tmp.path()).unwrap().count(),
        1,
        "no staging left"
    );
}
