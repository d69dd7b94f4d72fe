//! Component files: the shipped sheets load; bad files give errors naming the file and the field.
use std::path::{Path, PathBuf};

use pneuflex_pneumatics::*;

fn data_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../pneumatics")
}

/// A fresh scratch directory holding copies of the shipped sheets.
fn scratch(name: &str) -> PathBuf {
    let dir =
        std::env::temp_dir().join(format!("pneuflex-pneumatics-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    for e in std::fs::read_dir(data_dir()).unwrap() {
        let p = e.unwrap().path();
        if p.extension().is_some_and(|x| x == "toml") {
            std::fs::copy(&p, dir.join(p.file_name().unwrap())).unwrap();
        }
    }
    dir
}

/// Replaces `from` by `to` in `file` (which must contain it) and loads the actuator sheet; returns the error text.
fn broken(case: &str, file: &str, from: &str, to: &str) -> (String, String) {
    let dir = scratch(case);
    let path = dir.join(file);
    let text = std::fs::read_to_string(&path).unwrap();
    assert!(text.contains(from), "{file} lacks {from:?}");
    std::fs::write(&path, text.replacen(from, to, 1)).unwrap();
    let err = ActuatorSheet::load(dir.join("paper-actuator.toml")).expect_err("bad file accepted");
    (err.to_string(), path.display().to_string())
}

fn assert_names(msg: &str, path: &str, field: &str) {
    assert!(
        msg.contains(path),
        "message {msg:?} does not name the file {path}"
    );
    assert!(
        msg.contains(field),
        "message {msg:?} does not name the field {field}"
    );
}

#[test]
fn shipped_actuator_sheet_loads() {
    let sheet = ActuatorSheet::load(data_dir().join("paper-actuator.toml")).unwrap();
    let c = sheet.cylinder.cylinder;
    assert_eq!((c.bore_m, c.rod_m, c.stroke_m), (0.016, 0.005, 0.05));
    assert!(matches!(sheet.valve.valve.kind, ValveKind::OnOffPwm { .. }));
    assert_eq!(sheet.supply.supply.supply_pressure_pa, 601_325.0);
    assert!((sheet.mechanics.alpha_rad - 30f64.to_radians()).abs() < 1e-15);
    // Plausibility: the paper's 10-14 N contact forces are a modest fraction of the force range.
    let f_max = (sheet.supply.supply.supply_pressure_pa - 101_325.0) * c.area_a();
    assert!(14.0 / f_max < 0.25, "max force {f_max} N");
    // Sensor scaling: 4-20 mA over -0.8..0.8 MPa, 0-10 V over 0..75 mm.
    let dp = sheet.pressure_sensor.as_ref().unwrap();
    assert_eq!(dp.to_si(12.0), 0.0);
    assert_eq!(dp.to_si(20.0), 800_000.0);
    assert_eq!(dp.to_signal(-2.0e6), 4.0);
    let pos = sheet.position_sensor.as_ref().unwrap();
    assert!((pos.to_si(5.0) - 0.0375).abs() < 1e-15);
    // The model builds and has a mid-stroke transfer function with finite, positive figures.
    let (_, tf) = sheet.model().transfer_function_mid_stroke().unwrap();
    assert!(tf.omega_n > 0.0 && tf.xi_n > 0.0 && tf.k_n > 0.0);
}

#[test]
fn proportional_valve_sheet_loads() {
    let v = ValveSheet::load(&data_dir().join("proportional-5-3-valve.toml")).unwrap();
    assert_eq!(v.valve.underlap, 0.02);
    assert!(
        matches!(v.valve.kind, ValveKind::Proportional { response_time_s } if response_time_s == 0.005)
    );
}

#[test]
fn unknown_key_is_rejected() {
    let (msg, path) = broken(
        "unknown",
        "smc-mqm16-cylinder.toml",
        "bore_m = 0.016",
        "bore_m = 0.016\nbore_mm = 16",
    );
    assert_names(&msg, &path, "bore_mm");
}

#[test]
fn zero_size_is_rejected() {
    let (msg, path) = broken(
        "zero",
        "smc-mqm16-cylinder.toml",
        "stroke_m = 0.050",
        "stroke_m = 0.0",
    );
    assert_names(&msg, &path, "cylinder.stroke_m");
    assert!(msg.contains("must be > 0"), "{msg}");
}

#[test]
fn negative_size_is_rejected() {
    let (msg, path) = broken(
        "negative",
        "smc-mqm16-cylinder.toml",
        "bore_m = 0.016",
        "bore_m = -0.016",
    );
    assert_names(&msg, &path, "cylinder.bore_m");
    assert!(msg.contains("-0.016"), "{msg}");
}

#[test]
fn nan_is_rejected() {
    let (msg, path) = broken(
        "nan",
        "smc-mqm16-cylinder.toml",
        "dead_volume_b_m3 = 3.5e-6",
        "dead_volume_b_m3 = nan",
    );
    assert_names(&msg, &path, "cylinder.dead_volume_b_m3");
}

#[test]
fn supply_below_atmosphere_is_rejected() {
    // A gauge value typed where the absolute pressure belongs.
    let (msg, path) = broken(
        "supply",
        "supply-0p5mpa.toml",
        "pressure_abs_pa = 601325.0",
        "pressure_abs_pa = 50000.0",
    );
    assert_names(&msg, &path, "supply.pressure_abs_pa");
}

#[test]
fn rod_not_smaller_than_bore_is_rejected() {
    let (msg, path) = broken(
        "rod",
        "smc-mqm16-cylinder.toml",
        "rod_m = 0.005",
        "rod_m = 0.02",
    );
    assert_names(&msg, &path, "cylinder.rod_m");
}

#[test]
fn pwm_delay_longer_than_period_is_rejected() {
    let (msg, path) = broken(
        "delay",
        "a05ps25x-5-2-valve.toml",
        "switching_delay_s = 0.005",
        "switching_delay_s = 0.05",
    );
    assert_names(&msg, &path, "valve.switching_delay_s");
}

#[test]
fn field_of_other_valve_kind_is_rejected() {
    let (msg, path) = broken(
        "kind",
        "a05ps25x-5-2-valve.toml",
        "pwm_frequency_hz = 40.0",
        "pwm_frequency_hz = 40.0\nunderlap = 0.1",
    );
    assert_names(&msg, &path, "valve.underlap");
}

#[test]
fn negative_mass_in_actuator_sheet_is_rejected() {
    let (msg, path) = broken(
        "mass",
        "paper-actuator.toml",
        "moving_mass_kg = 0.6",
        "moving_mass_kg = -0.6",
    );
    assert_names(&msg, &path, "mechanics.moving_mass_kg");
}

#[test]
fn missing_component_file_is_reported() {
    let (msg, _) = broken(
        "missing",
        "paper-actuator.toml",
        "smc-mqm16-cylinder.toml",
        "no-such-cylinder.toml",
    );
    assert!(msg.contains("no-such-cylinder.toml"), "{msg}");
}

#[test]
fn wrong_sensor_quantity_is_rejected() {
    let (msg, path) = broken(
        "sensor",
        "paper-actuator.toml",
        "position_sensor = \"mps-0327-position-sensor.toml\"",
        "position_sensor = \"pre-u-ps12001-pressure-transmitter.toml\"",
    );
    assert_names(&msg, &path, "components.position_sensor");
}
