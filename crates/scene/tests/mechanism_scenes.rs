//! The shipped scenes with several actuators: what they must show (static squeeze, symmetric fingers,
//! static force balance of a block held by two inclined cylinders), and bad input named by file, line, key.

use std::path::{Path, PathBuf};

use pneuflex_multibody::STANDARD_GRAVITY;
use pneuflex_scene::RunResult;
use pneuflex_scene::mechanism::{self, MechanismScene};

fn scene_path(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../scenes")
        .join(name)
}

fn run(name: &str) -> (MechanismScene, Vec<RunResult>) {
    let scene = MechanismScene::load(&scene_path(name)).unwrap();
    let runs = mechanism::run_all(&scene, &mut |_| {}, None, &mut ()).unwrap();
    (scene, runs)
}

fn run_column(r: &RunResult, c: &str) -> Vec<f64> {
    r.trace
        .column(c)
        .unwrap_or_else(|| panic!("no column {c}"))
        .to_vec()
}

/// Mean of `column` over t in [t0, t1].
fn mean(run: &RunResult, column: &str, t0: f64, t1: f64) -> f64 {
    let t = run_column(run, "t");
    let y = run_column(run, column);
    let v: Vec<f64> = t
        .iter()
        .zip(&y)
        .filter(|(t, _)| (t0..=t1).contains(*t))
        .map(|(_, y)| *y)
        .collect();
    v.iter().sum::<f64>() / v.len() as f64
}

#[test]
fn the_gripper_squeezes_to_its_set_point_with_symmetric_fingers_and_its_pads_compress_f_over_k() {
    let (scene, runs) = run("gripper.toml");
    assert_eq!(runs.len(), 2);
    for r in &runs {
        assert!(r.diverged.is_none(), "{}: {:?}", r.name, r.diverged);
        // Static squeeze: 10 N on each side, and the finger's stroke is the first touch (0.03 m in the
        // URDF) plus the foam's compression F / k = 10 / 2000 m.
        for side in ["left", "right"] {
            let f = mean(r, &format!("{side}.f_e"), 2.5, 3.0);
            assert!((f - 10.0).abs() < 0.1, "{} {side}: squeeze {f} N", r.name);
            let x = mean(r, &format!("{side}.x"), 2.5, 3.0);
            assert!(
                (x - (0.03 + f / 2000.0)).abs() < 2e-4,
                "{} {side}: stroke {x} m, 0.03 + F/k = {} m",
                r.name,
                0.03 + f / 2000.0
            );
        }
        // Symmetric fingers: the two loops see the same thing, tick for tick, to within 1 % of the set point
        // (the mirrored frames are not bit for bit mirror images, and the object on its slide is free to
        // drift: measured 0.02 N at most, on rubber).
        let spread = |c: &str| {
            let (l, r) = (
                run_column(r, &format!("left.{c}")),
                run_column(r, &format!("right.{c}")),
            );
            l.iter()
                .zip(&r)
                .map(|(a, b)| (a - b).abs())
                .fold(0.0, f64::max)
        };
        assert!(
            spread("f_e") < 0.1,
            "{}: fingers differ by {} N",
            r.name,
            spread("f_e")
        );
        assert!(
            spread("x") < 1e-4,
            "{}: strokes differ by {} m",
            r.name,
            spread("x")
        );
    }
    // The claims as measured (scenes/gripper.toml): adaptive wins on foam, impedance on rubber.
    let summary = mechanism::summarise(&scene, &runs);
    let verdict = |window: &str| {
        summary
            .claims
            .iter()
            .filter(|c| c.statement.contains(window))
            .map(|c| c.holds)
            .collect::<Vec<_>>()
    };
    assert_eq!(verdict("foam"), [true, true]);
    assert_eq!(verdict("rubber"), [false, false]);
}

#[test]
fn the_lever_presses_its_payload_on_the_stop_at_the_set_point() {
    let (_, runs) = run("lever.toml");
    let r = &runs[0];
    assert!(r.diverged.is_none(), "{:?}", r.diverged);
    let f = mean(r, "elbow_cylinder.f_e", 2.0, 3.0);
    assert!((f - 10.0).abs() < 0.2, "press {f} N");
    // The payload rests on the stop: the stroke is the one at θ = 30° (0.1347 m) plus the pad's give.
    let x = mean(r, "elbow_cylinder.x", 2.0, 3.0);
    assert!((x - 0.1347).abs() < 2e-3, "stroke {x} m");
}

