//! The fit: Levenberg-Marquardt (`levenberg-marquardt` on nalgebra) over the free parameters, box bounds by
//! a smooth change of variable, forward-difference Jacobian with its columns replayed in parallel (rayon),
//! then 95 % intervals and correlations: value +- (1.96 sigma + bias bound), sigma the larger of a
//! Newey-West sandwich over segments and a bootstrap of the replay's restarts, the bias bound that
//! bootstrap's measured bias (see `fit` and [`restart_bootstrap`]).
//!
//! Residuals: for every compared row of every log, (simulated - measured) / sigma for p_a, p_b and x.
//! The sigmas start at 1 % of the supply and 0.5 mm; after a first fit they are set to each signal's
//! residual RMS and the fit is repeated (the noise of a pressure transmitter and of a position sensor
//! differ), so that the residual variance is ~1.
//!
//! Bounds: p = lo + (hi - lo) (1 + sin z) / 2, LM works on z (MINUIT's transform): every z is inside.

use levenberg_marquardt::{LeastSquaresProblem, LevenbergMarquardt, MinimizationReport};
use nalgebra::{DMatrix, DVector, Dyn, Owned};
use pneuflex_pneumatics::OneDofModel;
use rayon::prelude::*;
use std::sync::atomic::{AtomicUsize, Ordering};

use crate::IdentifyError;
use crate::params::{Key, Offsets};
use crate::replay::{Prepared, ReplayOptions, local_fit};

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
    /// Replicates of the restart-noise bootstrap that measures the bias of the segment-wise replay (see
    /// [`restart_bootstrap`]); 0 leaves the bias out of the intervals.
    pub bias_replicates: usize,
}

impl Default for FitOptions {
    fn default() -> Self {
        Self {
            replay: ReplayOptions::default(),
            reweight_passes: 1,
            patience: 20,
            coarse_segment_s: Some(0.03),
            hac_lag_s: 0.5,
            bias_replicates: 32,
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
    /// A signal's number once one came: the residuals are then refused, which ends LM at once.
    stop: Option<&'a AtomicUsize>,
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
            stop: None,
        }
    }

