//! The model-adequacy check of every report (issue 26): do the fitted model's residuals look like the
//! sensors' noise? A model that explains the data leaves residuals near the noise floor, near white, and as
//! small on held-out rows as on the fitted ones; a rig richer than the model (a leak, heat transfer, a
//! friction law, spool or line dynamics) leaves a pattern instead, and then the intervals, which assume the
//! model is right, say nothing about the bias: they are marked not valid (`Estimate::interval_valid`).
//!
//! Three figures per channel (p_a, p_b, x), each against a named threshold below:
//! - **noise floor:** residual RMS on the fit rows, less each segment's mean (the replay restarts every
//!   segment from a noisy reading, an offset that every row of the segment shares whatever the model: it
//!   is the replay's, not the model's), over the floor: the larger of the readings' quantisation (step /
//!   sqrt 12, the step being the grid the log's readings sit on: the ADC count; the sheets give the
//!   sensors' ranges, the rig file their bits) and their sample-to-sample scatter (third differences,
//!   clipped) on still stretches of the log (command and position steady). A log that never rests (a PWM
//!   limit cycle) has no still stretch; its scatter is then the residual's own row-to-row scatter, which
//!   the model's errors, smooth over four rows, do not reach;
//! - **whiteness:** the normalised autocorrelation of the same segment-demeaned residuals at lags
//!   1..[`LAGS`] within each segment, with the fraction of lags outside +-1.96/sqrt(N) and a Ljung-Box
//!   statistic reported, and their mean |autocorrelation| judged;
//! - **cross-log validation:** the held-out rows' residual RMS over the fit rows'.
//!
//! Then `likely_missing`: which effect's pattern the residuals carry, and how much of it (see
//! [`signatures`]); and [`widen`]: every interval widened to hold the truth under any probed effect the
//! model lacks, in the amounts the residuals allow (issue 44: a seal term a quarter of the tests' left the
//! residuals at the noise and F_c +174 % off, outside an interval the check called valid).

use pneuflex_pneumatics::OneDofModel;

use crate::fit::quantum;
use crate::params::{Key, Offsets};
use crate::replay::{Prepared, ReplayOptions};

/// Lags of the autocorrelation, samples (20 ms at 1 kHz: the valve's and the chambers' fast time constants).
pub const LAGS: usize = 20;
/// Residual RMS above this many noise floors is more than noise. A matched model on the emulated rig
/// (12-bit channels, 1 count of noise; tests/model_check.rs and the acceptance truths) leaves 0.96-1.23
/// floors (the restarts' propagated reading noise adds to the rows' own); the mismatches of issue 26 left
/// 2.6-4.9 times a matched model's residuals, the hidden effects of the tests 1.5-76 floors on their worst
/// channel.
pub const MAX_FLOOR_RATIO: f64 = 1.6;
/// Whiteness fails when the mean |autocorrelation| over lags 1..LAGS exceeds this. Not the +-1.96/sqrt(N)
/// band alone: with ~10^4 rows it is +-0.02, and the replay's start errors (the restarted velocity's error
/// decaying over the segment) correlate a matched model's residuals by more than that. Set from the spread
/// of matched models (40 truths of the fitted model, seeds 9180-9219, 4 s logs: the worst channel's mean
/// |autocorrelation| 0.092 +- 0.043, at most 0.179): 0.22 is exceeded by 0.15 % of them under a normal
/// fit, 3 % under a log-normal one (the design: at most 3 % of matched models fail here; 0.15 failed 8 of
/// 40, among them issue 44's seed 9173 at 0.1506). An effect this lets through is covered by the widened
/// intervals ([`widen`]); the hidden effects of the tests leave 0.23-0.50 on their worst channel.
pub const MAX_MEAN_ABS_AUTOCORRELATION: f64 = 0.22;
/// Held-out RMS above this many times the fit rows' RMS: the model does not carry to data it was not
/// fitted to (matched or freed models: 0.93-1.16; the held-out part of one excitation is much like the
/// fitted part, so this catches a model that drifts or was fitted to one regime, not the tests' effects).
pub const MAX_VALIDATION_RATIO: f64 = 1.5;
/// An effect is named when its pattern's partial correlation with the residuals is at least this: a
/// matched model's residuals reach 0.16 with one probe or another by chance (they are noise, and the
/// probes' patterns are smooth, so few effective samples), a missing effect's best 0.52-0.97.
pub const MIN_SIGNATURE_CORRELATION: f64 = 0.3;
/// A probe's amount this many standard errors (after [`AMOUNT_SE_FACTOR`]) beyond its absence names its
/// effect in `likely_missing` whatever its pattern's score (one-sided 0.19 % per probe).
pub const DETECT_Z: f64 = 2.9;
/// The probes' Newey-West standard errors times this: on matched models (40 truths, seeds 9180-9219,
/// 399 amounts) amount / standard error had an RMS of 1.38, not 1 (the replay's restarts correlate the
/// residuals beyond what the lag window holds), so the raw standard error is 1.4 times too small.
pub const AMOUNT_SE_FACTOR: f64 = 1.4;
/// An adequate fit's intervals cover every probed effect the residuals allow: amounts up to this many
/// standard errors above the estimated one (see [`widen`]).
pub const WIDEN_Z: f64 = 1.96;
/// The continuous effects' patterns are their replay's change over this fraction of one probe: the
/// tangent at the fit, as the keys' sensitivities are, not the secant to one whole probe. The keys take up
/// most of an effect (a lower exponent is nearly a smaller conductance and larger volumes: 99.8 % of its
/// pattern on a steps log), so the amount rests on the small rest, where the secant's curvature weighs as
/// much as the tangent: with whole probes an exponent 0.0375 low (issue 44, seed 52) was read as 0.08 +-
/// 0.02 probes instead of 0.375, and the intervals widened for it missed C and b.
pub const TANGENT_STEP: f64 = 0.1;
/// Newey-West lag of the probes' amounts, s (as the fit's `FitOptions::hac_lag_s`).
pub const HAC_LAG_S: f64 = 0.5;
/// A still window: this many rows, over which the command moves at most [`STILL_COMMAND`] and the
/// position at most [`STILL_POSITION_QUANTA`] steps of its grid (or [`STILL_POSITION_M`] without a grid).
pub const STILL_WINDOW: usize = 20;
/// See [`STILL_WINDOW`].
pub const STILL_COMMAND: f64 = 0.02;
/// See [`STILL_WINDOW`].
pub const STILL_POSITION_QUANTA: f64 = 4.0;
/// See [`STILL_WINDOW`].
pub const STILL_POSITION_M: f64 = 1e-4;

/// One channel's figures.
#[derive(Clone, Debug, serde::Serialize)]
pub struct ChannelCheck {
    /// `p_a`, `p_b` or `x`.
    pub signal: &'static str,
    /// Step of the readings' grid (Pa or m; 0 when they sit on none).
    pub resolution: f64,
    /// resolution / sqrt(12).
    pub quantisation_floor: f64,
    /// Scatter of the readings, sample to sample: on still windows, or on every row without enough of them.
    pub still_noise: f64,
    /// Whether `still_noise` is the residual's row-to-row scatter (too few still rows in the logs).
    pub noise_from_residual: bool,
    /// Rows in still windows (0: fewer than `MIN_STILL_ROWS`).
    pub still_rows: usize,
    /// The noise floor: the larger of the two.
    pub floor: f64,
    /// Residual RMS on the fit rows.
    pub rms_fit: f64,
    /// Residual RMS on the fit rows less each segment's mean (the restart's offset).
    pub rms_demeaned: f64,
    /// rms_demeaned / floor.
    pub floor_ratio: f64,
    /// Normalised autocorrelation at lags 1..LAGS of the segment-demeaned fit residuals.
    pub autocorrelation: Vec<f64>,
    /// Mean |autocorrelation| over those lags.
    pub mean_abs_autocorrelation: f64,
    /// Fraction of the lags outside +-1.96 / sqrt(N).
    pub lags_outside_fraction: f64,
    /// Ljung-Box Q over the lags (chi-square with LAGS degrees of freedom for white residuals; 31.4 is
    /// its 95 % point for 20 lags).
    pub ljung_box: f64,
    /// Residual RMS on the held-out rows (NaN if none).
    pub rms_validation: f64,
    /// The held-out rows' RMS over the fit rows', both less each segment's line (as `rms_demeaned`).
    pub validation_ratio: f64,
}

