//! What a run of a scene gives back: its trace, its metrics per window, the Lyapunov check.

use serde::Serialize;

use super::trace::Trace;
use crate::analysis::metrics::EventResponse;
use crate::schema::{ControllerKind, WindowKind};

/// The outcome of one controller run: its trace, metrics, Lyapunov check and divergence state.
#[derive(Clone, Debug)]
pub struct RunResult {
    /// Run name from the scene.
    pub name: String,
    /// Controller kind.
    pub controller: ControllerKind,
    /// Recorded signals (up to the divergence point for a diverged run).
    pub trace: Trace,
    /// Metrics per window, in the scene's window order (empty for a diverged run).
    pub windows: Vec<WindowMetrics>,
    /// Lyapunov check of the adaptive law's error system (adaptive runs only).
    pub lyapunov: Option<LyapunovSummary>,
    /// Why the run was stopped, when it diverged.
    pub diverged: Option<String>,
    /// Why the run was cut short by the user (a signal), when it was.
    pub interrupted: Option<String>,
    /// What a reader of the results should know (e.g. an adaptive parameter pinned at its projection bound).
    pub warnings: Vec<String>,
    /// The period of the valve's PWM carrier, s, as the plant that ran reports it (None: a proportional
    /// valve or no valve): the event metrics and the figures average over it.
    pub pwm_period_s: Option<f64>,
}

impl RunResult {
    /// Whether the trace holds g, p, d.
    pub fn is_adaptive(&self) -> bool {
        self.controller == ControllerKind::Adaptive
    }

    /// The metrics of the window named `name`.
    pub fn window(&self, name: &str) -> Option<&WindowMetrics> {
        self.windows.iter().find(|w| w.name == name)
    }
}

/// Metrics of one window.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct WindowMetrics {
    /// Window name.
    pub name: String,
    /// Window kind.
    pub kind: WindowKind,
    /// Window start, s.
    pub t0_s: f64,
    /// Window end, s.
    pub t1_s: f64,
    /// RMS of f_ref - f_e over the window, N.
    pub rms_force_error_n: f64,
    /// Sine windows: frequency of the reference, Hz.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub frequency_hz: Option<f64>,
    /// Sine windows: phase lag of f_e behind f_ref, degrees (positive = lags).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub phase_lag_deg: Option<f64>,
    /// Sine windows: amplitude ratio |f_e| / |f_ref| of the fitted sines.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub amplitude_ratio: Option<f64>,
    /// Step windows: mean of f_ref - f_e, N.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub steady_state_error_n: Option<f64>,
    /// Event windows: peak force, overshoot, settling.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub event: Option<EventResponse>,
}

/// The Lyapunov check of Section III-D for an adaptive run (what summary.json reports).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct LyapunovSummary {
    /// Reference model damping a_m, 1/s.
    pub a_m: f64,
    /// Reference model stiffness b_m, 1/s².
    pub b_m: f64,
    /// Initial a_p = b_d / m_d (eq. (28) with d = 0), 1/s.
    pub a_p0: f64,
    /// Initial b_p = (k_d + k_e) / m_d (eq. (28) with p = 0), 1/s².
    pub b_p0: f64,
    /// Solution P of A_mᵀP + PA_m = -Q, row-major.
    pub p: [[f64; 2]; 2],
    /// Largest |entry| of A_mᵀP + PA_m + Q.
    pub residual: f64,
    /// V at t = 0.
    pub v0: f64,
    /// V at the end.
    pub v_end: f64,
    /// Largest one-step rise of V.
    pub max_delta_v: f64,
    /// Whether V never rose by more than 1e-9·V(0) in a step.
    pub non_increasing: bool,
}
