//! The McKibben muscle as the engine's second actuator family (docs/muscles.md "In a mechanism"): the
//! antagonist elbow of scenes/antagonist.toml at rest balances its spring with the muscles' torque, each
//! muscle's tension the braid's closed form at its measured pressure and length; the scene's runs settle on
//! their force references, obey the invariants and carry the muscle's pressure `p_muscle` as its own column.

use std::path::{Path, PathBuf};

use pneuflex_control::{Telemetry, ValveCommand};
use pneuflex_scene::mechanism::{self, MechanismPlant, MechanismScene};
use pneuflex_scene::plants::Plant;

fn scene_path() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/antagonist.toml")
}

/// Tondu & Lopez's force (M5) worked from the sheet's catalogue numbers by hand, not through the muscle
/// crate: r0 = 5 mm, alpha0 = 20.47 deg, L0 = 0.2 m, k from eps_max = 0.25 (M6).
fn braid_force(p_gauge_pa: f64, length_m: f64) -> f64 {
    let a0 = 20.47_f64.to_radians();
    let (l0, r0) = (0.2, 0.005);
    let k = (1.0 - 1.0 / (3f64.sqrt() * a0.cos())) / 0.25;
    let (a, b) = (3.0 / a0.tan().powi(2), 1.0 / a0.sin().powi(2));
    let eps = 1.0 - length_m / l0;
    core::f64::consts::PI * r0 * r0 * p_gauge_pa * (a * (1.0 - k * eps).powi(2) - b)
}

/// The plant's own recorded signal `name` now.
fn recorded(plant: &MechanismPlant, name: &str) -> f64 {
    let mut out = vec![0.0; plant.signals().len()];
    plant.record(&mut out);
    let i = plant
        .signals()
        .iter()
        .position(|s| s.name == name)
        .unwrap_or_else(|| panic!("no signal {name}"));
    out[i]
}

/// scenes/antagonist.toml in `dir`, its muscles behind pressure regulators (the shipped sheet with
/// `[regulator]` in place of its valve), and its files named by absolute paths.
fn regulated_scene(dir: &Path) -> MechanismScene {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let pneumatics = root.join("pneumatics");
    let sheet = std::fs::read_to_string(pneumatics.join("festo-dmsp-10-muscle.toml"))
        .unwrap()
        .replace(
            "supply = \"supply-0p5mpa.toml\"",
            &format!("supply = {:?}", pneumatics.join("supply-0p5mpa.toml")),
        )
        .replace("valve = \"proportional-5-3-valve.toml\"", "")
        + "\n[regulator]\ntime_constant_s = 0.05\n";
    let sheet_path = dir.join("regulated-muscle.toml");
    std::fs::write(&sheet_path, sheet).unwrap();
    let text = std::fs::read_to_string(scene_path())
        .unwrap()
        .replace(
            "\"../urdf/antagonist-elbow.urdf\"",
            &format!("{:?}", root.join("urdf/antagonist-elbow.urdf")),
        )
        .replace(
            "\"../pneumatics/festo-dmsp-10-muscle.toml\"",
            &format!("{sheet_path:?}"),
        );
    let path = dir.join("antagonist.toml");
    std::fs::write(&path, text).unwrap();
    MechanismScene::load(&path).unwrap()
}