/// A missing effect the residuals point at.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Missing {
    /// `leakage`, `heat_transfer`, `friction`, `valve_dynamics`, or `unknown`.
    pub effect: &'static str,
    /// The keys that model it (to free, or to add to the sheet).
    pub keys: &'static str,
    /// What in the residuals points at it.
    pub evidence: String,
    /// |correlation| of the residuals with the effect's signature.
    pub correlation: f64,
    /// Standard errors of its best probe's amount beyond the effect's absence.
    pub beyond_absence: f64,
}

/// The check of one fit.
#[derive(Clone, Debug, serde::Serialize)]
pub struct ModelCheck {
    /// Whether the model explains the data to the sensors' noise (every figure within its threshold).
    pub adequate: bool,
    /// Which figures failed, in words.
    pub failed: Vec<String>,
    /// Per channel.
    pub channels: Vec<ChannelCheck>,
    /// Fit rows the figures are from.
    pub rows: usize,
    /// Each probe's score: the partial correlation of the residuals with the pattern a little of the
    /// effect would leave (see `likely_missing`).
    pub signatures: Vec<Signature>,
    /// The likely missing effect(s), empty when adequate.
    pub likely_missing: Vec<Missing>,
    /// The thresholds used.
    pub thresholds: Thresholds,
}

/// One probe of a missing effect and its score.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Signature {
    /// `leakage`, `heat_transfer`, `friction` or `valve_dynamics`.
    pub effect: &'static str,
    /// Which form of it was added (e.g. `piston`, `wall heat`, `spool travel`).
    pub probe: &'static str,
    /// |partial correlation| of the fit residuals with its pattern, given the fitted keys'.
    pub correlation: f64,
    /// The effect's score, the same for each of its probes: the multiple partial correlation of the
    /// residuals with the patterns of all its probes that lie beyond the effect's absence, together, given
    /// the fitted keys' (0 when none does). `likely_missing` is ranked by it.
    pub effect_correlation: f64,
    /// Whether the model has the effect with its keys fitted (then the probe is not scored: NaN amount).
    pub modelled: bool,
    /// The amount of the effect the residuals carry, in probes (the amount added; regression on the
    /// pattern and the fitted keys' sensitivities together).
    pub amount: f64,
    /// Its standard error (Newey-West over segments).
    pub amount_se: f64,
    /// The least amount there can be, in probes (0: the effect's absence).
    pub least_amount: f64,
    /// Per fitted key (in `--free`'s order), how far one probe of the effect in the rig would put the
    /// truth from the fitted value: the keys take up that much of it (physical units).
    pub shift: Vec<f64>,
}

/// The thresholds, as in the constants.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Thresholds {
    /// [`MAX_FLOOR_RATIO`].
    pub max_floor_ratio: f64,
    /// [`MAX_MEAN_ABS_AUTOCORRELATION`].
    pub max_mean_abs_autocorrelation: f64,
    /// [`MAX_VALIDATION_RATIO`].
    pub max_validation_ratio: f64,
    /// [`MIN_SIGNATURE_CORRELATION`].
    pub min_signature_correlation: f64,
    /// [`DETECT_Z`].
    pub detect_z: f64,
    /// [`WIDEN_Z`].
    pub widen_z: f64,
}

impl ModelCheck {
    /// One line naming the likely missing effect(s), for warnings.
    pub fn summary(&self) -> String {
        if self.adequate {
            return "the model explains the logs to the sensors' noise".into();
        }
        let names: Vec<String> = self
            .likely_missing
            .iter()
            .map(|m| {
                if m.keys.is_empty() {
                    m.effect.to_string()
                } else {
                    format!("{} ({})", m.effect, m.keys)
                }
            })
            .collect();
        format!(
            "the model does not explain the logs ({}); likely missing: {}; the intervals are not valid",
            self.failed.join("; "),
            names.join(", ")
        )
    }
}

/// One log's compared rows grouped by segment, for the whiteness.
struct Rows {
    /// Per segment: its first (restart) row and its compared rows (log indices).
    segments: Vec<(usize, Vec<usize>)>,
}

fn segment_rows(d: &Prepared, rows: &[usize]) -> Rows {
    let mut segments = Vec::new();
    let mut at = 0;
    for &(s, e) in &d.segments {
        let mut seg = Vec::new();
        while at < rows.len() && rows[at] <= e {
            if rows[at] > s {
                seg.push(rows[at]);
            }
            at += 1;
        }
        if seg.len() > LAGS + 1 {
            segments.push((s, seg));
        }
    }
    Rows { segments }
}

/// Still rows needed before their scatter is trusted; fewer, and the whole log's scatter is used.
pub const MIN_STILL_ROWS: usize = 200;
/// Differences beyond this many of their own RMS are signal (a valve edge's kink), not noise: clipped.
const CLIP: f64 = 3.5;

/// The RMS of the white noise behind third differences `d` (variance 20 s^2), the differences
/// clipped at [`CLIP`] times their RMS until it settles, so that the few differences a valve edge or an
/// impact throws far out do not count as noise.
fn clipped_scatter(d: &[f64]) -> f64 {
    let c: f64 = 20.0;
    let mut lim = f64::INFINITY;
    let mut rms = f64::NAN;
    for _ in 0..20 {
        let (ss, n) = d
            .iter()
            .filter(|v| v.abs() <= lim)
            .fold((0.0, 0usize), |(s, n), v| (s + v * v, n + 1));
        if n == 0 {
            return f64::NAN;
        }
        let r = (ss / n as f64).sqrt();
        if r == rms {
            break;
        }
        rms = r;
        lim = CLIP * r;
    }
    rms / c.sqrt()
}

/// Noise of each reading: its sample-to-sample scatter on still windows (command and position steady;
/// third differences, which a steady or smoothly moving signal does not reach); NaN and 0 rows with fewer
/// than [`MIN_STILL_ROWS`] still rows (see `check` for what is used then).
fn still_noise(d: &[Prepared], q_x: f64) -> ([f64; 3], usize) {
    let tol_x = if q_x > 0.0 {
        STILL_POSITION_QUANTA * q_x
    } else {
        STILL_POSITION_M
    };
    let mut still: Vec<(usize, usize, usize)> = Vec::new();
    for (i, p) in d.iter().enumerate() {
        let l = &p.log;
        let mut a = 0;
        while a + STILL_WINDOW <= l.len() {
            let w = a..a + STILL_WINDOW;
            let span = |v: &[f64]| {
                let (lo, hi) = v[w.clone()]
                    .iter()
                    .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &x| {
                        (lo.min(x), hi.max(x))
                    });
                hi - lo
            };
            if span(&l.u) <= STILL_COMMAND
                && span(&l.x) <= tol_x
                && l.measured[w.clone()].iter().all(|&m| m)
            {
                still.push((i, a, a + STILL_WINDOW));
            }
            a += STILL_WINDOW;
        }
    }
    let still_rows = still.len() * STILL_WINDOW;
    if still_rows < MIN_STILL_ROWS {
        return ([f64::NAN; 3], 0);
    }
    let mut diffs: [Vec<f64>; 3] = [vec![], vec![], vec![]];
    for &(i, a, b) in &still {
        let l = &d[i].log;
        for (c, v) in [&l.p_a, &l.p_b, &l.x].into_iter().enumerate() {
            diffs[c].extend(third_differences(&v[a..b]));
        }
    }
    (
        std::array::from_fn(|c| clipped_scatter(&diffs[c])),
        still_rows,
    )
}

/// `r` less its least-squares line over the row index: a segment's restart error (the position reading's
/// noise, the carried velocity's error) is an offset and a drift shared by the segment's rows, whatever
/// the model.
fn detrended(r: &[f64]) -> Vec<f64> {
    let n = r.len() as f64;
    let mx = (n - 1.0) / 2.0;
    let my = r.iter().sum::<f64>() / n;
    let (mut sxy, mut sxx) = (0.0, 0.0);
    for (k, v) in r.iter().enumerate() {
        let dx = k as f64 - mx;
        sxy += dx * (v - my);
        sxx += dx * dx;
    }
    let b = if sxx > 0.0 { sxy / sxx } else { 0.0 };
    r.iter()
        .enumerate()
        .map(|(k, v)| v - my - b * (k as f64 - mx))
        .collect()
}

