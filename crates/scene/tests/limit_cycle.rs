//! Issue 13: the event metrics see a limit cycle. On the proportional-valve plant, the adaptive controller
//! with inner kp = 10 /m limit-cycles near 16 Hz after the stiffness change and must be reported as not
//! settled with that frequency; with kp = 7 /m it settles.

use std::path::Path;

use pneuflex_scene::{RunResult, Scene, run_scene};

fn proportional_fig3(kp: f64) -> Vec<RunResult> {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/paper-fig3.toml");
    let text = std::fs::read_to_string(&path).unwrap();
    let text = text
        .replace("paper-actuator.toml", "paper-actuator-proportional.toml")
        .replace("kp_per_m = 10.0", &format!("kp_per_m = {kp:?}"));
    let scene = Scene::from_toml_str(&text, &path, path.parent().unwrap()).unwrap();
    run_scene(&scene, &mut |_| {}).unwrap()
}

fn stiffness_change(
    res: &[RunResult],
    run: &str,
) -> pneuflex_scene::analysis::metrics::EventResponse {
    res.iter()
        .find(|r| r.name == run)
        .unwrap()
        .window("stiffness_change")
        .unwrap()
        .event
        .clone()
        .unwrap()
}

#[test]
fn the_adaptive_limit_cycle_at_kp_10_is_not_settled_and_has_its_frequency() {
    let e = stiffness_change(&proportional_fig3(10.0), "adaptive");
    assert!(!e.settled, "{e:?}");
    let o = e.oscillation.expect("an oscillation");
    assert!((o.frequency_hz - 16.0).abs() <= 2.0, "{o:?}");
    assert!(o.amplitude_n > 1.0, "{o:?}");
    assert_eq!(e.signal, "f_e", "a proportional valve is read raw");
}

#[test]
fn at_kp_7_both_controllers_settle() {
    let res = proportional_fig3(7.0);
    for run in ["impedance", "adaptive"] {
        let e = stiffness_change(&res, run);
        assert!(e.settled, "{run}: {:?}", e.not_settled);
        assert!(e.oscillation.is_none(), "{run}: {e:?}");
    }
}
