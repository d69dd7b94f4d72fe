//! C and b per valve path (supply -> A, A -> exhaust, supply -> B, B -> exhaust): a truth whose four paths
//! differ (each C and b moved 20-40 % from the shipped valve's, seeded), hidden in the emulated rig with
//! noise and quantisation, is recovered by freeing the per-path keys; the fitted sheet writes them as
//! `[valve.paths.<path>]` and loads.
mod common;

use common::{names, request, shipped, steps};
use pneuflex_identify::params::Key;
use pneuflex_identify::perturb::perturb;
use pneuflex_identify::request::identify;

#[test]
fn recovers_c_and_b_per_path() {
    let keys: Vec<Key> = (0..4)
        .map(Key::PathConductance)
        .chain((0..4).map(Key::PathCritical))
        .collect();
    let shipped = shipped();
    let dir = common::scratch("valve-paths");
    let dir = dir.path().to_path_buf();
    let (truth, changes) = perturb(&shipped, &keys, 11, &dir.join("truth")).unwrap();
    // The truth sheet has its own paths: the loader reads them.
    let t = pneuflex_pneumatics::ActuatorSheet::load(&truth).unwrap();
    let v = t.actuator().valve;
    assert!((0..4).all(|i| v.paths[i].is_some()), "{v:?}");
    let c: Vec<f64> = (0..4)
        .map(|i| v.path(i).sonic_conductance_m3_per_s_pa)
        .collect();
    assert!(
        c.windows(2).all(|w| (w[0] / w[1] - 1.0).abs() > 0.01),
        "{c:?}"
    );
    let log = dir.join("free.csv");
    common::record(&truth, 11, steps(11), 6.0, None, &log);
    let req = request(vec![log], shipped, names(&keys));
    let id = identify(&req).unwrap();
    let r = &id.report;
    eprintln!("{}", pneuflex_identify::report::markdown(r));
    for (c, e) in changes.iter().zip(&r.fit.estimates) {
        assert_eq!(c.key.name(), e.key);
        let err = e.value / c.truth - 1.0;
        common::show_estimate("", c, e);
        common::assert_inside("", c, e);
        assert!(err.abs() <= 0.10, "{} off by {:.2} %", e.key, 100.0 * err);
        // The noise's interval within 5 %; the interval widened for the effects the model lacks
        // (issue 44, check::widen) holds the truth (above) and stays within 15 %: since the probes are
        // tangents at the fit (6ee70a8) two of the exhaust-side b's widen to 11-12 %, past the 10 % of
        // "poorly identified" (asserted below for the conductances only).
        let noise = e.widened.as_ref().map_or(e.ci95, |w| w.noise_ci95);
        let noise_half = (e.value - noise[0]).max(noise[1] - e.value) / e.value.abs();
        assert!(
            noise_half < 0.05,
            "{}: +-{:.2} % (noise alone)",
            e.key,
            100.0 * noise_half
        );
        let half = (e.value - e.ci95[0]).max(e.ci95[1] - e.value) / e.value.abs();
        assert!(half < 0.15, "{}: +-{:.2} % (widened)", e.key, 100.0 * half);
    }
    assert!(
        !r.warnings.iter().any(|w| w.contains("not identifiable")
            || (w.contains("poorly identified") && !w.contains("critical_pressure_ratio"))),
        "{:?}",
        r.warnings
    );
    let supply = id.model.actuator.supply.supply_pressure_pa;
    assert!(r.fit.rms_validation[0] < 0.02 * supply && r.fit.rms_validation[1] < 0.02 * supply);
    assert!(r.fit.rms_validation[2] < 0.5e-3);
    // The fitted sheet names its paths and loads with them.
    let out = dir.join("fit");
    let sheet = pneuflex_identify::request::write_outputs(&id, &req, &out).unwrap();
    let fitted = pneuflex_pneumatics::ActuatorSheet::load(&sheet).unwrap();
    let fv = fitted.actuator().valve;
    for (i, e) in r.fit.estimates[..4].iter().enumerate() {
        let p = fv.paths[i].expect("a path of its own");
        assert_eq!(p.sonic_conductance_m3_per_s_pa, e.value, "{}", e.key);
        assert_eq!(p.critical_pressure_ratio, r.fit.estimates[4 + i].value);
    }
}

/// A path the valve does not have, or a key a path does not take, is refused with the key named.
#[test]
fn refuses_an_unknown_path() {
    let shipped = common::root().join("pneumatics/a05ps25x-5-2-valve.toml");
    let text = std::fs::read_to_string(&shipped).unwrap();
    for (extra, named) in [
        (
            "[valve.paths.supply_c]\ncritical_pressure_ratio = 0.3\n",
            "supply_c",
        ),
        ("[valve.paths.supply_a]\nunderlap = 0.1\n", "underlap"),
        (
            "[valve.paths.a_exhaust]\ncritical_pressure_ratio = 1.2\n",
            "valve.paths.a_exhaust.critical_pressure_ratio",
        ),
    ] {
        let bad = format!("{text}\n{extra}");
        let e = pneuflex_pneumatics::ValveSheet::from_str(&shipped, &bad).unwrap_err();
        let m = e.to_string();
        assert!(
            m.contains(named) && m.contains("a05ps25x-5-2-valve.toml"),
            "{m}"
        );
    }
}