/// Third differences of consecutive values (white noise of RMS s: RMS sqrt(20) s).
fn third_differences(v: &[f64]) -> impl Iterator<Item = f64> + '_ {
    v.windows(4).map(|w| w[3] - 3.0 * w[2] + 3.0 * w[1] - w[0])
}

/// The check of the fit `model` / `off` (the fitted values) on `data`.
/// `free` holds the fitted keys with their start values (their sensitivities are taken out of each
/// probe's pattern, see [`signatures`]).
pub fn check(
    model: &OneDofModel,
    off: &Offsets,
    free: &[(Key, f64)],
    data: &[Prepared],
    opts: &ReplayOptions,
) -> ModelCheck {
    let preds: Vec<_> = data
        .iter()
        .map(|d| d.replay(model, off, opts, d.log.len()))
        .collect();
    fn read(d: &Prepared, i: usize) -> &[f64] {
        match i {
            0 => &d.log.p_a,
            1 => &d.log.p_b,
            _ => &d.log.x,
        }
    }
    // The grid per channel: the coarsest of the logs' (a log on no grid contributes 0).
    let resolution: [f64; 3] =
        std::array::from_fn(|i| data.iter().map(|d| quantum(read(d, i))).fold(0.0, f64::max));
    let (still, still_rows) = still_noise(data, resolution[2]);
    let fit_rows: Vec<Rows> = data.iter().map(|d| segment_rows(d, &d.compared)).collect();
    let held_rows: Vec<Rows> = data
        .iter()
        .map(|d| segment_rows(d, &d.validation))
        .collect();
    let mut channels = Vec::new();
    let mut failed = Vec::new();
    let mut total_rows = 0;
    for (i, signal) in ["p_a", "p_b", "x"].into_iter().enumerate() {
        let q = resolution[i];
        let qf = q / 12f64.sqrt();
        let r = residuals_of(data, &preds, &fit_rows, &held_rows, i);
        let demeaned = &r.demeaned;
        total_rows = total_rows.max(r.n);
        let rms_fit = (r.ss / r.n.max(1) as f64).sqrt();
        let rms_validation = if r.nv > 0 {
            (r.ssv / r.nv as f64).sqrt()
        } else {
            f64::NAN
        };
        // Without still stretches (a log that moves throughout, as under PWM), the scatter of the residual
        // from row to row: the valve's edges kink the readings' pressures every few rows, but the model's
        // replay kinks with them, and what a missing effect adds is smooth on the scale of four rows (a
        // spool delay's kinks are not, which the whiteness and the signatures then see).
        let (still_i, from_residual) = if still[i].is_finite() {
            (still[i], false)
        } else {
            let d: Vec<f64> = demeaned.iter().flat_map(|s| third_differences(s)).collect();
            (clipped_scatter(&d), true)
        };
        let floor = qf.max(still_i);
        let c0: f64 = demeaned.iter().flatten().map(|v| v * v).sum();
        let big_n: usize = demeaned.iter().map(Vec::len).sum();
        // Against the floor: the residual less each segment's restart offset (see the module doc).
        let rms_demeaned = (c0 / big_n.max(1) as f64).sqrt();
        let (autocorrelation, mean_abs, outside, ljung_box) = whiteness(demeaned, c0, big_n);
        let floor_ratio = if floor > 0.0 {
            rms_demeaned / floor
        } else {
            f64::INFINITY
        };
        // Both less each segment's line, as for the floor: the restarts' share of the RMS depends on how
        // the piston moves in each part (one matched truth's raw held-out x RMS was 1.43 times its fit's).
        let validation_ratio = if r.nh > 0 {
            (r.ssh / r.nh as f64).sqrt() / rms_demeaned
        } else {
            f64::NAN
        };
        failed.extend(failures(signal, floor_ratio, mean_abs, validation_ratio));
        channels.push(ChannelCheck {
            signal,
            resolution: q,
            quantisation_floor: qf,
            still_noise: still_i,
            noise_from_residual: from_residual,
            still_rows,
            floor,
            rms_fit,
            rms_demeaned,
            floor_ratio,
            autocorrelation,
            mean_abs_autocorrelation: mean_abs,
            lags_outside_fraction: outside,
            ljung_box,
            rms_validation,
            validation_ratio,
        });
    }
    let floors: [f64; 3] = std::array::from_fn(|i| channels[i].floor.max(f64::MIN_POSITIVE));
    // The probes' amounts name the missing effect and widen the intervals (`widen`); they do not judge
    // adequacy: on 40 matched truths of held-out seeds (9300-9339) an amount 2.9 standard errors beyond
    // absence came in 4 (max 4.2), and a freed LuGre fit's residuals carry 6 standard errors of the seal
    // term's pattern; an effect the figures let through is covered by the widening instead.
    let sig = signatures(model, off, free, data, opts, floors);
    let adequate = failed.is_empty();
    let likely_missing = if adequate {
        Vec::new()
    } else {
        name_missing(&sig)
    };
    ModelCheck {
        adequate,
        failed,
        channels,
        rows: total_rows,
        signatures: sig,
        likely_missing,
        thresholds: Thresholds {
            max_floor_ratio: MAX_FLOOR_RATIO,
            max_mean_abs_autocorrelation: MAX_MEAN_ABS_AUTOCORRELATION,
            max_validation_ratio: MAX_VALIDATION_RATIO,
            min_signature_correlation: MIN_SIGNATURE_CORRELATION,
            detect_z: DETECT_Z,
            widen_z: WIDEN_Z,
        },
    }
}

/// One channel's residual sums over the logs: squares over the compared rows (`ss`, `n`), the held-out rows
/// (`ssv`, `nv`) and the held-out segments less each one's line (`ssh`, `nh`), and each compared segment's
/// residual less its line (`demeaned`).
struct Residuals {
    ss: f64,
    n: usize,
    ssv: f64,
    nv: usize,
    ssh: f64,
    nh: usize,
    demeaned: Vec<Vec<f64>>,
}

/// [`Residuals`] of channel `i` (p_a, p_b, x) of the predictions `preds` on `data`.
fn residuals_of(
    data: &[Prepared],
    preds: &[crate::replay::Prediction],
    fit_rows: &[Rows],
    held_rows: &[Rows],
    i: usize,
) -> Residuals {
    let res = |d: &Prepared, p: &crate::replay::Prediction, i: usize, k: usize| match i {
        0 => p.p_a[k] - d.log.p_a[k],
        1 => p.p_b[k] - d.log.p_b[k],
        _ => p.x[k] - d.log.x[k],
    };
    let (mut ss, mut n) = (0.0, 0usize);
    let (mut ssv, mut nv) = (0.0, 0usize);
    let mut demeaned: Vec<Vec<f64>> = Vec::new();
    let (mut ssh, mut nh) = (0.0, 0usize);
    for (((d, p), rows), held) in data.iter().zip(preds).zip(fit_rows).zip(held_rows) {
        for (_, seg) in &held.segments {
            let r: Vec<f64> = seg.iter().map(|&k| res(d, p, i, k)).collect();
            if r.iter().all(|v| v.is_finite()) {
                ssh += detrended(&r).iter().map(|v| v * v).sum::<f64>();
                nh += seg.len();
            }
        }
        for &k in &d.compared {
            let r = res(d, p, i, k);
            if r.is_finite() {
                ss += r * r;
                n += 1;
            }
        }
        for &k in &d.validation {
            let r = res(d, p, i, k);
            if r.is_finite() {
                ssv += r * r;
                nv += 1;
            }
        }
        for (_, seg) in &rows.segments {
            let r: Vec<f64> = seg.iter().map(|&k| res(d, p, i, k)).collect();
            if r.iter().all(|v| v.is_finite()) {
                demeaned.push(detrended(&r));
            }
        }
    }
    Residuals {
        ss,
        n,
        ssv,
        nv,
        ssh,
        nh,
        demeaned,
    }
}

