//! Inner-loop design with margins: the open-loop frequency response of a run's inner position loop on the
//! scene's plant, linearised at an operating point in contact, at every environment stiffness the scene
//! meets; its gain and phase margins and crossovers, and the largest kp with a chosen gain margin.
//!
//! The plant is linearised numerically over one control tick (central differences of its own `advance`,
//! valve command held): s[k+1] = Φ s[k] + Γ u[k], x[k] = s_x[k]. The inner PID, as `pneuflex_control::Pid`
//! computes it (derivative on the measurement, backward difference and backward-Euler low-pass, integral
//! after the output), is u = -C_y(z) x with
//!     C_y(z) = kp + ki·dt/(z - 1) + kd·α(1 - z⁻¹) / (dt (1 - (1-α) z⁻¹)),  α = dt/(τ_d + dt),
//! so the loop broken at the valve command is L(z) = C_y(z) · c (zI - Φ)⁻¹ Γ, evaluated on z = e^{jωdt}.
//! A switching (PWM) valve is analysed as its average over one PWM period. Coulomb
//! friction is left out of the linearisation (see [`Linearisable::without_coulomb_friction`]).

use serde::Serialize;

use crate::error::SceneError;
use crate::plants::Linearisable;
use crate::schema::plant::linearisable_at;
use crate::schema::{EventSpec, Scene};

/// Margins of the inner loop at one environment stiffness.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Margins {
    /// Environment stiffness k_e, N/m.
    pub stiffness_n_per_m: f64,
    /// Gain crossover (|L| = 1), Hz.
    pub crossover_hz: Option<f64>,
    /// Phase margin at the gain crossover, degrees.
    pub phase_margin_deg: Option<f64>,
    /// Phase crossover (arg L = -180°), Hz.
    pub phase_crossover_hz: Option<f64>,
    /// Gain margin at the phase crossover, dB (None: the phase never reaches -180° below Nyquist).
    pub gain_margin_db: Option<f64>,
    /// Largest kp (other gains as in the scene) that keeps the gain margin at the target, 1/m.
    pub kp_max_per_m: Option<f64>,
    /// The outer force loop closed around this inner loop (impedance filter, inner loop, environment).
    pub outer: OuterMargins,
    /// The loop's frequency response: (Hz, |L| dB, arg L degrees, unwrapped).
    #[serde(skip)]
    pub bode: Vec<(f64, f64, f64)>,
}

/// Margins of the outer force loop at one stiffness: the impedance filter, the closed inner loop and the
/// environment, broken at the force (the adaptive law frozen at its start, g = p = d = 0: the impedance
/// controller's loop).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct OuterMargins {
    /// Gain crossover, Hz.
    pub crossover_hz: Option<f64>,
    /// Phase margin there, degrees.
    pub phase_margin_deg: Option<f64>,
    /// Phase crossover, Hz.
    pub phase_crossover_hz: Option<f64>,
    /// Gain margin there, dB.
    pub gain_margin_db: Option<f64>,
    /// The smallest b_d (m_d and the inner loop as in the scene) that keeps the outer gain margin at the
    /// target, N s/m (None: not within 100× the scene's).
    pub b_d_min_ns_per_m: Option<f64>,
}

/// The analysis of one run's inner loop.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct LoopAnalysis {
    /// Run name.
    pub run: String,
    /// The run's kp, 1/m.
    pub kp_per_m: f64,
    /// The gain margin the largest kp is computed for, dB.
    pub target_gain_margin_db: f64,
    /// The valve model the plant was linearised with.
    pub valve_model: String,
    /// Margins at each stiffness the scene meets (initial, then after each stiffness event).
    pub margins: Vec<Margins>,
}

