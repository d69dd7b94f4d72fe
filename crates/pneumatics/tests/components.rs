//! Component files: the shipped sheets load; bad files give errors naming the file and the field.
use std::path::{Path, PathBuf};

use pneuflex_pneumatics::*;

fn data_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../pneumatics")
}

/// A fresh scratch directory holding copies of the shipped sheets, removed when the returned guard drops.
fn scratch(name: &str) -> tempfile::TempDir {
    let dir = tempfile::Builder::new()
        .prefix(&format!("pneuflex-pneumatics-{name}-"))
        .tempdir()
        .unwrap();
    for e in std::fs::read_dir(data_dir()).unwrap() {
        let p = e.unwrap().path();
        if p.extension().is_some_and(|x| x == "toml") {
            std::fs::copy(&p, dir.path().join(p.file_name().unwrap())).unwrap();
        }
    }
    dir
}

/// Replaces `from` by `to` in `file` (which must contain it) and loads the actuator sheet; returns the error text,
/// the broken file's path and the guard of its scratch directory.
fn broken(case: &str, file: &str, from: &str, to: &str) -> (String, String, tempfile::TempDir) {
    let scratch = scratch(case);
    let dir = scratch.path().to_path_buf();
    let path = dir.join(file);
    let text = std::fs::read_to_string(&path).unwrap();
    assert!(text.contains(from), "{file} lacks {from:?}");
    std::fs::write(&path, text.replacen(from, to, 1)).unwrap();
    let err = ActuatorSheet::load(dir.join("paper-actuator.toml")).expect_err("bad file accepted");
    (err.to_string(), path.display().to_string(), scratch)
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
    let (msg, path, _scratch) = broken(
        "unknown",
        "smc-mqm16-cylinder.toml",
        "bore_m = 0.016",
        "bore_m = 0.016\nbore_mm = 16",
    );
    assert_names(&msg, &path, "bore_mm");
}