/// Whether residuals less their segments' lines are white: their autocorrelation over lags 1..=LAGS (`c0`:
/// the sum of squares, `big_n`: the rows), its mean magnitude, the fraction of lags outside the 95 % band,
/// and the Ljung-Box statistic.
fn whiteness(demeaned: &[Vec<f64>], c0: f64, big_n: usize) -> (Vec<f64>, f64, f64, f64) {
    let autocorrelation: Vec<f64> = (1..=LAGS)
        .map(|l| {
            let c: f64 = demeaned
                .iter()
                .map(|s| s.windows(l + 1).map(|w| w[0] * w[l]).sum::<f64>())
                .sum();
            if c0 > 0.0 { c / c0 } else { 0.0 }
        })
        .collect();
    let nf = big_n.max(1) as f64;
    let band = 1.96 / nf.sqrt();
    let mean_abs = autocorrelation.iter().map(|r| r.abs()).sum::<f64>() / LAGS as f64;
    let outside = autocorrelation.iter().filter(|r| r.abs() > band).count() as f64 / LAGS as f64;
    let ljung_box = nf
        * (nf + 2.0)
        * autocorrelation
            .iter()
            .enumerate()
            .map(|(l, r)| r * r / (nf - (l + 1) as f64).max(1.0))
            .sum::<f64>();
    (autocorrelation, mean_abs, outside, ljung_box)
}

/// What fails in one channel's check: its residual against the noise floor (a NaN ratio, no rows, fails
/// too), its whiteness, its held-out residual against the fit's.
fn failures(signal: &str, floor_ratio: f64, mean_abs: f64, validation_ratio: f64) -> Vec<String> {
    let mut failed = Vec::new();
    if floor_ratio.is_nan() || floor_ratio > MAX_FLOOR_RATIO {
        failed.push(format!(
            "{signal} residual {floor_ratio:.2} times the noise floor (limit {MAX_FLOOR_RATIO})"
        ));
    }
    if mean_abs > MAX_MEAN_ABS_AUTOCORRELATION {
        failed.push(format!(
            "{signal} residuals not white (mean |autocorrelation| {mean_abs:.2} over lags 1-{LAGS}, \
             limit {MAX_MEAN_ABS_AUTOCORRELATION})"
        ));
    }
    if validation_ratio > MAX_VALIDATION_RATIO {
        failed.push(format!(
            "{signal} held-out residual {validation_ratio:.2} times the fit's (limit \
             {MAX_VALIDATION_RATIO})"
        ));
    }
    failed
}

/// Partial correlations of a residual with several regressors, each given all the others, from the
/// Gram matrix of the series.
struct Partial {
    gram: nalgebra::DMatrix<f64>,
}

impl Partial {
    fn new(regressors: usize) -> Self {
        Self {
            gram: nalgebra::DMatrix::zeros(regressors + 1, regressors + 1),
        }
    }

    /// `cols[j]` the regressors' series, `y` the residual's (same length).
    fn add(&mut self, cols: &[Vec<f64>], y: &[f64]) {
        let mut all: Vec<&[f64]> = cols.iter().map(Vec::as_slice).collect();
        all.push(y);
        if all.iter().any(|c| c.iter().any(|v| !v.is_finite())) {
            return;
        }
        for i in 0..all.len() {
            for j in i..all.len() {
                let d: f64 = all[i].iter().zip(all[j]).map(|(a, b)| a * b).sum();
                self.gram[(i, j)] += d;
                if i != j {
                    self.gram[(j, i)] += d;
                }
            }
        }
    }

    /// |partial correlation| of the residual with regressor `j` given the others: from the precision
    /// matrix P of the normalised Gram, -P_jy / sqrt(P_jj P_yy). Regressors the others already span (a
    /// tiny ridge keeps P finite) come out near 0.
    fn r(&self, j: usize) -> f64 {
        let k = self.gram.nrows();
        let d: Vec<f64> = (0..k)
            .map(|i| self.gram[(i, i)].max(f64::MIN_POSITIVE).sqrt())
            .collect();
        let mut c = self.gram.clone();
        for a in 0..k {
            for b in 0..k {
                c[(a, b)] /= d[a] * d[b];
            }
            c[(a, a)] += 1e-9;
        }
        let Some(p) = c.try_inverse() else {
            return 0.0;
        };
        let y = k - 1;
        let r = -p[(j, y)] / (p[(j, j)] * p[(y, y)]).sqrt();
        if r.is_finite() { r.abs() } else { 0.0 }
    }
}

/// A model with a little of one effect added to the fitted one: what the effect would change in the
/// replay. The unit of each effect, one probe, is an amount ordinary for a rig of this size (a leak of
/// 3 % of the valve's conductance, 50 W/(m^2 K) of wall heat, an exponent 0.1 lower, a seal term of 2e-6
/// N/Pa, LuGre bristles with a break-away 50 % above the Coulomb force, 1 ms of spool travel or release
/// delay, 1 cm^3 lines); where the fitted model has the effect already, 50 % more of it. An effect that
/// grows from none continuously is replayed at [`TANGENT_STEP`] of its probe (the model's `step`), so
/// that its pattern, the change over `step`, is the tangent at the fit (see [`TANGENT_STEP`]); LuGre and
/// lines change the model's structure (a friction law, a line's orifice in series) and are replayed at one
/// whole probe.
fn probes(m: &OneDofModel) -> Vec<Probe> {
    let f = TANGENT_STEP;
    use pneuflex_pneumatics::{Friction, Lines, Orifice, ValveKind, WallHeat};
    let mut out = Vec::new();
    // The amount of an effect the model has already may be less, down to none: -2 probes of 50 % more.
    let least = |has: bool| if has { -2.0 } else { 0.0 };
    let c_valve = m.actuator.valve.orifice.sonic_conductance_m3_per_s_pa;
    for (i, name) in pneuflex_pneumatics::LEAKS.iter().enumerate() {
        let mut p = *m;
        let o = match m.effects.leaks.get(i) {
            Some(mut o) => {
                o.sonic_conductance_m3_per_s_pa *= 1.0 + 0.5 * f;
                o
            }
            None => Orifice {
                sonic_conductance_m3_per_s_pa: 0.03 * f * c_valve,
                critical_pressure_ratio: 0.3,
            },
        };
        p.effects.leaks.set(i, Some(o));
        out.push(Probe {
            effect: "leakage",
            probe: name,
            model: p,
            keys: &LEAK_KEYS[i],
            least: least(m.effects.leaks.get(i).is_some()),
            step: f,
        });
    }
    let mut p = *m;
    p.effects.wall_heat = Some(match m.effects.wall_heat {
        Some(mut h) => {
            h.coefficient_w_per_m2_k *= 1.0 + 0.5 * f;
            h
        }
        None => WallHeat {
            coefficient_w_per_m2_k: 50.0 * f,
            wall_temperature_k: m.actuator.supply.atmosphere_temperature_k,
        },
    });
    out.push(Probe {
        effect: "heat_transfer",
        probe: "wall heat",
        model: p,
        keys: &[Key::WallHeat],
        least: least(m.effects.wall_heat.is_some()),
        step: f,
    });
    let mut p = *m;
    p.actuator.gas.polytropic_exponent = (m.actuator.gas.polytropic_exponent - 0.1 * f).max(1.0);
    if p.actuator.gas.polytropic_exponent != m.actuator.gas.polytropic_exponent {
        // An exponent above the sheet's (up to the heat-capacity ratio 1.4 of air) is a probe's negative
        // amount: less heat exchange than modelled.
        let room = (1.4 - m.actuator.gas.polytropic_exponent).max(0.0) / 0.1;
        out.push(Probe {
            effect: "heat_transfer",
            probe: "polytropic exponent",
            model: p,
            keys: &[Key::PolytropicExponent],
            least: -room,
            step: (m.actuator.gas.polytropic_exponent - p.actuator.gas.polytropic_exponent) / 0.1,
        });
    }
    let mut p = *m;
    p.effects.coulomb_pressure_n_per_pa = Some(
        m.effects
            .coulomb_pressure_n_per_pa
            .map_or(2e-6 * f, |k| (1.0 + 0.5 * f) * k),
    );
    out.push(Probe {
        effect: "friction",
        probe: "seal pressure term",
        model: p,
        keys: &[Key::CoulombPressure],
        least: least(m.effects.coulomb_pressure_n_per_pa.is_some()),
        step: f,
    });
    let mut p = *m;
    let f_c = m.mechanics.friction.coulomb_n().max(0.1);
    p.mechanics.friction = match m.mechanics.friction {
        Friction::LuGre {
            coulomb_n,
            static_n,
            stribeck_velocity_m_per_s,
            bristle_stiffness_n_per_m,
            bristle_damping_n_s_per_m,
        } => Friction::LuGre {
            coulomb_n,
            static_n: coulomb_n + 1.5 * (static_n - coulomb_n).max(0.5 * coulomb_n),
            stribeck_velocity_m_per_s,
            bristle_stiffness_n_per_m,
            bristle_damping_n_s_per_m,
        },
        _ => Friction::LuGre {
            coulomb_n: f_c,
            static_n: 1.5 * f_c,
            stribeck_velocity_m_per_s: 0.005,
            bristle_stiffness_n_per_m: 2e4,
            bristle_damping_n_s_per_m: 100.0,
        },
    };
    out.push(Probe {
        effect: "friction",
        probe: "stick-slip / LuGre",
        model: p,
        keys: &[Key::Static, Key::BristleStiffness],
        least: least(matches!(m.mechanics.friction, Friction::LuGre { .. })),
        step: 1.0,
    });
    let spool = m.effects.spool.unwrap_or_default();
    match m.actuator.valve.kind {
        ValveKind::OnOffPwm {
            switching_delay_s, ..
        } => {
            let mut p = *m;
            let mut s = spool;
            s.spool_time_constant_s = if s.spool_time_constant_s > 0.0 {
                (1.0 + 0.5 * f) * s.spool_time_constant_s
            } else {
                1e-3 * f
            };
            p.effects.spool = Some(s);
            out.push(Probe {
                effect: "valve_dynamics",
                probe: "spool travel",
                model: p,
                keys: &[Key::SpoolTimeConstant],
                least: least(spool.spool_time_constant_s > 0.0),
                step: f,
            });
            let mut p = *m;
            let mut s = spool;
            s.release_delay_s = Some(s.release_delay_s.unwrap_or(switching_delay_s) + 1e-3 * f);
            p.effects.spool = Some(s);
            // A release delay the sheet sets may be shorter, down to none; one it lacks (the switching
            // delay stands for both edges) is the effect's absence.
            let least = spool.release_delay_s.map_or(0.0, |d| -d / 1e-3);
            out.push(Probe {
                effect: "valve_dynamics",
                probe: "release delay",
                model: p,
                keys: &[Key::ReleaseDelay],
                least,
                step: f,
            });
        }
        _ => {
            let mut p = *m;
            let mut s = spool;
            s.dead_time_s += 1e-3 * f;
            p.effects.spool = Some(s);
            out.push(Probe {
                effect: "valve_dynamics",
                probe: "dead time",
                model: p,
                keys: &[Key::DeadTime],
                least: -(spool.dead_time_s / 1e-3),
                step: f,
            });
        }
    }
    let mut p = *m;
    p.effects.lines = Some(match m.effects.lines {
        Some(mut l) => {
            l.volume_m3 *= 1.5;
            l
        }
        None => Lines {
            volume_m3: 1e-6,
            orifice: Orifice {
                sonic_conductance_m3_per_s_pa: 2.0 * c_valve,
                critical_pressure_ratio: 0.3,
            },
            length_m: 1.0,
            speed_of_sound_m_per_s: 343.0,
        },
    });
    out.push(Probe {
        effect: "valve_dynamics",
        probe: "lines",
        model: p,
        keys: &[Key::LineVolume, Key::LineConductance, Key::LineLength],
        least: least(m.effects.lines.is_some()),
        step: 1.0,
    });
    out
}