#[derive(Clone, Copy, Debug)]
pub(crate) struct Cx(pub(crate) f64, pub(crate) f64);
impl Cx {
    pub(crate) fn add(self, o: Cx) -> Cx {
        Cx(self.0 + o.0, self.1 + o.1)
    }
    pub(crate) fn sub(self, o: Cx) -> Cx {
        Cx(self.0 - o.0, self.1 - o.1)
    }
    pub(crate) fn mul(self, o: Cx) -> Cx {
        Cx(self.0 * o.0 - self.1 * o.1, self.0 * o.1 + self.1 * o.0)
    }
    pub(crate) fn div(self, o: Cx) -> Cx {
        let d = o.0 * o.0 + o.1 * o.1;
        Cx(
            (self.0 * o.0 + self.1 * o.1) / d,
            (self.1 * o.0 - self.0 * o.1) / d,
        )
    }
    pub(crate) fn abs(self) -> f64 {
        self.0.hypot(self.1)
    }
    pub(crate) fn arg(self) -> f64 {
        self.1.atan2(self.0)
    }
}

/// Solves (A) w = b for complex A (n×n, row-major) by Gaussian elimination with partial pivoting.
fn solve(mut a: Vec<Vec<Cx>>, mut b: Vec<Cx>) -> Option<Vec<Cx>> {
    let n = b.len();
    for col in 0..n {
        let piv = (col..n).max_by(|&i, &j| a[i][col].abs().total_cmp(&a[j][col].abs()))?;
        if a[piv][col].abs() < 1e-300 {
            return None;
        }
        a.swap(col, piv);
        b.swap(col, piv);
        for row in col + 1..n {
            let f = a[row][col].div(a[col][col]);
            let pivot_row = a[col].clone();
            for (x, p) in a[row][col..].iter_mut().zip(&pivot_row[col..]) {
                *x = x.sub(f.mul(*p));
            }
            b[row] = b[row].sub(f.mul(b[col]));
        }
    }
    let mut x = vec![Cx(0.0, 0.0); n];
    for i in (0..n).rev() {
        let mut s = b[i];
        for k in i + 1..n {
            s = s.sub(a[i][k].mul(x[k]));
        }
        x[i] = s.div(a[i][i]);
    }
    Some(x)
}

/// One-tick linearisation (Φ, Γ) of a plant at its current state under command `u0`.
fn linearise<P: Linearisable + ?Sized>(p: &mut P, u0: f64, dt: f64) -> (Vec<Vec<f64>>, Vec<f64>) {
    linearise_secant(p, u0, 1e-4, dt)
}

/// [`linearise`] with Γ the secant over ±`hu` of the command (the valve's gain seen by an oscillation of
/// that amplitude: over an underlapped centre the small-signal gain is the larger).
pub(crate) fn linearise_secant<P: Linearisable + ?Sized>(
    p: &mut P,
    u0: f64,
    hu: f64,
    dt: f64,
) -> (Vec<Vec<f64>>, Vec<f64>) {
    let s0 = p.state_vector();
    let scales = p.perturbation_scales();
    let n = s0.len();
    let step = |p: &mut P, s: &[f64], u: f64| -> Vec<f64> {
        p.set_state_vector(s);
        p.actuate(
            pneuflex_control::ValveCommand { u },
            &pneuflex_control::Telemetry::default(),
        );
        p.advance(dt);
        p.state_vector()
    };
    let mut phi = vec![vec![0.0; n]; n];
    for j in 0..n {
        let h = scales[j];
        let (mut a, mut b) = (s0.clone(), s0.clone());
        a[j] += h;
        b[j] -= h;
        let (fa, fb) = (step(p, &a, u0), step(p, &b, u0));
        for i in 0..n {
            phi[i][j] = (fa[i] - fb[i]) / (2.0 * h);
        }
    }
    let (fa, fb) = (step(p, &s0, u0 + hu), step(p, &s0, u0 - hu));
    let gamma = (0..n).map(|i| (fa[i] - fb[i]) / (2.0 * hu)).collect();
    p.set_state_vector(&s0);
    (phi, gamma)
}