#[test]
fn zero_size_is_rejected() {
    let (msg, path, _scratch) = broken(
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
    let (msg, path, _scratch) = broken(
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
    let (msg, path, _scratch) = broken(
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
    let (msg, path, _scratch) = broken(
        "supply",
        "supply-0p5mpa.toml",
        "pressure_abs_pa = 601325.0",
        "pressure_abs_pa = 50000.0",
    );
    assert_names(&msg, &path, "supply.pressure_abs_pa");
}

#[test]
fn rod_not_smaller_than_bore_is_rejected() {
    let (msg, path, _scratch) = broken(
        "rod",
        "smc-mqm16-cylinder.toml",
        "rod_m = 0.005",
        "rod_m = 0.02",
    );
    assert_names(&msg, &path, "cylinder.rod_m");
}

#[test]
fn pwm_delay_longer_than_period_is_rejected() {
    let (msg, path, _scratch) = broken(
        "delay",
        "a05ps25x-5-2-valve.toml",
        "switching_delay_s = 0.005",
        "switching_delay_s = 0.05",
    );
    assert_names(&msg, &path, "valve.switching_delay_s");
}

#[test]
fn field_of_other_valve_kind_is_rejected() {
    let (msg, path, _scratch) = broken(
        "kind",
        "a05ps25x-5-2-valve.toml",
        "pwm_frequency_hz = 40.0",
        "pwm_frequency_hz = 40.0\nunderlap = 0.1",
    );
    assert_names(&msg, &path, "valve.underlap");
}

#[test]
fn negative_mass_in_actuator_sheet_is_rejected() {
    let (msg, path, _scratch) = broken(
        "mass",
        "paper-actuator.toml",
        "moving_mass_kg = 0.6",
        "moving_mass_kg = -0.6",
    );
    assert_names(&msg, &path, "mechanics.moving_mass_kg");
}

#[test]
fn missing_component_file_is_reported() {
    let (msg, _, _scratch) = broken(
        "missing",
        "paper-actuator.toml",
        "smc-mqm16-cylinder.toml",
        "no-such-cylinder.toml",
    );
    assert!(msg.contains("no-such-cylinder.toml"), "{msg}");
}

#[test]
fn wrong_sensor_quantity_is_rejected() {
    let (msg, path, _scratch) = broken(
        "sensor",
        "paper-actuator.toml",
        "position_sensor = \"mps-0327-position-sensor.toml\"",
        "position_sensor = \"pre-u-ps12001-pressure-transmitter.toml\"",
    );
    assert_names(&msg, &path, "components.position_sensor");
}

/// `line:column` (1-based) of the value on the first line of `file` (in a fresh scratch copy) that starts
/// with `prefix`: where errors point (file:line:col: key: message).
fn line_of(file: &Path, prefix: &str) -> String {
    let text = std::fs::read_to_string(file).unwrap();
    let (i, l) = text
        .lines()
        .enumerate()
        .find(|(_, l)| l.trim_start().starts_with(prefix))
        .unwrap_or_else(|| panic!("{} has no line {prefix:?}", file.display()));
    let eq = l.find('=').expect("a key = value line");
    let value = eq + 1 + (l[eq + 1..].len() - l[eq + 1..].trim_start().len());
    format!("{}:{}", i + 1, l[..value].chars().count() + 1)
}

/// Loads `sheet` on a thread; an error within 5 s, or a panic (a hang or an unbounded read fails).
fn load_err_within_5_s(sheet: PathBuf) -> String {
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let _ = tx.send(ActuatorSheet::load(&sheet).map(|_| ()));
    });
    match rx.recv_timeout(std::time::Duration::from_secs(5)) {
        Ok(Err(e)) => e.to_string(),
        Ok(Ok(())) => panic!("accepted"),
        Err(_) => panic!("loading did not finish within 5 s"),
    }
}

/// Issue 11: `cylinder = "/dev/zero"` read without bound (~1 GB/s of memory); now a clear error at the
/// sheet's key, before anything is read.
#[cfg(unix)]
#[test]
fn device_as_component_is_refused_at_its_key() {
    let dir = scratch("device");
    let dir = dir.path().to_path_buf();
    let sheet = dir.join("paper-actuator.toml");
    let text = std::fs::read_to_string(&sheet).unwrap();
    std::fs::write(
        &sheet,
        text.replace("\"smc-mqm16-cylinder.toml\"", "\"/dev/zero\""),
    )
    .unwrap();
    let line = line_of(&sheet, "cylinder =");
    let msg = load_err_within_5_s(sheet.clone());
    assert!(
        msg.contains(&format!(
            "{}:{line}: components.cylinder: /dev/zero: not a regular file (a character device)",
            sheet.display()
        )),
        "{msg}"
    );
}

/// Issue 11: a FIFO as a component blocked forever in open(); now refused after a stat.
#[cfg(unix)]
#[test]
fn fifo_as_component_does_not_block() {
    let dir = scratch("fifo");
    let dir = dir.path().to_path_buf();
    let fifo = dir.join("valve.fifo");
    let made = std::process::Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .is_ok_and(|s| s.success());
    if !made {
        eprintln!("mkfifo unavailable; skipped");
        return;
    }
    let sheet = dir.join("paper-actuator.toml");
    let text = std::fs::read_to_string(&sheet).unwrap();
    std::fs::write(
        &sheet,
        text.replace("\"a05ps25x-5-2-valve.toml\"", "\"valve.fifo\""),
    )
    .unwrap();
    let msg = load_err_within_5_s(sheet);
    assert!(
        msg.contains("components.valve") && msg.contains("not a regular file (a FIFO)"),
        "{msg}"
    );
}

/// Issue 11: a sheet larger than the sheet limit is refused, not read.
#[test]
fn oversized_component_is_refused() {
    let dir = scratch("oversized");
    let dir = dir.path().to_path_buf();
    let big = dir.join("supply-0p5mpa.toml");
    let mut text = std::fs::read_to_string(&big).unwrap();
    text.push_str(&"#".repeat(2 << 20));
    std::fs::write(&big, text).unwrap();
    let msg = load_err_within_5_s(dir.join("paper-actuator.toml"));
    assert!(
        msg.contains("components.supply") && msg.contains("byte limit of a component sheet"),
        "{msg}"
    );
}

/// Issue 11: a missing component names the sheet, line and key that name it, and the OS error once.
#[test]
fn missing_component_names_the_key_that_names_it() {
    let (msg, sheet, _scratch) = broken(
        "missing-key",
        "paper-actuator.toml",
        "\"a05ps25x-5-2-valve.toml\"",
        "\"nope.toml\"",
    );
    let line = line_of(Path::new(&sheet), "valve =");
    let nope = Path::new(&sheet).with_file_name("nope.toml");
    assert!(
        msg.starts_with(&format!(
            "{sheet}:{line}: components.valve: {}: cannot read: ",
            nope.display()
        )),
        "{msg}"
    );
    let err = ActuatorSheet::load(&sheet).unwrap_err();
    assert_eq!(
        err.os_error().map(std::io::Error::kind),
        Some(std::io::ErrorKind::NotFound)
    );
    // The OS error is in the message, not also a `source()` (anyhow's `{:#}` would print it twice).
    assert!(std::error::Error::source(&err).is_none());
}

/// Issue 11: `stroke_m = 1e300` was accepted; now refused with the file, the key's line and the bound.
#[test]
fn absurd_stroke_is_rejected_at_its_line() {
    let (msg, path, _scratch) = broken(
        "stroke",
        "smc-mqm16-cylinder.toml",
        "stroke_m = 0.050",
        "stroke_m = 1e300",
    );
    let line = line_of(Path::new(&path), "stroke_m");
    assert!(
        msg.starts_with(&format!(
            "{path}:{line}: cylinder.stroke_m: must be in [0.001, 10] m"
        )),
        "{msg}"
    );
    assert!(msg.contains("got 1e300"), "{msg}");
}

/// Issue 11: a bore of 10 m or 10 um is not a pneumatic cylinder.
#[test]
fn absurd_bore_is_rejected_at_its_line() {
    for bad in ["10.0", "1e-5"] {
        let (msg, path, _scratch) = broken(
            &format!("bore-{bad}"),
            "smc-mqm16-cylinder.toml",
            "bore_m = 0.016",
            &format!("bore_m = {bad}"),
        );
        let line = line_of(Path::new(&path), "bore_m");
        assert!(
            msg.starts_with(&format!(
                "{path}:{line}: cylinder.bore_m: must be in [0.001, 1] m"
            )),
            "{msg}"
        );
    }
}

/// Issue 11: a sonic conductance of 1e-3 m^3/(s Pa) (1e5 times a real valve's) ran to -1e67 Pa.
#[test]
fn absurd_sonic_conductance_is_rejected_at_its_line() {
    let (msg, path, _scratch) = broken(
        "sonic",
        "a05ps25x-5-2-valve.toml",
        "sonic_conductance_m3_per_s_pa = 5.0e-9",
        "sonic_conductance_m3_per_s_pa = 1e-3",
    );
    let line = line_of(Path::new(&path), "sonic_conductance_m3_per_s_pa");
    assert!(
        msg.starts_with(&format!(
            "{path}:{line}: valve.sonic_conductance_m3_per_s_pa: must be in [1e-12, 1e-5]"
        )),
        "{msg}"
    );
}

/// Issue 11: a supply of 1e15 Pa was accepted.
#[test]
fn absurd_supply_is_rejected_at_its_line() {
    let (msg, path, _scratch) = broken(
        "supply-high",
        "supply-0p5mpa.toml",
        "pressure_abs_pa = 601325.0",
        "pressure_abs_pa = 1e15",
    );
    let line = line_of(Path::new(&path), "pressure_abs_pa");
    assert!(
        msg.starts_with(&format!(
            "{path}:{line}: supply.pressure_abs_pa: must be at most 1e7 Pa absolute"
        )),
        "{msg}"
    );
}

/// Validation errors carry the line of the key, as parse errors do; other physical bounds hold too.
#[test]
fn validation_errors_carry_the_line_of_the_key() {
    for (case, file, from, to, key) in [
        (
            "line-mass",
            "paper-actuator.toml",
            "moving_mass_kg = 0.6",
            "moving_mass_kg = -0.6",
            "moving_mass_kg",
        ),
        (
            "line-temp",
            "supply-0p5mpa.toml",
            "temperature_k = 293.15",
            "temperature_k = 5000.0",
            "temperature_k",
        ),
        (
            "line-pwm",
            "a05ps25x-5-2-valve.toml",
            "pwm_frequency_hz = 40.0",
            "pwm_frequency_hz = 1e9",
            "pwm_frequency_hz",
        ),
        (
            "line-dead",
            "smc-mqm16-cylinder.toml",
            "dead_volume_a_m3 = 3.5e-6",
            "dead_volume_a_m3 = 1e3",
            "dead_volume_a_m3",
        ),
        (
            "line-coulomb",
            "paper-actuator.toml",
            "coulomb_n = 0.6",
            "coulomb_n = 1e12",
            "coulomb_n",
        ),
    ] {
        let (msg, path, _scratch) = broken(case, file, from, to);
        let line = line_of(Path::new(&path), key);
        assert!(msg.starts_with(&format!("{path}:{line}: ")), "{msg}");
        assert!(msg.contains(key), "{msg}");
    }
}

/// The scratch sheets with `edits` (file, appended text) applied.
fn with_keys(
    case: &str,
    edits: &[(&str, &str)],
) -> (Result<ActuatorSheet, ComponentError>, tempfile::TempDir) {
    let scratch = scratch(case);
    let dir = scratch.path().to_path_buf();
    for (file, add) in edits {
        let path = dir.join(file);
        let text = std::fs::read_to_string(&path).unwrap();
        std::fs::write(&path, format!("{text}\n{add}\n")).unwrap();
    }
    (
        ActuatorSheet::load(dir.join("paper-actuator.toml")),
        scratch,
    )
}

/// Every effect's key (issue 26) loads into the model's effects, with its defaults; without them the
/// shipped sheet is the paper's model.
#[test]
fn effect_keys_load_with_their_defaults() {
    let shipped = ActuatorSheet::load(data_dir().join("paper-actuator.toml")).unwrap();
    assert!(shipped.model().is_paper_model());
    assert_eq!(shipped.effects, Effects::default());
    let (sheet, _g) = with_keys(
        "effects",
        &[
            (
                "smc-mqm16-cylinder.toml",
                "wall_heat_transfer_w_per_m2_k = 40.0\n[cylinder.leaks.piston]\nsonic_conductance_m3_per_s_pa = 2e-12\n\
                 [cylinder.leaks.b_atmosphere]\nsonic_conductance_m3_per_s_pa = 1e-13\ncritical_pressure_ratio = 0.4",
            ),
            (
                "a05ps25x-5-2-valve.toml",
                "release_delay_s = 0.003\nspool_time_constant_s = 0.001",
            ),
            (
                "paper-actuator.toml",
                "[lines]\nvolume_m3 = 2e-6\nsonic_conductance_m3_per_s_pa = 2e-8\nlength_m = 0.5",
            ),
        ],
    );
    let sheet = sheet.unwrap();
    let e = sheet.effects;
    let h = e.wall_heat.unwrap();
    assert_eq!(h.coefficient_w_per_m2_k, 40.0);
    assert_eq!(h.wall_temperature_k, 293.15, "default: the atmosphere's");
    assert_eq!(e.leaks.piston.unwrap().critical_pressure_ratio, 0.5);
    assert_eq!(e.leaks.b_atmosphere.unwrap().critical_pressure_ratio, 0.4);
    assert!(e.leaks.a_atmosphere.is_none());
    let s = e.spool.unwrap();
    assert_eq!(
        (
            s.release_delay_s,
            s.spool_time_constant_s,
            s.release_time_constant_s
        ),
        (Some(0.003), 0.001, None)
    );
    let l = e.lines.unwrap();
    assert!((l.speed_of_sound_m_per_s - (1.4 * 287.05 * 293.15f64).sqrt()).abs() < 1e-9);
    assert!((l.delay_s() - 0.5 / l.speed_of_sound_m_per_s).abs() < 1e-15);
    assert!(!sheet.model().is_paper_model());
}

/// LuGre and the pressure term of the friction load; a law's key given for another law is refused.
#[test]
fn lugre_and_pressure_term_keys() {
    let lugre = "[mechanics]\nmoving_mass_kg = 0.6\nviscous_n_s_per_m = 20.0\nfriction = \"lugre\"\n\
                 coulomb_n = 3.4\nstatic_n = 4.0\nbristle_stiffness_n_per_m = 1e5\n\
                 bristle_damping_n_s_per_m = 300.0\ncoulomb_pressure_n_per_pa = 7.8e-6\nalpha_deg = 30.0\n";
    let scratch = scratch("lugre");
    let dir = scratch.path().to_path_buf();
    let path = dir.join("paper-actuator.toml");
    let text = std::fs::read_to_string(&path).unwrap();
    let head = &text[..text.find("[mechanics]").unwrap()];
    std::fs::write(&path, format!("{head}{lugre}")).unwrap();
    let sheet = ActuatorSheet::load(&path).unwrap();
    assert!(matches!(
        sheet.mechanics.friction,
        Friction::LuGre { coulomb_n, static_n, stribeck_velocity_m_per_s, .. }
            if coulomb_n == 3.4 && static_n == 4.0 && stribeck_velocity_m_per_s == 1e-3
    ));
    assert_eq!(sheet.effects.coulomb_pressure_n_per_pa, Some(7.8e-6));
    for (from, to, key) in [
        (
            "bristle_stiffness_n_per_m = 1e5\n",
            "",
            "mechanics.bristle_stiffness_n_per_m",
        ),
        ("coulomb_n = 3.4", "coulomb_n = 0.0", "mechanics.coulomb_n"),
        (
            "friction = \"lugre\"",
            "friction = \"smooth\"",
            "mechanics.static_n",
        ),
        ("7.8e-6", "-1e-6", "mechanics.coulomb_pressure_n_per_pa"),
    ] {
        std::fs::write(&path, format!("{head}{}", lugre.replacen(from, to, 1))).unwrap();
        let err = ActuatorSheet::load(&path).expect_err(key).to_string();
        assert_names(&err, &path.display().to_string(), key);
    }
}

/// Out-of-range effect keys name their file, line and key.
#[test]
fn bad_effect_keys_name_the_key() {
    for (file, add, key) in [
        (
            "smc-mqm16-cylinder.toml",
            "wall_heat_transfer_w_per_m2_k = 1e6",
            "cylinder.wall_heat_transfer_w_per_m2_k",
        ),
        (
            "smc-mqm16-cylinder.toml",
            "wall_temperature_k = 300.0",
            "cylinder.wall_temperature_k",
        ),
        (
            "smc-mqm16-cylinder.toml",
            "[cylinder.leaks.a_atmosphere]\nsonic_conductance_m3_per_s_pa = -1.0",
            "cylinder.leaks.a_atmosphere.sonic_conductance_m3_per_s_pa",
        ),
        (
            "a05ps25x-5-2-valve.toml",
            "dead_time_s = 0.001",
            "valve.dead_time_s",
        ),
        (
            "a05ps25x-5-2-valve.toml",
            "release_delay_s = 20.0",
            "valve.release_delay_s",
        ),
        (
            "paper-actuator.toml",
            "[lines]\nvolume_m3 = 2e-6\nsonic_conductance_m3_per_s_pa = 2e-8\nlength_m = 500.0",
            "lines.length_m",
        ),
    ] {
        let (r, g) = with_keys("bad-effect", &[(file, add)]);
        let err = r.expect_err(key).to_string();
        assert_names(&err, &g.path().join(file).display().to_string(), key);
        assert!(err.contains(":"), "{err}");
    }
}
