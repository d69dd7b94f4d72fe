//! The limit-cycle onset of an inner loop on an on/off valve under PWM, from a sampled-data model of the
//! PWM rather than its period average: the valve latches the duty d = (1 + u)/2 at the start of each PWM
//! period and holds it for the period, each edge reaching the spool the switching delay later (the
//! simulation's `ValveKind::OnOffPwm`).
//!
//! The plant is the switching one, linearised tick by tick about its periodic orbit (the ripple of the
//! duty held at the operating point, [`Orbit`]): s[k+1] = Φ_k s[k] + γ_k v_held + γ'_k v_prev, v_held the
//! duty latched at the start of the tick's period and v_prev the previous period's (the spool still sees
//! it for the switching delay). A change of the duty moves the spool's edge, so γ_k is the jump of the
//! flows across the edge, in the tick that holds it and at the pressures the ripple has there. (The
//! period-averaged flows spread it over the period at the mean pressures: on paper-fig3 at kp 25 they miss
//! the response to a step of x by 54 % over six periods, the orbit by 0.02 %; the 63 mm rig's flip at half
//! the PWM rate they put at 89 /m, the simulation at 38, the orbit at 35.)
//!
//! Joined with the inner PID as `pneuflex_control::Pid` computes it (loop_margins.rs, C_y(z)): state
//! z = [s, I, d, x₋₁, u_prev, u_held]. Per tick: d ← (1−α) d + α (x − x₋₁)/dt, u = −kp x + I − kd d,
//! at a period start u_prev ← u_held and u_held ← u, I ← I − ki dt x. The map over a whole number of PWM
//! periods (the latch ticks repeat) is the monodromy M; the loop oscillates when M has an eigenvalue on or
//! outside the unit circle. The onset is the kp (ki, kd as in the scene) above the run's at which its
//! spectral radius reaches 1, and the oscillation's frequency is that eigenvalue's angle over the window
//! (aliased into ± half the window's rate, which the PWM rate bounds: −1, the flip of the latched duty
//! from period to period, is half the PWM rate).

use nalgebra::DMatrix;

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

/// One control tick of the plant, linearised: s' = Φ s + Γ_held v_held + Γ_prev v_prev, v_held the duty
/// latched at the start of the tick's PWM period and v_prev the previous period's; `latch` when a period
/// starts in this tick (the tick's command is latched).
#[derive(Clone, Debug)]
pub(crate) struct TickMap {
    pub phi: Vec<Vec<f64>>,
    pub held: Vec<f64>,
    pub prev: Vec<f64>,
    pub latch: bool,
}

/// The ticks of a window for one linearisation (Φ, Γ) of a plant whose duty acts through its held flows:
/// Γ on the held duty, or on the previous one inside the switching delay (`pattern`, [`latch_pattern`]).
pub(crate) fn held_ticks(
    phi: &[Vec<f64>],
    gamma: &[f64],
    pattern: &[(bool, bool)],
) -> Vec<TickMap> {
    let zero = vec![0.0; gamma.len()];
    pattern
        .iter()
        .map(|&(latch, in_delay)| TickMap {
            phi: phi.to_vec(),
            held: if in_delay {
                zero.clone()
            } else {
                gamma.to_vec()
            },
            prev: if in_delay {
                gamma.to_vec()
            } else {
                zero.clone()
            },
            latch,
        })
        .collect()
}