/// The PID's C_y(z) (u = -C_y x) at z.
fn pid_cy(pid: &pneuflex_control::PidParams, dt: f64, z: Cx) -> Cx {
    let one = Cx(1.0, 0.0);
    let zi = one.div(z);
    let alpha = dt / (pid.derivative_filter_s + dt);
    let integral = Cx(pid.ki_per_m_s * dt, 0.0).div(z.sub(one));
    let deriv = Cx(pid.kd_s_per_m * alpha / dt, 0.0)
        .mul(one.sub(zi))
        .div(one.sub(Cx(1.0 - alpha, 0.0).mul(zi)));
    Cx(pid.kp_per_m, 0.0).add(integral).add(deriv)
}

/// The plant's part of the loop at `freqs` (Hz): (Hz, z, the first state's response to the command,
/// e₀ᵀ(zI − Φ)⁻¹Γ); frequencies where zI − Φ is singular are left out. It does not depend on the PID, so
/// a search over kp computes it once.
fn plant_response(phi: &[Vec<f64>], gamma: &[f64], dt: f64, freqs: &[f64]) -> Vec<(f64, Cx, Cx)> {
    let n = gamma.len();
    let mut out = Vec::with_capacity(freqs.len());
    for &f in freqs {
        let w = std::f64::consts::TAU * f * dt;
        let z = Cx(w.cos(), w.sin());
        let a: Vec<Vec<Cx>> = (0..n)
            .map(|i| {
                (0..n)
                    .map(|j| {
                        let d = if i == j { z } else { Cx(0.0, 0.0) };
                        d.sub(Cx(phi[i][j], 0.0))
                    })
                    .collect()
            })
            .collect();
        let b = gamma.iter().map(|&g| Cx(g, 0.0)).collect();
        let Some(wv) = solve(a, b) else { continue };
        out.push((f, z, wv[0]));
    }
    out
}

/// Frequency response of L = C_y(z)·P(z) on a [`plant_response`]: (Hz, |L|, arg L rad) with the phase
/// unwrapped.
fn loop_response(
    plant: &[(f64, Cx, Cx)],
    pid: &pneuflex_control::PidParams,
    dt: f64,
) -> Vec<(f64, f64, f64)> {
    unwrapped(
        plant
            .iter()
            .map(|&(f, z, p)| (f, pid_cy(pid, dt, z).mul(p))),
    )
}

/// (Hz, |L|, arg L rad) of a complex response, the phase unwrapped from the lowest frequency.
pub(crate) fn unwrapped(resp: impl Iterator<Item = (f64, Cx)>) -> Vec<(f64, f64, f64)> {
    let mut out = Vec::new();
    let mut prev: Option<f64> = None;
    for (f, l) in resp {
        let mut ph = l.arg();
        if let Some(p) = prev {
            while ph - p > std::f64::consts::PI {
                ph -= std::f64::consts::TAU;
            }
            while ph - p < -std::f64::consts::PI {
                ph += std::f64::consts::TAU;
            }
        }
        prev = Some(ph);
        out.push((f, l.abs(), ph));
    }
    out
}

/// The outer force loop (eqs. 19–24) broken at the contact force: the impedance filter
/// 1/(m_d s² + b_d s + k_d) from the force error to the position reference, the inner loop closed,
/// T = C_r P / (1 + C_y P) with C_r = kp + ki·dt/(z − 1) (the PID's derivative acts on the measurement
/// only), and the environment k_e from the position to the force: L_o = k_e T / (m_d s² + b_d s + k_d),
/// s = jω (the filter's zero-order hold is exact to well under a degree below 20 Hz at 1 ms).
fn outer_response(
    plant: &[(f64, Cx, Cx)],
    pid: &pneuflex_control::PidParams,
    imp: &pneuflex_control::ImpedanceParams,
    k_e: f64,
    dt: f64,
) -> Vec<(f64, f64, f64)> {
    unwrapped(plant.iter().map(|&(f, z, p)| {
        let one = Cx(1.0, 0.0);
        let c_r = Cx(pid.kp_per_m, 0.0).add(Cx(pid.ki_per_m_s * dt, 0.0).div(z.sub(one)));
        let t = c_r.mul(p).div(one.add(pid_cy(pid, dt, z).mul(p)));
        let w = std::f64::consts::TAU * f;
        let filter = Cx(imp.k_d_n_per_m - imp.m_d_kg * w * w, imp.b_d_ns_per_m * w);
        (f, Cx(k_e, 0.0).mul(t).div(filter))
    }))
}