#[test]
fn the_cross_slide_block_is_in_static_balance_between_its_two_cylinders_and_pads() {
    let (_, runs) = run("cross-slide.toml");
    let r = &runs[0];
    assert!(r.diverged.is_none(), "{:?}", r.diverged);
    let (t0, t1) = (2.8, 3.0);
    let (f_floor, f_wall) = (mean(r, "press.f_e", t0, t1), mean(r, "push.f_e", t0, t1));
    let (f_press, f_push) = (
        mean(r, "press.force", t0, t1),
        mean(r, "push.force", t0, t1),
    );
    assert!((f_floor - 30.0).abs() < 0.3 && (f_wall - 20.0).abs() < 0.2);
    // Where the block is, from the two cylinders' lengths (L = retracted 0.2 m + stroke): Newton on
    // L_press² = bx² + (bz − 0.25)², L_push² = (bx + 0.25)² + bz².
    let l_press = 0.2 + mean(r, "press.x", t0, t1);
    let l_push = 0.2 + mean(r, "push.x", t0, t1);
    let (mut bx, mut bz) = (0.0_f64, 0.0_f64);
    for _ in 0..50 {
        let g1 = bx * bx + (bz - 0.25).powi(2) - l_press * l_press;
        let g2 = (bx + 0.25).powi(2) + bz * bz - l_push * l_push;
        let (a, b, c, d) = (2.0 * bx, 2.0 * (bz - 0.25), 2.0 * (bx + 0.25), 2.0 * bz);
        let det = a * d - b * c;
        bx -= (d * g1 - b * g2) / det;
        bz -= (a * g2 - c * g1) / det;
    }
    // The block touches both pads (floor at z = -0.01, wall at x = 0.01, each pad giving F / k).
    assert!(
        (bz - (-0.01 - f_floor / 20000.0)).abs() < 2e-4,
        "block z {bz}"
    );
    assert!(
        (bx - (0.01 + f_wall / 20000.0)).abs() < 2e-4,
        "block x {bx}"
    );
    // Lines of force from each clevis through the block's eye.
    let n_press = [bx / l_press, (bz + 0.05 - 0.3) / l_press];
    let n_push = [(bx - 0.05 + 0.3) / l_push, bz / l_push];
    // Along x: both cylinders against the wall pad; along z: both against the floor pad and the weight.
    let sum_x = f_press * n_press[0] + f_push * n_push[0] - f_wall;
    let sum_z = f_press * n_press[1] + f_push * n_push[1] + f_floor - 2.0 * STANDARD_GRAVITY;
    assert!(sum_x.abs() < 0.01 * 30.0, "x: {sum_x} N left over");
    assert!(sum_z.abs() < 0.01 * 30.0, "z: {sum_z} N left over");
    // The press's line tilts as the block moves sideways: it carries part of the wall load.
    assert!(n_press[0].abs() > 1e-3);
}

/// The error of `scene` (the gripper with `edit` applied to its text), as shown.
fn error_of(edit: impl Fn(String) -> String) -> String {
    let text = std::fs::read_to_string(scene_path("gripper.toml")).unwrap();
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let text = edit(text).replace("\"../", &format!("\"{}/", root.display()));
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("g.toml");
    std::fs::write(&file, text).unwrap();
    let err = match MechanismScene::load(&file) {
        Err(e) => e,
        Ok(scene) => match mechanism::build::build(&scene) {
            Err(e) => e,
            Ok(_) => panic!("accepted"),
        },
    };
    err.to_string()
        .replace(&file.display().to_string(), "g.toml")
}

