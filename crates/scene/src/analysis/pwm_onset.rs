//! The limit-cycle onset of an inner loop on an on/off valve under PWM, from a sampled-data model of the
//! PWM rather than its period average: the valve latches the duty d = (1 + u)/2 at the start of each PWM
//! period and holds it for the period, each edge reaching the spool the switching delay later (the
//! simulation's `ValveKind::OnOffPwm`). The period average of the flows is kept (a valve open both ways
//! at the centre, `Linearisable::hold_switching`); the hold and the delay are modelled exactly.
//!
//! The plant is linearised over one control tick, s[k+1] = Φ s[k] + Γ v[k] (v the duty the spool sees),
//! and joined with the inner PID as `pneuflex_control::Pid` computes it (loop_margins.rs, C_y(z)): state
//! z = [s, I, d, x₋₁, u_prev, u_held]. Per tick: d ← (1−α) d + α (x − x₋₁)/dt, u = −kp x + I − kd d,
//! at a period start u_prev ← u_held and u_held ← u, the plant sees u_prev for the ticks of the switching
//! delay and u_held after, I ← I − ki dt x. The map over a whole number of PWM periods (the latch ticks
//! repeat) is the monodromy M; the loop oscillates when M has an eigenvalue on or outside the unit circle.
//! The onset is the kp (ki, kd as in the scene) above the run's at which its spectral radius reaches 1, and the
//! oscillation's frequency is that eigenvalue's angle over the window (aliased into ± half the window's
//! rate, which the PWM rate bounds).

use nalgebra::DMatrix;

use super::loop_margins::{linearise_secant, settle};
use super::outer_law::{OuterLaw, Outputs};
use crate::SceneError;
use crate::plants::Linearisable;
use crate::schema::plant::linearisable_at;
use crate::schema::{RunSpec, Scene};

/// The sampled-data onset at one stiffness.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct PwmOnset {
    /// The smallest kp whose loop is not asymptotically stable, 1/m.
    pub kp_per_m: f64,
    /// The frequency of the oscillation there, Hz (the critical eigenvalue's angle over the window).
    pub frequency_hz: f64,
    /// The PWM period and the switching delay the model holds the duty over, s.
    pub pwm_period_s: f64,
    /// See `pwm_period_s`.
    pub switching_delay_s: f64,
}

/// The ticks of one window of whole PWM periods: for each, whether the duty is latched there and whether
/// the spool still sees the previous duty (inside the switching delay).
fn latch_pattern(dt: f64, period: f64, delay: f64) -> Vec<(bool, bool)> {
    // The fewest periods (up to 10) that span a whole number of ticks, nearest.
    let ratio = period / dt;
    let periods = (1..=10)
        .min_by(|&a, &b| {
            let e = |p: i32| (f64::from(p) * ratio - (f64::from(p) * ratio).round()).abs();
            e(a).total_cmp(&e(b))
        })
        .unwrap_or(1);
    let ticks = (f64::from(periods) * ratio).round().max(1.0) as usize;
    let mut last_latch = 0.0;
    (0..ticks)
        .map(|j| {
            let t = j as f64 * dt;
            // A period starts in this tick's step: the tick's command is latched.
            let latch = j == 0
                || ((t + 1e-9 * dt) / period).floor() > ((t - dt + 1e-9 * dt) / period).floor();
            if latch {
                last_latch = (((t + 1e-9 * dt) / period).floor()) * period;
            }
            (latch, t + dt - last_latch <= delay + 1e-9 * dt)
        })
        .collect()
}

