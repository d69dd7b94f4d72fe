//! The fit: Levenberg-Marquardt (`levenberg-marquardt` on nalgebra) over the free parameters, box bounds by
//! a smooth change of variable, forward-difference Jacobian with its columns replayed in parallel (rayon),
//! then 95 % intervals and correlations from the Jacobian at the optimum.
//!
//! Residuals: for every compared row of every log, (simulated - measured) / sigma for p_a, p_b and x.
//! The sigmas start at 1 % of the supply and 0.5 mm; after a first fit they are set to each signal's
//! residual RMS and the fit is repeated (the noise of a pressure transmitter and of a position sensor
//! differ), so that the residual variance is ~1 and the intervals follow from (J^T J)^-1.
//!
//! Bounds: p = lo + (hi - lo) (1 + sin z) / 2, LM works on z (MINUIT's transform): every z is inside.

use levenberg_marquardt::{LeastSquaresProblem, LevenbergMarquardt};
use nalgebra::{DMatrix, DVector, Dyn, Owned};
use pneuflex_pneumatics::OneDofModel;
use rayon::prelude::*;

use crate::IdentifyError;
use crate::params::{Key, Offsets};
use crate::replay::{Prepared, ReplayOptions};

/// One free parameter: key, start value and bounds.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Free {
    /// Which parameter.
    pub key: Key,
    /// Start value (the sheet's).
    pub start: f64,
    /// Lower bound.
    pub lo: f64,
    /// Upper bound.
    pub hi: f64,
}

/// Fit settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FitOptions {
    /// Replay settings.
    pub replay: ReplayOptions,
    /// Reweighting passes after the first fit (each: sigmas from the residuals, then LM again).
    pub reweight_passes: usize,
    /// LM patience (evaluations = patience * (parameters + 1)).
    pub patience: usize,
    /// Segment length of a first, coarse pass, s (`None`: no such pass). Short segments make the cost
    /// nearly quadratic far from the optimum (a 20-40 % wrong start drifts less in 30 ms than in 100 ms), so
    /// LM reaches the basin of the optimum; the passes with `replay.segment_s` then refine it.
    pub coarse_segment_s: Option<f64>,
    /// How far apart (s) the fit's errors may still be correlated, for the intervals (Newey-West lag).
    pub hac_lag_s: f64,
}

impl Default for FitOptions {
    fn default() -> Self {
        Self {
            replay: ReplayOptions::default(),
            reweight_passes: 1,
            patience: 20,
            coarse_segment_s: Some(0.03),
            hac_lag_s: 0.5,
        }
    }
}

/// The three compared signals.
pub const SIGNALS: [&str; 3] = ["p_a", "p_b", "x"];

/// Everything the fit needs, and the residuals of the current parameters.
#[derive(Clone)]
pub struct Problem<'a> {
    base: OneDofModel,
    base_off: Offsets,
    free: Vec<Free>,
    data: &'a [Prepared],
    opts: ReplayOptions,
    /// Sigma per signal (p_a, p_b in Pa, x in m).
    pub sigma: [f64; 3],
    z: DVector<f64>,
}

fn to_z(f: &Free, p: f64) -> f64 {
    let w = f.hi - f.lo;
    if w <= 0.0 {
        return 0.0;
    }
    (2.0 * (p - f.lo) / w - 1.0).clamp(-1.0, 1.0).asin()
}

fn from_z(f: &Free, z: f64) -> f64 {
    f.lo + (f.hi - f.lo) * 0.5 * (1.0 + z.sin())
}

impl<'a> Problem<'a> {
    /// A problem starting at the free parameters' start values.
    pub fn new(
        base: OneDofModel,
        base_off: Offsets,
        free: Vec<Free>,
        data: &'a [Prepared],
        opts: ReplayOptions,
        sigma: [f64; 3],
    ) -> Self {
        let z = DVector::from_iterator(free.len(), free.iter().map(|f| to_z(f, f.start)));
        Self {
            base,
            base_off,
            free,
            data,
            opts,
            sigma,
            z,
        }
    }

    /// The free parameters' current physical values.
    pub fn values(&self) -> Vec<f64> {
        self.free
            .iter()
            .zip(self.z.iter())
            .map(|(f, &z)| from_z(f, z))
            .collect()
    }

    /// The model and offsets with `values` for the free parameters.
    pub fn model_with(&self, values: &[f64]) -> (OneDofModel, Offsets) {
        let mut m = self.base;
        let mut o = self.base_off;
        for (f, &v) in self.free.iter().zip(values) {
            f.key.set(&mut m, &mut o, v);
        }
        (m, o)
    }