/// Crossovers and margins of a response.
pub(crate) fn margins_of(
    resp: &[(f64, f64, f64)],
) -> (Option<f64>, Option<f64>, Option<f64>, Option<f64>) {
    let lerp = |a: (f64, f64), b: (f64, f64), y: f64| a.0 + (b.0 - a.0) * (y - a.1) / (b.1 - a.1);
    let mut gc = None;
    let mut pm = None;
    for w in resp.windows(2) {
        let (a, b) = (w[0], w[1]);
        if a.1 >= 1.0 && b.1 < 1.0 {
            let f = lerp((a.0, a.1.ln()), (b.0, b.1.ln()), 0.0);
            let ph = a.2 + (b.2 - a.2) * (f - a.0) / (b.0 - a.0);
            gc = Some(f);
            pm = Some(180.0 + ph.to_degrees());
            break;
        }
    }
    let mut pc = None;
    let mut gm = None;
    let target = -std::f64::consts::PI;
    for w in resp.windows(2) {
        let (a, b) = (w[0], w[1]);
        if a.2 > target && b.2 <= target {
            let f = lerp((a.0, a.2), (b.0, b.2), target);
            let mag = (a.1.ln() + (b.1.ln() - a.1.ln()) * (f - a.0) / (b.0 - a.0)).exp();
            pc = Some(f);
            gm = Some(-20.0 * mag.log10());
            break;
        }
    }
    (gc, pm, pc, gm)
}

/// The loop broken at the valve command with the outer force loop closed as well (what an injection at
/// the valve measures, [`super::injection`]): u = C_r x_r − C_y x with x_r = −k_e x / (m_d s² + b_d s + k_d)
/// from the impedance filter (eqs. 19–24, its zero-order hold left out as in [`outer_response`]), so
///     L_all = P (C_y + C_r k_e / (m_d s² + b_d s + k_d)).
/// Run `index` of the scene's plant at stiffness `k_e`, linearised at the operating point of
/// [`analyse`]; (Hz, Re L, Im L) at `freqs`.
pub fn loop_at_valve(
    scene: &Scene,
    index: usize,
    k_e: f64,
    freqs: &[f64],
) -> Result<Vec<(f64, f64, f64)>, SceneError> {
    let run = &scene.runs[index];
    let Some(mut p) = linearisable_at(scene, k_e)? else {
        return Err(scene.invalid(
            "plant.kind",
            "the loop at the valve needs a plant the valve command drives continuously".into(),
        ));
    };
    let dt = scene.dt_s;
    let u = settle_at_contact(&mut *p, scene, run, k_e);
    let (phi, gamma) = linearise(&mut *p, u, dt);
    let (pidp, imp) = (&run.inner, &run.impedance);
    Ok(plant_response(&phi, &gamma, dt, freqs)
        .into_iter()
        .map(|(f, z, pz)| {
            let one = Cx(1.0, 0.0);
            let c_r = Cx(pidp.kp_per_m, 0.0).add(Cx(pidp.ki_per_m_s * dt, 0.0).div(z.sub(one)));
            let w = std::f64::consts::TAU * f;
            let filter = Cx(imp.k_d_n_per_m - imp.m_d_kg * w * w, imp.b_d_ns_per_m * w);
            let l = pz.mul(pid_cy(pidp, dt, z).add(c_r.mul(Cx(k_e, 0.0)).div(filter)));
            (f, l.0, l.1)
        })
        .collect())
}

