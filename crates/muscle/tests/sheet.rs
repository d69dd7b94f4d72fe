//! Muscle sheets: the shipped example loads with the values its comments derive, the three ways of giving
//! the braid agree, and bad sheets are refused naming file, line and key.

use std::path::{Path, PathBuf};

use pneuflex_muscle::{FeedSheet, MuscleSheet, SheetError};

fn pneumatics_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../pneumatics")
}

/// A sheet in a fresh folder whose supply and valve are the shipped ones (absolute paths); `muscle` is the
/// body of `[muscle]`, `feed` the lines after `[components] supply = ...`.
fn sheet(muscle: &str, feed: &str) -> (tempfile::TempDir, PathBuf, String) {
    let dir = tempfile::tempdir().unwrap();
    let p = pneumatics_dir();
    let text = format!(
        "name = \"test muscle\"\n[muscle]\n{muscle}\n[components]\nsupply = \"{}\"\n{feed}\n",
        p.join("supply-0p5mpa.toml").display(),
    );
    let path = dir.path().join("muscle.toml");
    std::fs::write(&path, &text).unwrap();
    (dir, path, text)
}

const VALVE: &str = "valve = \"VALVE\"";

fn valve_line() -> String {
    VALVE.replace(
        "VALVE",
        &pneumatics_dir()
            .join("proportional-5-3-valve.toml")
            .display()
            .to_string(),
    )
}

const BASE: &str = "nominal_diameter_m = 0.010\nrest_length_m = 0.200\ndead_volume_m3 = 3.0e-6";

fn load(muscle: &str, feed: &str) -> Result<MuscleSheet, SheetError> {
    let (_dir, path, _) = sheet(muscle, feed);
    MuscleSheet::load(&path)
}

/// The line (1-based) of the first line of `text` that starts with `key`.
fn line_of(text: &str, key: &str) -> usize {
    text.lines().position(|l| l.starts_with(key)).unwrap() + 1
}

#[test]
fn shipped_example_loads_with_its_derived_values() {
    let s = MuscleSheet::load(pneumatics_dir().join("festo-dmsp-10-muscle.toml")).unwrap();
    let b = &s.chamber.muscle.braid;
    assert!((b.rest_braid_angle_rad.to_degrees() - 20.47).abs() < 1e-12);
    // k = (1 - 1 / (sqrt(3) cos 20.47 deg)) / 0.25 = 0.383736 / 0.25 = 1.534944 (the sheet's comment).
    assert!(
        (b.end_effect_factor - 1.534_944).abs() < 1e-6,
        "{}",
        b.end_effect_factor
    );
    assert!((b.max_contraction() - 0.25).abs() < 1e-14);
    // 629.2 N at 6 bar and no contraction, the catalogue's 630 N (the comment's derivation).
    let f = b.pressure_force(6.0e5, 0.0);
    assert!((f - 629.244).abs() < 1e-3, "{f}");
    assert_eq!(s.chamber.supply.supply_pressure_pa, 601_325.0);
    assert_eq!(s.chamber.gas.polytropic_exponent, 1.4);
    let FeedSheet::Valve(v) = &s.feed else {
        panic!("a valve-fed sheet")
    };
    assert_eq!(v.valve.orifice.sonic_conductance_m3_per_s_pa, 5.0e-9);
    let fr = &s.chamber.muscle.friction;
    assert_eq!(
        (
            fr.coulomb_n,
            fr.coulomb_n_per_pa,
            fr.smooth_velocity_m_per_s
        ),
        (2.0, 2.0e-5, 1.0e-3)
    );
}