#[test]
fn bad_input_in_every_new_key_is_named_with_file_line_and_key() {
    // The line of a text in the shipped scene, from 1.
    let shipped = std::fs::read_to_string(scene_path("gripper.toml")).unwrap();
    let line_of = |needle: &str| shipped.lines().position(|l| l.contains(needle)).unwrap() + 1;
    let sensor_at = format!(
        "g.toml:{}:16: actuators[0].force_sensor: no contact named \"thumb\"",
        line_of("force_sensor = \"left_pad\"")
    );
    // The unknown key is written on the line after x_d_m.
    let speed_at = format!(
        "g.toml:{}:9: actuators[0].speed: unknown field `speed`",
        line_of("x_d_m = 0.03") + 1
    );
    // (text in the shipped scene, what replaces it, what the error must say)
    let cases: Vec<(&str, &str, &str)> = vec![
        (
            "force_sensor = \"left_pad\"",
            "force_sensor = \"thumb\"",
            &sensor_at,
        ),
        (
            "joint = \"left_slide\"",
            "joint = \"left_slide\"\nanchors = { link_a = \"palm\", point_a_m = [0, 0, 0], link_b = \"object\", point_b_m = [0, 0, 0], retracted_length_m = 0.1 }",
            "actuators[0].joint: give exactly one mount",
        ),
        (
            "joint = \"left_slide\"",
            "joint = \"left_slid\"",
            "actuators[0].joint: ",
        ),
        (
            "link_b = \"object\"",
            "link_b = \"obj\"",
            "contacts[0].link_b: ",
        ),
        (
            "stiffness_n_per_m = 2000.0",
            "stiffness_n_per_m = -2000.0",
            "contacts[0].stiffness_n_per_m",
        ),
        (
            "contact = \"left_pad\"",
            "contact = \"thumb_pad\"",
            "events[0].contact: no contact named \"thumb_pad\"",
        ),
        (
            "t_s = 5.0",
            "t_s = 50.0",
            "events[0].t_s: must be within the run",
        ),
        (
            "initial_position_m = 0.028",
            "initial_position_m = 0.5",
            "actuators[0].initial_position_m: ",
        ),
        ("x_d_m = 0.03", "x_d_m = 0.03\nspeed = 2", &speed_at),
        (
            "name = \"right\"",
            "name = \"left\"",
            "actuators[1].name: \"left\" is listed twice",
        ),
        (
            "metric = \"rms_force_error_n\"",
            "metric = \"speed\"",
            "claims[0].metric: unknown metric",
        ),
        (
            "sheet = \"../pneumatics/gripper-finger.toml\"",
            "sheet = \"../pneumatics/lever-actuator.toml\"",
            "actuators[0].sheet: the cylinder's stroke is 0.2 m, the joint 'left_slide' allows 0.05 m",
        ),
    ];
    let more: Vec<(&str, &str, &str)> = vec![
        (
            "chamber_substeps = 10",
            "chamber_substeps = 10\nheld_links = [\"plinth\"]",
            "held_links: ",
        ),
        // The shipped scene's one spring, the object's fixture.
        (
            "joint = \"object_slide\"",
            "joint = \"wrist\"",
            "springs[0].joint: ",
        ),
        (
            "stiffness_n_per_m = 100.0",
            "stiffness_n_per_m = -10.0",
            "springs[0].stiffness_n_per_m",
        ),
        // A second one, after it.
        (
            "[[runs]]",
            "[[springs]]\nname = \"ret\"\njoint = \"wrist\"\nstiffness_n_per_m = 10.0\n\n[[runs]]",
            "springs[1].joint: ",
        ),
        (
            "contact = \"left_pad\"",
            "contact = \"left_pad\"\nspring = \"wood\"",
            "events[0].t_s: name exactly one of `contact` or `spring`",
        ),
    ];
    for (from, to, wanted) in more {
        let msg = error_of(|t| t.replacen(from, to, 1));
        assert!(msg.contains(wanted), "{msg:?} lacks {wanted:?}");
    }
    for (from, to, wanted) in cases {
        let msg = error_of(|t| t.replacen(from, to, 1));
        assert!(msg.contains(wanted), "{msg:?} lacks {wanted:?}");
        assert!(
            msg.starts_with("g.toml"),
            "{msg:?} does not name the file first"
        );
    }
}

/// RMS of a − b over their common length.
fn rms_diff(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len().min(b.len());
    (a.iter().zip(b).map(|(x, y)| (x - y).powi(2)).sum::<f64>() / n as f64).sqrt()
}

/// Mean over each PWM period (25 samples of 1 ms at 40 Hz), trailing.
fn period_mean(v: &[f64]) -> Vec<f64> {
    let mut out = Vec::with_capacity(v.len());
    let mut sum = 0.0;
    for (i, x) in v.iter().enumerate() {
        sum += x;
        if i >= 25 {
            sum -= v[i - 25];
        }
        out.push(sum / (i + 1).min(25) as f64);
    }
    out
}

#[test]
fn the_paper_rig_as_a_mechanism_scene_follows_the_paper_rig_scene() {
    // The same URDF, sheet, controllers and schedule: the carriage held, the wood face on a spring mount, a
    // stiff pad for the flange's contact. Measured: RMS Δf_e 1.18 % / 1.17 % of the force level (0.38 % /
    // 0.33 % over a PWM period), Δx 0.13 mm (the pad's 0.1 mm give at 10 N).
    let (_, mech) = run("paper-fig3-mechanism.toml");
    let scene = pneuflex_scene::Scene::load(&scene_path("paper-fig3-multibody.toml")).unwrap();
    let rig = pneuflex_scene::run_scene(&scene, &mut |_| {}).unwrap();
    for name in ["impedance", "adaptive"] {
        let m = mech.iter().find(|r| r.name == name).unwrap();
        let r = rig.iter().find(|r| r.name == name).unwrap();
        let (f_m, f_r) = (run_column(m, "flange.f_e"), r.trace.column("f_e").unwrap());
        let level = (r
            .trace
            .column("f_ref")
            .unwrap()
            .iter()
            .map(|f| f * f)
            .sum::<f64>()
            / f_r.len() as f64)
            .sqrt();
        let raw = rms_diff(&f_m, f_r) / level;
        let averaged = rms_diff(&period_mean(&f_m), &period_mean(f_r)) / level;
        assert!(
            raw < 0.02,
            "{name}: RMS Δf_e {:.2} % of the force level",
            100.0 * raw
        );
        assert!(
            averaged < 0.01,
            "{name}: over a PWM period {:.2} %",
            100.0 * averaged
        );
        let dx = rms_diff(&run_column(m, "flange.x"), r.trace.column("x").unwrap());
        assert!(dx < 2e-4, "{name}: RMS Δx {dx} m");
    }
}

