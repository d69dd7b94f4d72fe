//! Metrics over time windows of a trace: RMS force error, phase lag on sine references (least-squares
//! sine fit at the known frequency), steady-state error on steps, and peak / overshoot / settling after events.

use serde::Serialize;

/// Indices [i0, i1) of the samples with t0 <= t < t1 (t is increasing); the last sample is included
/// when t1 reaches it.
pub fn window_indices(t: &[f64], t0: f64, t1: f64) -> (usize, usize) {
    let eps = 1e-9 * (t1 - t0).abs().max(1e-9);
    let i0 = t.partition_point(|&ti| ti < t0 - eps);
    let mut i1 = t.partition_point(|&ti| ti < t1 - eps);
    if i1 == t.len() - 1 && (t[i1] - t1).abs() <= eps {
        i1 += 1;
    }
    (i0, i1.max(i0))
}

/// Root mean square of f_ref - f_e over the samples, N (NaN for an empty window).
pub fn rms_error(f_ref: &[f64], f_e: &[f64]) -> f64 {
    let n = f_ref.len().min(f_e.len());
    if n == 0 {
        return f64::NAN;
    }
    let s: f64 = f_ref.iter().zip(f_e).map(|(r, f)| (r - f) * (r - f)).sum();
    (s / n as f64).sqrt()
}

/// Mean of f_ref - f_e over the samples, N: the steady-state error when the window covers a settled step.
pub fn mean_error(f_ref: &[f64], f_e: &[f64]) -> f64 {
    let n = f_ref.len().min(f_e.len());
    if n == 0 {
        return f64::NAN;
    }
    f_ref.iter().zip(f_e).map(|(r, f)| r - f).sum::<f64>() / n as f64
}

/// Least-squares fit y ≈ a sin(ωt) + b cos(ωt) + c at the known angular frequency ω (rad/s).
/// Returns (amplitude, phase rad, bias) with y ≈ amplitude · sin(ωt + phase) + bias; None when singular.
pub fn fit_sine(t: &[f64], y: &[f64], omega: f64) -> Option<(f64, f64, f64)> {
    // Normal equations (3x3) of the basis [sin, cos, 1].
    let mut m = [[0.0_f64; 3]; 3];
    let mut r = [0.0_f64; 3];
    for (&ti, &yi) in t.iter().zip(y) {
        let b = [(omega * ti).sin(), (omega * ti).cos(), 1.0];
        for i in 0..3 {
            for j in 0..3 {
                m[i][j] += b[i] * b[j];
            }
            r[i] += b[i] * yi;
        }
    }
    let sol = solve3(m, r)?;
    let (a, b, c) = (sol[0], sol[1], sol[2]);
    Some((a.hypot(b), b.atan2(a), c))
}

/// Gaussian elimination with partial pivoting for a 3x3 system; None when (nearly) singular.
fn solve3(mut m: [[f64; 3]; 3], mut r: [f64; 3]) -> Option<[f64; 3]> {
    let scale = m.iter().flatten().fold(0.0_f64, |s, v| s.max(v.abs()));
    if scale == 0.0 || !scale.is_finite() {
        return None;
    }
    for col in 0..3 {
        let piv = (col..3).max_by(|&a, &b| m[a][col].abs().total_cmp(&m[b][col].abs()))?;
        if m[piv][col].abs() < 1e-12 * scale {
            return None;
        }
        m.swap(col, piv);
        r.swap(col, piv);
        for row in col + 1..3 {
            let f = m[row][col] / m[col][col];
            let pivot_row = m[col];
            for (a, p) in m[row][col..].iter_mut().zip(&pivot_row[col..]) {
                *a -= f * p;
            }
            r[row] -= f * r[col];
        }
    }
    let mut x = [0.0; 3];
    for i in (0..3).rev() {
        let s: f64 = (i + 1..3).map(|k| m[i][k] * x[k]).sum();
        x[i] = (r[i] - s) / m[i][i];
    }
    Some(x)
}

