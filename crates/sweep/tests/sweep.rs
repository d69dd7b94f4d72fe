//! The sweep engine: determinism across thread counts, the closed form of impedance control on the ideal
//! plant, clean errors before anything runs, a diverged point as a row.

use pneuflex_sweep::points::DEFAULT_MAX_POINTS;
use std::path::{Path, PathBuf};

use pneuflex_sweep::{SetArg, Status, Sweep, SweepError};

fn repo(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../..")
        .join(rel)
}

fn data(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data")
        .join(rel)
}

fn sets(args: &[&str]) -> Vec<SetArg> {
    args.iter()
        .map(|a| SetArg::parse(a).unwrap_or_else(|e| panic!("{e}")))
        .collect()
}

fn sweep(scene: &Path, args: &[&str]) -> Result<Sweep, SweepError> {
    Sweep::new(scene, &sets(args), None, 0, DEFAULT_MAX_POINTS)
}

fn table(s: &Sweep, threads: usize) -> String {
    let idx: Vec<usize> = (0..s.len()).collect();
    s.table(&s.run(&idx, threads, None, &|| {}).unwrap())
}

#[test]
fn one_and_two_threads_write_the_same_table() {
    let s = sweep(
        &repo("scenes/paper-fig3-ideal.toml"),
        &[
            "environment.stiffness_n_per_m=log:300:3000:3",
            "runs[adaptive].inner.kp_per_m=100,200",
        ],
    )
    .unwrap();
    assert_eq!(s.len(), 6);
    let one = table(&s, 1);
    let two = table(&s, 2);
    assert_eq!(one, two);
    // 6 points x 2 runs, plus the header.
    assert_eq!(one.lines().count(), 13, "{one}");
    assert!(one.starts_with(
        "point,environment.stiffness_n_per_m,runs[adaptive].inner.kp_per_m,run,controller,status,reason,step.rms_force_error_n,"
    ));
}

/// f_e / f_r of the linear loop k_e G / (Z + k_e G) at s = jw (crates/scene/tests/closed_form.rs).
fn closed_form(w: f64, k_e: f64) -> (f64, f64) {
    let (m_d, b_d, k_d, om, ze) = (2.0, 52.4, 200.0, 200.0, 1.0);
    type C = (f64, f64);
    let mul = |a: C, b: C| (a.0 * b.0 - a.1 * b.1, a.0 * b.1 + a.1 * b.0);
    let div = |a: C, b: C| {
        let d = b.0 * b.0 + b.1 * b.1;
        ((a.0 * b.0 + a.1 * b.1) / d, (a.1 * b.0 - a.0 * b.1) / d)
    };
    let s: C = (0.0, w);
    let s2 = mul(s, s);
    let z = (m_d * s2.0 + b_d * s.0 + k_d, m_d * s2.1 + b_d * s.1);
    let g = div(
        (om * om, 0.0),
        (
            s2.0 + 2.0 * ze * om * s.0 + om * om,
            s2.1 + 2.0 * ze * om * s.1,
        ),
    );
    let keg = (k_e * g.0, k_e * g.1);
    let h = div(keg, (z.0 + keg.0, z.1 + keg.1));
    (h.0.hypot(h.1), -h.1.atan2(h.0).to_degrees())
}

#[test]
fn a_stiffness_sweep_on_the_ideal_plant_matches_the_closed_form() {
    let s = sweep(
        &data("ideal-impedance.toml"),
        &["environment.stiffness_n_per_m=log:100:3000:5"],
    )
    .unwrap();
    let idx: Vec<usize> = (0..s.len()).collect();
    let res = s.run(&idx, 2, None, &|| {}).unwrap();
    let col = |name: &str| s.metric_index(name).unwrap();
    let (lag_i, ratio_i, sse_i) = (
        col("sine.phase_lag_deg"),
        col("sine.amplitude_ratio"),
        col("step.steady_state_error_n"),
    );
    let w = std::f64::consts::TAU * 0.8;
    for p in &res {
        let k_e = s.points.row(p.index)[0].as_f64().unwrap();
        let r = &p.runs[0];
        assert_eq!(r.status, Status::Ok, "{r:?}");
        let (ratio_cf, lag_cf) = closed_form(w, k_e);
        let static_cf = 10.0 * 200.0 / (200.0 + k_e);
        let (lag, ratio, sse) = (
            r.metrics[lag_i].unwrap(),
            r.metrics[ratio_i].unwrap(),
            r.metrics[sse_i].unwrap(),
        );
        eprintln!(
            "k_e {k_e:8.1}: lag {lag:.3} ({lag_cf:.3}) deg, ratio {ratio:.4} ({ratio_cf:.4}), static {sse:.4} ({static_cf:.4}) N"
        );
        assert!(
            (lag - lag_cf).abs() < 0.5,
            "k_e {k_e}: lag {lag} vs {lag_cf}"
        );
        assert!(
            (ratio - ratio_cf).abs() < 0.01 * ratio_cf,
            "k_e {k_e}: ratio {ratio} vs {ratio_cf}"
        );
        assert!(
            (sse - static_cf).abs() < 0.02,
            "k_e {k_e}: static error {sse} vs {static_cf}"
        );
    }
}

