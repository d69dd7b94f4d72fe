//! The metrics of every window of a run, from its trace: what `summary.json` reports per window.

use crate::analysis::metrics;
use crate::run::result::WindowMetrics;
use crate::run::trace::Trace;
use crate::schema::{ForcePiece, Scene, WindowKind};

/// The metrics of every window of the scene on a trace, the event metrics averaged over the valve's PWM
/// period (the run's [`RunResult::pwm_period_s`](crate::RunResult); None: no averaging).
pub fn compute_windows(scene: &Scene, tr: &Trace, pwm_period_s: Option<f64>) -> Vec<WindowMetrics> {
    scene
        .metrics
        .iter()
        .map(|w| {
            let (i0, i1) = metrics::window_indices(tr.t(), w.t0_s, w.t1_s);
            let (t, r, f) = (&tr.t()[i0..i1], &tr.f_ref()[i0..i1], &tr.f_e()[i0..i1]);
            let mut m = WindowMetrics {
                name: w.name.clone(),
                kind: w.kind,
                t0_s: w.t0_s,
                t1_s: w.t1_s,
                rms_force_error_n: metrics::rms_error(r, f),
                frequency_hz: None,
                phase_lag_deg: None,
                amplitude_ratio: None,
                steady_state_error_n: None,
                event: None,
            };
            match w.kind {
                WindowKind::Sine => {
                    if let Some(ForcePiece::Sine { frequency_hz, .. }) =
                        scene.reference.sine_in(w.t0_s, w.t1_s)
                    {
                        let om = std::f64::consts::TAU * frequency_hz;
                        m.frequency_hz = Some(frequency_hz);
                        m.phase_lag_deg = metrics::phase_lag_deg(t, r, f, frequency_hz);
                        if let (Some((ar, _, _)), Some((af, _, _))) =
                            (metrics::fit_sine(t, r, om), metrics::fit_sine(t, f, om))
                        {
                            m.amplitude_ratio = Some(af / ar);
                        }
                    }
                }
                WindowKind::Step => m.steady_state_error_n = Some(metrics::mean_error(r, f)),
                WindowKind::Event => {
                    // The steady state the response is measured against: the sine the window ends on,
                    // repeated, or the constant reference's mean error.
                    let steady = match scene.reference.sine_in(w.t1_s - 1e-9, w.t1_s) {
                        Some(ForcePiece::Sine { frequency_hz, .. }) => {
                            metrics::Steady::Periodic(frequency_hz)
                        }
                        _ => metrics::Steady::Constant,
                    };
                    m.event = metrics::event_response(t, r, f, steady, pwm_period_s);
                }
            }
            m
        })
        .collect()
}