    fn stopped(&self) -> bool {
        self.stop.is_some_and(|s| s.load(Ordering::Relaxed) != 0)
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
    /// (`d r / d(p / scale)`), for the intervals: central differences over +-`rel_step` of each scale,
    /// columns in parallel (one-sided where a bound is nearer).
    ///
    /// The step is of the size of the intervals themselves (~0.1 %), not LM's 1e-6: the replay has events
    /// (end stops, Coulomb friction's sign, PWM edges against the row grid) at which a residual jumps, and a
    /// jump of size d inside a step h adds d / h to the column; a step of 1e-6 made the mass's column far too
    /// long on one log (truth of seed 15: reported +-0.006 %, 0.05 % off), while over 0.1 % the smooth
    /// sensitivity dominates. The central quotient's own error is h^2 d3r/dp3 / 6, negligible at 1e-3.
    pub fn physical_jacobian(
        &self,
        values: &[f64],
        r0: &DVector<f64>,
        rel_step: f64,
    ) -> DMatrix<f64> {
        let cols: Vec<DVector<f64>> = (0..values.len())
            .into_par_iter()
            .map(|j| {
                let f = &self.free[j];
                let s = f.key.scale(f.start);
                let h = rel_step * s;
                let at = |d: f64| {
                    let mut v = values.to_vec();
                    v[j] += d;
                    self.residuals_at(&v)
                };
                let up = values[j] + h <= f.hi;
                let down = values[j] - h >= f.lo;
                match (up, down) {
                    (true, true) => (at(h) - at(-h)) / (2.0 * h / s),
                    (true, false) => (at(h) - r0) / (h / s),
                    _ => (r0 - at(-h)) / (h / s),
                }
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
        if self.stopped() {
            return None;
        }
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
    /// Standard error (infinite when the data do not determine it): the larger of the sandwich's and the
    /// restart-noise bootstrap's.
    pub std_error: f64,
    /// Bias of the segment-wise replay measured by the restart-noise bootstrap (estimate minus the value it
    /// was simulated from, mean over the replicates), same unit as the value. Not subtracted from `value`.
    pub bias: f64,
    /// What the interval adds for that bias: |bias| + 1.96 times the bootstrap mean's standard error.
    pub bias_bound: f64,
    /// 95 % confidence interval, value +- (1.96 std_error + bias_bound).
    pub ci95: [f64; 2],
    /// Half-width of the interval relative to the value.
    pub rel_half_width: f64,
    /// Whether the fitted value sits on a bound (within 0.1 % of the range).
    pub at_bound: bool,
    /// Whether `ci95` can be trusted: false when the model check finds the model not adequate
    /// (`crate::check`): the interval then covers the noise of a model that is not the rig's and the
    /// probed effects' linear share, not the whole bias of a missing effect that large, and may exclude
    /// the truth.
    pub interval_valid: bool,
    /// Set when `ci95` was widened to hold the truth under an effect the model lacks (the model check's
    /// probes, `crate::check::widen`): which effect, the amounts the residuals allow, and the interval
    /// before.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub widened: Option<Widening>,
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
    fit_stoppable(base, free, data, opts, None)
}

/// [`fit`] that a signal can stop (`stop` holds its number once one came): LM ends at its next
/// evaluation and the fit returns [`IdentifyError::Interrupted`] with the values reached.
pub fn fit_stoppable(
    base: &OneDofModel,
    free: &[Free],
    data: &[Prepared],
    opts: &FitOptions,
    stop: Option<&AtomicUsize>,
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
    pb.stop = stop;
    let interrupted = |pb: &Problem, pass: &str| IdentifyError::Interrupted {
        signal: stop.map_or(0, |s| s.load(Ordering::Relaxed)),
        reached: free
            .iter()
            .zip(pb.values())
            .map(|(f, v)| (f.key.name().to_string(), v))
            .collect(),
        pass: pass.to_string(),
    };
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
        let (z, report) = coarse_pass(base, free, data, opts, seg, sigma0, stop);
        evaluations += report.number_of_evaluations * (n + 1);
        termination.push(format!("coarse {:?}", report.termination));
        pb.z = z;
        if pb.stopped() {
            return Err(interrupted(&pb, "the coarse pass"));
        }
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
        if pb.stopped() {
            return Err(interrupted(
                &pb,
                &format!("pass {} of {}", pass + 1, opts.reweight_passes + 1),
            ));
        }
    }
    let values = pb.values();
    let r0 = pb.residuals_at(&values);
    let m = r0.len();
    let ssr = r0.norm_squared();
    let variance = ssr / (m - n).max(1) as f64;
    let j = pb.physical_jacobian(&values, &r0, 1e-3);
    evaluations += 2 * n + 1;
    let (pinv, null) = pseudo_inverse(&(j.transpose() * &j));
    let mut cov = robust_covariance(&j, &r0, data, &pinv, variance, opts);
    // The replay's own bias (restart noise, see `restart_bootstrap`), and its sampling spread under the
    // sensor noise alone, in the same scaled units as `cov`.
    let rms_fit = pb.rms_at(&values, false);
    let boot = restart_bootstrap(&pb, &values, &j, &pinv, opts.bias_replicates);
    evaluations += opts.bias_replicates;
    let estimates = estimates_of(free, &values, &mut cov, &null, boot.as_ref());
    let correlation = correlation_of(&cov, &null);
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

/// A screening fit (`crate::select`): Levenberg-Marquardt from the free parameters' starts on `data` with
/// the residuals weighted by `sigma` (a previous fit's, so no reweighting pass), no coarse pass, no
/// intervals, and at most `patience` x (parameters + 1) residual evaluations; LM also stops once a step
/// changes the cost or the scaled parameters by less than `tolerance` relative (the fit's own passes use
/// the crate's 30 machine epsilons). The values reached and the residual evaluations made (each LM
/// iteration adds the Jacobian's parameters + 1 replays).
#[allow(clippy::too_many_arguments)]
pub fn screen(
    base: &OneDofModel,
    free: &[Free],
    data: &[Prepared],
    opts: &ReplayOptions,
    sigma: [f64; 3],
    patience: usize,
    tolerance: f64,
    stop: Option<&AtomicUsize>,
) -> Result<(Vec<f64>, usize), IdentifyError> {
    let mut pb = Problem::new(*base, Offsets::default(), free.to_vec(), data, *opts, sigma);
    pb.stop = stop;
    let start: Vec<f64> = free.iter().map(|f| f.start).collect();
    if pb.residuals_at(&start).iter().any(|v| *v >= 1e12) {
        return Err(IdentifyError::Fit(
            "the replay with the start values does not stay finite: check the sheet and the logs"
                .into(),
        ));
    }
    let (pb, report) = LevenbergMarquardt::new()
        .with_patience(patience)
        .with_ftol(tolerance)
        .with_xtol(tolerance)
        .minimize(pb);
    if pb.stopped() {
        return Err(IdentifyError::Interrupted {
            signal: stop.map_or(0, |s| s.load(Ordering::Relaxed)),
            reached: free
                .iter()
                .zip(pb.values())
                .map(|(f, v)| (f.key.name().to_string(), v))
                .collect(),
            pass: "the screening fit".into(),
        });
    }
    Ok((pb.values(), report.number_of_evaluations))
}

/// The coarse pass (`FitOptions::coarse_segment_s`): LM over the logs cut into segments of `seg` s, from the
/// start values; the optimum it reaches (in LM's variables, z) and LM's report.
fn coarse_pass(
    base: &OneDofModel,
    free: &[Free],
    data: &[Prepared],
    opts: &FitOptions,
    seg: f64,
    sigma0: [f64; 3],
    stop: Option<&AtomicUsize>,
) -> (DVector<f64>, MinimizationReport<f64>) {
    let ro = ReplayOptions {
        segment_s: seg,
        settle_s: opts.replay.settle_s.min(0.4 * seg),
        ..opts.replay
    };
    let coarse: Vec<Prepared> = data
        .iter()
        .map(|d| Prepared::new(d.log.clone(), &ro, d.fit_end))
        .collect();
    let mut cp = Problem::new(
        *base,
        Offsets::default(),
        free.to_vec(),
        &coarse,
        ro,
        sigma0,
    );
    cp.stop = stop;
    let (cp, report) = LevenbergMarquardt::new()
        .with_patience(opts.patience)
        .minimize(cp);
    (cp.z, report)
}

/// Each free parameter's estimate with its 95 % interval: the covariance's standard error (at least the
/// restart bootstrap's spread, which scales `cov`), the bootstrap's bias and its bound; infinite for a
/// parameter without information (`null`).
fn estimates_of(
    free: &[Free],
    values: &[f64],
    cov: &mut DMatrix<f64>,
    null: &[bool],
    boot: Option<&Bootstrap>,
) -> Vec<Estimate> {
    let n = free.len();
    let mut estimates = Vec::with_capacity(n);
    let mut std = vec![0.0; n];
    for (k, f) in free.iter().enumerate() {
        let s = f.key.scale(f.start);
        let (bias, bias_bound) = match boot {
            Some(b) => {
                // A variance at least the bootstrap's (it sees the restart noise through the replay).
                let sd_k = b.sd[k];
                let c = cov[(k, k)].max(0.0);
                if sd_k * sd_k > c && c > 0.0 {
                    let f = (sd_k * sd_k / c).sqrt();
                    for l in 0..n {
                        cov[(k, l)] *= f;
                        cov[(l, k)] *= f;
                    }
                }
                let se_mean = sd_k / (b.replicates as f64).sqrt();
                (s * b.bias[k], s * (b.bias[k].abs() + 1.96 * se_mean))
            }
            None => (0.0, 0.0),
        };
        std[k] = if null[k] {
            f64::INFINITY
        } else {
            s * cov[(k, k)].max(0.0).sqrt()
        };
        let v = values[k];
        let half = 1.96 * std[k] + bias_bound;
        let range = f.hi - f.lo;
        estimates.push(Estimate {
            key: f.key.name().to_string(),
            start: f.start,
            value: v,
            bounds: [f.lo, f.hi],
            std_error: std[k],
            bias,
            bias_bound,
            ci95: [v - half, v + half],
            rel_half_width: if v != 0.0 {
                half / v.abs()
            } else {
                f64::INFINITY
            },
            at_bound: (v - f.lo).abs() < 1e-3 * range || (f.hi - v).abs() < 1e-3 * range,
            // Set by the model check (`crate::request`), which needs the fitted model's residuals.
            interval_valid: true,
            widened: None,
        });
    }
    estimates
}

/// The pseudo-inverse of JᵀJ by eigen-decomposition, and which parameters lie in its null space (a
/// direction with no information: infinite variance).
fn pseudo_inverse(jtj: &DMatrix<f64>) -> (DMatrix<f64>, Vec<bool>) {
    let n = jtj.nrows();
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
    (pinv, null)
}

/// Covariance robust to correlated errors (Newey-West over segments): the replay restarts each segment
/// from a measured, noisy state, and carries velocity, temperatures and the PWM clock into the next, so
/// the residuals of a segment share errors with each other and with the next few segments. With s_c =
/// J_c^T r_c the score of segment c, meat = sum_c s_c s_c^T + sum_{l=1..L} (1 - l/(L+1)) sum_c (s_c
/// s_{c-l}^T + s_{c-l} s_c^T) within each log, L = `hac_lag_s` / segment length; covariance
/// (J^T J)^-1 meat (J^T J)^-1 with the small-sample factor G/(G-1) (N-1)/(N-p), and never below the
/// white-noise covariance s^2 (J^T J)^-1.
fn robust_covariance(
    j: &DMatrix<f64>,
    r0: &DVector<f64>,
    data: &[Prepared],
    pinv: &DMatrix<f64>,
    variance: f64,
    opts: &FitOptions,
) -> DMatrix<f64> {
    let (m, n) = (r0.len(), pinv.nrows());
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
    let sandwich = pinv * meat * pinv * small;
    let white = pinv * variance;
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
    cov
}

/// The correlation matrix of `cov` (NaN for a parameter without information).
fn correlation_of(cov: &DMatrix<f64>, null: &[bool]) -> Vec<Vec<f64>> {
    let n = cov.nrows();
    (0..n)
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
        .collect()
}

/// What the restart bootstrap measured, per free parameter in scaled units (value / scale).
struct Bootstrap {
    /// Mean of (estimate - value simulated from) over the replicates.
    bias: Vec<f64>,
    /// Standard deviation of the estimates over the replicates.
    sd: Vec<f64>,
    /// Number of replicates.
    replicates: usize,
}

/// Parametric bootstrap of the segment-wise replay's errors in the variables.
///
/// Each segment restarts from readings (pressures and position at its first row; the first segment's
/// velocity from a local fit) that carry the sensors' noise and rounding, and the model maps those start
/// errors nonlinearly into the compared rows; so the least-squares estimate is biased by an amount the
/// Jacobian cannot show, and its spread is not only the compared rows' noise. This measures both on the log
/// itself: a synthetic world in which the fitted values are the truth and every segment's true start is
/// the state the replay starts from, i.e. the true signals are the fitted replay `y_hat`. Each replicate
/// reads them as the rig would, `y* = round_q(y_hat) + L e` (e ~ N(0, I_3) per row; `round_q` to the
/// log's own grid, see [`quantum`]; `L L^T` the residuals' covariance of (p_a, p_b, x) less `q^2 / 12`, so
/// noise shared by two signals stays shared), restarts from those readings as the fit does, and takes one
/// Gauss-Newton step from the truth, `d = -(J^T J)^+ J^T r*(theta_hat)` (J at the optimum; one step, as d
/// is a few 1e-3 of the value). bias = mean(d), sd = std(d).
///
/// Measured on the emulated rig (truth of seed 10, ten noise seeds): the bootstrap's bias has the sign of
/// the true mean error and about half its size for C, V_a, V_b (+0.05 vs +0.11 %, +0.10 vs +0.22 %, +0.09
/// vs +0.22 %), a sixth for m, the wrong sign for b (+0.016 vs -0.10 %): only part of the bias is this
/// mechanism. The sigma is ~1.4 times the estimates' spread (the residual covariance it draws from also
/// holds the restart errors' propagation), which covers the rest there: over truths of seeds 1-20,
/// |error| / std error has an RMS of 0.61. `None` with fewer than 2 replicates.
fn restart_bootstrap(
    pb: &Problem,
    values: &[f64],
    j: &DMatrix<f64>,
    pinv: &DMatrix<f64>,
    replicates: usize,
) -> Option<Bootstrap> {
    let n = values.len();
    if replicates < 2 || n == 0 {
        return None;
    }
    let (m, o) = pb.model_with(values);
    let preds: Vec<_> = pb
        .data
        .iter()
        .map(|d| d.replay(&m, &o, &pb.opts, d.fit_end))
        .collect();
    // The readings' quantum per log and signal, and the white part of the noise: the residual RMS is
    // sqrt(sigma_w^2 + q^2 / 12), the rounding's share taken out.
    let quanta: Vec<[f64; 3]> = pb
        .data
        .iter()
        .map(|d| {
            let rows = &d.log;
            [quantum(&rows.p_a), quantum(&rows.p_b), quantum(&rows.x)]
        })
        .collect();
    // The noise of the three readings as one vector: the covariance of the residuals (p_a, p_b, x) over the
    // compared rows, less the rounding's q^2 / 12 on the diagonal, as its Cholesky factor. The signals'
    // noises need not be independent: a rig that measures p_a as p_b plus a differential reading (the
    // paper's) has the p_b noise in both.
    let factors: Vec<nalgebra::Matrix3<f64>> = pb
        .data
        .iter()
        .zip(&preds)
        .zip(&quanta)
        .map(|((d, y), q)| {
            let mut c = nalgebra::Matrix3::<f64>::zeros();
            let mut k_n = 0usize;
            for &k in &d.compared {
                let e = nalgebra::Vector3::new(
                    d.log.p_a[k] - y.p_a[k],
                    d.log.p_b[k] - y.p_b[k],
                    d.log.x[k] - y.x[k],
                );
                if e.iter().all(|v| v.is_finite()) {
                    c += e * e.transpose();
                    k_n += 1;
                }
            }
            c /= k_n.max(1) as f64;
            for i in 0..3 {
                c[(i, i)] = (c[(i, i)] - q[i] * q[i] / 12.0).max(0.0);
            }
            c.cholesky().map(|ch| ch.l()).unwrap_or_else(|| {
                // Not positive definite (a signal with no noise left): each signal on its own.
                nalgebra::Matrix3::from_diagonal(&c.diagonal().map(f64::sqrt))
            })
        })
        .collect();
    let jt = j.transpose();
    let steps: Vec<DVector<f64>> = (0..replicates)
        .into_par_iter()
        .map(|rep| {
            // A fixed seed per replicate: the intervals are reproducible.
            let mut rng = Gauss::new(
                0x9E37_79B9_7F4A_7C15 ^ (rep as u64 + 1).wrapping_mul(0xD1B5_4A32_D192_ED03),
            );
            let syn: Vec<Prepared> = pb
                .data
                .iter()
                .zip(&preds)
                .zip(&quanta)
                .zip(&factors)
                .map(|(((d, y), q), lf)| {
                    let mut s = d.clone();
                    let l = &mut s.log;
                    // Rounded to the log's grid, then the noise (after the rounding, as the emulator
                    // does; an ADC that rounds after the noise is dithered by it and has less bias, so
                    // this errs on the wide side).
                    let read = |v: f64, origin: f64, i: usize, e: f64| {
                        let g = if q[i] > 0.0 {
                            origin + q[i] * ((v - origin) / q[i]).round()
                        } else {
                            v
                        };
                        g + e
                    };
                    let origin = [d.log.p_a[0], d.log.p_b[0], d.log.x[0]];
                    let mut nx = vec![0.0; l.len()];
                    let rows = d.fit_end.min(l.len() - 1) + 1;
                    for (k, n) in nx.iter_mut().enumerate().take(rows) {
                        if !(y.x[k].is_finite() && y.p_a[k].is_finite() && y.p_b[k].is_finite()) {
                            continue;
                        }
                        let z = nalgebra::Vector3::new(rng.next(), rng.next(), rng.next());
                        let e = lf * z;
                        l.p_a[k] = read(y.p_a[k], origin[0], 0, e[0]);
                        l.p_b[k] = read(y.p_b[k], origin[1], 1, e[1]);
                        l.x[k] = read(y.x[k], origin[2], 2, e[2]);
                        *n = l.x[k] - y.x[k];
                    }
                    for (seg, &(a, _)) in d.segments.iter().enumerate() {
                        // Restarts from the reading, the first velocity from the local fit (linear:
                        // fit(y_hat + n) = fit(y_hat) + fit(n)).
                        s.x0[seg] = d.x0[seg] + nx[a];
                        s.v0[seg] = d.v0[seg]
                            + local_fit(&l.t, &nx, &l.measured, a, pb.opts.velocity_half_window)[1];
                    }
                    s
                })
                .collect();
            let p = Problem::new(
                pb.base,
                pb.base_off,
                pb.free.clone(),
                &syn,
                pb.opts,
                pb.sigma,
            );
            let r = p.residuals_at(values);
            -(pinv * (&jt * r))
        })
        .collect();
    let b = replicates as f64;
    let mut bias = vec![0.0; n];
    let mut sd = vec![0.0; n];
    for k in 0..n {
        let mean = steps.iter().map(|d| d[k]).sum::<f64>() / b;
        let var = steps.iter().map(|d| (d[k] - mean).powi(2)).sum::<f64>() / (b - 1.0);
        bias[k] = mean;
        sd[k] = var.sqrt();
    }
    Some(Bootstrap {
        bias,
        sd,
        replicates,
    })
}

/// The step of the grid a logged signal's readings sit on (an ADC count in SI units), or 0 when they sit
/// on none: the smallest gap between distinct readings, accepted when 99 % of all gaps are whole multiples
/// of it (to 1e-3 of the step; the trace writes full-precision floats).
pub(crate) fn quantum(v: &[f64]) -> f64 {
    let mut u: Vec<f64> = v.iter().copied().filter(|x| x.is_finite()).collect();
    u.sort_by(f64::total_cmp);
    let span = u.last().copied().unwrap_or(0.0) - u.first().copied().unwrap_or(0.0);
    if u.len() < 3 || span <= 0.0 {
        return 0.0;
    }
    let tiny = 1e-9 * span;
    let gaps: Vec<f64> = u
        .windows(2)
        .map(|w| w[1] - w[0])
        .filter(|&g| g > tiny)
        .collect();
    let Some(q) = gaps.iter().copied().reduce(f64::min) else {
        return 0.0;
    };
    let on_grid = gaps
        .iter()
        .filter(|&&g| ((g / q) - (g / q).round()).abs() < 1e-3)
        .count();
    if on_grid as f64 >= 0.99 * gaps.len() as f64 {
        q
    } else {
        0.0
    }
}

/// Standard normal deviates: splitmix64 words through Box-Muller.
struct Gauss {
    state: u64,
    spare: Option<f64>,
}

impl Gauss {
    fn new(seed: u64) -> Self {
        Self {
            state: seed,
            spare: None,
        }
    }

    fn uniform(&mut self) -> f64 {
        self.state = self.state.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.state;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        // In (0, 1]: the logarithm below stays finite.
        ((z >> 11) as f64 + 1.0) / (1u64 << 53) as f64
    }

    fn next(&mut self) -> f64 {
        if let Some(v) = self.spare.take() {
            return v;
        }
        let (u1, u2) = (self.uniform(), self.uniform());
        let r = (-2.0 * u1.ln()).sqrt();
        let a = std::f64::consts::TAU * u2;
        self.spare = Some(r * a.sin());
        r * a.cos()
    }
}

/// How an interval was widened for an effect the model lacks ([`crate::check`]'s widening, kept beside the
/// estimate it widens).
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Widening {
    /// The probe that moved the bound(s) most (e.g. `seal pressure term`).
    pub probe: String,
    /// Its effect.
    pub effect: String,
    /// The amounts of it the residuals allow, in probes: [least, most].
    pub amounts: [f64; 2],
    /// The 95 % interval before (the noise's and the replay's alone).
    pub noise_ci95: [f64; 2],
}

#[cfg(test)]
mod tests {
    use super::quantum;

    #[test]
    fn finds_the_grid_of_quantised_readings() {
        // 12-bit pressure readings: 268.62 Pa per count from an offset, in any order, with repeats.
        let q = 268.620_268_62;
        let v: Vec<f64> = [5, 9, 9, 6, 100, 7, 5, 2000, 8]
            .iter()
            .map(|&c| 101_325.0 + c as f64 * q)
            .collect();
        assert!((quantum(&v) / q - 1.0).abs() < 1e-9, "{}", quantum(&v));
        // Readings on no grid (a float sensor, or a filtered signal): 0, no rounding is simulated.
        let w: Vec<f64> = (0..200).map(|i| (i as f64 * 0.37).sin()).collect();
        assert_eq!(quantum(&w), 0.0);
        // Too few distinct values to tell.
        assert_eq!(quantum(&[1.0, 1.0]), 0.0);
    }
}
