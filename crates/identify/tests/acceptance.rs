//! Issue 16's acceptance: a truth perturbed 20-40 % from the shipped sheet (seeded), hidden in the emulated
//! rig with sensor noise and ADC quantisation; logs recorded in lockstep; the fit recovers each identifiable
//! parameter within 5 % (C and b within 10 %) and inside its 95 % interval, predicts held-out data within
//! 2 % of the supply (pressures) and 0.5 mm (position), and flags a parameter the data cannot identify.
mod common;

use common::{USUAL_KEYS as KEYS, held_steps, names, request, shipped, steps};
use pneuflex_identify::params::Key;
use pneuflex_identify::perturb::perturb;
use pneuflex_identify::request::{Request, identify};

/// Whether the warnings call `key` not (well) identified (a correlation warning alone does not: it says the
/// logs pin a combination, and the interval says how well each is known).
fn not_identified(warnings: &[String], key: &str) -> bool {
    warnings.iter().any(|w| {
        w.starts_with(&format!("{key}: not identifiable"))
            || w.starts_with(&format!("{key}: poorly"))
    })
}

/// Seeds of the truths: `PNEUFLEX_IDENTIFY_SEED` (one seed) or 1 to 6, every one of them asserted (no
/// seed is left out for missing its interval).
fn seeds() -> Vec<u64> {
    match std::env::var("PNEUFLEX_IDENTIFY_SEED") {
        Ok(s) => vec![s.parse().expect("PNEUFLEX_IDENTIFY_SEED is a u64")],
        Err(_) => (1..=6).collect(),
    }
}

/// The widest 95 % interval (half-width relative to the value) accepted for C, b, the dead volumes and the
/// mass: an interval may not buy its coverage by being useless (measured: below 0.5 % on seeds 1-6).
const MAX_REL_HALF_WIDTH: f64 = 0.05;

#[test]
fn recovers_a_hidden_truth() {
    for seed in seeds() {
        check_seed(seed);
    }
}

fn check_seed(seed: u64) {
    let dir = common::scratch(&format!("acceptance-{seed}"));
    let dir = dir.path().to_path_buf();
    let (truth, changes) = perturb(&shipped(), &KEYS, seed, &dir.join("truth")).unwrap();
    let log = dir.join("free.csv");
    common::record(&truth, seed, steps(seed), 6.0, None, &log);
    let req = request(vec![log], shipped(), names(&KEYS));
    let id = identify(&req).unwrap();
    let r = &id.report;
    let f = &r.fit;
    eprintln!("seed {seed}:\n{}", pneuflex_identify::report::markdown(r));
    let what = format!("seed {seed}: ");
    for (c, e) in changes.iter().zip(&f.estimates) {
        assert_eq!(c.key.name(), e.key);
        let err = e.value / c.truth - 1.0;
        common::show_estimate(&what, c, e);
        eprintln!(
            "  +-{:.3} %: std error {:.3} %, replay bias {:+.3} %, bias bound {:.3} %",
            100.0 * e.rel_half_width,
            100.0 * e.std_error / e.value.abs(),
            100.0 * e.bias / e.value.abs(),
            100.0 * e.bias_bound / e.value.abs()
        );
        common::assert_inside(&what, c, e);
        let flagged = not_identified(&r.warnings, &e.key);
        if flagged {
            // A flagged parameter is reported as not (well) identified: its interval says how far off it may be.
            continue;
        }
        let tol = match c.key {
            Key::SonicConductance | Key::CriticalRatio => 0.10,
            _ => 0.05,
        };
        assert!(
            err.abs() <= tol,
            "seed {seed}: {} off by {:.2} % (allowed {} %)",
            e.key,
            100.0 * err,
            100.0 * tol
        );
    }
    // The identifiable core is never flagged: C, b, both dead volumes and the mass (this excitation
    // accelerates the piston at ~80 m/s^2 under the PWM carrier).
    for k in &KEYS[..4] {
        assert!(
            !not_identified(&r.warnings, k.name()),
            "seed {seed}: {} flagged: {:?}",
            k.name(),
            r.warnings
        );
    }
    // Honest but not absurd: the intervals of C, b, the volumes and the mass are narrower than +-5 %.
    for e in f.estimates.iter().filter(|e| e.key != Key::Coulomb.name()) {
        assert!(
            e.rel_half_width < MAX_REL_HALF_WIDTH,
            "seed {seed}: {}: 95 % interval +-{:.2} % (allowed {} %)",
            e.key,
            100.0 * e.rel_half_width,
            100.0 * MAX_REL_HALF_WIDTH
        );
    }
    let supply = id.model.actuator.supply.supply_pressure_pa;
    assert!(f.rms_validation[0] < 0.02 * supply && f.rms_validation[1] < 0.02 * supply);
    assert!(
        f.rms_validation[2] < 0.5e-3,
        "x RMS {} m",
        f.rms_validation[2]
    );
}

