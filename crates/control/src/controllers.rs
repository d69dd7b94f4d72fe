//! The two controllers of Section III: position-based impedance control and model-reference
//! adaptive impedance control, each followed by the inner PID position loop.

use crate::adaptive::{AdaptiveLaw, AdaptiveParams, VelocitySource};
use crate::error::ParamError;
use crate::impedance::{ImpedanceFilter, ImpedanceParams};
use crate::io::{Controller, Sensors, Setpoint, Telemetry, ValveCommand};
use crate::pid::{Pid, PidParams};
use crate::signal::Signal;

/// The adaptive law's parameters, recorded every tick (SI; eq. (35)).
const ADAPTIVE_SIGNALS: [Signal; 3] = [
    Signal::new("g", "m", "adaptive", "adaptive auxiliary term g (eq. 35)"),
    Signal::new(
        "p",
        "m/N",
        "adaptive",
        "adaptive proportional factor p (eq. 35)",
    ),
    Signal::new(
        "d",
        "s",
        "adaptive",
        "adaptive differential factor d (eq. 35)",
    ),
];

/// Position-based impedance control: x_r = x_d + x_f (eq. (23)), then PID on x_r - x.
#[derive(Clone, Copy, Debug)]
pub struct ImpedanceController {
    filter: ImpedanceFilter,
    pid: Pid,
    telemetry: Telemetry,
}

impl ImpedanceController {
    /// Builds the controller; both parameter sets are validated.
    pub fn new(impedance: ImpedanceParams, pid: PidParams) -> Result<Self, ParamError> {
        Ok(Self {
            filter: ImpedanceFilter::new(impedance)?,
            pid: Pid::new(pid)?,
            telemetry: Telemetry::default(),
        })
    }

    /// The impedance filter (x_f state).
    pub fn filter(&self) -> &ImpedanceFilter {
        &self.filter
    }

    /// Retunes the target impedance (m_d, b_d, k_d) from the next update on, the filter's state kept.
    pub fn set_impedance(&mut self, params: ImpedanceParams) -> Result<(), ParamError> {
        self.filter.set_params(params)
    }

    /// The inner position loop.
    pub fn pid(&self) -> &Pid {
        &self.pid
    }
}

impl Controller for ImpedanceController {
    fn update(&mut self, s: &Sensors, sp: &Setpoint, dt: f64) -> ValveCommand {
        // eq. (19): e = f_r - f_e.
        let e = sp.f_ref - s.f_e;
        // eq. (22), exact ZOH step.
        let x_f = self.filter.step(e, dt);
        // eq. (23).
        let x_r = sp.x_d + x_f;
        let u = self.pid.update(x_r, s.x, dt);
        self.telemetry = Telemetry {
            x_r,
            x_f,
            dx_f: 0.0,
            e,
        };
        ValveCommand::clamped(u)
    }

    fn telemetry(&self) -> Telemetry {
        self.telemetry
    }

    fn reset(&mut self) {
        self.filter.reset();
        self.pid.reset();
        self.telemetry = Telemetry::default();
    }
}

/// Model-reference adaptive impedance control: x_r = x_d + x_f + Δx_f (eq. (25) with x_d
/// restored), Δx_f = g + p e + d ẋ (eq. (36)), then PID on x_r - x.
#[derive(Clone, Copy, Debug)]
pub struct AdaptiveImpedanceController {
    filter: ImpedanceFilter,
    law: AdaptiveLaw,
    pid: Pid,
    telemetry: Telemetry,
}

impl AdaptiveImpedanceController {
    /// Builds the controller; all parameter sets are validated.
    pub fn new(
        impedance: ImpedanceParams,
        adaptive: AdaptiveParams,
        pid: PidParams,
    ) -> Result<Self, ParamError> {
        Ok(Self {
            filter: ImpedanceFilter::new(impedance)?,
            law: AdaptiveLaw::new(adaptive)?,
            pid: Pid::new(pid)?,
            telemetry: Telemetry::default(),
        })
    }

    /// The same controller with its adaptive parameters held for the whole run, in SI: g in m, p in m/N,
    /// d in s ([`AdaptiveLaw::frozen`]). At g = p = d = 0 it is the [`ImpedanceController`].
    pub fn frozen(
        impedance: ImpedanceParams,
        adaptive: AdaptiveParams,
        pid: PidParams,
        g_m: f64,
        p_m_per_n: f64,
        d_s: f64,
    ) -> Result<Self, ParamError> {
        let (fu, pu) = (adaptive.force_unit_n, adaptive.position_unit_m);
        Ok(Self {
            filter: ImpedanceFilter::new(impedance)?,
            law: AdaptiveLaw::frozen(adaptive, g_m / pu, p_m_per_n * fu / pu, d_s)?,
            pid: Pid::new(pid)?,
            telemetry: Telemetry::default(),
        })
    }

    /// The impedance filter (x_f state).
    pub fn filter(&self) -> &ImpedanceFilter {
        &self.filter
    }

    /// The adaptive law (g, p, d in the params' units).
    pub fn law(&self) -> &AdaptiveLaw {
        &self.law
    }

    /// The inner position loop.
    pub fn pid(&self) -> &Pid {
        &self.pid
    }
}

impl Controller for AdaptiveImpedanceController {
    fn update(&mut self, s: &Sensors, sp: &Setpoint, dt: f64) -> ValveCommand {
        let e = sp.f_ref - s.f_e;
        let x_f = self.filter.step(e, dt);
        // eq. (36) with ẋ measured (eq. (26)'s ė replaced by ẋ, ė = -k_e ẋ in contact).
        let a = self.law.params();
        let dx_f = if a.adapt_in_contact_only && s.f_e.is_finite() && s.f_e <= a.contact_threshold_n
        {
            self.law.hold()
        } else {
            let v = match a.velocity_source {
                VelocitySource::Measured => s.x_dot,
                VelocitySource::ImpedanceFilter => self.filter.v_f(),
            };
            self.law.update(e, v, dt)
        };
        // eq. (25): the paper prints x_r = x_f + Δx_f; x_d is restored so that Δx_f = 0 gives eq. (23).
        let x_r = sp.x_d + x_f + dx_f;
        let u = self.pid.update(x_r, s.x, dt);
        self.telemetry = Telemetry { x_r, x_f, dx_f, e };
        ValveCommand::clamped(u)
    }

    fn telemetry(&self) -> Telemetry {
        self.telemetry
    }

    fn reset(&mut self) {
        self.filter.reset();
        self.law.reset();
        self.pid.reset();
        self.telemetry = Telemetry::default();
    }

    fn signals(&self) -> &'static [Signal] {
        &ADAPTIVE_SIGNALS
    }

    fn record(&self, out: &mut [f64]) {
        // In SI: g in m, p in m/N, d in s (the law runs in the params' units).
        let a = self.law.params();
        out.copy_from_slice(&[
            self.law.g() * a.position_unit_m,
            self.law.p() * a.position_unit_m / a.force_unit_n,
            self.law.d(),
        ]);
    }
}