/// One probe: a little of one effect added to the fitted model (see [`probes`]).
struct Probe {
    effect: &'static str,
    probe: &'static str,
    model: OneDofModel,
    /// The keys that model it: when one is fitted, the effect is in the model and the probe says nothing.
    keys: &'static [Key],
    /// The least amount of the effect there can be, in probes (0: none; below 0 when the model has some).
    least: f64,
    /// How much of one probe `model` holds (its pattern is the replay's change over this).
    step: f64,
}

/// The keys of each leak probe (`pneuflex_pneumatics::LEAKS`).
const LEAK_KEYS: [[Key; 1]; 3] = [
    [Key::LeakConductance(0)],
    [Key::LeakConductance(1)],
    [Key::LeakConductance(2)],
];

/// The fit rows' residuals of `model` as one vector (p_a, p_b, x per row, each over its floor), and the
/// range of each segment's entries in it (the clusters of [`Amounts`]'s covariance, one list per log).
fn stacked(
    model: &OneDofModel,
    off: &Offsets,
    data: &[Prepared],
    opts: &ReplayOptions,
    floors: [f64; 3],
) -> (Vec<f64>, Vec<Vec<std::ops::Range<usize>>>) {
    let mut out = Vec::new();
    let mut clusters = Vec::new();
    for d in data {
        let p = d.replay(model, off, opts, d.fit_end);
        let mut segs: Vec<std::ops::Range<usize>> = Vec::new();
        let mut seg = usize::MAX;
        for &k in &d.compared {
            let s = d
                .segments
                .partition_point(|&(s, _)| s < k)
                .saturating_sub(1);
            if s != seg {
                segs.push(out.len()..out.len());
                seg = s;
            }
            out.push((p.p_a[k] - d.log.p_a[k]) / floors[0]);
            out.push((p.p_b[k] - d.log.p_b[k]) / floors[1]);
            out.push((p.x[k] - d.log.x[k]) / floors[2]);
            if let Some(r) = segs.last_mut() {
                r.end = out.len();
            }
        }
        clusters.push(segs);
    }
    (out, clusters)
}

/// What one probe's pattern explains of the residuals, as a regression of the residuals' negative on the
/// fitted keys' sensitivities and the pattern together: `-r = J d + e a` (the truth's readings are the
/// fitted replay plus the keys' and the effect's changes).
#[derive(Clone, Debug, Default)]
struct Amounts {
    /// |partial correlation| of the residuals with the pattern, given the keys' sensitivities.
    correlation: f64,
    /// The amount `a` of the effect the residuals carry, in probes.
    amount: f64,
    /// Its standard error: Newey-West over the segments (their rows share a restart error, and the
    /// velocity and temperatures carry into the next), as the fit's own covariance.
    amount_se: f64,
    /// Per fitted key, how far one probe of the effect in the rig moves the truth from the fitted value
    /// (physical units): the keys absorb what they can of the effect, `d = -(J^T J)^-1 J^T e`.
    shift: Vec<f64>,
}

/// The solution of the symmetric system `g x = v` through the pseudo-inverse (eigenvalues below 1e-12 of
/// the largest dropped: a regressor the others span gets no weight), and that pseudo-inverse.
fn pinv_of(g: &nalgebra::DMatrix<f64>) -> nalgebra::DMatrix<f64> {
    let n = g.nrows();
    let eig = g.clone().symmetric_eigen();
    let lmax = eig.eigenvalues.iter().cloned().fold(0.0_f64, f64::max);
    let mut p = nalgebra::DMatrix::<f64>::zeros(n, n);
    for (i, &l) in eig.eigenvalues.iter().enumerate() {
        if l > 1e-12 * lmax && l > 0.0 {
            let v = eig.eigenvectors.column(i);
            p += (v * v.transpose()) / l;
        }
    }
    p
}

