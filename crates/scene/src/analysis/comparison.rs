//! A rig's run against the simulation of the same scene and run (`pneuflex compare`, docs/your-rig.md): each
//! window's metrics side by side with their difference, from the same metric code as `run`, and the RMS of
//! the difference of the two traces sample by sample.

use serde::Serialize;

use super::claims::{METRICS, value};
use crate::run::RunResult;

/// One metric of one window on both sides.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct MetricPair {
    pub window: String,
    pub metric: &'static str,
    pub rig: Option<f64>,
    pub simulation: Option<f64>,
    /// rig − simulation.
    pub difference: Option<f64>,
}

/// The comparison of one run.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Comparison {
    /// The scene's run both sides ran.
    pub run: String,
    /// Every metric either side has, window by window.
    pub metrics: Vec<MetricPair>,
    /// Rows compared (the shorter trace's), and their time span, s.
    pub samples: usize,
    pub span_s: f64,
    /// RMS over those rows of f_e(rig) − f_e(simulation), N, and of x, m.
    pub f_e_rms_difference_n: f64,
    pub x_rms_difference_m: f64,
    /// The largest |t(rig) − t(simulation)| over those rows, s (0 when both run on the scene's ticks).
    pub time_misalignment_s: f64,
}

/// Compares `rig` with `sim`, window by window (both computed on the same scene's windows).
pub fn compare(run: &str, rig: &RunResult, sim: &RunResult) -> Comparison {
    let mut metrics = Vec::new();
    for w in &sim.windows {
        let r = rig.window(&w.name);
        for m in METRICS {
            let (a, b) = (r.and_then(|r| value(r, m)), value(w, m));
            if a.is_none() && b.is_none() {
                continue;
            }
            metrics.push(MetricPair {
                window: w.name.clone(),
                metric: m,
                rig: a,
                simulation: b,
                difference: a.zip(b).map(|(a, b)| a - b),
            });
        }
    }
    let n = rig.trace.len().min(sim.trace.len());
    let rms = |a: &[f64], b: &[f64]| {
        let s: f64 = a[..n]
            .iter()
            .zip(&b[..n])
            .map(|(a, b)| (a - b) * (a - b))
            .sum();
        if n == 0 {
            f64::NAN
        } else {
            (s / n as f64).sqrt()
        }
    };
    let (tr, ts) = (rig.trace.t(), sim.trace.t());
    Comparison {
        run: run.to_string(),
        metrics,
        samples: n,
        span_s: if n > 0 { tr[n - 1] - tr[0] } else { 0.0 },
        f_e_rms_difference_n: rms(rig.trace.f_e(), sim.trace.f_e()),
        x_rms_difference_m: rms(rig.trace.x(), sim.trace.x()),
        time_misalignment_s: tr[..n]
            .iter()
            .zip(&ts[..n])
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max),
    }
}