/// The stiffnesses a scene's environment takes: the initial one, then after each stiffness event.
pub fn stiffnesses(scene: &Scene) -> Vec<f64> {
    let mut k = vec![scene.environment.stiffness_n_per_m];
    let mut events: Vec<&EventSpec> = scene.events.iter().collect();
    events.sort_by(|a, b| a.t_s().total_cmp(&b.t_s()));
    for e in events {
        if let EventSpec::Stiffness {
            stiffness_n_per_m, ..
        } = e
            && !k.contains(stiffness_n_per_m)
        {
            k.push(*stiffness_n_per_m);
        }
    }
    k
}

/// Analyses run `index`'s inner loop on the scene's plant at every stiffness the scene meets; `target_db`
/// is the gain margin the largest kp is computed for.
pub fn analyse(scene: &Scene, index: usize, target_db: f64) -> Result<LoopAnalysis, SceneError> {
    let run = &scene.runs[index];
    let mut margins = Vec::new();
    let mut valve_model = "as in the scene";
    for k_e in stiffnesses(scene) {
        let Some(mut p) = linearisable_at(scene, k_e)? else {
            return Err(scene.invalid(
                "plant.kind",
                "loop analysis needs a plant the valve command drives continuously: \"pneumatic\" \
                 with a proportional valve, or \"linear\""
                    .into(),
            ));
        };
        if p.switching() {
            p.average_switching();
            valve_model = "the on/off valve averaged over its PWM period (duty (1+u)/2, both \
                           paths open at the centre, lag = switching delay + half a period)";
        }
        let m = at_stiffness(&mut *p, scene, run, k_e, target_db);
        margins.push(m);
    }
    Ok(LoopAnalysis {
        run: run.name.clone(),
        kp_per_m: run.inner.kp_per_m,
        target_gain_margin_db: target_db,
        valve_model: valve_model.into(),
        margins,
    })
}

/// Log-spaced frequencies from 0.1 Hz to just below Nyquist.
fn frequencies(dt: f64) -> Vec<f64> {
    let (lo, hi) = (0.1_f64, 0.49 / dt);
    let n = 600;
    (0..n)
        .map(|i| lo * (hi / lo).powf(i as f64 / (n - 1) as f64))
        .collect()
}

/// The operating point of the analyses: the inner loop alone holding the position that presses the scene's
/// first reference force into the environment of stiffness `k_e`, settled for 2 s; the command it holds.
fn settle_at_contact<P: Linearisable + ?Sized>(
    p: &mut P,
    scene: &Scene,
    run: &crate::schema::RunSpec,
    k_e: f64,
) -> f64 {
    let dt = scene.dt_s;
    let f_op = scene.setpoints().map(|sp| sp.at(0.0).f_ref).unwrap_or(0.0);
    let x_op = scene.environment.x_e_m + if k_e > 0.0 { f_op / k_e } else { 0.0 };
    let mut pid = pneuflex_control::Pid::new(run.inner).expect("validated with the scene");
    let mut u = 0.0;
    for _ in 0..(2.0 / dt).round() as usize {
        let x = p.sense().x;
        u = pid.update(x_op, x, dt);
        p.actuate(
            pneuflex_control::ValveCommand { u },
            &pneuflex_control::Telemetry::default(),
        );
        p.advance(dt);
    }
    u
}