fn err(scene: &Path, args: &[&str]) -> String {
    match sweep(scene, args) {
        Ok(_) => panic!("{args:?} must be refused"),
        Err(e) => e.to_string(),
    }
}

#[test]
fn a_key_that_does_not_exist_is_the_scenes_own_error() {
    let fig3 = repo("scenes/paper-fig3.toml");
    let e = err(&fig3, &["environment.stifness_n_per_m=100,200"]);
    assert!(e.contains("paper-fig3.toml"), "{e}");
    assert!(e.contains("unknown field `stifness_n_per_m`"), "{e}");
    assert!(e.contains("sweep point #0 of 2"), "{e}");
    let e = err(&fig3, &["runs[adaptve].inner.kp_per_m=5"]);
    assert!(e.contains("no element named \"adaptve\""), "{e}");
    assert!(
        e.contains("[\"impedance\", \"adaptive\", \"frozen_means\", \"frozen_bounds\"]"),
        "{e}"
    );
    let e = err(&fig3, &["runs[7].inner.kp_per_m=5"]);
    assert!(e.contains("has 4 element(s), no [7]"), "{e}");
    // A frozen run runs its source's controller: moving its gain alone is refused with the key.
    let e = err(&fig3, &["runs[frozen_means].inner.kp_per_m=5"]);
    assert!(e.contains("runs[2].inner") && e.contains("differ"), "{e}");
    let e = err(&fig3, &["nothing.here=5"]);
    assert!(e.contains("unknown field `nothing`"), "{e}");
    let e = err(&fig3, &["environment[0]=5"]);
    assert!(e.contains("`environment` is a table, not an array"), "{e}");
    let e = err(&fig3, &["plant.actuator:mechanics.moving_mas_kg=0.5"]);
    assert!(
        e.contains("paper-actuator.toml") && e.contains("moving_mas_kg"),
        "{e}"
    );
}

#[test]
fn bad_ranges_are_clean_errors() {
    for (arg, want) in [
        ("environment.stiffness_n_per_m=log:0:100:3", "LO > 0"),
        (
            "environment.stiffness_n_per_m=lin:1:2",
            "takes three numbers",
        ),
        (
            "environment.stiffness_n_per_m=lin:1:2:0",
            "N must be in 1 ..= 100000",
        ),
        (
            "environment.stiffness_n_per_m=lin:a:2:3",
            "LO `a` is not a number",
        ),
        (
            "environment.stiffness_n_per_m=geo:1:2:3",
            "unknown SPEC kind `geo:`",
        ),
        ("environment.stiffness_n_per_m=lhs:5:1", "needs LO < HI"),
        ("environment.stiffness_n_per_m", "expected KEY=SPEC"),
        ("runs[adaptive.inner.kp_per_m=1", "`[` without `]`"),
    ] {
        let e = match SetArg::parse(arg) {
            Ok(_) => panic!("{arg} must be refused"),
            Err(e) => e.to_string(),
        };
        assert!(e.contains(want), "{arg}: {e}");
    }
    // A sampled key without --samples.
    let e = err(
        &repo("scenes/paper-fig3.toml"),
        &["environment.stiffness_n_per_m=lhs:100:200"],
    );
    assert!(e.contains("needs --samples"), "{e}");
}