/// [`Amounts`] of the pattern `e` given the keys' sensitivities `jac` (each per `steps[j]` of its key,
/// physical units) for the stacked residuals `base` in `clusters`; `lag` the Newey-West lag in segments.
fn amounts(
    jac: &[Vec<f64>],
    steps: &[f64],
    e: &[f64],
    base: &[f64],
    clusters: &[Vec<std::ops::Range<usize>>],
    lag: usize,
) -> Amounts {
    use nalgebra::{DMatrix, DVector};
    let p = jac.len();
    let n = base.len();
    let finite = |v: &[f64]| v.iter().all(|x| x.is_finite());
    if !finite(e) || !finite(base) || jac.iter().any(|c| !finite(c)) || n <= p + 1 {
        return Amounts {
            amount: f64::NAN,
            amount_se: f64::NAN,
            shift: vec![f64::NAN; p],
            ..Amounts::default()
        };
    }
    let mut cols: Vec<&[f64]> = jac.iter().map(Vec::as_slice).collect();
    cols.push(e);
    let (x, norms) = unit_columns(&cols, n);
    let y = DVector::from_iterator(n, base.iter().map(|v| -v));
    let xtx = x.transpose() * &x;
    let gi = pinv_of(&xtx);
    let coef = &gi * (x.transpose() * &y);
    let u = &y - &x * &coef;
    // Newey-West over the segments of each log (weights 1 - l/(L+1)), with the fit's small-sample factor.
    let mut meat = DMatrix::<f64>::zeros(p + 1, p + 1);
    let mut g = 0usize;
    for log in clusters {
        let scores: Vec<DVector<f64>> = log
            .iter()
            .map(|r| x.rows(r.start, r.len()).transpose() * u.rows(r.start, r.len()))
            .collect();
        g += scores.len();
        for (c, s_c) in scores.iter().enumerate() {
            meat += s_c * s_c.transpose();
            for l in 1..=lag.min(c) {
                let w = 1.0 - l as f64 / (lag + 1) as f64;
                let s_l = &scores[c - l];
                meat += (s_c * s_l.transpose() + s_l * s_c.transpose()) * w;
            }
        }
    }
    let small = if g > 1 {
        (g as f64 / (g as f64 - 1.0)) * ((n as f64 - 1.0) / (n - p - 1) as f64)
    } else {
        1.0
    };
    let cov = &gi * meat * &gi * small;
    let amount = coef[p] / norms[p];
    let amount_se = AMOUNT_SE_FACTOR * cov[(p, p)].max(0.0).sqrt() / norms[p];
    // The keys' share of the pattern: their regression on it alone.
    let xj = x.columns(0, p).into_owned();
    let bj = pinv_of(&(xj.transpose() * &xj)) * (xj.transpose() * x.column(p));
    let shift = (0..p)
        .map(|j| -bj[j] * norms[p] / norms[j] * steps[j])
        .collect();
    let mut part = Partial::new(p + 1);
    let owned: Vec<Vec<f64>> = cols.iter().map(|c| c.to_vec()).collect();
    part.add(&owned, base);
    Amounts {
        correlation: part.r(p),
        amount,
        amount_se,
        shift,
    }
}

/// Which effect's pattern the residuals carry, computed by the replay itself: each probe (see [`probes`])
/// is replayed, and its change of the residuals is the pattern that effect would leave. The fitted keys
/// would readjust to an added effect, so the residuals are regressed on their own sensitivities (one
/// replay per key, +0.1 % of its scale) and the pattern together ([`amounts`]): the pattern's partial
/// correlation with the residuals is the effect's score, its coefficient the amount of the effect the
/// residuals carry (with a standard error robust to the segments' shared errors), and the keys' share of
/// the pattern how far that amount moves the truth from the fitted values (for [`widen`]).
///
/// Why this and not a rule per effect: the replay restarts every segment, the valve holds the chambers
/// to its supply and exhaust, and the fitted keys take up part of any missing effect, so what is left of
/// a leak, a heat exchange or a lag in the residuals has a shape no simple proxy (a drift on held segments,
/// a correlation with dp/dt) gives reliably; the probes' patterns have it exactly. It remains a linear
/// regression on one amount of each effect near the fit, not a fit of each: effects whose patterns
/// overlap (heat transfer and valve dynamics both act after fast pressure changes) can score alike.
fn signatures(
    model: &OneDofModel,
    off: &Offsets,
    free: &[(Key, f64)],
    data: &[Prepared],
    opts: &ReplayOptions,
    floors: [f64; 3],
) -> Vec<Signature> {
    use rayon::prelude::*;
    let (base, clusters) = stacked(model, off, data, opts, floors);
    let diff = |m: &OneDofModel, o: &Offsets| -> Vec<f64> {
        stacked(m, o, data, opts, floors)
            .0
            .iter()
            .zip(&base)
            .map(|(a, b)| a - b)
            .collect()
    };
    let steps: Vec<f64> = free
        .iter()
        .map(|&(k, start)| 1e-3 * k.scale(start))
        .collect();
    let jac: Vec<Vec<f64>> = free
        .par_iter()
        .zip(&steps)
        .map(|(&(k, _), &h)| {
            let (mut m, mut o) = (*model, *off);
            let v = k.get(&m, &o);
            k.set(&mut m, &mut o, v + h);
            diff(&m, &o)
        })
        .collect();
    let lag = (HAC_LAG_S / opts.segment_s).ceil().max(0.0) as usize;
    let scored: Vec<(Signature, Option<Vec<f64>>)> = probes(model)
        .par_iter()
        .map(|pr| {
            let modelled = pr.keys.iter().any(|k| free.iter().any(|(f, _)| f == k));
            let (a, e) = if modelled {
                let a = Amounts {
                    amount: f64::NAN,
                    amount_se: f64::NAN,
                    shift: vec![0.0; free.len()],
                    ..Amounts::default()
                };
                (a, None)
            } else {
                let e: Vec<f64> = diff(&pr.model, off).iter().map(|v| v / pr.step).collect();
                (amounts(&jac, &steps, &e, &base, &clusters, lag), Some(e))
            };
            let s = Signature {
                effect: pr.effect,
                probe: pr.probe,
                correlation: a.correlation,
                effect_correlation: f64::NAN,
                modelled,
                amount: a.amount,
                amount_se: a.amount_se,
                least_amount: pr.least,
                shift: a.shift,
            };
            (s, e)
        })
        .collect();
    // Each effect's score: its probes in a direction the effect can take, together.
    let joint: Vec<f64> = scored
        .iter()
        .map(|(s, _)| {
            let pats: Vec<&[f64]> = scored
                .iter()
                .filter(|(t, _)| t.effect == s.effect && beyond_absence(t) > 0.0)
                .filter_map(|(_, e)| e.as_deref())
                .collect();
            explained(&jac, &pats, &base)
        })
        .collect();
    scored
        .into_iter()
        .zip(joint)
        .map(|((mut s, _), j)| {
            s.effect_correlation = j;
            s
        })
        .collect()
}

/// The multiple partial correlation of the residuals `base` with the patterns `pats` together, given the
/// keys' sensitivities `jac`: the square root of the share of the residuals' sum of squares, less what the
/// keys explain, that the patterns explain too (0 without patterns).
fn explained(jac: &[Vec<f64>], pats: &[&[f64]], base: &[f64]) -> f64 {
    use nalgebra::DVector;
    if pats.is_empty() || base.iter().any(|v| !v.is_finite()) {
        return 0.0;
    }
    let n = base.len();
    let y = DVector::from_column_slice(base);
    let ssr = |cols: &[&[f64]]| -> f64 {
        let (x, _) = unit_columns(cols, n);
        let coef = pinv_of(&(x.transpose() * &x)) * (x.transpose() * &y);
        (&y - &x * coef).norm_squared()
    };
    let mut cols: Vec<&[f64]> = jac.iter().map(Vec::as_slice).collect();
    let keys = ssr(&cols);
    cols.extend_from_slice(pats);
    if cols.iter().any(|c| c.iter().any(|v| !v.is_finite())) {
        return 0.0;
    }
    let all = ssr(&cols);
    if keys > 0.0 {
        ((keys - all) / keys).max(0.0).sqrt()
    } else {
        0.0
    }
}

/// Widens each estimate's interval to hold the truth under every probed effect the model lacks, in any
/// amount the residuals allow: one probe of effect e moves the truth from the fitted value by `shift`
/// (the keys absorb that much of e, [`Amounts`]); the residuals allow amounts in [max(least, a - z se),
/// max(least, a + z se)] (z = [`WIDEN_Z`]) and always the effect's absence; so the interval is the union of
/// itself shifted by `shift * amount` over that range and over the probes. Applied on any fit: an adequate
/// one then never leaves an interval that excludes a truth an unmodelled (probed) effect has biased; on a
/// fit that is not adequate the intervals are marked not valid anyway. A probe the fitted keys span (the
/// pattern nearly theirs) has a large standard error: its effect cannot be told from the keys on these
/// logs, and the interval says so by its width.
pub fn widen(estimates: &mut [crate::fit::Estimate], mc: &ModelCheck) {
    for (j, e) in estimates.iter_mut().enumerate() {
        let noise = e.ci95;
        let (mut lo, mut hi) = (0.0_f64, 0.0_f64);
        let mut by: Option<(f64, &Signature, [f64; 2])> = None;
        for s in &mc.signatures {
            if s.modelled || !(s.amount.is_finite() && s.amount_se.is_finite()) {
                continue;
            }
            let Some(&d) = s.shift.get(j) else { continue };
            if !d.is_finite() {
                continue;
            }
            let a = [
                (s.amount - WIDEN_Z * s.amount_se).max(s.least_amount),
                (s.amount + WIDEN_Z * s.amount_se).max(s.least_amount),
            ];
            let moves = [d * a[0], d * a[1], 0.0];
            let m_lo = moves.iter().cloned().fold(0.0, f64::min);
            let m_hi = moves.iter().cloned().fold(0.0, f64::max);
            lo = lo.min(m_lo);
            hi = hi.max(m_hi);
            let reach = m_hi - m_lo;
            if by.as_ref().is_none_or(|(r, _, _)| reach > *r) {
                by = Some((reach, s, a));
            }
        }
        // No further than the fit's bounds (the fit takes the truth to be inside them).
        e.ci95 = [
            (noise[0] + lo).max(e.bounds[0].min(noise[0])),
            (noise[1] + hi).min(e.bounds[1].max(noise[1])),
        ];
        let half = (e.value - e.ci95[0]).max(e.ci95[1] - e.value);
        e.rel_half_width = if e.value != 0.0 {
            half / e.value.abs()
        } else {
            f64::INFINITY
        };
        e.widened = by
            .filter(|(r, _, _)| *r > 0.0)
            .map(|(_, s, a)| crate::fit::Widening {
                probe: s.probe.to_string(),
                effect: s.effect.to_string(),
                amounts: a,
                noise_ci95: noise,
            });
    }
}

