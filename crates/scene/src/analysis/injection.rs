//! The loop at one actuator's valve command, measured by injection: what `tf --loop` gives for a scene of
//! several actuators, where no state-space linearisation of the mechanism exists. The scene runs through
//! the one loop with every controller closed; a small multisine d is added to actuator `a`'s command after
//! its controller (u = u_c + d), and over a window of whole periods the loop broken there is
//!     L(jω) = −U_c(jω) / U(jω)
//! at each of the multisine's frequencies (u_c = −L u, a standard open-loop measurement in closed loop).
//! The reference is held, so the loop is quiet but for d. A linear plant gives L exactly (up to the
//! transient left after the settling time); a nonlinear one its response to an oscillation of d's size.

use pneuflex_control::{Controller, Sensors, Setpoint, Telemetry, ValveCommand};
use serde::Serialize;

use super::loop_margins::{Cx, unwrapped};
use crate::error::SceneError;
use crate::plants::{ActuatorGeometry, EventSpec, Plant, PlantError, Visual, VisualPose};
use crate::run::{RunPlan, simulate_run};
use crate::schema::{ControllerKind, DivergenceSpec};

/// How the loop at an actuator is measured.
#[derive(Clone, Debug, PartialEq)]
pub struct Injection {
    /// The actuator whose command d is added to.
    pub actuator: usize,
    /// Time before the measurement window: the start's transient dies out, s.
    pub settle_s: f64,
    /// The measurement window, s: the multisine's period, so its frequencies are multiples of 1/window.
    pub window_s: f64,
    /// RMS of d, in valve-command units.
    pub rms: f64,
    /// Highest frequency measured, Hz.
    pub f_max_hz: f64,
    /// Number of frequencies (log-spaced, each a whole number of periods in the window).
    pub frequencies: usize,
}

impl Default for Injection {
    fn default() -> Self {
        Self {
            actuator: 0,
            settle_s: 4.0,
            window_s: 4.0,
            rms: 0.02,
            f_max_hz: 100.0,
            frequencies: 30,
        }
    }
}

/// The measured loop and its margins.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct MeasuredLoop {
    /// Gain crossover (|L| = 1), Hz.
    pub crossover_hz: Option<f64>,
    /// Phase margin there, degrees.
    pub phase_margin_deg: Option<f64>,
    /// Phase crossover (arg L = −180°), Hz.
    pub phase_crossover_hz: Option<f64>,
    /// Gain margin there, dB (None: the phase does not reach −180° below the highest frequency measured).
    pub gain_margin_db: Option<f64>,
    /// (Hz, |L| dB, arg L degrees, unwrapped) at each frequency measured.
    pub bode: Vec<(f64, f64, f64)>,
    /// The same as complex numbers (Hz, Re L, Im L), for checks against a model.
    #[serde(skip)]
    pub response: Vec<(f64, f64, f64)>,
}

/// The multisine's bins: log-spaced whole numbers of periods per window, from 2 (the first bin, one period,
/// is where the start's slowest transient leaks most: on the linear model 9 % off its |L|) to `f_max`,
/// distinct.
fn bins(window_ticks: usize, dt: f64, f_max_hz: f64, n: usize) -> Vec<usize> {
    const LOWEST: f64 = 2.0;
    let top = ((f_max_hz * window_ticks as f64 * dt).floor() as usize)
        .min(window_ticks / 2 - 1)
        .max(2);
    let mut out: Vec<usize> = (0..n)
        .map(|i| {
            let r = if n > 1 {
                i as f64 / (n - 1) as f64
            } else {
                0.0
            };
            (LOWEST * (top as f64 / LOWEST).powf(r)).round() as usize
        })
        .collect();
    out.dedup();
    out
}