#[test]
fn a_loop_closed_on_a_joint_angle_reads_that_angle() {
    // The lever's controller on the elbow's angle (rad) instead of the stroke: at rest on the stop the angle
    // is 30° (0.5236 rad, where the payload meets it) plus the pad's give; an unknown joint is refused.
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let text = std::fs::read_to_string(scene_path("lever.toml"))
        .unwrap()
        .replace("\"../", &format!("\"{}/", root.display()))
        .replace(
            "force_sensor = \"press\"",
            "force_sensor = \"press\"\nposition_sensor = \"elbow\"",
        )
        .replacen("x_d_m = 0.130", "x_d_m = 0.5", 1)
        .replace("kp_per_m = 10.0", "kp_per_m = 1.0");
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("lever.toml");
    std::fs::write(&file, &text).unwrap();
    let scene = MechanismScene::load(&file).unwrap();
    let runs = mechanism::run_all(&scene, &mut |_| {}, None, &mut ()).unwrap();
    let angle = mean(&runs[0], "elbow_cylinder.x", 2.5, 3.0);
    let touch = std::f64::consts::FRAC_PI_6;
    assert!((touch..0.54).contains(&angle), "elbow at {angle} rad");
    let f = mean(&runs[0], "elbow_cylinder.f_e", 2.5, 3.0);
    assert!((f - 10.0).abs() < 1.0, "press {f} N");
    std::fs::write(&file, text.replace("\"elbow\"", "\"knee\"")).unwrap();
    let scene = MechanismScene::load(&file).unwrap();
    let e = mechanism::build::build(&scene)
        .err()
        .expect("refused")
        .to_string();
    assert!(
        e.contains("actuators[0].position_sensor") && e.contains("knee"),
        "{e}"
    );
}

#[test]
fn an_actuator_with_its_own_gains_runs_them_and_bad_ones_are_named() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let base = std::fs::read_to_string(scene_path("cross-slide.toml"))
        .unwrap()
        .replace("\"../", &format!("\"{}/", root.display()))
        .replace("duration_s = 6.0", "duration_s = 1.0")
        .replace("t1_s = 6.0", "t1_s = 1.0")
        .replace("t0_s = 4.0", "t0_s = 0.5")
        .replace("t0_s = 2.0\nt1_s = 3.0", "t0_s = 0.2\nt1_s = 0.5");
    let dir = tempfile::tempdir().unwrap();
    let run_with = |gains: &str| -> Result<Vec<RunResult>, String> {
        let text = base.replacen(
            "force_sensor = \"wall\"",
            &format!("force_sensor = \"wall\"\n{gains}"),
            1,
        );
        let file = dir.path().join("x.toml");
        std::fs::write(&file, text).unwrap();
        let scene = MechanismScene::load(&file).map_err(|e| e.to_string())?;
        mechanism::run_all(&scene, &mut |_| {}, None, &mut ()).map_err(|e| e.to_string())
    };
    let plain = run_with("").unwrap();
    // The run's own gains written as the actuator's: the same run, bit for bit.
    let same =
        run_with("gains = { inner = { kp_per_m = 10.0, ki_per_m_s = 20.0, kd_s_per_m = 0.0 } }")
            .unwrap();
    assert_eq!(plain[0].trace, same[0].trace);
    // Softer gains on the push cylinder only: its loop changes, the press's command differs through the
    // block they share, and the columns are those of the same actuators.
    let soft =
        run_with("gains = { inner = { kp_per_m = 3.0, ki_per_m_s = 6.0, kd_s_per_m = 0.0 } }")
            .unwrap();
    assert_eq!(plain[0].trace.columns(), soft[0].trace.columns());
    assert_ne!(
        run_column(&plain[0], "push.u"),
        run_column(&soft[0], "push.u")
    );
    let e = run_with("gains = { inner = { kp_per_m = -3.0, ki_per_m_s = 6.0, kd_s_per_m = 0.0 } }")
        .unwrap_err();
    assert!(e.contains("actuators[1].gains.inner.kp_per_m"), "{e}");
}
