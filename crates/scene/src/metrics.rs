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

/// Response to an event (a disturbance such as a stiffness change) over a window starting at the event.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct EventResponse {
    /// Largest contact force f_e in the window, N.
    pub peak_force_n: f64,
    /// Largest force error |f_e - f_ref| in the window, N (the disturbance peak).
    pub peak_error_n: f64,
    /// Recovery overshoot, N: after the force error first returns through zero, the largest error on the
    /// opposite side (0 when it never crosses, or crosses without overshooting).
    pub recovery_overshoot_n: f64,
    /// The ±band for settling, N: 2% of the largest |f_ref| in the window.
    pub settling_band_n: f64,
    /// 2% settling time after the event, s: from the window start until |f_ref - f_e| stays within the band
    /// to the end of the window; None when it is outside the band at the window end (not settled).
    pub settling_time_s: Option<f64>,
    /// Steady tracking error, N: the largest |f_ref - f_e| over the window's tail (its last reference period
    /// for a sine, else its last 10%). A sine reference leaves a periodic error that never enters the
    /// plain 2% band.
    pub tracking_error_n: f64,
    /// Settling time back to the steady tracking level, s: until |f_ref - f_e| stays within
    /// `tracking_error_n + settling_band_n` (None when the window's tail is still outside it).
    pub settling_time_to_tracking_s: Option<f64>,
}

/// Peak force, recovery overshoot and 2% settling times of f_e after an event at `t[0]`; `tail_s` is the
/// length of the window's tail over which the steady tracking error is measured.
pub fn event_response(t: &[f64], f_ref: &[f64], f_e: &[f64], tail_s: f64) -> Option<EventResponse> {
    if t.is_empty() {
        return None;
    }
    let peak_force_n = f_e.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let err: Vec<f64> = f_ref.iter().zip(f_e).map(|(r, f)| r - f).collect();
    // Disturbance peak: the sample of largest |e|; its sign tells which way the error was pushed.
    let (i_pk, peak_error_n) = err
        .iter()
        .enumerate()
        .fold((0, 0.0_f64), |(bi, bv), (i, e)| {
            if e.abs() > bv { (i, e.abs()) } else { (bi, bv) }
        });
    let sign = err[i_pk].signum();
    let recovery_overshoot_n = match (i_pk..err.len()).find(|&i| sign * err[i] <= 0.0) {
        Some(ic) => err[ic..].iter().map(|e| -sign * e).fold(0.0_f64, f64::max),
        None => 0.0,
    };
    let ref_peak = f_ref.iter().fold(0.0_f64, |m, r| m.max(r.abs()));
    let band = 0.02 * ref_peak;
    let settle = |band: f64| match err.iter().rposition(|e| e.abs() > band) {
        None => Some(0.0),
        Some(i) if i + 1 < err.len() => Some(t[i + 1] - t[0]),
        Some(_) => None,
    };
    let t_end = t[t.len() - 1];
    let i_tail = t
        .partition_point(|&ti| ti < t_end - tail_s)
        .min(t.len() - 1);
    let tracking_error_n = err[i_tail..].iter().fold(0.0_f64, |m, e| m.max(e.abs()));
    // The tail itself is inside its own band by construction, so "not settled" needs the band's edge to be
    // reached just at the end; require the last crossing to lie before the tail.
    let to_tracking = match err.iter().rposition(|e| e.abs() > tracking_error_n + band) {
        // The disturbance peak lies in the tail itself: the error has not come down at all.
        _ if i_pk >= i_tail => None,
        None => Some(0.0),
        Some(i) if i + 1 < i_tail => Some(t[i + 1] - t[0]),
        Some(_) => None,
    };
    Some(EventResponse {
        peak_force_n,
        peak_error_n,
        recovery_overshoot_n,
        settling_band_n: band,
        settling_time_s: settle(band),
        tracking_error_n,
        settling_time_to_tracking_s: to_tracking,
    })
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
        // e(t) = -A e^{-at} cos(wt): peak error A at t = 0; the recovery overshoot is the extremum of the
        // second half-wave, where d/dt[e^{-at} cos(wt)] = 0: w t* = π - atan(a/w).
        let (amp, a, w) = (5.0, 2.0, 10.0);
        let t: Vec<f64> = (0..=4000).map(|k| k as f64 * 1e-3).collect();
        let f_ref = vec![10.0; t.len()];
        let f_e: Vec<f64> = t
            .iter()
            .map(|&ti| 10.0 + amp * (-a * ti).exp() * (w * ti).cos())
            .collect();
        let r = event_response(&t, &f_ref, &f_e, 0.4).unwrap();
        assert!((r.peak_force_n - 15.0).abs() < 1e-9);
        let ts_pk = (std::f64::consts::PI - (a / w).atan()) / w;
        let want = amp * (-a * ts_pk).exp() * (w * ts_pk).cos().abs();
        assert!(
            (r.recovery_overshoot_n - want).abs() < 1e-4 * want,
            "{} vs {want}",
            r.recovery_overshoot_n
        );
        // Settles when the envelope A e^{-at} falls to 0.2 N: t = ln(25)/2 ≈ 1.609 s; the last
        // band crossing is at a cosine peak just before that.
        let ts = r.settling_time_s.unwrap();
        let env = (amp / 0.2_f64).ln() / a;
        assert!(
            ts <= env + 1e-3 && ts > env - std::f64::consts::PI / w,
            "{ts} vs {env}"
        );
    }

    #[test]
    fn unsettled_window_reports_none() {
        let t: Vec<f64> = (0..100).map(|k| k as f64 * 0.01).collect();
        let f_ref = vec![10.0; 100];
        let f_e = vec![9.0; 100];
        let r = event_response(&t, &f_ref, &f_e, 0.1).unwrap();
        assert_eq!(r.settling_time_s, None);
        assert!((r.tracking_error_n - 1.0).abs() < 1e-12);
        assert_eq!(r.settling_time_to_tracking_s, Some(0.0));
    }
}