/// The monodromy of the inner loop over one latch window, for `pid` on the tick linearisation (Φ, Γ);
/// with `outer` the loop also holds the controller around the PID (the impedance filter and the adaptive
/// law, [`OuterLaw`]): its x_r replaces the constant reference and its states follow the PWM's.
pub(crate) fn monodromy(
    phi: &[Vec<f64>],
    gamma: &[f64],
    pid: &pneuflex_control::PidParams,
    dt: f64,
    pattern: &[(bool, bool)],
    outer: Option<(&OuterLaw, &Outputs)>,
) -> DMatrix<f64> {
    let n = gamma.len();
    let (i_i, i_d, i_x, i_prev, i_held, i_o) = (n, n + 1, n + 2, n + 3, n + 4, n + 5);
    let m = n + 5 + if outer.is_some() { OuterLaw::STATES } else { 0 };
    let alpha = dt / (pid.derivative_filter_s + dt);
    let tick = |z: &[f64], latch: bool, in_delay: bool| -> Vec<f64> {
        let x = z[0];
        let d = (1.0 - alpha) * z[i_d] + alpha * (x - z[i_x]) / dt;
        let (x_r, o_next) = match outer {
            Some((o, out)) => {
                let (x_r, next) = o.tick(&z[i_o..], &z[..n], out);
                (x_r, Some(next))
            }
            None => (0.0, None),
        };
        let u = pid.kp_per_m * (x_r - x) + z[i_i] - pid.kd_s_per_m * d;
        let (prev, held) = if latch {
            (z[i_held], u)
        } else {
            (z[i_prev], z[i_held])
        };
        let v = if in_delay { prev } else { held };
        let mut out = vec![0.0; m];
        for (r, row) in phi.iter().enumerate() {
            out[r] = row.iter().zip(z).map(|(a, b)| a * b).sum::<f64>() + gamma[r] * v;
        }
        // Without integral action I is a constant the loop never moves (an eigenvalue 1 that is no
        // oscillation): held at 0.
        out[i_i] = if pid.ki_per_m_s == 0.0 {
            0.0
        } else {
            z[i_i] + pid.ki_per_m_s * dt * (x_r - x)
        };
        out[i_d] = d;
        out[i_x] = x;
        out[i_prev] = prev;
        out[i_held] = held;
        if let Some(next) = o_next {
            out[i_o..].copy_from_slice(&next);
        }
        out
    };
    // The map is linear: its columns are the images of the unit vectors, tick after tick.
    let mut cols: Vec<Vec<f64>> = (0..m)
        .map(|j| {
            let mut e = vec![0.0; m];
            e[j] = 1.0;
            e
        })
        .collect();
    for &(latch, in_delay) in pattern {
        for c in &mut cols {
            *c = tick(c, latch, in_delay);
        }
    }
    DMatrix::from_fn(m, m, |r, c| cols[c][r])
}

/// The eigenvalue of largest modulus: (modulus, angle in rad). A map with a non-finite entry (a plant
/// linearised at an absurd stiffness), or whose Schur iteration does not converge, has no eigenvalues to
/// trust: it counts as unstable (modulus ∞), so the search ends instead of iterating forever on NaN.
pub(crate) fn critical(m: &DMatrix<f64>) -> (f64, f64) {
    if m.iter().any(|v| !v.is_finite()) {
        return (f64::INFINITY, 0.0);
    }
    let Some(schur) = m.clone().try_schur(f64::EPSILON, 10_000) else {
        return (f64::INFINITY, 0.0);
    };
    schur
        .complex_eigenvalues()
        .iter()
        .map(|l| (l.norm(), l.arg().abs()))
        .max_by(|a, b| a.0.total_cmp(&b.0))
        .unwrap_or((0.0, 0.0))
}

/// The sampled-data onset of run `run` at stiffness `k_e`, on a plant with a switching valve: the upper
/// edge of the band of stable kp that holds (or is nearest below) the run's kp. None for a valve that
/// does not switch, or when no edge lies within 1000× of the run's kp either way.
pub fn pwm_onset<P: Linearisable + ?Sized>(
    plant: &mut P,
    scene: &Scene,
    run: &RunSpec,
    k_e: f64,
    outer: Option<&OuterLaw>,
) -> Option<PwmOnset> {
    let dt = scene.dt_s;
    let (period, delay) = plant.hold_switching()?;
    plant.without_coulomb_friction();
    let u_op = settle(plant, scene, &run.inner, k_e);
    let (phi, gamma) = linearise_secant(plant, u_op, 1e-4, dt);
    let outputs = Outputs::of(plant);
    let outer = outer
        .filter(|_| !outputs.no_contact())
        .map(|o| (o, &outputs));
    let pattern = latch_pattern(dt, period, delay);
    let window_s = pattern.len() as f64 * dt;
    let at = |kp: f64| {
        let pid = pneuflex_control::PidParams {
            kp_per_m: kp,
            ..run.inner
        };
        critical(&monodromy(&phi, &gamma, &pid, dt, &pattern, outer))
    };
    // The stable band of kp (ki, kd as in the scene) around the run's own kp, and its upper edge: below
    // it a fixed ki dominates and the loop can be unstable too, so the scan starts at the run's kp — up
    // while stable, or down to the band when the run's kp is already past the edge.
    let kp0 = run.inner.kp_per_m.max(1e-6);
    let (hi, angle) = stability_edge(&at, kp0)?;
    Some(PwmOnset {
        kp_per_m: hi,
        frequency_hz: angle / (std::f64::consts::TAU * window_s),
        pwm_period_s: period,
        switching_delay_s: delay,
    })
}