/// The keys that model each effect (to add to the sheet and free).
fn effect_keys(effect: &str) -> &'static str {
    match effect {
        "leakage" => {
            "cylinder.leaks.{piston,a_atmosphere,b_atmosphere}.sonic_conductance_m3_per_s_pa"
        }
        "heat_transfer" => "cylinder.wall_heat_transfer_w_per_m2_k, gas.polytropic_exponent",
        "friction" => {
            "mechanics.coulomb_pressure_n_per_pa, mechanics.friction = \"stick_slip\" or \"lugre\" \
             (static_n, bristle_stiffness_n_per_m)"
        }
        "valve_dynamics" => "valve.spool_time_constant_s, valve.release_delay_s, [lines]",
        _ => "",
    }
}

/// How many standard errors a probe's amount lies beyond the effect's absence, in a direction the effect
/// can take (more of it; less of one the model has): 0 otherwise (an absent effect in a negative amount
/// is not that effect) or when the probe is not scored.
pub fn beyond_absence(s: &Signature) -> f64 {
    if s.modelled || !(s.amount.is_finite() && s.amount_se > 0.0) {
        return 0.0;
    }
    let t = s.amount / s.amount_se;
    if t > 0.0 {
        t
    } else if s.least_amount < 0.0 {
        -t
    } else {
        0.0
    }
}

/// The likely missing effects, best first: the probes whose amount lies beyond the effect's absence in a
/// direction the effect can take, named when detected ([`DETECT_Z`] standard errors) or when their
/// pattern's partial correlation reaches [`MIN_SIGNATURE_CORRELATION`], each effect ranked by its score
/// (`effect_correlation`: its probes in such a direction together, given the keys), then by its best
/// probe's. The sign matters: ranked by the correlation alone, sign ignored, a hidden leak was put on the
/// release delay first (issue 44; a release shorter than the switching delay, which no rig has). The
/// probes together matter: a rig leaks across the piston and to atmosphere at once, and no single leak
/// probe is that pattern, while one wall-heat probe is most of it (issue 44, seed 52: the hidden leak at
/// every magnitude came second to heat transfer by its best probe, 0.73 against 0.84, first by the
/// effect's score, 0.96 against 0.88).
fn name_missing(sig: &[Signature]) -> Vec<Missing> {
    let mut ranked: Vec<(&Signature, f64)> = sig
        .iter()
        .map(|s| (s, beyond_absence(s)))
        .filter(|&(s, t)| t > 0.0 && (t >= DETECT_Z || s.correlation >= MIN_SIGNATURE_CORRELATION))
        .collect();
    // By score, not standard errors: on the honesty grid (docs/identification.md) the standard errors
    // ranked a seal term second to spool travel (5.3 against 7.0, scores 0.41 against 0.24).
    ranked.sort_by(|a, b| {
        b.0.effect_correlation
            .total_cmp(&a.0.effect_correlation)
            .then(b.0.correlation.total_cmp(&a.0.correlation))
    });
    let mut out: Vec<Missing> = Vec::new();
    for (s, t) in ranked {
        if out.iter().any(|m| m.effect == s.effect) {
            continue;
        }
        out.push(Missing {
            effect: s.effect,
            keys: effect_keys(s.effect),
            evidence: evidence(s, t),
            correlation: s.correlation,
            beyond_absence: t,
        });
    }
    if out.is_empty() {
        let best = sig.iter().map(|s| s.correlation).fold(0.0, f64::max);
        let best_t = sig.iter().map(beyond_absence).fold(0.0, f64::max);
        return vec![Missing {
            effect: "unknown",
            keys: "",
            evidence: format!(
                "no effect's pattern reaches |r| = {MIN_SIGNATURE_CORRELATION} with the residuals in a \
                 direction the effect can take, nor {DETECT_Z} standard errors beyond its absence (best \
                 |r| {best:.2}, {best_t:.1} standard errors): an effect not among the probes, or several at once"
            ),
            correlation: best,
            beyond_absence: best_t,
        }];
    }
    out
}

fn evidence(s: &Signature, t: f64) -> String {
    format!(
        "the residuals follow the pattern of a little {} ({}), |r| = {:.2} (its forms together {:.2}); \
         {:.3} +- {:.3} probes, {:.1} standard errors beyond none",
        s.effect.replace('_', " "),
        s.probe,
        s.correlation,
        s.effect_correlation,
        s.amount,
        s.amount_se,
        t
    )
}