/// `y` less its least-squares fit by a bias and the first `harmonics` harmonics of `frequency_hz`: what is
/// left is not periodic with the reference (a limit cycle at its own frequency, noise). A reference-periodic
/// distortion — the odd harmonics friction puts on a tracked sine — is removed with it.
pub fn remove_harmonics(t: &[f64], y: &[f64], frequency_hz: f64, harmonics: usize) -> Vec<f64> {
    let w = std::f64::consts::TAU * frequency_hz;
    let m = 1 + 2 * harmonics;
    let basis = |ti: f64| -> Vec<f64> {
        let mut b = Vec::with_capacity(m);
        b.push(1.0);
        for k in 1..=harmonics {
            let a = k as f64 * w * ti;
            b.push(a.sin());
            b.push(a.cos());
        }
        b
    };
    let mut ata = vec![vec![0.0; m]; m];
    let mut aty = vec![0.0; m];
    for (&ti, &yi) in t.iter().zip(y) {
        let b = basis(ti);
        for i in 0..m {
            for j in 0..m {
                ata[i][j] += b[i] * b[j];
            }
            aty[i] += b[i] * yi;
        }
    }
    // Gaussian elimination with partial pivoting; a singular fit leaves y as it is.
    for col in 0..m {
        let Some(piv) = (col..m).max_by(|&a, &b| ata[a][col].abs().total_cmp(&ata[b][col].abs()))
        else {
            return y.to_vec();
        };
        if ata[piv][col].abs() < 1e-12 {
            return y.to_vec();
        }
        ata.swap(col, piv);
        aty.swap(col, piv);
        for row in col + 1..m {
            let f = ata[row][col] / ata[col][col];
            let pivot_row = ata[col].clone();
            for (x, p) in ata[row][col..].iter_mut().zip(&pivot_row[col..]) {
                *x -= f * p;
            }
            aty[row] -= f * aty[col];
        }
    }
    let mut c = vec![0.0; m];
    for i in (0..m).rev() {
        let s: f64 = (i + 1..m).map(|k| ata[i][k] * c[k]).sum();
        c[i] = (aty[i] - s) / ata[i][i];
    }
    t.iter()
        .zip(y)
        .map(|(&ti, &yi)| yi - basis(ti).iter().zip(&c).map(|(b, ci)| b * ci).sum::<f64>())
        .collect()
}

/// Phase lag of `y` behind `reference` at frequency `frequency_hz`, degrees in (-180, 180]
/// (positive = y lags). Both signals are fitted by least squares with a bias.
pub fn phase_lag_deg(t: &[f64], reference: &[f64], y: &[f64], frequency_hz: f64) -> Option<f64> {
    let w = std::f64::consts::TAU * frequency_hz;
    let (_, ph_r, _) = fit_sine(t, reference, w)?;
    let (amp_y, ph_y, _) = fit_sine(t, y, w)?;
    if amp_y == 0.0 {
        return None;
    }
    let mut d = (ph_r - ph_y).to_degrees();
    while d > 180.0 {
        d -= 360.0;
    }
    while d <= -180.0 {
        d += 360.0;
    }
    Some(d)
}

/// A sustained oscillation found where a run should have settled (a limit cycle, or chatter).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Oscillation {
    /// Its frequency, Hz (from the zero crossings of the residual).
    pub frequency_hz: f64,
    /// Its amplitude, N (half the peak-to-peak of the residual).
    pub amplitude_n: f64,
}

/// Response to an event (a disturbance such as a stiffness change) over a window starting at the event,
/// measured against the run's own periodic steady state: the force error over the window's tail (its last
/// reference period on a sine, its last 10 % on a step), continued periodically back to the event.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct EventResponse {
    /// Which force the response is read on: `f_e`, or `f_e averaged over one PWM period (… s)` on a
    /// plant with an on/off valve, whose raw force chatters at the PWM frequency.
    pub signal: String,
    /// Largest contact force f_e in the window (raw), N.
    pub peak_force_n: f64,
    /// Largest force error |f_ref - f_e| in the window (on `signal`), N.
    pub peak_error_n: f64,
    /// The jump: the largest deviation of the error from its periodic steady state, N (the disturbance).
    pub jump_n: f64,
    /// Recovery overshoot, N: after the deviation first returns through zero, its largest excursion on the
    /// other side (0 when it never crosses).
    pub recovery_overshoot_n: f64,
    /// The recovery overshoot as a percentage of the jump.
    pub recovery_overshoot_pct: f64,
    /// The ±band for settling, N: 2 % of the largest |f_ref| in the window, or the run's own steady
    /// ripple (the tail's largest residual) when that is larger.
    pub settling_band_n: f64,
    /// Whether the run settled: back within the band of its periodic steady state, with no sustained
    /// oscillation and a bounded steady error.
    pub settled: bool,
    /// Settling time, s: from the event until the deviation stays within the band; None when not settled.
    pub settling_time_s: Option<f64>,
    /// The settling time with the band 5 % narrower and 5 % wider, s ([`SETTLING_BAND_PROBE`]).
    pub settling_time_range_s: [Option<f64>; 2],
    /// Whether the settling time hangs on where the band is drawn: one of the two probes differs from it by
    /// more than 10 % (or one settles and the other not). A decaying peak of the deviation then sits at the
    /// band's edge, and the settling time jumps with anything that moves that peak a little (the step, a
    /// parameter): compare such a run's settling time only with its range.
    pub settling_fragile: bool,
    /// Why the run did not settle (None when it did).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub not_settled: Option<String>,
    /// The sustained oscillation found in the tail, when there is one.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub oscillation: Option<Oscillation>,
    /// Steady tracking error, N: the largest |f_ref - f_e| over the window's tail (on `signal`).
    pub tracking_error_n: f64,
}