fn at_stiffness<P: Linearisable + ?Sized>(
    p: &mut P,
    scene: &Scene,
    run: &crate::schema::RunSpec,
    k_e: f64,
    target_db: f64,
) -> Margins {
    let dt = scene.dt_s;
    p.without_coulomb_friction();
    let u = settle_at_contact(p, scene, run, k_e);
    let (phi, gamma) = linearise(p, u, dt);
    let plant = plant_response(&phi, &gamma, dt, &frequencies(dt));
    let resp = loop_response(&plant, &run.inner, dt);
    let (gc, pm, pc, gm) = margins_of(&resp);
    let (ogc, opm, opc, ogm) =
        margins_of(&outer_response(&plant, &run.inner, &run.impedance, k_e, dt));
    // The smallest b_d with the target outer gain margin: more damping lowers the crossover and moves the
    // filter's pole b_d/m_d up, so the margin grows with b_d; bisection on a log scale.
    let outer_ok = |b_d: f64| {
        let imp = pneuflex_control::ImpedanceParams {
            b_d_ns_per_m: b_d,
            ..run.impedance
        };
        margins_of(&outer_response(&plant, &run.inner, &imp, k_e, dt))
            .3
            .is_none_or(|g| g >= target_db)
    };
    let b_d0 = run.impedance.b_d_ns_per_m.max(1e-6);
    let b_d_min = if outer_ok(b_d0) {
        let (mut lo, mut hi) = (0.0_f64, b_d0);
        for _ in 0..30 {
            let mid = 0.5 * (lo + hi);
            if outer_ok(mid) { hi = mid } else { lo = mid }
        }
        Some(hi)
    } else if outer_ok(100.0 * b_d0) {
        let (mut lo, mut hi) = (b_d0, 100.0 * b_d0);
        for _ in 0..30 {
            let mid = (lo * hi).sqrt();
            if outer_ok(mid) { hi = mid } else { lo = mid }
        }
        Some(hi)
    } else {
        None
    };
    let outer = OuterMargins {
        crossover_hz: ogc,
        phase_margin_deg: opm,
        phase_crossover_hz: opc,
        gain_margin_db: ogm,
        b_d_min_ns_per_m: b_d_min,
    };
    // The largest kp with the target gain margin: bisection on kp (ki, kd as in the scene).
    let gm_at = |kp: f64| {
        let pid = pneuflex_control::PidParams {
            kp_per_m: kp,
            ..run.inner
        };
        margins_of(&loop_response(&plant, &pid, dt)).3
    };
    let ok = |kp: f64| gm_at(kp).is_none_or(|g| g >= target_db);
    let kp_max = {
        let (mut lo, mut hi) = (0.0_f64, run.inner.kp_per_m.max(1.0));
        while ok(hi) && hi < 1e6 {
            lo = hi;
            hi *= 2.0;
        }
        if hi >= 1e6 {
            None
        } else {
            for _ in 0..40 {
                let mid = 0.5 * (lo + hi);
                if ok(mid) { lo = mid } else { hi = mid }
            }
            Some(lo)
        }
    };
    Margins {
        stiffness_n_per_m: k_e,
        crossover_hz: gc,
        phase_margin_deg: pm,
        phase_crossover_hz: pc,
        gain_margin_db: gm,
        kp_max_per_m: kp_max,
        outer,
        bode: resp
            .iter()
            .map(|&(f, m, ph)| (f, 20.0 * m.log10(), ph.to_degrees()))
            .collect(),
    }
}

/// The limit-cycle onset of run `index` at stiffness `k_e` on the scene's plant (see [`limit_cycle_onset`]);
/// None on a plant whose valve and friction this prediction does not model (the linear model has neither,
/// the ideal loop and the multibody rig are not analysed).
pub fn onset_at(
    scene: &Scene,
    index: usize,
    k_e: f64,
) -> Result<Option<(f64, f64, f64)>, SceneError> {
    Ok(linearisable_at(scene, k_e)?
        .filter(|p| p.has_valve_and_friction())
        .and_then(|p| limit_cycle_onset(&*p, scene, &scene.runs[index], k_e)))
}