/// Crossovers and margins of a measured response (Hz, L), read from the wrapped phase: a measurement's
/// phase can jump between neighbouring frequencies (an adapting law, noise), so no unwrapped phase from the
/// lowest frequency is trusted. The gain crossover is the first fall of |L| through 1 (log-linear
/// interpolation), its margin 180° + arg L there in (−180°, 180°]; the phase crossover the first crossing of
/// the negative real axis (Im L changes sign with Re L < 0) above the gain crossover (the one that bounds a
/// rise of the gain: the loop at the valve with the impedance filter closed has −270° at low frequency, so
/// its phase also crosses −180° below the gain crossover, where only a fall of the gain would matter), its
/// margin −20 log₁₀|L| there.
fn measured_margins(resp: &[(f64, Cx)]) -> (Option<f64>, Option<f64>, Option<f64>, Option<f64>) {
    let wrap = |deg: f64| {
        let w = deg.rem_euclid(360.0);
        if w > 180.0 { w - 360.0 } else { w }
    };
    let mut gc = None;
    let mut pm = None;
    for w in resp.windows(2) {
        let ((fa, a), (fb, b)) = (w[0], w[1]);
        if a.abs() >= 1.0 && b.abs() < 1.0 {
            let r = a.abs().ln() / (a.abs().ln() - b.abs().ln());
            let f = fa + r * (fb - fa);
            // The phase between the two: b's angle relative to a's, the short way round.
            let step = b.div(a).arg();
            gc = Some(f);
            pm = Some(wrap(180.0 + (a.arg() + r * step).to_degrees()));
            break;
        }
    }
    let mut pc = None;
    let mut gm = None;
    for w in resp.windows(2) {
        let ((fa, a), (fb, b)) = (w[0], w[1]);
        if gc.is_some_and(|g| fb <= g) {
            continue;
        }
        if (a.1 > 0.0) != (b.1 > 0.0) {
            let r = a.1 / (a.1 - b.1);
            let re = a.0 + r * (b.0 - a.0);
            if re < 0.0 {
                pc = Some(fa + r * (fb - fa));
                let mag = (a.abs().ln() + r * (b.abs().ln() - a.abs().ln())).exp();
                gm = Some(-20.0 * mag.log10());
                break;
            }
        }
    }
    (gc, pm, pc, gm)
}

/// A plant whose actuator `actuator` gets `d[tick]` added to its command.
struct Injected<'a, 'p> {
    inner: &'a mut (dyn Plant + 'p),
    actuator: usize,
    d: &'a [f64],
    tick: usize,
}

impl Plant for Injected<'_, '_> {
    fn sense(&self) -> Sensors {
        self.inner.sense()
    }
    fn actuate(&mut self, command: ValveCommand, telemetry: &Telemetry) {
        self.actuate_actuator(0, command, telemetry);
    }
    fn advance(&mut self, dt: f64) {
        self.inner.advance(dt);
        self.tick += 1;
    }
    fn actuator_names(&self) -> &[String] {
        self.inner.actuator_names()
    }
    fn sense_actuator(&self, i: usize) -> Sensors {
        self.inner.sense_actuator(i)
    }
    fn actuate_actuator(&mut self, i: usize, command: ValveCommand, telemetry: &Telemetry) {
        let u = if i == self.actuator {
            command.u + self.d.get(self.tick).copied().unwrap_or(0.0)
        } else {
            command.u
        };
        self.inner
            .actuate_actuator(i, ValveCommand { u }, telemetry);
    }
    fn apply(&mut self, event: &EventSpec) -> Result<(), PlantError> {
        self.inner.apply(event)
    }
    fn reset(&mut self) {
        self.inner.reset();
        self.tick = 0;
    }
    fn check_invariants(&self) -> Result<(), PlantError> {
        self.inner.check_invariants()
    }
    fn signals(&self) -> &'static [pneuflex_control::Signal] {
        self.inner.signals()
    }
    fn record(&self, out: &mut [f64]) {
        self.inner.record(out);
    }
    fn visuals(&self) -> Vec<Visual> {
        self.inner.visuals()
    }
    fn visual_poses(&self, pose: &mut dyn FnMut(usize, VisualPose)) {
        self.inner.visual_poses(pose);
    }
    fn actuator_geometry(&self) -> Option<ActuatorGeometry> {
        self.inner.actuator_geometry()
    }
    fn pwm_period_s(&self) -> Option<f64> {
        self.inner.pwm_period_s()
    }
}