/// The monodromy of the inner loop over one latch window of `ticks`, for `pid`; with `outer` the loop
/// also holds the controller around the PID (the impedance filter and the adaptive law, [`OuterLaw`]):
/// its x_r replaces the constant reference and its states follow the PWM's.
pub(crate) fn monodromy(
    ticks: &[TickMap],
    pid: &pneuflex_control::PidParams,
    dt: f64,
    outer: Option<(&OuterLaw, &Outputs)>,
) -> DMatrix<f64> {
    let n = ticks.first().map_or(0, |t| t.held.len());
    let (i_i, i_d, i_x, i_prev, i_held, i_o) = (n, n + 1, n + 2, n + 3, n + 4, n + 5);
    let m = n + 5 + if outer.is_some() { OuterLaw::STATES } else { 0 };
    let alpha = dt / (pid.derivative_filter_s + dt);
    let tick = |z: &[f64], t: &TickMap| -> Vec<f64> {
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
        let (prev, held) = if t.latch {
            (z[i_held], u)
        } else {
            (z[i_prev], z[i_held])
        };
        let mut out = vec![0.0; m];
        for (r, row) in t.phi.iter().enumerate() {
            out[r] = row.iter().zip(z).map(|(a, b)| a * b).sum::<f64>()
                + t.held[r] * held
                + t.prev[r] * prev;
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
    for t in ticks {
        for c in &mut cols {
            *c = tick(c, t);
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
/// does not switch, when no PID holds the contact still ([`Orbit::of`]), or when no edge lies within
/// 1000× of the run's kp either way.
pub fn pwm_onset<P: Linearisable + ?Sized>(
    plant: &mut P,
    scene: &Scene,
    run: &RunSpec,
    k_e: f64,
    outer: Option<&OuterLaw>,
) -> Option<PwmOnset> {
    let dt = scene.dt_s;
    let (period, delay) = plant.boxed_clone().hold_switching()?;
    plant.without_coulomb_friction();
    let pattern = latch_pattern(dt, period, delay);
    let Orbit { ticks, start, .. } = Orbit::of(plant, scene, run, k_e, &pattern)?;
    let outputs = Outputs::of(&mut *start.boxed_clone());
    let outer = outer
        .filter(|_| !outputs.no_contact())
        .map(|o| (o, &outputs));
    let window_s = pattern.len() as f64 * dt;
    let at = |kp: f64| {
        let pid = pneuflex_control::PidParams {
            kp_per_m: kp,
            ..run.inner
        };
        critical(&monodromy(&ticks, &pid, dt, outer))
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

/// The switching plant linearised tick by tick about its periodic orbit (its PWM ripple) over one window
/// of whole PWM periods, and where the orbit starts.
pub(crate) struct Orbit {
    /// Each tick's map (see [`Orbit::of`]).
    pub ticks: Vec<TickMap>,
    /// The plant at the window's start (a latch tick).
    pub start: Box<dyn Linearisable>,
    /// The inner PID that holds it there (the run's, or at a fraction of its kp) and the position it holds,
    /// m: what a check of the maps against the switching plant continues from.
    #[allow(dead_code)]
    pub pid: pneuflex_control::Pid,
    #[allow(dead_code)]
    pub x_op: f64,
}

impl Orbit {
    /// The orbit of `plant` (a switching valve) in contact at stiffness `k_e`: the inner PID at the run's
    /// gains holds the scene's first reference force for 2 s (a whole number of windows of `pattern`, so
    /// the next tick latches), at half its kp again while the window does not repeat (x back within 2 % of
    /// its ripple, the run's kp past the inner loop's edge), up to three times. Over the next window each
    /// tick's Φ_j comes from central differences of the plant's own step from the orbit's state, and the
    /// duty's inputs from the orbit's sensitivity to the command latched at each period start:
    /// S_{k+1} = Φ_k S_k + γ_k gives γ_k, on the held duty up to the next latch and on the previous duty
    /// through the next period's switching delay. A duty change moves the spool's edge, so γ_k is the jump
    /// of the flows across the edge in the tick that holds it, with the pressures the ripple has there;
    /// the period-averaged model spreads it over the period at the mean pressures. None when no kp holds
    /// the contact still (a non-finite state, or no window repeats).
    pub fn of<P: Linearisable + ?Sized>(
        plant: &P,
        scene: &Scene,
        run: &RunSpec,
        k_e: f64,
        pattern: &[(bool, bool)],
    ) -> Option<Self> {
        let dt = scene.dt_s;
        let n_w = pattern.len();
        let f_op = scene.setpoints().map(|sp| sp.at(0.0).f_ref).unwrap_or(0.0);
        let x_op = scene.environment.x_e_m + if k_e > 0.0 { f_op / k_e } else { 0.0 };
        let act = |p: &mut dyn Linearisable, u: f64| {
            p.actuate(
                pneuflex_control::ValveCommand { u },
                &pneuflex_control::Telemetry::default(),
            );
            p.advance(dt);
        };
        let windows = ((2.0 / dt) / n_w as f64).ceil() as usize;
        // The orbit over one window: each tick's plant and command.
        let mut settled = None;
        for halvings in 0..4 {
            let gains = pneuflex_control::PidParams {
                kp_per_m: run.inner.kp_per_m * 0.5_f64.powi(halvings),
                ..run.inner
            };
            let mut c = pneuflex_control::Pid::new(gains).ok()?;
            let mut p: Box<dyn Linearisable> = plant.boxed_clone();
            for _ in 0..windows * n_w {
                let u = c.update(x_op, p.sense().x, dt);
                act(&mut *p, u);
            }
            let (start, pid) = (p.boxed_clone(), c);
            let mut orbit: Vec<(Box<dyn Linearisable>, f64)> = Vec::with_capacity(n_w);
            for _ in 0..n_w {
                let u = c.update(x_op, p.sense().x, dt);
                orbit.push((p.boxed_clone(), u));
                act(&mut *p, u);
            }
            let xs: Vec<f64> = orbit.iter().map(|o| o.0.sense().x).collect();
            let ripple = xs.iter().cloned().fold(f64::MIN, f64::max)
                - xs.iter().cloned().fold(f64::MAX, f64::min);
            let drift = (p.sense().x - xs[0]).abs();
            if p.state_vector().iter().all(|v| v.is_finite()) && drift <= 0.02 * ripple + 1e-7 {
                settled = Some((orbit, start, pid));
                break;
            }
        }
        let (orbit, start, pid) = settled?;
        let scales = orbit[0].0.perturbation_scales();
        let n = scales.len();
        let step_from = |base: &dyn Linearisable, s: &[f64], u: f64| -> Vec<f64> {
            let mut q = base.boxed_clone();
            q.set_state_vector(s);
            act(&mut *q, u);
            q.state_vector()
        };
        let phis: Vec<Vec<Vec<f64>>> = orbit
            .iter()
            .map(|(base, u)| {
                let s0 = base.state_vector();
                let mut phi = vec![vec![0.0; n]; n];
                for j in 0..n {
                    let h = scales[j];
                    let (mut a, mut b) = (s0.clone(), s0.clone());
                    a[j] += h;
                    b[j] -= h;
                    let (fa, fb) = (step_from(&**base, &a, *u), step_from(&**base, &b, *u));
                    for (i, row) in phi.iter_mut().enumerate() {
                        row[j] = (fa[i] - fb[i]) / (2.0 * h);
                    }
                }
                phi
            })
            .collect();
        let mut ticks: Vec<TickMap> = pattern
            .iter()
            .zip(&phis)
            .map(|(&(latch, _), phi)| TickMap {
                phi: phi.clone(),
                held: vec![0.0; n],
                prev: vec![0.0; n],
                latch,
            })
            .collect();
        // A duty step of 0.1 % of the command's range moves the edge by 0.05 % of the period.
        let hu = 1e-3;
        let latches: Vec<usize> = (0..n_w).filter(|&j| pattern[j].0).collect();
        for (li, &l) in latches.iter().enumerate() {
            // The next latch (in the next window for the last) and the ticks of its switching delay.
            let l2 = latches.get(li + 1).copied().unwrap_or(n_w + latches[0]);
            let delay_ticks = (0..n_w).take_while(|&i| pattern[(l2 + i) % n_w].1).count();
            let end = l2 + delay_ticks.max(1);
            let run_from = |du: f64| -> Vec<Vec<f64>> {
                let mut q = orbit[l].0.boxed_clone();
                let mut out = vec![q.state_vector()];
                for k in l..end {
                    let u = orbit[k % n_w].1 + if k == l { du } else { 0.0 };
                    act(&mut *q, u);
                    out.push(q.state_vector());
                }
                out
            };
            let (a, b) = (run_from(hu), run_from(-hu));
            let sens: Vec<Vec<f64>> = a
                .iter()
                .zip(&b)
                .map(|(a, b)| a.iter().zip(b).map(|(a, b)| (a - b) / (2.0 * hu)).collect())
                .collect();
            for k in l..end {
                let phi = &phis[k % n_w];
                let (s, s1) = (&sens[k - l], &sens[k + 1 - l]);
                let g: Vec<f64> = (0..n)
                    .map(|i| s1[i] - phi[i].iter().zip(s).map(|(a, b)| a * b).sum::<f64>())
                    .collect();
                let t = &mut ticks[k % n_w];
                if k < l2 {
                    t.held = g;
                } else {
                    t.prev = g;
                }
            }
        }
        Some(Self {
            ticks,
            start,
            pid,
            x_op,
        })
    }
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
                &held_ticks(&[vec![1.0]], &[k * dt], &pattern),
                &pid,
                dt,
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
                &held_ticks(&[vec![1.0]], &[k * dt], &delayed),
                &pid,
                dt,
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

    #[test]
    fn the_orbits_tick_maps_follow_the_switching_plant_over_six_windows() {
        // paper-fig3's PWM plant in contact at 1400 N/m, the inner PID at kp 25 (its onset is near 30): a
        // 20 µm step of x at a latch tick, followed on the switching plant with its PID, against the
        // monodromy's prediction window by window; the period-averaged linearisation for comparison.
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
        let scene = Scene::load(&root.join("scenes/paper-fig3.toml")).unwrap();
        let (dt, k_e) = (scene.dt_s, 1400.0);
        let mut run = scene.runs[scene.run_index("impedance").unwrap()].clone();
        run.inner.kp_per_m = 25.0;
        let mut plant = linearisable_at(&scene, k_e).unwrap().unwrap();
        plant.without_coulomb_friction();
        let (period, delay) = plant.boxed_clone().hold_switching().unwrap();
        let pattern = latch_pattern(dt, period, delay);
        let o = Orbit::of(&*plant, &scene, &run, k_e, &pattern).unwrap();
        assert_eq!(o.pid.params().kp_per_m, 25.0, "settled at the run's kp");
        let follow = |dx: f64| -> Vec<f64> {
            let (mut p, mut c) = (o.start.boxed_clone(), o.pid);
            let mut s = p.state_vector();
            s[0] += dx;
            p.set_state_vector(&s);
            let mut xs = Vec::new();
            for _ in 0..6 {
                for _ in 0..pattern.len() {
                    let u = c.update(o.x_op, p.sense().x, dt);
                    p.actuate(
                        pneuflex_control::ValveCommand { u },
                        &pneuflex_control::Telemetry::default(),
                    );
                    p.advance(dt);
                }
                xs.push(p.sense().x);
            }
            xs
        };
        let dx = 2e-5;
        let (a, b) = (follow(dx), follow(0.0));
        let truth: Vec<f64> = a.iter().zip(&b).map(|(a, b)| a - b).collect();
        let predict = |ticks: &[TickMap]| -> Vec<f64> {
            let m = monodromy(ticks, &run.inner, dt, None);
            let mut z = nalgebra::DVector::zeros(m.nrows());
            z[0] = dx;
            (0..6)
                .map(|_| {
                    z = &m * &z;
                    z[0]
                })
                .collect()
        };
        let worst = |p: &[f64]| {
            let scale = truth.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
            p.iter()
                .zip(&truth)
                .fold(0.0_f64, |m, (p, t)| m.max((p - t).abs()))
                / scale
        };
        let orbit = worst(&predict(&o.ticks));
        // The period-averaged model as it was (its own operating point, settled on the held flows).
        let mut held = plant.boxed_clone();
        held.hold_switching();
        let u_op = super::super::loop_margins::settle(&mut *held, &scene, &run.inner, k_e);
        let (phi, gamma) = super::super::loop_margins::linearise_secant(&mut *held, u_op, 1e-4, dt);
        let averaged = worst(&predict(&held_ticks(&phi, &gamma, &pattern)));
        eprintln!("truth {truth:?}; worst error: orbit {orbit:.4}, period average {averaged:.4}");
        assert!(orbit < 0.05, "orbit {orbit}");
    }
}
