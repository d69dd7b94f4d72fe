//! Replaying a log through the 1-DOF model: the logged valve command and contact force drive
//! `pneuflex_pneumatics::OneDofModel` (eqs. 1-11), segment by segment.
//!
//! Segment-wise fitting (a simple form of multiple shooting): the log is cut into segments of
//! `segment_s`; each starts from the measured position (the first also from the measured pressures and a
//! velocity fitted to the measured positions), so a long log cannot drift away however wrong the start values
//! are. Pressures (see [`ReplayOptions::reset_pressures`]), temperatures (not measured), the velocity (see
//! [`ReplayOptions::carry_velocity`]), the valve's PWM clock and spool schedule, and for a model with those
//! effects the lines' gas and LuGre's bristles (not measured) carry over from the previous segment's end.
//! The first `settle_s` of each segment, where the start's measurement noise dies out, is not compared.
//!
//! Timing (docs/identification.md): row k's command acts from row k to row k+1, as on the rig, where the
//! board applies the command of tick k during the next sample period.

use pneuflex_pneumatics::{ChamberState, ExtendedState, OneDofModel, OneDofState, ValveState};

use crate::log::Log;
use crate::params::Offsets;

/// Segments after the one following an end-stop impact that are not compared either.
const SETTLE_AFTER_IMPACT: usize = 2;

/// How a log is replayed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ReplayOptions {
    /// Segment length, s.
    pub segment_s: f64,
    /// Start of each segment not compared, s.
    pub settle_s: f64,
    /// Integration steps per log period (RK4, the valve's edges located exactly).
    pub substeps: usize,
    /// Half-width of the position fit that gives a segment's start velocity, samples.
    pub velocity_half_window: usize,
    /// Start a segment with the velocity the previous one ended with (not the fit of the measured position):
    /// under PWM the acceleration jumps at every spool edge, so a local polynomial through quantised
    /// positions misses the velocity by tens of mm/s, while the replay's own velocity is as good as the fit.
    pub carry_velocity: bool,
    /// The stroke (m), when known: segments in which the measured position moves into or out of the band
    /// of `stop_band_m` at either end stop are not compared. The end stops are inelastic (the velocity is
    /// cut at the impact): whether a replay reaches a stop inside an integration step or just misses it
    /// flips with the last digit of a parameter, which makes the residuals jump and the Jacobian (and the
    /// intervals) meaningless there. Segments resting on a stop throughout are kept.
    pub stroke_m: Option<f64>,
    /// Width of the end-stop band, m.
    pub stop_band_m: f64,
    /// Restart each segment from the measured pressures too (else only the first segment, and after an
    /// impact): the chamber pressures are stable under the valve's flows, unlike the position, and a restart
    /// from a noisy reading biases the fit (errors in the variables: the start error decays at a rate that
    /// depends on C and the volumes).
    pub reset_pressures: bool,
}

impl Default for ReplayOptions {
    fn default() -> Self {
        Self {
            segment_s: 0.1,
            settle_s: 0.015,
            substeps: 10,
            velocity_half_window: 3,
            carry_velocity: true,
            stroke_m: None,
            stop_band_m: 5e-4,
            reset_pressures: true,
        }
    }
}

/// A log prepared for replay: its segments and their start velocities.
#[derive(Clone, Debug)]
pub struct Prepared {
    /// The log.
    pub log: Log,
    /// Segments as row ranges `[start, end]` (the end row is the next segment's start).
    pub segments: Vec<(usize, usize)>,
    /// Velocity at each segment's start, m/s.
    pub v0: Vec<f64>,
    /// Position at each segment's start, m: the reading itself. Not the local fit's value (which has a
    /// third of the reading's noise): under PWM the piston's acceleration jumps at every spool edge, so a
    /// quadratic through +-3 samples misses the position by a deterministic, signal-dependent amount, and
    /// those biased restarts biased the fit (truth of seed 10, noise-free 16-bit log: C +0.09 %, V_a
    /// +0.22 %, V_b +0.19 % with the fit's value, +0.002 / +0.03 / +0.02 % with the reading). The reading's
    /// noise is random, and the intervals account for it (crate::fit, the restart bootstrap).
    pub x0: Vec<f64>,
    /// Segments that follow an end-stop impact (see [`ReplayOptions::stroke_m`]): they start from the
    /// fitted velocity, not the previous segment's, so that the impact's discontinuity does not carry over.
    pub after_impact: Vec<bool>,
    /// Rows the fit compares (after each segment's settling), in order.
    pub compared: Vec<usize>,
    /// Held-out rows compared for validation only.
    pub validation: Vec<usize>,
    /// First row of the held-out part.
    pub fit_end: usize,
}