/// Measures the loop at `inj.actuator`'s valve command on `plant` (in the state the caller left it, its
/// events applied) with `controllers` closed around it, each tracking `reference(i, t)`.
#[allow(clippy::too_many_arguments)]
pub fn measure(
    plant: &mut dyn Plant,
    controllers: &mut [&mut dyn Controller],
    controller: ControllerKind,
    reference: &mut dyn FnMut(usize, f64) -> Setpoint,
    dt: f64,
    inj: &Injection,
    divergence: &DivergenceSpec,
    invalid: &dyn Fn(&str, String) -> SceneError,
) -> Result<MeasuredLoop, SceneError> {
    let settle = (inj.settle_s / dt).round() as usize;
    let window = (inj.window_s / dt).round() as usize;
    let bins = bins(window, dt, inj.f_max_hz, inj.frequencies);
    // Schroeder phases keep the multisine's peak near its RMS times 1.7 (a crest factor of a single sine).
    let n = bins.len() as f64;
    let amplitude = inj.rms * (2.0 / n).sqrt();
    let phases: Vec<f64> = (0..bins.len())
        .map(|i| -std::f64::consts::PI * (i * (i + 1)) as f64 / n)
        .collect();
    let d: Vec<f64> = (0..=settle + window)
        .map(|k| {
            bins.iter()
                .zip(&phases)
                .map(|(&m, &ph)| {
                    amplitude * (std::f64::consts::TAU * (m * k) as f64 / window as f64 + ph).cos()
                })
                .sum()
        })
        .collect();
    let names = plant.actuator_names().to_vec();
    let u_column = match names.get(inj.actuator) {
        Some(a) => format!("{a}.u"),
        None => "u".to_string(),
    };
    let plan = RunPlan {
        name: "injection",
        controller,
        dt_s: dt,
        n_steps: settle + window,
        events: &[],
        divergence,
        invalid,
    };
    let mut injected = Injected {
        inner: plant,
        actuator: inj.actuator,
        d: &d,
        tick: 0,
    };
    let run = simulate_run(
        &plan,
        &mut injected,
        controllers,
        reference,
        &mut |_| {},
        &mut (),
        None,
    )?;
    if let Some(why) = &run.diverged {
        return Err(invalid(
            "runs",
            format!("the loop measurement diverged: {why}"),
        ));
    }
    let u_c = run
        .trace
        .column(&u_column)
        .expect("every actuator's block has its command");
    // Fourier coefficients at each bin over the window, of the controller's command and of d.
    let dft = |x: &dyn Fn(usize) -> f64, m: usize| -> Cx {
        let mut acc = Cx(0.0, 0.0);
        for k in 0..window {
            let w = -std::f64::consts::TAU * (m * k) as f64 / window as f64;
            acc = acc.add(Cx(x(settle + k) * w.cos(), x(settle + k) * w.sin()));
        }
        acc
    };
    let response: Vec<(f64, Cx)> = bins
        .iter()
        .map(|&m| {
            let uc = dft(&|k| u_c[k], m);
            let dd = dft(&|k| d[k], m);
            let l = Cx(0.0, 0.0).sub(uc.div(uc.add(dd)));
            (m as f64 / (window as f64 * dt), l)
        })
        .collect();
    let resp = unwrapped(response.iter().copied());
    let (gc, pm, pc, gm) = measured_margins(&response);
    Ok(MeasuredLoop {
        crossover_hz: gc,
        phase_margin_deg: pm,
        phase_crossover_hz: pc,
        gain_margin_db: gm,
        bode: resp
            .iter()
            .map(|&(f, m, ph)| (f, 20.0 * m.log10(), ph.to_degrees()))
            .collect(),
        response: response.iter().map(|(f, l)| (*f, l.0, l.1)).collect(),
    })
}

/// The loop at one actuator's valve of one run of a mechanism scene, in one phase of its events.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ActuatorLoop {
    /// The run.
    pub run: String,
    /// The actuator whose valve the loop is broken at.
    pub actuator: String,
    /// The events applied before the measurement (from t = 0 on): none, then each time's events in turn.
    pub after_events_at_s: Option<f64>,
    /// The loop and its margins.
    #[serde(flatten)]
    pub measured: MeasuredLoop,
}