impl EventResponse {
    /// "fragile: 0.805–1.121 s with the band ±5 %" when the settling time is fragile (else None): what a
    /// table or a figure says beside it.
    pub fn fragility(&self) -> Option<String> {
        if !self.settling_fragile {
            return None;
        }
        let pct = 100.0 * SETTLING_BAND_PROBE;
        let [narrow, wide] = self.settling_time_range_s;
        Some(match (self.settling_time_s, narrow, wide) {
            (Some(ts), Some(n), Some(w)) => format!(
                "fragile: {:.3}–{:.3} s with the band ±{pct:.0} %",
                ts.min(n).min(w),
                ts.max(n).max(w)
            ),
            (Some(_), None, _) => format!("fragile: not settled with the band {pct:.0} % narrower"),
            (Some(_), _, None) => format!("fragile: not settled with the band {pct:.0} % wider"),
            (None, _, Some(w)) => {
                format!("fragile: settles in {w:.3} s with the band {pct:.0} % wider")
            }
            (None, Some(n), None) => {
                format!("fragile: settles in {n:.3} s with the band {pct:.0} % narrower")
            }
            (None, None, None) => "fragile".to_string(),
        })
    }
}

/// How far the settling band is moved (as a fraction of it, each way) to probe a settling time's sensitivity.
pub const SETTLING_BAND_PROBE: f64 = 0.05;

/// Centred moving average over `n` samples: always a whole window of `n` (shifted inwards at the ends, so a
/// PWM period is always averaged whole); `n` <= 1 returns the input.
pub fn moving_average(y: &[f64], n: usize) -> Vec<f64> {
    if n <= 1 || y.is_empty() {
        return y.to_vec();
    }
    let mut prefix = Vec::with_capacity(y.len() + 1);
    prefix.push(0.0);
    for v in y {
        prefix.push(prefix.last().copied().unwrap_or(0.0) + v);
    }
    let n = n.min(y.len());
    (0..y.len())
        .map(|i| {
            let a = i.saturating_sub(n / 2).min(y.len() - n);
            (prefix[a + n] - prefix[a]) / n as f64
        })
        .collect()
}

/// The shape of the reference over a window, for the steady state the response is measured against.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Steady {
    /// A constant reference: the steady state is the tail's mean error.
    Constant,
    /// A sine of this frequency, Hz: the steady state is the tail's last period, repeated.
    Periodic(f64),
}