    /// Weighted residuals of the fit rows at `values`.
    pub fn residuals_at(&self, values: &[f64]) -> DVector<f64> {
        let (m, o) = self.model_with(values);
        let per_log: Vec<Vec<f64>> = self
            .data
            .par_iter()
            .map(|d| {
                let pred = d.replay(&m, &o, &self.opts, d.fit_end);
                let l = &d.log;
                let mut r = Vec::with_capacity(3 * d.compared.len());
                for &k in &d.compared {
                    r.push((pred.p_a[k] - l.p_a[k]) / self.sigma[0]);
                    r.push((pred.p_b[k] - l.p_b[k]) / self.sigma[1]);
                    r.push((pred.x[k] - l.x[k]) / self.sigma[2]);
                }
                r
            })
            .collect();
        let r: Vec<f64> = per_log.into_iter().flatten().collect();
        // A replay that blew up is a bad direction, not a result: LM backs off on a huge residual.
        DVector::from_iterator(
            r.len(),
            r.into_iter().map(|v| if v.is_finite() { v } else { 1e12 }),
        )
    }

    /// Physical-units residual RMS per signal (Pa, Pa, m) at `values`, over the fit rows (`validation` =
    /// false) or the held-out rows.
    pub fn rms_at(&self, values: &[f64], validation: bool) -> [f64; 3] {
        let (m, o) = self.model_with(values);
        let mut ss = [0.0; 3];
        let mut n = 0usize;
        for d in self.data {
            let rows = if validation {
                &d.validation
            } else {
                &d.compared
            };
            if rows.is_empty() {
                continue;
            }
            let pred = d.replay(&m, &o, &self.opts, d.log.len());
            for &k in rows {
                ss[0] += (pred.p_a[k] - d.log.p_a[k]).powi(2);
                ss[1] += (pred.p_b[k] - d.log.p_b[k]).powi(2);
                ss[2] += (pred.x[k] - d.log.x[k]).powi(2);
                n += 1;
            }
        }
        let n = n.max(1) as f64;
        [(ss[0] / n).sqrt(), (ss[1] / n).sqrt(), (ss[2] / n).sqrt()]
    }

    /// Jacobian of the weighted residuals with respect to the parameters divided by their scales
    /// (`d r / d(p / scale)`), forward differences, columns in parallel.
    pub fn physical_jacobian(&self, values: &[f64], r0: &DVector<f64>) -> DMatrix<f64> {
        let cols: Vec<DVector<f64>> = (0..values.len())
            .into_par_iter()
            .map(|j| {
                let f = &self.free[j];
                let s = f.key.scale(f.start);
                // Step inside the bounds.
                let mut h = 1e-6 * s;
                if values[j] + h > f.hi {
                    h = -h;
                }
                let mut v = values.to_vec();
                v[j] += h;
                (self.residuals_at(&v) - r0) / (h / s)
            })
            .collect();
        DMatrix::from_columns(&cols)
    }
}

impl LeastSquaresProblem<f64, Dyn, Dyn> for Problem<'_> {
    type ResidualStorage = Owned<f64, Dyn>;
    type JacobianStorage = Owned<f64, Dyn, Dyn>;
    type ParameterStorage = Owned<f64, Dyn>;

    fn set_params(&mut self, z: &DVector<f64>) {
        self.z.copy_from(z);
    }

    fn params(&self) -> DVector<f64> {
        self.z.clone()
    }

    fn residuals(&self) -> Option<DVector<f64>> {
        Some(self.residuals_at(&self.values()))
    }

    fn jacobian(&self) -> Option<DMatrix<f64>> {
        let r0 = self.residuals()?;
        let z0 = self.z.clone();
        let cols: Vec<DVector<f64>> = (0..z0.len())
            .into_par_iter()
            .map(|j| {
                let h = 1e-6 * (1.0 + z0[j].abs());
                let v: Vec<f64> = self
                    .free
                    .iter()
                    .enumerate()
                    .map(|(i, f)| from_z(f, if i == j { z0[i] + h } else { z0[i] }))
                    .collect();
                (self.residuals_at(&v) - &r0) / h
            })
            .collect();
        Some(DMatrix::from_columns(&cols))
    }
}

/// One fitted parameter.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Estimate {
    /// Dotted key.
    pub key: String,
    /// Start value.
    pub start: f64,
    /// Fitted value.
    pub value: f64,
    /// Bounds used.
    pub bounds: [f64; 2],
    /// Standard error (infinite when the data do not determine it).
    pub std_error: f64,
    /// 95 % confidence interval, value +- 1.96 std_error.
    pub ci95: [f64; 2],
    /// Half-width of the interval relative to the value.
    pub rel_half_width: f64,
    /// Whether the fitted value sits on a bound (within 0.1 % of the range).
    pub at_bound: bool,
}