#[test]
fn the_elbow_rests_where_the_muscles_torque_balances_the_spring() {
    let dir = tempfile::tempdir().unwrap();
    let scene = regulated_scene(dir.path());
    let mut plant = MechanismPlant::new(&scene).unwrap();
    let dt = scene.dt_s;
    // Open loop: the flexor regulated to 3 bar gauge (u = 0.2 of [-1, 1] from atmosphere to the 5 bar
    // supply), the extensor to 2 bar; the arm comes to rest against the spring.
    for _ in 0..8000 {
        plant.actuate_actuator(0, ValveCommand::clamped(0.2), &Telemetry::default());
        plant.actuate_actuator(1, ValveCommand::clamped(-0.2), &Telemetry::default());
        plant.advance(dt);
        plant.check_invariants().unwrap();
    }
    let m = plant.mechanism();
    let (angle, rate) = m.joint_position("elbow").unwrap();
    // Nearly at rest: the braid friction's tanh (M7) is a stiff damper near rest, so the arm creeps in
    // for seconds; its inertia's torque (I theta'' ~ 1e-5 N m) is negligible, its friction is not and
    // is taken into the balance by hand.
    assert!(rate.abs() < 1e-3, "the arm still turns at {rate} rad/s");
    assert!(
        angle > 0.02,
        "the fuller flexor turns the arm to +angle, got {angle} rad"
    );
    let atm = 101_325.0;
    // Torque about the joint (at the origin, axis z) of each muscle's force on the forearm, -T n at end_b.
    let mut torque = 0.0;
    for (i, (name, gauge)) in [("flexor", 3e5), ("extensor", 2e5)].into_iter().enumerate() {
        let s = m.actuator_state(i);
        let length = (s.end_b - s.end_a).length();
        let p = recorded(&plant, &format!("{name}.p_muscle"));
        assert!((p - atm - gauge).abs() < 1.0, "{name}: {p} Pa");
        // (M5) plus the friction (M7) at the muscle's lengthening rate: (2 N + 2 N/bar p) tanh(L'/1 mm/s).
        let friction = (2.0 + 2e-5 * (p - atm)) * (s.x_dot_m_s / 1e-3).tanh();
        let tension = braid_force(p - atm, length) + friction;
        assert!(tension > 50.0, "{name} pulls {tension} N at {p} Pa");
        // The engine applied the tension the closed form gives.
        let applied = -m.actuator_force(i);
        assert!(
            (applied - tension).abs() < 1e-3 * tension,
            "{name}: applied {applied} N, (M5) at p = {p} Pa, L = {length} m gives {tension} N"
        );
        let f = -tension * s.axis;
        torque += s.end_b.x * f.y - s.end_b.y * f.x;
    }
    // The spring's torque k theta (its rest is the URDF's zero), the spring's and the bearing's damping.
    let spring = 10.0 * angle + (0.2 + 0.1) * rate;
    assert!(
        (torque - spring).abs() < 2e-3 * spring,
        "muscles' torque {torque} N m against the spring's {spring} N m at {angle} rad"
    );
}

#[test]
fn the_antagonist_scene_settles_on_its_force_references_under_both_controllers() {
    let scene = MechanismScene::load(&scene_path()).unwrap();
    let runs = mechanism::run_all(&scene, &mut |_| {}, None, &mut ()).unwrap();
    for r in &runs {
        assert!(r.diverged.is_none(), "{}: {:?}", r.name, r.diverged);
        let col = |c: &str| {
            r.trace
                .column(c)
                .unwrap_or_else(|| panic!("no {c}"))
                .to_vec()
        };
        let t = col("t");
        let mean = |c: &str, t0: f64, t1: f64| {
            let v: Vec<f64> = t
                .iter()
                .zip(col(c))
                .filter(|(t, _)| (t0..t1).contains(*t))
                .map(|(_, y)| y)
                .collect();
            v.iter().sum::<f64>() / v.len() as f64
        };
        // The muscle's one pressure is its own column; the loop's cylinder chambers stay empty.
        assert!(col("flexor.p_a").iter().all(|p| p.is_nan()));
        let p = col("flexor.p_muscle");
        let bad: Vec<&f64> = p
            .iter()
            .filter(|p| !(**p > 0.9e5 && **p <= 6.1e5))
            .take(5)
            .collect();
        assert!(bad.is_empty(), "{}: {bad:?}", r.name);
        // Settled on the references within the impedance law's static error k_d (x - x_d) <= 6 N.
        for (c, want, t0, t1) in [
            ("flexor.f_e", 100.0, 2.0, 3.0),
            ("extensor.f_e", 100.0, 2.0, 3.0),
            ("flexor.f_e", 150.0, 7.0, 8.0),
            ("extensor.f_e", 100.0, 7.0, 8.0),
        ] {
            let got = mean(c, t0, t1);
            assert!(
                (got - want).abs() < 6.0,
                "{}: {c} {got} N over [{t0}, {t1}) s",
                r.name
            );
        }
    }
}
