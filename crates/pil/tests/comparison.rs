//! PIL's comparison of a board run with the host's, without the board: the host run of paper-fig3's
//! adaptive run against copies of itself with one controller signal changed. Every signal the controller
//! declares is compared on its own (issue 24, item 6): a change in one is found there, and only there.

use std::path::Path;

use pneuflex_pil::{compare, single_run_scene};
use pneuflex_scene::{RunResult, Scene, run_scene};

fn adaptive_run() -> (Scene, RunResult) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/paper-fig3.toml");
    let scene = Scene::load(&path).expect("paper-fig3 loads");
    let i = scene
        .runs
        .iter()
        .position(|r| r.name == "adaptive")
        .expect("an adaptive run");
    let one = single_run_scene(&scene, i);
    let r = run_scene(&one, &mut |_| {})
        .expect("runs")
        .pop()
        .expect("one run");
    (one, r)
}

/// The run with column `name` rewritten by `change` (row index, value).
fn with_column(r: &RunResult, name: &str, change: impl Fn(usize, f64) -> f64) -> RunResult {
    let mut out = r.clone();
    let columns = out
        .trace
        .clone()
        .into_columns()
        .into_iter()
        .map(|(c, v)| {
            let v = if c.name == name {
                v.iter().enumerate().map(|(k, &x)| change(k, x)).collect()
            } else {
                v
            };
            (c, v)
        })
        .collect();
    out.trace = pneuflex_scene::Trace::from_columns(columns).expect("same shape");
    out
}

#[test]
fn every_declared_controller_signal_is_compared_on_its_own() {
    let (scene, host) = adaptive_run();
    let signals = scene.controller(0).expect("controller").signals();
    let names: Vec<&str> = signals.iter().map(|s| s.name).collect();
    assert_eq!(names, ["g", "p", "d"]);

    // The host against itself: every tick and every signal identical.
    let same = compare(&host, &host, signals, 0);
    assert_eq!(same.bit_identical_ticks, same.ticks);
    assert_eq!(same.controller_signals.len(), 3);
    for s in &same.controller_signals {
        assert_eq!(
            (s.bit_identical_ticks, s.max_abs_diff),
            (same.ticks, 0.0),
            "{}",
            s.name
        );
    }

    // d one ulp off at tick 1234 (the command untouched): found in d alone, with the ulp as its size.
    let k = 1234;
    let d_host = host.trace.column("d").expect("d")[k];
    let off = with_column(&host, "d", |i, x| {
        if i == k {
            f64::from_bits(x.to_bits() + 1)
        } else {
            x
        }
    });
    let c = compare(&off, &host, signals, 0);
    assert_eq!(c.first_divergent_tick, None, "u is the same");
    assert_eq!(c.bit_identical_ticks, c.ticks - 1);
    for s in &c.controller_signals {
        let want = if s.name == "d" { c.ticks - 1 } else { c.ticks };
        assert_eq!(s.bit_identical_ticks, want, "{}", s.name);
    }
    let d = c.controller_signals.iter().find(|s| s.name == "d").unwrap();
    let ulp = (f64::from_bits(d_host.to_bits() + 1) - d_host).abs();
    assert_eq!(d.max_abs_diff, ulp);
    assert_eq!(d.unit, "s");

    // A NaN where the host has a number: never identical, infinitely far.
    let nan = with_column(&host, "g", |i, x| if i == 10 { f64::NAN } else { x });
    let c = compare(&nan, &host, signals, 0);
    let g = c.controller_signals.iter().find(|s| s.name == "g").unwrap();
    assert_eq!(
        (g.bit_identical_ticks, g.max_abs_diff),
        (c.ticks - 1, f64::INFINITY)
    );
}