/// The simulated signals of a replay, one per row.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Prediction {
    /// Position, m.
    pub x: Vec<f64>,
    /// Chamber A pressure, Pa.
    pub p_a: Vec<f64>,
    /// Chamber B pressure, Pa.
    pub p_b: Vec<f64>,
}

impl Prepared {
    /// Cuts `log` into segments (see the module doc); rows from `fit_end` on are held out for validation
    /// (a segment boundary lies at `fit_end`; `fit_end = len - 1` holds nothing out).
    pub fn new(log: Log, o: &ReplayOptions, fit_end: usize) -> Self {
        let n = log.len();
        let mut fit_end = fit_end.clamp(1, n - 1);
        // The held-out part starts from a measurement too.
        while fit_end < n - 1 && !log.measured[fit_end] {
            fit_end += 1;
        }
        let dt = log.dt().max(1e-9);
        let per = ((o.segment_s / dt).round() as usize).max(2);
        let settle = (o.settle_s / dt).round() as usize;
        let mut segments = Vec::new();
        for (a, b) in [(0, fit_end), (fit_end, n - 1)] {
            let mut s = a;
            while s < b {
                let mut e = (s + per).min(b);
                // A short tail joins the previous segment.
                if b - e < per / 4 {
                    e = b;
                }
                // A segment starts from a measurement (on the board's grid a sample the host did not
                // read is no start): the boundary moves on to the next measured row.
                while e < b && !log.measured[e] {
                    e += 1;
                }
                segments.push((s, e));
                s = e;
            }
        }
        let fits: Vec<[f64; 2]> = segments
            .iter()
            .map(|&(s, _)| local_fit(&log.t, &log.x, &log.measured, s, o.velocity_half_window))
            .collect();
        let v0 = fits.iter().map(|f| f[1]).collect();
        let x0 = segments.iter().map(|&(s, _)| log.x[s]).collect();
        let near_stop = |x: f64| {
            o.stroke_m
                .is_some_and(|l| x < o.stop_band_m || x > l - o.stop_band_m)
        };
        let impact = |s: usize, e: usize| {
            let n = (s..=e).filter(|&k| near_stop(log.x[k])).count();
            n > 0 && n < e - s + 1
        };
        let after_impact: Vec<bool> = (0..segments.len())
            .map(|i| i > 0 && impact(segments[i - 1].0, segments[i - 1].1))
            .collect();
        // Not compared: impact segments, and the `SETTLE_AFTER_IMPACT + 1` after each (the first starts from
        // the fitted velocity, whose error under PWM needs ~0.2 s to die out, damping time m / K_v and the
        // pneumatic stiffness's).
        let skip: Vec<bool> = (0..segments.len())
            .map(|i| {
                impact(segments[i].0, segments[i].1)
                    || (i.saturating_sub(SETTLE_AFTER_IMPACT)..=i).any(|j| after_impact[j])
            })
            .collect();
        let rows = |lo: usize, hi: usize| -> Vec<usize> {
            segments
                .iter()
                .enumerate()
                .filter(|&(i, &(s, e))| s >= lo && e <= hi && !skip[i])
                .map(|(_, se)| se)
                .flat_map(|&(s, e)| (s + 1 + settle).min(e + 1)..=e)
                .filter(|&k| log.measured[k])
                .collect()
        };
        let compared = rows(0, fit_end);
        let validation = rows(fit_end, n - 1);
        Self {
            log,
            segments,
            v0,
            x0,
            after_impact,
            compared,
            validation,
            fit_end,
        }
    }

    /// Compared fit rows per segment of the fit part, in the order of `compared` (the clusters of the
    /// interval estimate: errors of a segment's start state are shared by its rows).
    pub fn fit_clusters(&self) -> Vec<usize> {
        self.segments
            .iter()
            .filter(|&&(_, e)| e <= self.fit_end)
            .map(|&(s, e)| self.compared.iter().filter(|&&k| k > s && k <= e).count())
            .filter(|&n| n > 0)
            .collect()
    }