/// The upper edge of the band of stable kp that holds (or is nearest below) `kp0`, for `at` giving the
/// spectral radius and the critical eigenvalue's angle at a kp: (kp, angle there). None when no edge lies
/// within 1000× of `kp0` either way.
pub(crate) fn stability_edge(at: &dyn Fn(f64) -> (f64, f64), kp0: f64) -> Option<(f64, f64)> {
    let stable = |kp: f64| at(kp).0 < 1.0;
    let (mut lo, mut hi) = if stable(kp0) {
        let mut k = kp0;
        while stable(k * 1.1) {
            k *= 1.1;
            if k > 1000.0 * kp0 {
                return None;
            }
        }
        (k, k * 1.1)
    } else {
        let mut k = kp0;
        while !stable(k / 1.1) {
            k /= 1.1;
            if k < 1e-3 * kp0 {
                return None;
            }
        }
        (k / 1.1, k)
    };
    for _ in 0..50 {
        let mid = 0.5 * (lo + hi);
        if stable(mid) { lo = mid } else { hi = mid }
    }
    Some((hi, at(hi).1))
}

/// [`pwm_onset`] of run `index` at stiffness `k_e` on the scene's plant; None for a plant whose valve
/// does not switch (a proportional valve, the linear and ideal plants; the multibody rig is not analysed).
pub fn pwm_onset_at(scene: &Scene, index: usize, k_e: f64) -> Result<Option<PwmOnset>, SceneError> {
    Ok(linearisable_at(scene, k_e)?
        .and_then(|mut p| pwm_onset(&mut *p, scene, &scene.runs[index], k_e, None)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_latch_pattern_holds_whole_periods_and_the_delay() {
        // 40 Hz at 1 ms: one latch every 25 ticks, the first 5 ticks of each inside a 5 ms delay.
        let p = latch_pattern(1e-3, 0.025, 0.005);
        assert_eq!(p.len(), 25);
        assert!(p[0].0 && p[1..].iter().all(|t| !t.0));
        assert_eq!(p.iter().filter(|t| t.1).count(), 5);
        assert!(p[..5].iter().all(|t| t.1));
        // 30 Hz at 1 ms: three periods span 100 ticks, latched at 0, 34, 67.
        let p = latch_pattern(1e-3, 1.0 / 30.0, 0.0);
        assert_eq!(p.len(), 100);
        let latches: Vec<usize> = (0..100).filter(|&j| p[j].0).collect();
        assert_eq!(latches, [0, 34, 67]);
    }

    #[test]
    fn a_held_proportional_loop_matches_the_closed_form_of_its_sampled_gain() {
        // A pure integrator x' = K v (Φ = 1, Γ = K dt) under P control, the duty held for N ticks:
        // over a period x ← (1 − kp K N dt) x, unstable from kp = 2 / (K N dt).
        let (k, dt, n) = (0.5, 1e-3, 25usize);
        let pattern: Vec<(bool, bool)> = (0..n).map(|j| (j == 0, false)).collect();
        let pid = pneuflex_control::PidParams {
            kp_per_m: 0.0,
            ki_per_m_s: 0.0,
            kd_s_per_m: 0.0,
            ..pneuflex_control::PidParams::default()
        };
        let radius = |kp: f64| {
            let pid = pneuflex_control::PidParams {
                kp_per_m: kp,
                ..pid
            };
            critical(&monodromy(
                &[vec![1.0]],
                &[k * dt],
                &pid,
                dt,
                &pattern,
                None,
            ))
            .0
        };
        let onset = 2.0 / (k * n as f64 * dt);
        assert!(radius(0.99 * onset) < 1.0 && radius(1.01 * onset) > 1.0);
        // The derivative filter's state decays by (1 − α)^N a window whatever kp (kd = 0 here).
        let alpha = dt / (pid.derivative_filter_s + dt);
        let filter = (1.0 - alpha).powi(n as i32);
        for a in [0.3_f64, 0.9, 1.2, 1.7] {
            let want = (1.0 - a).abs().max(filter);
            assert!(
                (radius(a / (k * n as f64 * dt)) - want).abs() < 1e-9,
                "a = {a}"
            );
        }
        // A delay of the whole period adds a period of lag: x_{k+1} = x_k − a x_{k−1} (a = kp K N dt),
        // whose roots have modulus √a for a > 1/4: unstable from a = 1.
        let delayed: Vec<(bool, bool)> = (0..n).map(|j| (j == 0, true)).collect();
        let radius = |kp: f64| {
            let pid = pneuflex_control::PidParams {
                kp_per_m: kp,
                ..pid
            };
            critical(&monodromy(
                &[vec![1.0]],
                &[k * dt],
                &pid,
                dt,
                &delayed,
                None,
            ))
            .0
        };
        for a in [0.5_f64, 0.99, 1.01, 1.5] {
            let want = a.sqrt().max(filter);
            assert!(
                (radius(a / (k * n as f64 * dt)) - want).abs() < 1e-9,
                "delayed, a = {a}"
            );
        }
    }
}