/// The loop at each actuator's valve, for every run of a mechanism scene and every phase of its events
/// (none applied, then those up to each event time): the other actuators' controllers closed as in the
/// scene, each actuator's force reference held at its value at t = 0 (its first piece).
pub fn mechanism_loops(
    scene: &crate::mechanism::MechanismScene,
    inj: &Injection,
) -> Result<Vec<ActuatorLoop>, SceneError> {
    use crate::mechanism::MechanismPlant;
    use crate::mechanism::plant::loop_events;
    let events = loop_events(scene);
    let mut times: Vec<f64> = events.iter().map(EventSpec::t_s).collect();
    times.sort_by(f64::total_cmp);
    times.dedup();
    let phases: Vec<Option<f64>> = std::iter::once(None)
        .chain(times.into_iter().map(Some))
        .collect();
    let invalid = |key: &str, message: String| scene.invalid(key, message);
    let mut out = Vec::new();
    for (r, spec) in scene.runs.iter().enumerate() {
        for phase in &phases {
            for (a, actuator) in scene.actuators.iter().enumerate() {
                let mut plant = MechanismPlant::new(scene)?;
                if let Some(t) = phase {
                    for e in events.iter().filter(|e| e.t_s() <= *t) {
                        plant
                            .apply(e)
                            .map_err(|err| scene.invalid("events", err.to_string()))?;
                    }
                }
                let held: Vec<Setpoint> = plant.schedules().iter().map(|s| s.at(0.0)).collect();
                let mut controllers = scene.run_controllers(r)?;
                let mut each: Vec<&mut dyn Controller> = controllers
                    .iter_mut()
                    .map(|c| &mut **c as &mut dyn Controller)
                    .collect();
                let measured = measure(
                    &mut plant,
                    &mut each,
                    spec.controller,
                    &mut |i, _| held[i],
                    scene.dt_s,
                    &Injection {
                        actuator: a,
                        ..inj.clone()
                    },
                    &scene.divergence,
                    &invalid,
                )?;
                out.push(ActuatorLoop {
                    run: spec.name.clone(),
                    actuator: actuator.name.clone(),
                    after_events_at_s: *phase,
                    measured,
                });
            }
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn margins_of_a_known_loop() {
        // L = K / (s (s + 1)²): phase −180° at ω = 1 rad/s where |L| = K/2; K = 1 gives 6.02 dB of gain
        // margin. Sampled on a grid, its phase wrapped as a measurement gives it.
        let l = |w: f64| {
            let s = Cx(0.0, w);
            let one = Cx(1.0, 0.0);
            one.div(s.mul(s.add(one)).mul(s.add(one)))
        };
        let resp: Vec<(f64, Cx)> = (0..400)
            .map(|i| {
                let w = 0.05 * 1.02_f64.powi(i);
                (w / std::f64::consts::TAU, l(w))
            })
            .collect();
        let (gc, pm, pc, gm) = measured_margins(&resp);
        assert!(
            (pc.unwrap() * std::f64::consts::TAU - 1.0).abs() < 1e-3,
            "{pc:?}"
        );
        assert!((gm.unwrap() - 20.0 * 2f64.log10()).abs() < 0.01, "{gm:?}");
        // |L| = 1 at ω ≈ 0.6823 rad/s (ω (1 + ω²) = 1), arg L = −90° − 2 atan ω.
        let w = 0.682_327_803_8_f64;
        assert!(
            (gc.unwrap() * std::f64::consts::TAU - w).abs() < 2e-3,
            "{gc:?}"
        );
        let want = 180.0 - 90.0 - 2.0 * w.atan().to_degrees();
        assert!((pm.unwrap() - want).abs() < 0.1, "{pm:?} vs {want}");
    }

    #[test]
    fn the_bins_are_whole_periods_log_spaced_and_distinct() {
        let b = bins(4000, 0.001, 100.0, 30);
        assert_eq!(b[0], 2);
        assert_eq!(*b.last().unwrap(), 400);
        assert!(b.windows(2).all(|w| w[1] > w[0]), "{b:?}");
    }
}