#[test]
fn a_value_the_validation_rejects_is_refused_before_anything_runs() {
    let fig3 = repo("scenes/paper-fig3.toml");
    let e = err(&fig3, &["environment.stiffness_n_per_m=700,-5"]);
    // file:line:col: key: message, and the point.
    assert!(e.starts_with(&format!("{}:17:", fig3.display())), "{e}");
    assert!(
        e.contains(": environment.stiffness_n_per_m: must be >= 0, got -5"),
        "{e}"
    );
    assert!(
        e.contains("sweep point #1 of 2: environment.stiffness_n_per_m = -5"),
        "{e}"
    );
    let e = err(&fig3, &["runs[adaptive].inner.kp_per_m=10,-1"]);
    assert!(e.contains("runs[1].inner.kp_per_m"), "{e}");
    assert!(e.contains("#1 of 2"), "{e}");
    // An integer key given a fraction: the parser's own message.
    let e = err(&fig3, &["plant.substeps=10,10.5"]);
    assert!(e.contains("plant.substeps") && e.contains("10.5"), "{e}");
    // A sheet value the sheet's validation rejects.
    let e = err(&fig3, &["plant.actuator:mechanics.moving_mass_kg=0.6,-1"]);
    assert!(
        e.contains("paper-actuator.toml") && e.contains("mechanics.moving_mass_kg"),
        "{e}"
    );
    assert!(e.contains("#1 of 2"), "{e}");
}

#[test]
fn a_point_that_diverges_is_a_row() {
    // A force limit below the reference stops the run as diverged at that point only.
    let s = sweep(
        &data("ideal-impedance.toml"),
        &["divergence.max_abs_force_n=5,1e5"],
    )
    .unwrap();
    let idx: Vec<usize> = (0..s.len()).collect();
    let res = s.run(&idx, 2, None, &|| {}).unwrap();
    assert_eq!(res[0].runs[0].status, Status::Diverged);
    assert!(res[0].runs[0].reason.contains("max_abs_force_n"));
    assert!(res[0].runs[0].metrics.iter().all(Option::is_none));
    assert_eq!(res[1].runs[0].status, Status::Ok);
    let t = s.table(&res);
    let row0 = t.lines().nth(1).unwrap();
    assert!(
        row0.starts_with("0,5,impedance,impedance,diverged,"),
        "{row0}"
    );
}

#[test]
fn sheet_values_reach_the_plant() {
    // The valve's sonic conductance, through the actuator sheet: a smaller valve tracks worse.
    let s = sweep(
        &repo("scenes/paper-fig3-proportional.toml"),
        &["plant.actuator:components.valve:valve.sonic_conductance_m3_per_s_pa=lin:1e-9:4e-9:2"],
    )
    .unwrap();
    let res = s.run(&[0, 1], 2, None, &|| {}).unwrap();
    let rms = s.metric_index("sine.rms_force_error_n").unwrap();
    let a = res[0].runs[0].metrics[rms].unwrap();
    let b = res[1].runs[0].metrics[rms].unwrap();
    assert!(a != b, "the sheet edit changed nothing: {a} {b}");
}

#[test]
fn samples_are_deterministic_and_inside_their_bounds() {
    let args = [
        "environment.stiffness_n_per_m=lhs-log:100:10000",
        "runs[impedance].impedance.b_d_ns_per_m=rand:20:80",
    ];
    let a = Sweep::new(
        &data("ideal-impedance.toml"),
        &sets(&args),
        Some(8),
        7,
        DEFAULT_MAX_POINTS,
    )
    .unwrap();
    let b = Sweep::new(
        &data("ideal-impedance.toml"),
        &sets(&args),
        Some(8),
        7,
        DEFAULT_MAX_POINTS,
    )
    .unwrap();
    let c = Sweep::new(
        &data("ideal-impedance.toml"),
        &sets(&args),
        Some(8),
        8,
        DEFAULT_MAX_POINTS,
    )
    .unwrap();
    assert_eq!(a.points, b.points);
    assert_ne!(a.points, c.points);
    // Latin hypercube: one sample in each eighth of the log range.
    let rows: Vec<_> = (0..a.len()).map(|i| a.points.row(i)).collect();
    let mut bins: Vec<usize> = rows
        .iter()
        .map(|v| {
            let k = v[0].as_f64().unwrap();
            ((k.log10() - 2.0) / 2.0 * 8.0).floor() as usize
        })
        .collect();
    bins.sort_unstable();
    assert_eq!(bins, (0..8).collect::<Vec<_>>());
    for v in &rows {
        let b = v[1].as_f64().unwrap();
        assert!((20.0..80.0).contains(&b));
    }
}