/// The braid by its angle, its fibre length b = L0 / cos(alpha0) or its turns n = L0 tan(alpha0) / (pi D)
/// (M1) is the same braid: alpha0 = 25 deg, L0 = 0.2 m, D = 10 mm give b = 0.220676 m, n = 2.968607.
#[test]
fn braid_angle_length_and_turns_agree() {
    let alpha = 25f64.to_radians();
    let b = 0.2 / alpha.cos();
    let n = 0.2 * alpha.tan() / (std::f64::consts::PI * 0.010);
    assert!(
        (b - 0.220_676).abs() < 1e-6 && (n - 2.968_607).abs() < 1e-6,
        "{b} {n}"
    );
    for extra in [
        "braid_angle_deg = 25.0".to_string(),
        format!("braid_length_m = {b:.17}"),
        format!("braid_turns = {n:.17}"),
    ] {
        let m = format!("{BASE}\n{extra}\nend_effect_factor = 1.2");
        let s = load(&m, &valve_line()).unwrap();
        let got = s.chamber.muscle.braid.rest_braid_angle_rad.to_degrees();
        assert!((got - 25.0).abs() < 1e-9, "{extra}: {got} deg");
        assert!((s.chamber.muscle.braid.turns() - n).abs() < 1e-9);
    }
    // A regulator instead of the valve.
    let m = format!("{BASE}\nbraid_angle_deg = 25.0\nend_effect_factor = 1.2");
    let s = load(&m, "[regulator]\ntime_constant_s = 0.03").unwrap();
    assert_eq!(
        s.feed,
        FeedSheet::Regulator {
            time_constant_s: 0.03
        }
    );
}

/// Each refusal names the file, the key's line and the key, and says what was wrong.
#[test]
fn bad_sheets_name_file_line_and_key() {
    let cases: [(String, String, &str, &str); 6] = [
        // A braid that extends under pressure.
        (
            format!("{BASE}\nbraid_angle_deg = 60.0\nend_effect_factor = 1.2"),
            valve_line(),
            "braid_angle_deg",
            "a muscle contracts only below 54.7356 deg",
        ),
        // Two ways of giving the braid.
        (
            format!("{BASE}\nbraid_angle_deg = 25.0\nbraid_turns = 3.0\nend_effect_factor = 1.2"),
            valve_line(),
            "braid_turns",
            "give only one of muscle.braid_angle_deg, muscle.braid_length_m, muscle.braid_turns",
        ),
        // More contraction than the braid allows: at 25 deg the limit is 1 - 1/(sqrt(3) cos 25) = 0.3630.
        (
            format!("{BASE}\nbraid_angle_deg = 25.0\nmax_contraction = 0.5"),
            valve_line(),
            "max_contraction",
            "must be at most the braid's own limit 1 - 1/(sqrt(3) cos alpha0) = 0.3630",
        ),
        // A fibre shorter than the muscle.
        (
            format!("{BASE}\nbraid_length_m = 0.15\nend_effect_factor = 1.2"),
            valve_line(),
            "braid_length_m",
            "must be longer than muscle.rest_length_m",
        ),
        // An end-effect factor below the ideal cylinder's.
        (
            format!("{BASE}\nbraid_angle_deg = 25.0\nend_effect_factor = 0.8"),
            valve_line(),
            "end_effect_factor",
            "must be in [1, 10]",
        ),
        // Neither a valve nor a regulator.
        (
            format!("{BASE}\nbraid_angle_deg = 25.0\nend_effect_factor = 1.2"),
            String::new(),
            "[components]",
            "give a valve (components.valve) or a regulator",
        ),
    ];
    for (muscle, feed, key, says) in cases {
        let (_dir, path, text) = sheet(&muscle, &feed);
        let msg = MuscleSheet::load(&path).unwrap_err().to_string();
        let line = line_of(&text, key);
        let at = format!("{}:{line}:", path.display());
        assert!(msg.starts_with(&at), "{msg}\n(want it at {at})");
        let dotted = if key.starts_with('[') {
            "components".to_string()
        } else {
            format!("muscle.{key}")
        };
        assert!(msg.contains(&format!(": {dotted}: ")), "{msg}");
        eprintln!("{msg}");
        assert!(msg.contains(says), "{msg}");
    }
}

