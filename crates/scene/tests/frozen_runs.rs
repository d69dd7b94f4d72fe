//! Frozen runs (`frozen = { run = "adaptive", at = "means" | "bounds" }`): the loader copies the adaptive
//! run's controller, the runner holds g, p, d at the values the adaptive run's trace gives, and the claims
//! say whether the adaptation, those values or the projection bound earned each win.

use std::path::{Path, PathBuf};

use pneuflex_scene::analysis::claims::{EarnedBy, adaptation_verdict, check};
use pneuflex_scene::{FrozenAt, RunResult, Scene, WindowKind, WindowMetrics, run_scene};

const P_MAX: f64 = 3.57e-4;
const D_MAX: f64 = 0.005;

/// paper-fig3-ideal with projection bounds on its adaptive run, and `runs` appended after its runs.
fn text_with(runs: &str) -> String {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/paper-fig3-ideal.toml");
    let text = std::fs::read_to_string(path).unwrap();
    let bounded = text.replacen(
        "sigma3 = 0.1 }",
        &format!("sigma3 = 0.1, p_max_m_per_n = {P_MAX}, d_max_s = {D_MAX} }}"),
        1,
    );
    assert_ne!(bounded, text, "the adaptive table was found");
    let at = bounded.find("[[metrics]]").unwrap();
    format!("{}{runs}\n{}", &bounded[..at], &bounded[at..])
}

const FROZEN: &str = r#"
[[runs]]
name = "frozen_means"
frozen = { run = "adaptive", at = "means" }

[[runs]]
name = "frozen_bounds"
frozen = { run = "adaptive", at = "bounds" }
"#;

fn load(text: &str) -> Result<Scene, String> {
    Scene::from_toml_str(text, &PathBuf::from("scenes/x.toml"), Path::new("scenes"))
        .map_err(|e| e.to_string())
}

/// The error of a bad scene, checked to name the file, a line and `key`.
fn refused(text: &str, key: &str) -> String {
    let e = load(text).expect_err("the scene is refused");
    assert!(e.starts_with("scenes/x.toml:"), "no file: {e}");
    let line = e.split(':').nth(1).unwrap_or("");
    assert!(line.parse::<usize>().is_ok(), "no line: {e}");
    assert!(e.contains(key), "{key} not named: {e}");
    e
}

#[test]
fn a_frozen_run_gets_the_controller_of_its_source_and_keys_it_repeats() {
    let s = load(&text_with(FROZEN)).unwrap_or_else(|e| panic!("{e}"));
    let (src, m, b) = (&s.runs[1], &s.runs[2], &s.runs[3]);
    for f in [m, b] {
        assert_eq!(
            (f.controller, f.impedance, f.adaptive, f.inner),
            (src.controller, src.impedance, src.adaptive, src.inner),
            "{}",
            f.name
        );
    }
    assert_eq!(m.frozen.as_ref().unwrap().at, FrozenAt::Means);
    assert_eq!(b.frozen.as_ref().unwrap().at, FrozenAt::Bounds);
    // What a sweep's `runs[*].inner.kp_per_m` does: the same value written into every run loads.
    let kp = src.inner.kp_per_m;
    let every = text_with(FROZEN).replace(
        "at = \"means\" }",
        &format!("at = \"means\" }}\ninner = {{ kp_per_m = {kp:?} }}"),
    );
    load(&every).unwrap_or_else(|e| panic!("{e}"));
    // A frozen run has no controller of its own before the scene ran.
    let e = s.controller(2).err().expect("no controller").to_string();
    assert!(e.contains("runs[2].frozen"), "{e}");
}

#[test]
fn a_bad_frozen_run_is_refused_with_its_file_line_and_key() {
    let e = refused(
        &text_with(FROZEN).replace(
            "run = \"adaptive\", at = \"means\"",
            "run = \"adaptiv\", at = \"means\"",
        ),
        "runs[2].frozen.run",
    );
    assert!(e.contains("adaptiv"), "{e}");
    // The impedance run has no law to freeze.
    refused(
        &text_with(FROZEN).replace(
            "run = \"adaptive\", at = \"means\"",
            "run = \"impedance\", at = \"means\"",
        ),
        "runs[2].frozen.run",
    );
    // A key of its own that makes the controller differ from its source.
    let e = refused(
        &text_with(FROZEN).replace(
            "at = \"means\" }",
            "at = \"means\" }\ninner = { kp_per_m = 123.0 }",
        ),
        "runs[2].inner",
    );
    assert!(e.contains("adaptive"), "{e}");
    // An unknown `at`.
    refused(
        &text_with(FROZEN).replace("at = \"means\"", "at = \"median\""),
        "runs[2].frozen.at",
    );
    // "bounds" without bounds on the source.
    let no_bounds =
        text_with(FROZEN).replace(&format!(", p_max_m_per_n = {P_MAX}, d_max_s = {D_MAX}"), "");
    let e = refused(&no_bounds, "runs[3].frozen.at");
    assert!(e.contains("p_max_m_per_n"), "{e}");
    // An adapting run after a frozen one (it would run after the values were taken).
    let late = format!(
        "{FROZEN}\n[[runs]]\nname = \"late\"\ncontroller = \"impedance\"\n\
         impedance = {{ m_d_kg = 2.0, b_d_ns_per_m = 52.4, k_d_n_per_m = 0.0 }}\n\
         inner = {{ kp_per_m = 10.0, ki_per_m_s = 20.0, kd_s_per_m = 0.0 }}\n"
    );
    refused(&text_with(&late), "runs[4].name");
}

fn mean(c: &[f64]) -> f64 {
    c.iter().sum::<f64>() / c.len() as f64
}