/// The design matrix of `cols` (each `n` long), each column over its norm (the keys' sensitivities and the
/// patterns differ by orders of magnitude), and the norms.
fn unit_columns(cols: &[&[f64]], n: usize) -> (nalgebra::DMatrix<f64>, Vec<f64>) {
    let norms: Vec<f64> = cols
        .iter()
        .map(|c| {
            c.iter()
                .map(|v| v * v)
                .sum::<f64>()
                .sqrt()
                .max(f64::MIN_POSITIVE)
        })
        .collect();
    let x = nalgebra::DMatrix::from_fn(n, cols.len(), |i, j| cols[j][i] / norms[j]);
    (x, norms)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::log::Log;

    /// Uniform deviates in [-0.5, 0.5) from a fixed LCG: reproducible noise.
    fn noise(n: usize, seed: u64) -> Vec<f64> {
        let mut s = seed;
        (0..n)
            .map(|_| {
                s = s
                    .wrapping_mul(6_364_136_223_846_793_005)
                    .wrapping_add(1_442_695_040_888_963_407);
                (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5
            })
            .collect()
    }

    /// A log resting for its first half (command and position steady, readings with white noise of a
    /// known RMS on a 12-bit grid) and moving fast in its second.
    fn resting_then_moving() -> (Prepared, [f64; 3]) {
        let n = 2000;
        let t: Vec<f64> = (0..n).map(|k| k as f64 * 1e-3).collect();
        let q = [268.6, 268.6, 1.889e-5];
        // Uniform noise of 3 counts' width: RMS 3 q / sqrt(12), well above the rounding's q / sqrt(12).
        let read = |base: &dyn Fn(usize) -> f64, i: usize, seed: u64| -> Vec<f64> {
            let e = noise(n, seed);
            (0..n)
                .map(|k| q[i] * ((base(k) + 3.0 * q[i] * e[k]) / q[i]).round())
                .collect()
        };
        let moving = |k: usize| k >= n / 2;
        let log = Log {
            path: "mem.csv".into(),
            sha256: String::new(),
            u: (0..n)
                .map(|k| {
                    if moving(k) {
                        (k as f64 * 0.05).sin()
                    } else {
                        0.1
                    }
                })
                .collect(),
            x: read(
                &|k| {
                    if moving(k) {
                        0.02 + 0.01 * (t[k] * 40.0).sin()
                    } else {
                        0.02
                    }
                },
                2,
                1,
            ),
            p_a: read(
                &|k| {
                    if moving(k) {
                        3e5 + 1e5 * (t[k] * 40.0).sin()
                    } else {
                        3e5
                    }
                },
                0,
                2,
            ),
            p_b: read(
                &|k| {
                    2e5 + if moving(k) {
                        5e4 * (t[k] * 40.0).cos()
                    } else {
                        0.0
                    }
                },
                1,
                3,
            ),
            f_e: vec![0.0; n],
            t,
            measured: vec![true; n],
            note: None,
        };
        let expected = std::array::from_fn(|i| {
            let width = 3.0 * q[i];
            (width * width / 12.0 + q[i] * q[i] / 12.0).sqrt()
        });
        (
            Prepared::new(log, &ReplayOptions::default(), n - 1),
            expected,
        )
    }

    #[test]
    fn still_stretches_give_the_readings_noise() {
        let (p, expected) = resting_then_moving();
        let (s, rows) = still_noise(std::slice::from_ref(&p), quantum(&p.log.x));
        // The resting half only: the moving half's windows are not still.
        assert_eq!(rows, 1000);
        for i in 0..3 {
            assert!(
                (s[i] / expected[i] - 1.0).abs() < 0.1,
                "channel {i}: {} against {}",
                s[i],
                expected[i]
            );
        }
    }

    #[test]
    fn a_log_that_never_rests_has_no_still_noise() {
        let (mut p, _) = resting_then_moving();
        p.log.u = (0..p.log.len()).map(|k| (k as f64 * 0.05).sin()).collect();
        let (s, rows) = still_noise(std::slice::from_ref(&p), quantum(&p.log.x));
        assert_eq!(rows, 0);
        assert!(s.iter().all(|v| v.is_nan()));
    }

    #[test]
    fn clipping_drops_a_few_edges_and_keeps_the_noise() {
        // White noise of RMS 1 through third differences, and a kink every 100 rows 50 times as large.
        let e: Vec<f64> = noise(20_000, 7).iter().map(|v| v * 12f64.sqrt()).collect();
        let mut d: Vec<f64> = third_differences(&e).collect();
        for k in (0..d.len()).step_by(100) {
            d[k] += 50.0;
        }
        let s = clipped_scatter(&d);
        assert!((s - 1.0).abs() < 0.1, "{s}");
    }

    /// A residual made of a known amount of a pattern plus a part the keys explain: the regression gives
    /// the amount back, and the shift is what the keys take up of the pattern (closed form below).
    #[test]
    fn a_probes_amount_and_shift_come_back() {
        let n = 3000;
        let e = noise(n, 11);
        // One key whose sensitivity is half the pattern plus its own part: it takes up 0.5 of the pattern
        // per step, so one probe moves its truth by -0.5 steps of 1e-3.
        let own = noise(n, 12);
        let j: Vec<f64> = (0..n).map(|i| 0.5 * e[i] + own[i]).collect();
        let white = noise(n, 13);
        let (alpha, d) = (0.7, 0.2);
        let base: Vec<f64> = (0..n)
            .map(|i| -(alpha * e[i] + d * j[i]) + 0.01 * white[i])
            .collect();
        let clusters = vec![(0..n / 100).map(|c| 100 * c..100 * (c + 1)).collect()];
        let a = amounts(&[j], &[1e-3], &e, &base, &clusters, 2);
        assert!((a.amount - alpha).abs() < 0.01, "{}", a.amount);
        assert!(a.amount_se > 0.0 && a.amount_se < 0.01, "{}", a.amount_se);
        // Regression of the pattern on the key alone: b = <j, e> / <j, j> (uniform deviates of variance
        // 1/12 each: 0.5 / 12 / (0.25 / 12 + 1 / 12) = 0.4).
        let b = e
            .iter()
            .zip(&own)
            .map(|(x, o)| x * (0.5 * x + o))
            .sum::<f64>()
            / e.iter()
                .zip(&own)
                .map(|(x, o)| (0.5 * x + o).powi(2))
                .sum::<f64>();
        assert!((b - 0.4).abs() < 0.03, "{b}");
        assert!(
            (a.shift[0] + b * 1e-3).abs() < 1e-12,
            "{:?} vs {}",
            a.shift,
            -b * 1e-3
        );
    }

    /// An effect's score with one probe is that probe's partial correlation (computed another way, from
    /// the precision matrix); a second probe of the effect never lowers it, and one that carries the rest
    /// of the residuals raises it to nearly 1.
    #[test]
    fn an_effects_score_is_the_partial_correlation_of_its_probes_together() {
        let n = 2000;
        let j = noise(n, 21);
        let (e1, e2, w) = (noise(n, 22), noise(n, 23), noise(n, 24));
        let base: Vec<f64> = (0..n)
            .map(|i| 0.4 * j[i] + 0.3 * e1[i] + 0.2 * e2[i] + 0.05 * w[i])
            .collect();
        let jac = vec![j.clone()];
        let one = explained(&jac, &[&e1], &base);
        let mut part = Partial::new(2);
        part.add(&[j.clone(), e1.clone()], &base);
        assert!(
            (one - part.r(1)).abs() < 1e-6,
            "{one} against {}",
            part.r(1)
        );
        let both = explained(&jac, &[&e1, &e2], &base);
        assert!(both > one && both > 0.99, "{both} against {one}");
        assert_eq!(explained(&jac, &[], &base), 0.0);
    }

    /// An interval is widened on the side the effect moves the truth, by the shift times the most the
    /// residuals allow, a + 1.96 se; an effect in an amount below its absence does not narrow it.
    #[test]
    fn widening_covers_the_amounts_the_residuals_allow() {
        let sig = |amount: f64, shift: f64| Signature {
            effect: "friction",
            probe: "seal pressure term",
            correlation: 0.1,
            effect_correlation: 0.1,
            modelled: false,
            amount,
            amount_se: 0.5,
            least_amount: 0.0,
            shift: vec![shift],
        };
        let est = || crate::fit::Estimate {
            key: "mechanics.coulomb_n".into(),
            start: 0.6,
            value: 1.0,
            bounds: [0.12, 3.0],
            std_error: 0.1,
            bias: 0.0,
            bias_bound: 0.0,
            ci95: [0.8, 1.2],
            rel_half_width: 0.2,
            at_bound: false,
            interval_valid: true,
            widened: None,
        };
        let mc = |signatures: Vec<Signature>| ModelCheck {
            adequate: true,
            failed: vec![],
            channels: vec![],
            rows: 0,
            signatures,
            likely_missing: vec![],
            thresholds: Thresholds {
                max_floor_ratio: MAX_FLOOR_RATIO,
                max_mean_abs_autocorrelation: MAX_MEAN_ABS_AUTOCORRELATION,
                max_validation_ratio: MAX_VALIDATION_RATIO,
                min_signature_correlation: MIN_SIGNATURE_CORRELATION,
                detect_z: DETECT_Z,
                widen_z: WIDEN_Z,
            },
        };
        // 0.3 +- 0.5 probes, each moving F_c by -0.2 N: the truth may be up to 0.2 (0.3 + 0.98) N lower.
        let mut e = [est()];
        widen(&mut e, &mc(vec![sig(0.3, -0.2)]));
        assert!(
            (e[0].ci95[0] - (0.8 - 0.2 * 1.28)).abs() < 1e-12,
            "{:?}",
            e[0].ci95
        );
        assert_eq!(e[0].ci95[1], 1.2);
        let w = e[0].widened.as_ref().unwrap();
        assert_eq!(w.noise_ci95, [0.8, 1.2]);
        assert!((w.amounts[0] - 0.0).abs() < 1e-12 && (w.amounts[1] - 1.28).abs() < 1e-12);
        // Far below its absence (-3 +- 0.5): only the absence is allowed, nothing is widened.
        let mut e = [est()];
        widen(&mut e, &mc(vec![sig(-3.0, -0.2)]));
        assert_eq!(e[0].ci95, [0.8, 1.2]);
        assert!(e[0].widened.is_none());
        // Never beyond the fit's bounds.
        let mut e = [est()];
        widen(&mut e, &mc(vec![sig(10.0, -0.2)]));
        assert_eq!(e[0].ci95[0], 0.12);
    }

    #[test]
    fn detrending_takes_out_a_line_only() {
        let r: Vec<f64> = (0..50).map(|k| 3.0 + 0.2 * k as f64).collect();
        assert!(detrended(&r).iter().all(|v| v.abs() < 1e-12));
        let w: Vec<f64> = (0..50)
            .map(|k| if k % 2 == 0 { 1.0 } else { -1.0 })
            .collect();
        let d = detrended(&w);
        // The alternation has almost no line in it (a slope of 0.0024 per row): it stays.
        assert!(d.iter().zip(&w).all(|(a, b)| (a - b).abs() < 0.07));
    }
}
