//! The validation figure of `identify`: the first VALIDATION_WINDOW_S of the held-out rows (not the whole
//! part, whose PWM cycles overlay into a band), measured against the model, each signal with a residual
//! panel: five stacked panels.

use std::path::PathBuf;

use pneuflex_identify::log::Log;
use pneuflex_identify::replay::Prediction;
use pneuflex_identify::report::validation_figure;

fn png_size(bytes: &[u8]) -> (u32, u32) {
    assert!(bytes.starts_with(b"\x89PNG\r\n\x1a\n"), "not a PNG");
    let be = |b: &[u8]| u32::from_be_bytes([b[0], b[1], b[2], b[3]]);
    (be(&bytes[16..20]), be(&bytes[20..24]))
}

#[test]
fn the_validation_figure_shows_a_readable_window_with_its_residuals() {
    let n = 4000;
    let t: Vec<f64> = (0..n).map(|k| k as f64 * 1e-3).collect();
    let wave = |a: f64, f: f64| t.iter().map(|t| a * (f * t).sin()).collect::<Vec<f64>>();
    let p_a: Vec<f64> = wave(2e4, 250.0).iter().map(|v| 3e5 + v).collect();
    let p_b: Vec<f64> = wave(1e4, 250.0).iter().map(|v| 2.5e5 - v).collect();
    let x: Vec<f64> = wave(1e-3, 3.0).iter().map(|v| 0.02 + v).collect();
    let log = Log {
        path: PathBuf::from("excite/trace.csv"),
        sha256: String::new(),
        t: t.clone(),
        u: vec![0.0; n],
        x: x.clone(),
        p_a: p_a.clone(),
        p_b: p_b.clone(),
        f_e: vec![0.0; n],
        measured: vec![true; n],
        note: None,
    };
    // A model off by 2 kPa and 0.1 mm.
    let pred = Prediction {
        x: x.iter().map(|v| v - 1e-4).collect(),
        p_a: p_a.iter().map(|v| v - 2e3).collect(),
        p_b: p_b.iter().map(|v| v + 2e3).collect(),
    };
    // The last 40 % held out, with a segment's settling rows left out every 100 rows.
    let rows: Vec<usize> = (2400..n).filter(|k| k % 100 >= 15).collect();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("validation-1.png");
    validation_figure(&path, &log, &pred, &rows).unwrap();
    let size = png_size(&std::fs::read(&path).unwrap());
    assert_eq!(
        size,
        (1200, 5 * 260),
        "five panels: p_a, p_b, their residual, x, its residual"
    );
    if let Ok(keep) = std::env::var("PNEUFLEX_KEEP_FIGURE") {
        std::fs::copy(&path, keep).unwrap();
    }
    // Nothing held out: nothing drawn, no error.
    let none = dir.path().join("none.png");
    validation_figure(&none, &log, &pred, &[]).unwrap();
    assert!(!none.exists());
}
