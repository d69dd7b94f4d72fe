//! What the tool found, kept true: the gains `pneuflex tune` found for `scenes/paper-fig7-realistic.toml`
//! (wood 2e5 N/m, iron 2e7 N/m, proportional valve) keep both controllers stable — every event window
//! settles, the steady force errors stay small (docs/sweeps.md, "Findings").

use std::path::Path;

use pneuflex_scene::{Scene, run_scene};

#[test]
fn paper_fig7_realistic_both_controllers_settle_with_the_tuned_gains() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/paper-fig7-realistic.toml");
    let scene = Scene::load(&path).unwrap_or_else(|e| panic!("{e}"));
    let results = run_scene(&scene, &mut |_| {}).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(results.len(), 2);
    for r in &results {
        assert!(r.diverged.is_none(), "{}: {:?}", r.name, r.diverged);
        for w in &r.windows {
            if let Some(ev) = &w.event {
                assert!(ev.settled, "{} {}: {:?}", r.name, w.name, ev.not_settled);
            }
        }
        for (window, limit) in [("wood_steady", 0.5), ("iron_steady", 0.5)] {
            let rms = r.window(window).unwrap().rms_force_error_n;
            eprintln!("{} {window}: RMS force error {rms:.4} N", r.name);
            assert!(rms < limit, "{} {window}: RMS force error {rms} N", r.name);
        }
    }
}