#[test]
fn a_key_can_follow_another() {
    // Fig. 3's doubling at every stiffness: the event's stiffness is twice the initial one at every point.
    let s = sweep(
        &repo("scenes/paper-fig3-ideal.toml"),
        &[
            "environment.stiffness_n_per_m=350,700",
            "events[0].stiffness_n_per_m=@environment.stiffness_n_per_m*2",
            "runs[*].inner.kp_per_m=100,200",
        ],
    )
    .unwrap();
    assert_eq!(s.len(), 4);
    let follow: Vec<f64> = (0..s.len())
        .map(|i| s.points.row(i)[1].as_f64().unwrap())
        .collect();
    assert_eq!(follow, [700.0, 700.0, 1400.0, 1400.0]);
    // The grid's axes are the two swept keys, not the follower.
    let grid = s.points.grid.as_ref().unwrap();
    assert_eq!(grid.iter().map(|g| g.0).collect::<Vec<_>>(), [0, 2]);
    let e = match SetArg::parse("events[0].stiffness_n_per_m=@nothing.swept") {
        Ok(a) => match Sweep::new(
            &repo("scenes/paper-fig3-ideal.toml"),
            &[a],
            None,
            0,
            DEFAULT_MAX_POINTS,
        ) {
            Ok(_) => panic!("a follower of nothing must be refused"),
            Err(e) => e.to_string(),
        },
        Err(e) => e.to_string(),
    };
    assert!(e.contains("not swept"), "{e}");
}

#[test]
fn the_chunked_run_writes_the_same_table() {
    let s = sweep(
        &data("ideal-impedance.toml"),
        &["environment.stiffness_n_per_m=log:100:3000:70"],
    )
    .unwrap();
    let idx: Vec<usize> = (0..s.len()).collect();
    let whole = table(&s, 2);
    let mut streamed = s.header();
    s.run_chunked(&idx, 1, None, None, &|| {}, &mut |chunk| {
        streamed.push_str(&s.table(chunk)[s.header().len()..]);
        Ok(())
    })
    .unwrap();
    assert_eq!(streamed, whole);
}

/// The table's `settling_fragile` column is the run's own (`event.settling_fragile`, docs/scenes.md): a
/// sweep point at the scene's values gives the scene's settling times and their fragility, and a heatmap of
/// a settling time knows which column marks it.
#[test]
fn a_settling_time_comes_with_its_fragility() {
    let path = repo("scenes/paper-fig3-ideal.toml");
    let s = sweep(&path, &["runs[*].inner.kp_per_m=200"]).unwrap();
    let idx: Vec<usize> = (0..s.len()).collect();
    let res = s.run(&idx, 1, None, &|| {}).unwrap();
    let ts = s.metric_index("stiffness_change.settling_time_s").unwrap();
    let fragile = s.metric_index("stiffness_change.settling_fragile").unwrap();
    assert_eq!(s.fragile_column(ts), Some(fragile));
    assert_eq!(s.fragile_column(fragile), None);
    let scene = pneuflex_scene::Scene::load(&path).unwrap();
    let own = pneuflex_scene::run_scene(&scene, &mut |_| {}).unwrap();
    let mut flagged = 0;
    for (row, run) in res[0].runs.iter().zip(&own) {
        let e = run
            .window("stiffness_change")
            .unwrap()
            .event
            .as_ref()
            .unwrap();
        assert_eq!(row.metrics[ts], e.settling_time_s, "{}", run.name);
        assert_eq!(
            row.metrics[fragile],
            Some(if e.settling_fragile { 1.0 } else { 0.0 }),
            "{}",
            run.name
        );
        flagged += usize::from(e.settling_fragile);
    }
    // The ideal plant's impedance run settles at 0.332 s, 0.411 s with the band 5 % narrower.
    assert_eq!(flagged, 1, "{:?}", res[0].runs);
}
