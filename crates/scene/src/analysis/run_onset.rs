//! The limit-cycle onset of a whole run's loop at one stiffness: the inner PID with the controller around
//! it (the impedance filter, and the adaptive law with p and d where an oscillation drives them,
//! [`OuterLaw`]), on the scene's plant. A switching valve is analysed by the sampled-data model of its
//! PWM (pwm_onset.rs), a proportional one by describing functions of the valve's saturation and the
//! Coulomb friction (loop_margins.rs's method, the stability judged on the closed loop's tick map: the
//! onset is the kp, ki and kd as in the scene, at which its spectral radius reaches 1). Where the values
//! the adaptation reaches cannot be known the onset says why instead of a number.

use serde::Serialize;

use super::loop_margins::{linearise_secant, settle};
use super::outer_law::{HeldGains, OuterLaw, Outputs};
use super::pwm_onset::{critical, held_ticks, monodromy, pwm_onset, stability_edge};
use crate::SceneError;
use crate::plants::Linearisable;
use crate::schema::plant::linearisable_at;
use crate::schema::{RunSpec, Scene};

/// The predicted onset of one run at one stiffness.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RunOnset {
    /// The run.
    pub run: String,
    /// The environment's stiffness, N/m.
    pub stiffness_n_per_m: f64,
    /// "sampled-data PWM" or "describing functions".
    pub method: &'static str,
    /// The smallest kp (ki, kd as in the scene) above the run's at which the loop oscillates, 1/m; None
    /// with `not_predicted`, or when no onset lies within 1000× of the run's kp.
    pub kp_per_m: Option<f64>,
    /// The oscillation's frequency there, Hz.
    pub frequency_hz: Option<f64>,
    /// The position amplitude the describing functions find it at, m (not with the PWM's model).
    pub amplitude_m: Option<f64>,
    /// The adaptive law's p and d as the analysis holds them.
    pub held: Option<HeldGains>,
    /// Why the method cannot predict this run's onset.
    pub not_predicted: Option<String>,
}

/// The onset of run `index` at stiffness `k_e`; None for a plant the prediction does not model (the
/// linear plant has no valve or friction; the ideal loop and the multibody rig are not analysed).
pub fn run_onset(scene: &Scene, index: usize, k_e: f64) -> Result<Option<RunOnset>, SceneError> {
    let run = &scene.runs[index];
    let Some(mut plant) = linearisable_at(scene, k_e)? else {
        return Ok(None);
    };
    let switching = plant.switching();
    if !switching && !plant.has_valve_and_friction() {
        return Ok(None);
    }
    let method = if switching {
        "sampled-data PWM"
    } else {
        "describing functions"
    };
    let mut onset = RunOnset {
        run: run.name.clone(),
        stiffness_n_per_m: k_e,
        method,
        kp_per_m: None,
        frequency_hz: None,
        amplitude_m: None,
        held: None,
        not_predicted: None,
    };
    let outer = match OuterLaw::of_run(run, scene.dt_s) {
        Ok(o) => o,
        Err(why) => {
            onset.not_predicted = Some(why);
            return Ok(Some(onset));
        }
    };
    onset.held = Some(outer.held.clone());
    if switching {
        if let Some(p) = pwm_onset(&mut *plant, scene, run, k_e, Some(&outer)) {
            onset.kp_per_m = Some(p.kp_per_m);
            onset.frequency_hz = Some(p.frequency_hz);
        }
    } else if let Some((kp, hz, a)) = describing_onset(&*plant, scene, run, k_e, &outer) {
        onset.kp_per_m = Some(kp);
        onset.frequency_hz = Some(hz);
        onset.amplitude_m = Some(a);
    }
    Ok(Some(onset))
}

/// The describing-function onset of the whole loop: for position amplitudes A_x of 0.05 to 20 mm the
/// Coulomb friction is the viscous damping 4 F_c / (π ω A_x) and the valve the secant gain over the
/// command amplitude kp·A_x; at each amplitude kp and the frequency are iterated together, and the
/// smallest kp over the amplitudes is the onset. Returns (kp, Hz, A_x in m).
fn describing_onset<P: Linearisable + ?Sized>(
    plant: &P,
    scene: &Scene,
    run: &RunSpec,
    k_e: f64,
    outer: &OuterLaw,
) -> Option<(f64, f64, f64)> {
    let dt = scene.dt_s;
    let f_c = plant.coulomb_n();
    let nyquist = 0.5 / dt;
    let mut best: Option<(f64, f64, f64)> = None;
    for i in 0..16 {
        let a_x = 5e-5 * (400.0_f64).powf(i as f64 / 15.0);
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
            let outputs = Outputs::of(&mut *p);
            let o = Some((outer, &outputs)).filter(|_| !outputs.no_contact());
            // One tick, the command applied at once: the closed loop's own map.
            let at = |k: f64| {
                let pid = pneuflex_control::PidParams {
                    kp_per_m: k,
                    ..run.inner
                };
                critical(&monodromy(
                    &held_ticks(&phi, &gamma, &[(true, false)]),
                    &pid,
                    dt,
                    o,
                ))
            };
            let Some((k, angle)) = stability_edge(&at, run.inner.kp_per_m.max(1e-6)) else {
                break;
            };
            let f = (angle / (std::f64::consts::TAU * dt)).min(nyquist);
            found = Some((k, f));
            if (k - kp).abs() < 0.01 * k {
                break;
            }
            kp = k;
            f_osc = f.max(0.1);
        }
        if let Some((k, f)) = found
            && best.is_none_or(|b| k < b.0)
        {
            best = Some((k, f, a_x));
        }
    }
    best
}