/// What the fit found.
#[derive(Clone, Debug, serde::Serialize)]
pub struct FitResult {
    /// Estimates, in the order of `--free`.
    pub estimates: Vec<Estimate>,
    /// Correlation matrix of the estimates (NaN where a variance is infinite).
    pub correlation: Vec<Vec<f64>>,
    /// Residual RMS on the fit rows: p_a, p_b (Pa), x (m).
    pub rms_fit: [f64; 3],
    /// Residual RMS at the start values, same units.
    pub rms_start: [f64; 3],
    /// Residual RMS on the held-out rows with the fitted values (NaN if nothing was held out).
    pub rms_validation: [f64; 3],
    /// Sigmas of the final weighting, Pa, Pa, m.
    pub sigma: [f64; 3],
    /// Number of compared rows in the fit.
    pub rows: usize,
    /// Residual variance of the weighted problem at the optimum (~1 when the weights are right).
    pub residual_variance: f64,
    /// LM's termination, per pass.
    pub termination: Vec<String>,
    /// Replays of all logs made (residual and Jacobian evaluations).
    pub evaluations: usize,
}

/// Fits `free` in `base` to `data`.
pub fn fit(
    base: &OneDofModel,
    free: &[Free],
    data: &[Prepared],
    opts: &FitOptions,
) -> Result<FitResult, IdentifyError> {
    let rows: usize = data.iter().map(|d| d.compared.len()).sum();
    if rows <= free.len() {
        return Err(IdentifyError::Fit(format!(
            "{rows} compared rows for {} free parameters: the logs are too short for the segment settings",
            free.len()
        )));
    }
    let supply = base.actuator.supply.supply_pressure_pa;
    let sigma0 = [0.01 * supply, 0.01 * supply, 0.5e-3];
    let mut pb = Problem::new(
        *base,
        Offsets::default(),
        free.to_vec(),
        data,
        opts.replay,
        sigma0,
    );
    let start: Vec<f64> = free.iter().map(|f| f.start).collect();
    let rms_start = pb.rms_at(&start, false);
    if rms_start.iter().any(|v| !v.is_finite()) {
        return Err(IdentifyError::Fit(
            "the replay with the start values does not stay finite: check the sheet and the logs"
                .into(),
        ));
    }
    let n = free.len();
    let mut termination = Vec::new();
    let mut evaluations = 0;
    if let Some(seg) = opts.coarse_segment_s.filter(|&s| s < opts.replay.segment_s) {
        let ro = ReplayOptions {
            segment_s: seg,
            settle_s: opts.replay.settle_s.min(0.4 * seg),
            ..opts.replay
        };
        let coarse: Vec<Prepared> = data
            .iter()
            .map(|d| Prepared::new(d.log.clone(), &ro, d.fit_end))
            .collect();
        let cp = Problem::new(
            *base,
            Offsets::default(),
            free.to_vec(),
            &coarse,
            ro,
            sigma0,
        );
        let (cp, report) = LevenbergMarquardt::new()
            .with_patience(opts.patience)
            .minimize(cp);
        evaluations += report.number_of_evaluations * (n + 1);
        termination.push(format!("coarse {:?}", report.termination));
        pb.z = cp.z.clone();
    }
    for pass in 0..=opts.reweight_passes {
        if pass > 0 {
            let rms = pb.rms_at(&pb.values(), false);
            // A floor: a signal fitted to the bit must not take all the weight.
            pb.sigma = [rms[0].max(1.0), rms[1].max(1.0), rms[2].max(1e-7)];
        }
        let lm = LevenbergMarquardt::new().with_patience(opts.patience);
        let (p, report) = lm.minimize(pb);
        pb = p;
        evaluations += report.number_of_evaluations * (n + 1);
        termination.push(format!("{:?}", report.termination));
    }
    let values = pb.values();
    let r0 = pb.residuals_at(&values);
    let m = r0.len();
    let ssr = r0.norm_squared();
    let variance = ssr / (m - n).max(1) as f64;
    let j = pb.physical_jacobian(&values, &r0);
    evaluations += n + 1;
    let jtj = j.transpose() * &j;
    // Pseudo-inverse by eigen-decomposition: a direction with no information gets infinite variance.
    let eig = jtj.clone().symmetric_eigen();
    let lmax = eig.eigenvalues.iter().cloned().fold(0.0_f64, f64::max);
    let mut pinv = DMatrix::<f64>::zeros(n, n);
    let mut null = vec![false; n];
    for (i, &l) in eig.eigenvalues.iter().enumerate() {
        let v = eig.eigenvectors.column(i);
        if l > 1e-12 * lmax && l > 0.0 {
            pinv += (v * v.transpose()) / l;
        } else {
            for (k, nk) in null.iter_mut().enumerate() {
                if v[k].abs() > 0.1 {
                    *nk = true;
                }
            }
        }
    }
    // Covariance robust to correlated errors (Newey-West over segments): the replay restarts each segment
    // from a measured, noisy state, and carries velocity, temperatures and the PWM clock into the next, so
    // the residuals of a segment share errors with each other and with the next few segments. With s_c =
    // J_c^T r_c the score of segment c, meat = sum_c s_c s_c^T + sum_{l=1..L} (1 - l/(L+1)) sum_c (s_c
    // s_{c-l}^T + s_{c-l} s_c^T) within each log, L = `hac_lag_s` / segment length; covariance
    // (J^T J)^-1 meat (J^T J)^-1 with the small-sample factor G/(G-1) (N-1)/(N-p), and never below the
    // white-noise covariance s^2 (J^T J)^-1.
    let lag = (opts.hac_lag_s / opts.replay.segment_s).ceil().max(0.0) as usize;
    let mut scores: Vec<Vec<DVector<f64>>> = Vec::new();
    let mut at = 0;
    for d in data {
        let mut sc = Vec::new();
        for c in d.fit_clusters() {
            let rows = 3 * c;
            sc.push(j.rows(at, rows).transpose() * r0.rows(at, rows));
            at += rows;
        }
        scores.push(sc);
    }
    let g: usize = scores.iter().map(Vec::len).sum();
    let mut meat = DMatrix::<f64>::zeros(n, n);
    for sc in &scores {
        for (c, s_c) in sc.iter().enumerate() {
            meat += s_c * s_c.transpose();
            for l in 1..=lag.min(c) {
                let w = 1.0 - l as f64 / (lag + 1) as f64;
                let s_l = &sc[c - l];
                meat += (s_c * s_l.transpose() + s_l * s_c.transpose()) * w;
            }
        }
    }
    let small = if g > 1 {
        (g as f64 / (g as f64 - 1.0)) * ((m as f64 - 1.0) / (m - n).max(1) as f64)
    } else {
        1.0
    };
    let sandwich = &pinv * meat * &pinv * small;
    let white = &pinv * variance;
    let mut cov = sandwich.clone();
    for k in 0..n {
        // Keep the correlations of the sandwich; take the larger variance of the two estimates.
        let f = (white[(k, k)] / sandwich[(k, k)].max(f64::MIN_POSITIVE))
            .max(1.0)
            .sqrt();
        for l in 0..n {
            cov[(k, l)] *= f;
            cov[(l, k)] *= f;
        }
    }
    let mut estimates = Vec::with_capacity(n);
    let mut std = vec![0.0; n];
    for (k, f) in free.iter().enumerate() {
        let s = f.key.scale(f.start);
        std[k] = if null[k] {
            f64::INFINITY
        } else {
            s * cov[(k, k)].max(0.0).sqrt()
        };
        let v = values[k];
        let half = 1.96 * std[k];
        let range = f.hi - f.lo;
        estimates.push(Estimate {
            key: f.key.name().to_string(),
            start: f.start,
            value: v,
            bounds: [f.lo, f.hi],
            std_error: std[k],
            ci95: [v - half, v + half],
            rel_half_width: if v != 0.0 {
                half / v.abs()
            } else {
                f64::INFINITY
            },
            at_bound: (v - f.lo).abs() < 1e-3 * range || (f.hi - v).abs() < 1e-3 * range,
        });
    }
    let correlation = (0..n)
        .map(|a| {
            (0..n)
                .map(|b| {
                    if null[a] || null[b] {
                        f64::NAN
                    } else {
                        let d = (cov[(a, a)] * cov[(b, b)]).sqrt();
                        if d > 0.0 { cov[(a, b)] / d } else { f64::NAN }
                    }
                })
                .collect()
        })
        .collect();
    let rms_fit = pb.rms_at(&values, false);
    let rms_validation = if data.iter().any(|d| !d.validation.is_empty()) {
        pb.rms_at(&values, true)
    } else {
        [f64::NAN; 3]
    };
    Ok(FitResult {
        estimates,
        correlation,
        rms_fit,
        rms_start,
        rms_validation,
        sigma: pb.sigma,
        rows,
        residual_variance: variance,
        termination,
        evaluations,
    })
}