/// Peak force, jump, recovery overshoot and settling of the force error after an event at `t[0]`, against
/// the window's own periodic steady state; `averaging_s` is the PWM period to average f_e over (None on a
/// continuous valve). A tail that oscillates (residual after the reference's own periodic part above
/// 7.5 % of the reference) or keeps a steady error above 25 % of the reference is "not settled" and reports
/// why.
pub fn event_response(
    t: &[f64],
    f_ref: &[f64],
    f_e: &[f64],
    steady: Steady,
    averaging_s: Option<f64>,
) -> Option<EventResponse> {
    let n = t.len().min(f_ref.len()).min(f_e.len());
    if n < 4 {
        return None;
    }
    let dt = (t[n - 1] - t[0]) / (n - 1) as f64;
    let peak_force_n = f_e[..n].iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let raw: Vec<f64> = (0..n).map(|i| f_ref[i] - f_e[i]).collect();
    let (err, signal) = match averaging_s {
        Some(p) if p > 1.5 * dt => (
            moving_average(&raw, (p / dt).round() as usize),
            format!("f_e averaged over one PWM period ({p} s)"),
        ),
        _ => (raw, "f_e".to_string()),
    };
    // The tail: the last two reference periods of a sine (at most half the window), the last 10 % of a
    // step. The periodic steady state is the tail's mean period, so one period's ripple does not define it.
    let (tail_s, periods) = match steady {
        Steady::Periodic(f) => {
            let half = 0.5 * (t[n - 1] - t[0]);
            if 2.0 / f <= half {
                (2.0 / f, 2)
            } else {
                ((1.0 / f).min(half), 1)
            }
        }
        Steady::Constant => (0.1 * (t[n - 1] - t[0]), 1),
    };
    let n_tail = ((tail_s / dt).round() as usize).clamp(2 * periods, n / 2);
    let i_tail = n - n_tail;
    let tail = &err[i_tail..];
    let dev = deviation_from_steady(&err, i_tail, periods, steady);
    let (i_pk, jump_n) = dev
        .iter()
        .enumerate()
        .fold((0, 0.0_f64), |(bi, bv), (i, d)| {
            if d.abs() > bv { (i, d.abs()) } else { (bi, bv) }
        });
    let sign = dev[i_pk].signum();
    let recovery_overshoot_n = match (i_pk..n).find(|&i| sign * dev[i] <= 0.0) {
        Some(ic) => dev[ic..].iter().map(|d| -sign * d).fold(0.0_f64, f64::max),
        None => 0.0,
    };
    let ref_peak = f_ref[..n].iter().fold(0.0_f64, |m, r| m.max(r.abs()));
    let peak_error_n = err.iter().fold(0.0_f64, |m, e| m.max(e.abs()));
    let tracking_error_n = tail.iter().fold(0.0_f64, |m, e| m.max(e.abs()));

    let (oscillation, ripple) = tail_oscillation(&t[i_tail..n], tail, steady, ref_peak);
    let band = (0.02 * ref_peak).max(ripple);
    let mean_abs_tail = tail.iter().map(|e| e.abs()).sum::<f64>() / n_tail as f64;
    let not_settled = if let Some(o) = oscillation {
        Some(format!(
            "sustained oscillation at {:.1} Hz, amplitude {:.2} N",
            o.frequency_hz, o.amplitude_n
        ))
    } else if mean_abs_tail > 0.25 * ref_peak {
        Some(format!(
            "steady force error of {mean_abs_tail:.2} N (over 25 % of the {ref_peak:.2} N reference): \
             not tracking (an end stop, or lost contact)"
        ))
    } else {
        None
    };
    // Settling: the deviation stays within the band from then to the end of the window.
    let settling = |band: f64| match (&not_settled, dev.iter().rposition(|d| d.abs() > band)) {
        (Some(_), _) => None,
        (None, None) => Some(0.0),
        (None, Some(i)) if i + 1 < i_tail => Some(t[i + 1] - t[0]),
        (None, Some(_)) => None,
    };
    let settling_time_s = settling(band);
    // The same with the band a little narrower and wider: a settling time that jumps between them is set
    // by a peak at the band's edge, not by how fast the loop recovers.
    let settling_time_range_s = [
        settling(band * (1.0 - SETTLING_BAND_PROBE)),
        settling(band * (1.0 + SETTLING_BAND_PROBE)),
    ];
    let settling_fragile = settling_time_range_s
        .iter()
        .any(|p| match (settling_time_s, p) {
            (Some(ts), Some(p)) => (p - ts).abs() > 0.1 * ts,
            (a, b) => a.is_some() != b.is_some(),
        });
    let not_settled = match (&not_settled, settling_time_s) {
        (None, None) => Some(format!(
            "still outside the ±{band:.2} N band of its periodic steady state in the last {tail_s:.2} s"
        )),
        _ => not_settled,
    };
    Some(EventResponse {
        signal,
        peak_force_n,
        peak_error_n,
        jump_n,
        recovery_overshoot_n,
        recovery_overshoot_pct: if jump_n > 0.0 {
            100.0 * recovery_overshoot_n / jump_n
        } else {
            0.0
        },
        settling_band_n: band,
        settled: settling_time_s.is_some(),
        settling_time_s,
        settling_time_range_s,
        settling_fragile,
        not_settled,
        oscillation,
        tracking_error_n,
    })
}