/// The onset of a limit cycle predicted by describing functions: for oscillation amplitudes A_x of the
/// position (0.05 to 20 mm), Coulomb friction becomes the viscous damping 4 F_c / (π ω A_x ω) and the valve
/// the secant gain over the command amplitude kp·A_x; the smallest kp at which the loop's gain margin
/// reaches 0 dB for some amplitude is the predicted onset, with the oscillation's frequency (the phase
/// crossover). Returns (kp, Hz, A_x in m).
pub fn limit_cycle_onset<P: Linearisable + ?Sized>(
    plant: &P,
    scene: &Scene,
    run: &crate::schema::RunSpec,
    k_e: f64,
) -> Option<(f64, f64, f64)> {
    let dt = scene.dt_s;
    let f_c = plant.coulomb_n();
    let freqs = frequencies(dt);
    let mut best: Option<(f64, f64, f64)> = None;
    for i in 0..16 {
        let a_x = 5e-5 * (400.0_f64).powf(i as f64 / 15.0);
        // Iterate kp and the frequency together a few times (both enter the describing functions).
        let (mut kp, mut f_osc) = (run.inner.kp_per_m, 15.0);
        let mut found = None;
        for _ in 0..6 {
            let mut p = plant.boxed_clone();
            p.without_coulomb_friction();
            let w = std::f64::consts::TAU * f_osc;
            if f_c > 0.0 {
                p.add_viscous(4.0 * f_c / (std::f64::consts::PI * w * a_x));
            }
            let pid = pneuflex_control::PidParams {
                kp_per_m: kp,
                ..run.inner
            };
            let u_op = settle(&mut *p, scene, &pid, k_e);
            let hu = (kp * a_x).clamp(1e-4, 1.0);
            let (phi, gamma) = linearise_secant(&mut *p, u_op, hu, dt);
            let plant_resp = plant_response(&phi, &gamma, dt, &freqs);
            // kp at 0 dB for this linearisation (bisection), and the phase crossover there.
            let gm = |k: f64| {
                let pid = pneuflex_control::PidParams {
                    kp_per_m: k,
                    ..run.inner
                };
                margins_of(&loop_response(&plant_resp, &pid, dt))
            };
            let (mut lo, mut hi) = (0.0_f64, 1000.0_f64);
            if gm(hi).3.is_none_or(|g| g >= 0.0) {
                break;
            }
            for _ in 0..40 {
                let mid = 0.5 * (lo + hi);
                if gm(mid).3.is_none_or(|g| g >= 0.0) {
                    lo = mid
                } else {
                    hi = mid
                }
            }
            let pc = gm(hi).2;
            found = Some((hi, pc.unwrap_or(f_osc)));
            if (hi - kp).abs() < 0.01 * hi {
                break;
            }
            kp = hi;
            f_osc = pc.unwrap_or(f_osc);
        }
        if let Some((k, f)) = found
            && best.is_none_or(|b| k < b.0)
        {
            best = Some((k, f, a_x));
        }
    }
    best
}

/// Settles the plant on its inner loop alone at the contact position of the scene's first force; returns
/// the command there.
pub(crate) fn settle<P: Linearisable + ?Sized>(
    p: &mut P,
    scene: &Scene,
    pid: &pneuflex_control::PidParams,
    k_e: f64,
) -> f64 {
    let dt = scene.dt_s;
    let f_op = scene.setpoints().map(|sp| sp.at(0.0).f_ref).unwrap_or(0.0);
    let x_op = scene.environment.x_e_m + if k_e > 0.0 { f_op / k_e } else { 0.0 };
    let mut c = pneuflex_control::Pid::new(*pid).expect("validated with the scene");
    let mut u = 0.0;
    for _ in 0..(2.0 / dt).round() as usize {
        let x = p.sense().x;
        u = c.update(x_op, x, dt);
        p.actuate(
            pneuflex_control::ValveCommand { u },
            &pneuflex_control::Telemetry::default(),
        );
        p.advance(dt);
    }
    u
}