/// Moving mass from a log with no acceleration (the piston held against its stop while the chambers are
/// stepped): flagged as not identifiable, with the experiment that would identify it; the pressure
/// parameters are still fitted.
#[test]
fn flags_mass_from_a_log_without_motion() {
    let dir = common::scratch("unidentifiable");
    let dir = dir.path().to_path_buf();
    let log = dir.join("held.csv");
    let text = common::record(&shipped(), 9, held_steps(), 2.0, None, &log);
    let l = pneuflex_identify::log::parse_log(&log, &text, String::new()).unwrap();
    let x_max = l.x.iter().cloned().fold(0.0, f64::max);
    assert!(
        x_max < 2e-4,
        "the piston must stay on its stop, reached {x_max} m"
    );
    let free = vec![
        "valve.sonic_conductance_m3_per_s_pa,cylinder.dead_volume_a_m3".into(),
        "mechanics.moving_mass_kg".into(),
    ];
    let req = Request {
        validation_fraction: 0.2,
        ..request(vec![log], shipped(), free)
    };
    let id = identify(&req).unwrap();
    let w = &id.report.warnings;
    eprintln!("{w:#?}");
    let mass = w
        .iter()
        .find(|w| {
            w.starts_with("mechanics.moving_mass_kg: not identifiable")
                || w.starts_with("mechanics.moving_mass_kg: poorly identified")
        })
        .expect("the mass is flagged");
    assert!(
        mass.contains("free motion with large accelerations"),
        "{mass}"
    );
    assert!(
        !id.report.fit.estimates[2].std_error.is_finite()
            || id.report.fit.estimates[2].rel_half_width > 0.1
    );
    // C is fitted from the pressure steps: on the truth (the shipped sheet), with a narrow interval and no
    // warning of its own. (Where the mass lands in its flat valley sets the correlations with it: at 2.6 kg
    // on the board's Q15 commands, C pairs with the mass at r = 0.99, a warning that says to fix one.)
    let c = &id.report.fit.estimates[0];
    assert_eq!(c.key, "valve.sonic_conductance_m3_per_s_pa");
    assert!(
        (c.value / 5e-9 - 1.0).abs() < 0.01 && c.rel_half_width < 0.01,
        "C = {} +-{:.2} %",
        c.value,
        100.0 * c.rel_half_width
    );
    assert!(
        !w.iter()
            .any(|w| w.starts_with("valve.sonic_conductance_m3_per_s_pa:")),
        "C is identified from pressure steps: {w:?}"
    );
}

/// The other keys: the valve's switching delay, viscous friction and a sensor offset (2 kPa added to every
/// p_b reading of the log), with C and V_a; each inside its interval and within 5 % (C 10 %), the offset
/// within 100 Pa.
#[test]
fn recovers_delay_viscous_friction_and_an_offset() {
    let keys = [
        Key::SonicConductance,
        Key::SwitchingDelay,
        Key::Viscous,
        Key::DeadVolumeA,
    ];
    let dir = common::scratch("delay-offset");
    let dir = dir.path().to_path_buf();
    let (truth, changes) = perturb(&shipped(), &keys, 3, &dir.join("truth")).unwrap();
    let text = common::record(&truth, 3, steps(3), 6.0, None, &dir.join("raw.csv"));
    // The p_b sensor's readings: the loop's column and the board's record of them.
    let header = text.lines().find(|l| l.starts_with("t,")).unwrap();
    let cols: Vec<usize> = header
        .split(',')
        .enumerate()
        .filter(|(_, c)| *c == "p_b" || *c == "board_p_b")
        .map(|(i, _)| i)
        .collect();
    assert_eq!(cols.len(), 2, "{header}");
    let mut out = String::new();
    for line in text.lines() {
        if line.starts_with('#') || line.starts_with("t,") {
            out += line;
        } else {
            let mut f: Vec<String> = line.split(',').map(str::to_string).collect();
            for &i in &cols {
                if let Ok(v) = f[i].parse::<f64>() {
                    f[i] = (v + 2000.0).to_string();
                }
            }
            out += &f.join(",");
        }
        out.push('\n');
    }
    let log = dir.join("offset.csv");
    std::fs::write(&log, out).unwrap();
    let mut free = names(&keys);
    free.push("offset.p_b_pa".into());
    let id = identify(&request(vec![log], shipped(), free)).unwrap();
    let est = &id.report.fit.estimates;
    for (c, e) in changes.iter().zip(est) {
        let err = e.value / c.truth - 1.0;
        common::show_estimate("", c, e);
        common::assert_inside("", c, e);
        let tol = if c.key == Key::SonicConductance {
            0.10
        } else {
            0.05
        };
        assert!(err.abs() <= tol, "{} off by {:.2} %", e.key, 100.0 * err);
    }
    let off = &est[4];
    eprintln!(
        "offset.p_b_pa: {} [{}, {}]",
        off.value, off.ci95[0], off.ci95[1]
    );
    assert!((off.value - 2000.0).abs() < 100.0, "{off:?}");
    assert!(off.ci95[0] <= 2000.0 && 2000.0 <= off.ci95[1], "{off:?}");
}

/// Several logs at once: the log held on the stop (pressure transients, no motion) with a free-motion log
/// identifies the mass the held log alone could not.
#[test]
fn two_logs_identify_what_one_could_not() {
    let dir = common::scratch("two-logs");
    let dir = dir.path().to_path_buf();
    let held = dir.join("held.csv");
    common::record(&shipped(), 9, held_steps(), 2.0, None, &held);
    let free_log = dir.join("free.csv");
    common::record(&shipped(), 9, steps(9), 4.0, None, &free_log);
    let free = vec!["valve.sonic_conductance_m3_per_s_pa,mechanics.moving_mass_kg".into()];
    let req = Request {
        validation_fraction: 0.2,
        ..request(vec![held, free_log], shipped(), free)
    };
    let id = identify(&req).unwrap();
    let r = &id.report;
    assert_eq!(r.logs.len(), 2);
    assert!(r.logs.iter().all(|l| l.fit_rows > 0));
    assert!(
        !not_identified(&r.warnings, "mechanics.moving_mass_kg"),
        "{:?}",
        r.warnings
    );
    // The logs come from the shipped sheet: the fit stays at its values.
    let m = &r.fit.estimates[1];
    assert!((m.value / 0.6 - 1.0).abs() < 0.01, "{m:?}");
}
