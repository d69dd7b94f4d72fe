//! `tune` recovers a known optimum: impedance control of a 10 N force step on the ideal inner loop, the
//! damping b_d that minimises the RMS force error (= the integral of the squared error) over the step.
//!
//! For an infinitely fast inner loop the force loop is m_d s² + b_d s + k_e and the squared-error integral
//! (1 + 4ζ²)/(4ζω_n) is least at ζ = 0.5: b_d = sqrt(m_d k_e). The ideal loop's own dynamics (ω = 200 rad/s,
//! ζ = 1) shift that optimum; the test finds the exact continuous-time optimum of the whole loop by
//! integrating it here (RK4, 0.1 ms) with a golden-section search, and requires `tune` within 2 % of it.

use std::path::{Path, PathBuf};

use pneuflex_sweep::SetArg;
use pneuflex_sweep::tune::{FreeArg, Term, TuneOptions, Tuner};

fn data(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data")
        .join(rel)
}

/// ∫₀² e² dt of the continuous loop: m_d ẍ_f + b_d ẋ_f = e, ẍ + 2ζω ẋ + ω² x = ω² x_f, e = 10 - k_e x.
fn ise(b_d: f64, k_e: f64) -> f64 {
    let (m_d, om, ze) = (2.0, 200.0, 1.0);
    let f = |s: [f64; 4]| {
        let e = 10.0 - k_e * s[2];
        [
            s[1],
            (e - b_d * s[1]) / m_d,
            s[3],
            om * om * (s[0] - s[2]) - 2.0 * ze * om * s[3],
        ]
    };
    let h = 1e-4;
    let mut s = [0.0; 4];
    let mut acc = 0.0;
    for _ in 0..20_000 {
        let e0 = 10.0 - k_e * s[2];
        let k1 = f(s);
        let add = |a: [f64; 4], k: [f64; 4], c: f64| {
            [
                a[0] + c * k[0],
                a[1] + c * k[1],
                a[2] + c * k[2],
                a[3] + c * k[3],
            ]
        };
        let k2 = f(add(s, k1, h / 2.0));
        let k3 = f(add(s, k2, h / 2.0));
        let k4 = f(add(s, k3, h));
        for i in 0..4 {
            s[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
        }
        let e1 = 10.0 - k_e * s[2];
        acc += 0.5 * h * (e0 * e0 + e1 * e1);
    }
    acc
}

fn golden(mut a: f64, mut b: f64, k_e: f64) -> f64 {
    let g = (5f64.sqrt() - 1.0) / 2.0;
    for _ in 0..60 {
        let (c, d) = (b - g * (b - a), a + g * (b - a));
        if ise(c, k_e) < ise(d, k_e) {
            b = d;
        } else {
            a = c;
        }
    }
    0.5 * (a + b)
}

#[test]
fn tune_recovers_the_damping_that_minimises_the_step_error() {
    let k_e = 700.0;
    let exact = golden(10.0, 100.0, k_e);
    let second_order = (2.0 * k_e).sqrt();
    eprintln!("optimum b_d: whole loop {exact:.3}, second-order approximation {second_order:.3}");
    assert!((exact - second_order).abs() < 0.3 * second_order);
    let tuner = Tuner::new(
        &data("ideal-step.toml"),
        vec![FreeArg::parse("runs[impedance].impedance.b_d_ns_per_m=[10,100]").unwrap()],
        &[SetArg::parse("environment.stiffness_n_per_m=700").unwrap()],
        None,
        vec![Term::parse("step.rms_force_error_n=1").unwrap()],
        pneuflex_sweep::points::DEFAULT_MAX_POINTS,
    )
    .unwrap();
    let opts = TuneOptions {
        budget: 80,
        seed: 3,
        threads: 2,
        ..TuneOptions::default()
    };
    let history = tuner.search(&opts, None, &|| {}).unwrap();
    assert!(history.len() <= 80 + 8);
    let best = pneuflex_sweep::tune_output::best(&history).unwrap();
    let b = best.x[0];
    eprintln!("tune: b_d = {b:.3} (J = {:.5})", best.j);
    assert!(
        (b - exact).abs() < 0.02 * exact,
        "tune found b_d = {b}, the optimum is {exact}"
    );
    // The same seed on one thread: the same search, bit for bit.
    let one = tuner
        .search(
            &TuneOptions {
                threads: 1,
                ..opts.clone()
            },
            None,
            &|| {},
        )
        .unwrap();
    assert_eq!(one, history);
}

#[test]
fn a_bad_free_key_or_box_is_refused_before_anything_runs() {
    let err = |free: &str, terms: &[&str]| match Tuner::new(
        &data("ideal-step.toml"),
        vec![FreeArg::parse(free).unwrap()],
        &[],
        None,
        terms.iter().map(|t| Term::parse(t).unwrap()).collect(),
        pneuflex_sweep::points::DEFAULT_MAX_POINTS,
    ) {
        Ok(_) => panic!("{free} must be refused"),
        Err(e) => e.to_string(),
    };
    // A box whose lower corner the scene's validation refuses.
    let e = err(
        "runs[impedance].impedance.m_d_kg=[-1,2]",
        &["step.rms_force_error_n=1"],
    );
    assert!(e.contains("runs[0].impedance.m_d_kg"), "{e}");
    let e = err(
        "runs[impedance].impedance.b_d=[1,2]",
        &["step.rms_force_error_n=1"],
    );
    assert!(e.contains("unknown field `b_d`"), "{e}");
    assert!(FreeArg::parse("environment.stiffness_n_per_m=[5,1]").is_err());
    // A box in the logarithm: both bounds > 0.
    let f = FreeArg::parse("runs[impedance].impedance.b_d_ns_per_m=log[10,1000]").unwrap();
    assert!(f.log && f.lo == 10.0 && f.hi == 1000.0);
    assert!(FreeArg::parse("runs[impedance].impedance.b_d_ns_per_m=log[0,1000]").is_err());
    assert!(FreeArg::parse("environment.stiffness_n_per_m=5").is_err());
    // The scene has only a step window: the default objective has no terms.
    let e = err("runs[impedance].impedance.b_d_ns_per_m=[10,100]", &[]);
    assert!(e.contains("--term"), "{e}");
}