/// An unknown key is a parse error at its line; a supply sheet that cannot be read is blamed on the key
/// naming it and names the missing file.
#[test]
fn unknown_key_and_missing_component() {
    let m = format!("{BASE}\nbraid_angle_deg = 25.0\nend_effect_factor = 1.2\nbraid_colour = 1.0");
    let (_dir, path, text) = sheet(&m, &valve_line());
    let msg = MuscleSheet::load(&path).unwrap_err().to_string();
    let line = line_of(&text, "braid_colour");
    assert!(
        msg.starts_with(&format!("{}:{line}:", path.display())) && msg.contains("braid_colour"),
        "{msg}"
    );

    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("m.toml");
    let text = format!(
        "[muscle]\n{BASE}\nbraid_angle_deg = 25.0\nend_effect_factor = 1.2\n[components]\nsupply = \"no-such-supply.toml\"\n[regulator]\ntime_constant_s = 0.02\n"
    );
    std::fs::write(&path, &text).unwrap();
    let msg = MuscleSheet::load(&path).unwrap_err().to_string();
    let line = line_of(&text, "supply =");
    assert!(
        msg.starts_with(&format!("{}:{line}:", path.display()))
            && msg.contains("components.supply")
            && msg.contains("no-such-supply.toml"),
        "{msg}"
    );
}

/// The shipped muscle, its valve fully open at 5 bar, lifts a 20 kg weight (196.1 N) and holds it where the
/// static balance pi r0^2 p [a (1 - k eps)^2 - b] = m g puts it, solved here by bisection with the sheet's
/// alpha0 = 20.47 deg and k = (1 - 1/(sqrt(3) cos alpha0)) / 0.25: eps = 0.14192, 28.4 mm of lift.
#[test]
fn shipped_muscle_lifts_a_weight_to_its_static_balance() {
    use pneuflex_muscle::{ChamberState, Load, MusclePlant, PlantState};
    let s = MuscleSheet::load(pneumatics_dir().join("festo-dmsp-10-muscle.toml")).unwrap();
    let weight = 20.0 * 9.80665;
    let alpha0 = 20.47f64.to_radians();
    let (a, b) = (3.0 / alpha0.tan().powi(2), 1.0 / alpha0.sin().powi(2));
    let k = (1.0 - 1.0 / (3f64.sqrt() * alpha0.cos())) / 0.25;
    let p = 601_325.0 - 101_325.0;
    let residual = |eps: f64| {
        std::f64::consts::PI * 0.005 * 0.005 * p * (a * (1.0 - k * eps).powi(2) - b) - weight
    };
    let (mut lo, mut hi) = (0.0, 0.25);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if residual(mid) > 0.0 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let eps = 0.5 * (lo + hi);
    assert!((eps - 0.141_92).abs() < 1e-5, "{eps}");
    let load = Load {
        mass_kg: 20.0,
        spring_n_per_m: 0.0,
        spring_free_length_m: 0.0,
        damping_n_s_per_m: 50.0,
        pull_n: weight,
    };
    let mut plant = MusclePlant::new(s.chamber, load, s.plant_feed());
    let l_hang = 0.2 + weight / 5.0e4; // hanging on the stretch stiffness, unpressurised
    let mut x = PlantState {
        length_m: l_hang,
        velocity_m_per_s: 0.0,
        chamber: ChamberState {
            pressure_pa: 101_325.0,
            temperature_k: 293.15,
        },
        inflow_kg: 0.0,
    };
    let dt = 1.0e-4;
    assert!(dt < plant.friction_step_limit_s());
    for _ in 0..150_000 {
        plant.step(&mut x, 1.0, dt);
    }
    let want = 0.2 * (1.0 - eps);
    assert!(
        (x.length_m - want).abs() < 1e-7,
        "{} m vs {want} m",
        x.length_m
    );
    assert!((x.chamber.pressure_pa - 601_325.0).abs() < 1.0);
}