#[test]
fn a_frozen_run_holds_the_means_or_the_bounds_of_its_sources_trace() {
    let s = load(&text_with(FROZEN)).unwrap_or_else(|e| panic!("{e}"));
    let res = run_scene(&s, &mut |_| {}).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(res.len(), 4);
    let run = |n: &str| res.iter().find(|r| r.name == n).unwrap();
    let col = |r: &RunResult, c: &str| r.trace.column(c).unwrap().to_vec();
    let a = run("adaptive");
    let (g, p, d) = (mean(&col(a, "g")), mean(&col(a, "p")), mean(&col(a, "d")));
    assert!(p > 0.0 && d < 0.0, "the law moved: p {p}, d {d}");
    for (name, want) in [
        ("frozen_means", [g, p, d]),
        ("frozen_bounds", [g, P_MAX, -D_MAX]),
    ] {
        let r = run(name);
        assert!(r.diverged.is_none(), "{name}: {:?}", r.diverged);
        for (c, w) in ["g", "p", "d"].iter().zip(want) {
            let v = col(r, c);
            assert!(
                v.iter()
                    .all(|x| (x - w).abs() <= 1e-12 * w.abs().max(1e-12)),
                "{name}.{c}: held {w}, trace {}..{}",
                v[0],
                v[v.len() - 1]
            );
        }
        assert!(
            r.lyapunov.is_none(),
            "{name}: a frozen law has no Lyapunov check"
        );
        assert!(r.warnings.is_empty(), "{name}: {:?}", r.warnings);
        // The same controller, another trace: the held law is not the adapting one.
        assert_ne!(r.trace.f_e(), a.trace.f_e(), "{name}");
    }
}

/// A run with one sine window `w` whose RMS force error is `rms`.
fn result(name: &str, rms: f64) -> RunResult {
    RunResult {
        name: name.into(),
        controller: pneuflex_scene::ControllerKind::Adaptive,
        trace: pneuflex_scene::Trace::with_capacity(0, Vec::new()),
        windows: vec![WindowMetrics {
            name: "sine".into(),
            kind: WindowKind::Sine,
            t0_s: 3.0,
            t1_s: 6.0,
            rms_force_error_n: rms,
            frequency_hz: None,
            phase_lag_deg: None,
            amplitude_ratio: None,
            steady_state_error_n: None,
            event: None,
        }],
        lyapunov: None,
        diverged: None,
        interrupted: None,
        warnings: Vec::new(),
        pwm_period_s: None,
    }
}

#[test]
fn the_verdict_follows_the_share_of_the_lead_the_frozen_runs_keep() {
    let s = load(&text_with(FROZEN)).unwrap_or_else(|e| panic!("{e}"));
    let c = s
        .claims
        .iter()
        .find(|c| c.window == "sine" && c.metric == "rms_force_error_n")
        .expect("the sine RMS claim");
    // impedance 2.0, adaptive 1.0: a lead of 1.0; the frozen runs keep (2 - v) of it.
    let verdict = |means: f64, bounds: f64| {
        let res = [
            result("impedance", 2.0),
            result("adaptive", 1.0),
            result("frozen_means", means),
            result("frozen_bounds", bounds),
        ];
        let checked = check(c, &res);
        adaptation_verdict(&s, c, &checked, &res).expect("a verdict")
    };
    assert_eq!(verdict(1.9, 1.8).earned_by, EarnedBy::Adaptation);
    assert_eq!(verdict(1.4, 1.8).earned_by, EarnedBy::ParameterValues);
    // Both keep half: the bound suffices.
    let v = verdict(1.2, 1.3);
    assert_eq!(v.earned_by, EarnedBy::ProjectionBound, "{}", v.why);
    assert!((v.frozen[1].share_of_lead.unwrap() - 0.7).abs() < 1e-12);
    // Just under half is not enough.
    assert_eq!(verdict(1.51, 1.51).earned_by, EarnedBy::Adaptation);
    // The adaptive run loses: nothing to attribute, and the frozen run that would win is named.
    let res = [
        result("impedance", 1.0),
        result("adaptive", 2.0),
        result("frozen_means", 0.5),
        result("frozen_bounds", 3.0),
    ];
    let checked = check(c, &res);
    let v = adaptation_verdict(&s, c, &checked, &res).unwrap();
    assert_eq!(v.earned_by, EarnedBy::NoWin);
    assert!(v.why.contains("frozen_means"), "{}", v.why);
    // Without the frozen runs among the results there is no verdict.
    let res = [result("impedance", 2.0), result("adaptive", 1.0)];
    assert!(adaptation_verdict(&s, c, &check(c, &res), &res).is_none());
}

#[test]
fn a_frozen_run_whose_source_diverges_is_not_run_and_says_why() {
    // Anti-damping gains (σ1 negative as printed, a huge μ1) drive the adaptive run's g away: it diverges,
    // and there is nothing to hold.
    let mut s = load(&text_with(FROZEN)).unwrap_or_else(|e| panic!("{e}"));
    let mut a = s.runs[1].adaptive.unwrap();
    a.sigma1_sign = pneuflex_control::Sigma1Sign::AsPrinted;
    a.mu1 = 1e4;
    a.g_max_m = f64::INFINITY;
    for r in &mut s.runs[1..] {
        r.adaptive = Some(a);
    }
    let res = run_scene(&s, &mut |_| {}).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(res.len(), 4);
    assert!(res[1].diverged.is_some(), "the adaptive run diverges");
    for r in &res[2..] {
        let why = r.diverged.as_deref().expect("not run");
        assert!(
            why.contains("`adaptive`") && why.contains("not run"),
            "{why}"
        );
        assert_eq!(r.trace.len(), 0);
    }
}