    /// Replays the log through `model` with sensor offsets `off` (measured = true + offset), up to row
    /// `upto` (the segments starting before it; rows after it stay NaN).
    pub fn replay(
        &self,
        model: &OneDofModel,
        off: &Offsets,
        o: &ReplayOptions,
        upto: usize,
    ) -> Prediction {
        let l = &self.log;
        let n = l.len();
        let mut out = Prediction {
            x: vec![f64::NAN; n],
            p_a: vec![f64::NAN; n],
            p_b: vec![f64::NAN; n],
        };
        let t_gas = model.actuator.supply.atmosphere_temperature_k;
        let (mut t_a, mut t_b) = (t_gas, t_gas);
        let mut p_end: Option<(f64, f64)> = None;
        let mut valve = ValveState::default();
        let mut extra = ExtendedState::default();
        let mut v_end = None;
        let sub = u32::try_from(o.substeps.max(1)).unwrap_or(u32::MAX);
        // G_alpha of eq. (1), once for the replay rather than at every step.
        let gravity_n = model.mechanics.gravity_force();
        for (seg, &(s, e)) in self.segments.iter().enumerate() {
            if s >= upto {
                break;
            }
            let carry_pressures = p_end.is_some() && !o.reset_pressures && !self.after_impact[seg];
            let mut st = OneDofState {
                t: l.t[s],
                x: self.x0[seg] - off.x,
                // The previous segment's velocity when there is one (see `ReplayOptions::carry_velocity`).
                x_dot: match v_end {
                    Some(v) if o.carry_velocity && !self.after_impact[seg] => v,
                    _ => self.v0[seg],
                },
                chambers: {
                    let (p_a, p_b) = match p_end {
                        Some(p) if carry_pressures => p,
                        _ => (l.p_a[s] - off.p_a, l.p_b[s] - off.p_b),
                    };
                    ChamberState { p_a, p_b, t_a, t_b }
                },
                valve,
                // The lines' gas (not measured) carries over like the temperatures (the first segment's
                // starts at its chambers'); LuGre's bristles carry over except after an impact.
                extra: ExtendedState {
                    lines: extra.lines,
                    bristle_m: if self.after_impact[seg] {
                        0.0
                    } else {
                        extra.bristle_m
                    },
                },
            };
            out.x[s] = st.x + off.x;
            out.p_a[s] = st.chambers.p_a + off.p_a;
            out.p_b[s] = st.chambers.p_b + off.p_b;
            for k in s..e {
                let t_end = l.t[k + 1];
                // `sub` substeps of the log's period (the chamber constants and the spool held between
                // them: OneDofModel::advance), the contact force interpolated inside the period.
                let mut i = 0u32;
                model.advance(&mut st, l.u[k], gravity_n, t_end - l.t[k], sub, |_| {
                    let w = (f64::from(i) + 0.5) / f64::from(sub);
                    i += 1;
                    -(l.f_e[k] + w * (l.f_e[k + 1] - l.f_e[k]))
                });
                // No drift of the model's clock against the log's.
                st.t = t_end;
                out.x[k + 1] = st.x + off.x;
                out.p_a[k + 1] = st.chambers.p_a + off.p_a;
                out.p_b[k + 1] = st.chambers.p_b + off.p_b;
            }
            t_a = st.chambers.t_a;
            t_b = st.chambers.t_b;
            valve = st.valve;
            extra = st.extra;
            v_end = Some(st.x_dot);
            p_end = Some((st.chambers.p_a, st.chambers.p_b));
        }
        out
    }
}

/// Value and slope at row `c` of a least-squares quadratic through the measured rows of `[c - w, c + w]`
/// (clipped to the log). A quadratic, not a line: under PWM the piston oscillates at the carrier frequency,
/// and a line over a good part of a period would average the velocity away.
pub(crate) fn local_fit(t: &[f64], y: &[f64], measured: &[bool], c: usize, w: usize) -> [f64; 2] {
    let a = c.saturating_sub(w);
    let b = (c + w).min(t.len() - 1);
    let rows: Vec<usize> = (a..=b).filter(|&i| measured[i]).collect();
    if rows.len() < 3 {
        let v = match (rows.first(), rows.last()) {
            (Some(&a), Some(&b)) if b > a => (y[b] - y[a]) / (t[b] - t[a]),
            _ => 0.0,
        };
        return [y[c], v];
    }
    // Normal equations of y = c0 + c1 s + c2 s^2 in s = t - t[c]; the slope at c is c1.
    let mut m = [[0.0f64; 3]; 3];
    let mut r = [0.0f64; 3];
    for i in rows {
        let s = t[i] - t[c];
        let p = [1.0, s, s * s];
        for (j, pj) in p.iter().enumerate() {
            for (k, pk) in p.iter().enumerate() {
                m[j][k] += pj * pk;
            }
            r[j] += pj * y[i];
        }
    }
    solve3(m, r).map_or([y[c], 0.0], |k| [k[0], k[1]])
}

/// Solves a 3x3 linear system by Cramer's rule; `None` when singular.
fn solve3(m: [[f64; 3]; 3], r: [f64; 3]) -> Option<[f64; 3]> {
    let det = |m: &[[f64; 3]; 3]| {
        m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
            - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
    };
    let d = det(&m);
    if d.abs() < 1e-300 {
        return None;
    }
    let mut out = [0.0; 3];
    for (j, o) in out.iter_mut().enumerate() {
        let mut mj = m;
        for i in 0..3 {
            mj[i][j] = r[i];
        }
        *o = det(&mj) / d;
    }
    Some(out)
}