/// Does the tail `tail` (at times `tt`) hold a sustained oscillation? The reference's own periodic part
/// (bias and the first five harmonics of a sine's frequency, or the mean of a constant) is removed and what
/// is left is looked at. Returns the oscillation, if any, and the residual's largest magnitude (the run's
/// own steady ripple).
fn tail_oscillation(
    tt: &[f64],
    tail: &[f64],
    steady: Steady,
    ref_peak: f64,
) -> (Option<Oscillation>, f64) {
    let residual: Vec<f64> = match steady {
        Steady::Periodic(f) => remove_harmonics(tt, tail, f, 5),
        Steady::Constant => {
            let m = tail.iter().sum::<f64>() / tail.len() as f64;
            tail.iter().map(|e| e - m).collect()
        }
    };
    let (lo, hi) = residual
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &r| {
            (l.min(r), h.max(r))
        });
    let amplitude_n = 0.5 * (hi - lo);
    let crossings = residual
        .windows(2)
        .filter(|w| (w[0] < 0.0) != (w[1] < 0.0))
        .count();
    let span = tt[tt.len() - 1] - tt[0];
    // A sustained oscillation is one above 7.5 % of the reference (a 16 Hz limit cycle of 3.4 N on a 12 N
    // reference, not the residual PWM ripple after averaging); the settling band is 2 % of the reference,
    // or the run's own steady ripple when that is larger (a loop settles to its ripple, not below it).
    let ripple = residual.iter().fold(0.0_f64, |m, r| m.max(r.abs()));
    let oscillation =
        (amplitude_n > 0.075 * ref_peak && crossings >= 4 && span > 0.0).then(|| Oscillation {
            frequency_hz: crossings as f64 / (2.0 * span),
            amplitude_n,
        });
    (oscillation, ripple)
}

/// The error's deviation from its periodic steady state: the tail's mean period (over `periods`
/// periods from `i_tail`), continued back from the tail, or the tail's mean for a constant reference.
fn deviation_from_steady(err: &[f64], i_tail: usize, periods: usize, steady: Steady) -> Vec<f64> {
    let n = err.len();
    let n_tail = n - i_tail;
    let tail = &err[i_tail..];
    let n_period = n_tail / periods;
    let tail_mean = tail.iter().sum::<f64>() / n_tail as f64;
    let period_mean: Vec<f64> = (0..n_period)
        .map(|k| (0..periods).map(|p| tail[p * n_period + k]).sum::<f64>() / periods as f64)
        .collect();
    let ss = |i: usize| -> f64 {
        match steady {
            Steady::Constant => tail_mean,
            Steady::Periodic(_) => {
                let k = (i as isize - i_tail as isize).rem_euclid(n_period as isize) as usize;
                period_mean[k]
            }
        }
    };
    let dev: Vec<f64> = (0..n).map(|i| err[i] - ss(i)).collect();
    dev
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sine_fit_recovers_a_known_phase() {
        let f = 0.8;
        let w = std::f64::consts::TAU * f;
        let t: Vec<f64> = (0..3001).map(|k| 3.0 + k as f64 * 1e-3).collect();
        let r: Vec<f64> = t.iter().map(|&ti| 10.0 + 2.0 * (w * ti).sin()).collect();
        let lag = 0.3_f64; // rad
        let y: Vec<f64> = t
            .iter()
            .map(|&ti| 8.0 + 1.5 * (w * ti - lag).sin())
            .collect();
        let d = phase_lag_deg(&t, &r, &y, f).unwrap();
        assert!((d - lag.to_degrees()).abs() < 1e-9, "{d}");
        let (a, _, c) = fit_sine(&t, &y, w).unwrap();
        assert!((a - 1.5).abs() < 1e-9 && (c - 8.0).abs() < 1e-9);
    }

    #[test]
    fn event_response_of_a_damped_oscillation() {
        // e(t) = -A e^{-at} cos(wt) on a constant reference: the steady state is 0, the jump A at t = 0,
        // the recovery overshoot the extremum of the second half-wave, where d/dt[e^{-at} cos(wt)] = 0:
        // w t* = π - atan(a/w).
        let (amp, a, w) = (5.0, 2.0, 10.0);
        let t: Vec<f64> = (0..=4000).map(|k| k as f64 * 1e-3).collect();
        let f_ref = vec![10.0; t.len()];
        let f_e: Vec<f64> = t
            .iter()
            .map(|&ti| 10.0 + amp * (-a * ti).exp() * (w * ti).cos())
            .collect();
        let r = event_response(&t, &f_ref, &f_e, Steady::Constant, None).unwrap();
        assert!((r.peak_force_n - 15.0).abs() < 1e-9);
        assert!((r.jump_n - amp).abs() < 1e-2, "{}", r.jump_n);
        let ts_pk = (std::f64::consts::PI - (a / w).atan()) / w;
        let want = amp * (-a * ts_pk).exp() * (w * ts_pk).cos().abs();
        assert!(
            (r.recovery_overshoot_n - want).abs() < 1e-2 * want,
            "{} vs {want}",
            r.recovery_overshoot_n
        );
        assert!((r.recovery_overshoot_pct - 100.0 * want / amp).abs() < 0.5);
        // Settles when the envelope A e^{-at} falls to the 0.2 N band: t = ln(25)/2 ≈ 1.609 s; the last
        // band crossing is at a cosine peak just before that.
        assert!(r.settled && r.not_settled.is_none());
        let ts = r.settling_time_s.unwrap();
        let env = (amp / 0.2_f64).ln() / a;
        assert!(
            ts <= env + 1e-3 && ts > env - std::f64::consts::PI / w,
            "{ts} vs {env}"
        );
    }

    /// e(t) = amp·e^{-a t} on a 10 N constant reference, 0–4 s at 1 ms.
    fn decay(amp: f64, a: f64) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
        let t: Vec<f64> = (0..=4000).map(|k| k as f64 * 1e-3).collect();
        let f_e = t.iter().map(|&ti| 10.0 + amp * (-a * ti).exp()).collect();
        (t.clone(), vec![10.0; t.len()], f_e)
    }

    #[test]
    fn a_smooth_decay_has_a_settling_time_that_does_not_hang_on_the_band() {
        // |d| = 5 e^{-4t} falls to a band b at t = ln(5/b)/4: the nominal 0.2 N band (2 % of 10 N; the
        // tail's ripple is ~1e-6 N) and the probes 5 % either side, each to the 1 ms sample after it.
        let (t, f_ref, f_e) = decay(5.0, 4.0);
        let r = event_response(&t, &f_ref, &f_e, Steady::Constant, None).unwrap();
        let at = |b: f64| (5.0 / b).ln() / 4.0;
        let b = r.settling_band_n;
        assert!((b - 0.2).abs() < 1e-4, "{b}");
        let close = |got: Option<f64>, want: f64| got.is_some_and(|g| (g - want).abs() <= 1.5e-3);
        assert!(
            close(r.settling_time_s, at(b)),
            "{:?} vs {}",
            r.settling_time_s,
            at(b)
        );
        let [narrow, wide] = r.settling_time_range_s;
        assert!(
            close(narrow, at(0.95 * b)),
            "{narrow:?} vs {}",
            at(0.95 * b)
        );
        assert!(close(wide, at(1.05 * b)), "{wide:?} vs {}", at(1.05 * b));
        assert!(!r.settling_fragile && r.fragility().is_none());
    }

    #[test]
    fn a_peak_at_the_edge_of_the_band_makes_the_settling_time_fragile() {
        // e(t) = -A e^{-at} cos(wt): its k-th extremum is at w t_k = kπ - atan(a/w). A is chosen so that
        // the 5th sits 2 % above the 0.2 N band: the nominal band and the narrower probe settle after it,
        // the wider probe after the 4th, half a period (π/w = 0.314 s) sooner.
        let (a, w) = (2.0_f64, 10.0_f64);
        let t_k = |k: f64| (k * std::f64::consts::PI - (a / w).atan()) / w;
        let shape = |ti: f64| (-a * ti).exp() * (w * ti).cos();
        let amp = 1.02 * 0.2 / shape(t_k(5.0)).abs();
        let t: Vec<f64> = (0..=4000).map(|k| k as f64 * 1e-3).collect();
        let f_ref = vec![10.0; t.len()];
        let f_e: Vec<f64> = t.iter().map(|&ti| 10.0 + amp * shape(ti)).collect();
        let r = event_response(&t, &f_ref, &f_e, Steady::Constant, None).unwrap();
        let ts = r.settling_time_s.unwrap();
        let [narrow, wide] = r.settling_time_range_s;
        let (narrow, wide) = (narrow.unwrap(), wide.unwrap());
        // After the 5th extremum and before the 6th; the wider probe after the 4th and before the 5th.
        assert!(ts > t_k(5.0) && ts < t_k(5.5), "{ts} vs {}", t_k(5.0));
        assert!(narrow >= ts && narrow < t_k(6.0), "{narrow}");
        assert!(wide > t_k(4.0) && wide < t_k(4.5), "{wide} vs {}", t_k(4.0));
        assert!(r.settling_fragile);
        let text = r.fragility().unwrap();
        assert!(
            text.contains(&format!("{wide:.3}–{narrow:.3} s with the band ±5 %")),
            "{text}"
        );
    }

    #[test]
    fn a_limit_cycle_on_a_sine_is_not_settled_and_reports_its_frequency() {
        // A 1 Hz sine reference tracked with a lag, plus a 16 Hz oscillation of 3.4 N that never decays.
        let t: Vec<f64> = (0..=4000).map(|k| 6.0 + k as f64 * 1e-3).collect();
        let w = std::f64::consts::TAU;
        let f_ref: Vec<f64> = t.iter().map(|&ti| 10.0 + 2.0 * (w * ti).sin()).collect();
        let f_e: Vec<f64> = t
            .iter()
            .map(|&ti| {
                10.0 + 1.8 * (w * ti - 0.4).sin() + 3.4 * (std::f64::consts::TAU * 16.0 * ti).sin()
            })
            .collect();
        let r = event_response(&t, &f_ref, &f_e, Steady::Periodic(1.0), None).unwrap();
        assert!(!r.settled && r.settling_time_s.is_none());
        let o = r.oscillation.unwrap();
        assert!((o.frequency_hz - 16.0).abs() < 0.5, "{o:?}");
        assert!((o.amplitude_n - 3.4).abs() < 0.1, "{o:?}");
        assert!(
            r.not_settled
                .unwrap()
                .contains("sustained oscillation at 1")
        );
        // The same tracking without the oscillation settles at once: the lagging sine is its steady state.
        let f_e: Vec<f64> = t
            .iter()
            .map(|&ti| 10.0 + 1.8 * (w * ti - 0.4).sin())
            .collect();
        let r = event_response(&t, &f_ref, &f_e, Steady::Periodic(1.0), None).unwrap();
        assert_eq!(r.settling_time_s, Some(0.0));
        assert!(
            r.tracking_error_n > 0.5,
            "a periodic error, not a settling failure"
        );
    }

    #[test]
    fn a_run_pinned_at_an_end_stop_is_not_settled() {
        let t: Vec<f64> = (0..1000).map(|k| k as f64 * 1e-3).collect();
        let f_ref = vec![10.0; 1000];
        let f_e = vec![42.0; 1000];
        let r = event_response(&t, &f_ref, &f_e, Steady::Constant, None).unwrap();
        assert!(!r.settled);
        assert!(r.not_settled.unwrap().contains("not tracking"));
    }

    #[test]
    fn pwm_chatter_is_averaged_away_when_the_period_is_given() {
        // A settled 10 N force with ±1.3 N of 40 Hz square-wave ripple.
        let t: Vec<f64> = (0..=2000).map(|k| k as f64 * 1e-3).collect();
        let f_ref = vec![10.0; t.len()];
        let f_e: Vec<f64> = t
            .iter()
            .map(|&ti| 10.0 + if (ti * 40.0).fract() < 0.5 { 1.3 } else { -1.3 })
            .collect();
        let raw = event_response(&t, &f_ref, &f_e, Steady::Constant, None).unwrap();
        assert!(!raw.settled, "the raw chatter is an oscillation");
        let avg = event_response(&t, &f_ref, &f_e, Steady::Constant, Some(0.025)).unwrap();
        assert!(avg.settled, "{:?}", avg.not_settled);
        assert!(avg.signal.contains("PWM period"));
    }

    #[test]
    fn moving_average_of_a_ramp_is_the_ramp_inside() {
        let y: Vec<f64> = (0..20).map(f64::from).collect();
        let m = moving_average(&y, 5);
        // Whole windows everywhere: the first values average 0..5, the last 15..20.
        assert!(
            (m[10] - 10.0).abs() < 1e-12
                && (m[0] - 2.0).abs() < 1e-12
                && (m[19] - 17.0).abs() < 1e-12
        );
    }
}
