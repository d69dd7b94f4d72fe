//! The pneumatic cylinder as a force element for an external rigid-body engine (the Rapier rig of
//! `pneuflex-multibody`, MuJoCo through the Python bindings or the native plugin of `pneuflex-mujoco`):
//! the engine gives the flange motion over a step, the element integrates valve and chambers over it and
//! returns the piston force. It lives here, beside the chamber equations, because it is pneumatics only;
//! every engine uses this one implementation.

use crate::actuator::{Actuator, ChamberState, ChamberStep};
use crate::regulator::{PressureRegulator, RegulatedStep, rk4_chambers};
use crate::valve::ValveState;

/// The pneumatic cylinder as a force element: it integrates the two chamber states (eqs. (2)-(10), via
/// [`Actuator::step_chambers`]) and the valve ([`crate::ValveModel::segment`]) over each physics step, in
/// `substeps` equal substeps split at the valve's spool edges, with the flange moving at the step's
/// velocity, and returns the piston force p_a S_a - p_b S_b - p_atm S_rod (eq. (1)'s F_1 - F_2). Viscous
/// friction K_v and Coulomb friction are not included (the engine's joint damping; the sheet's friction law).
///
/// With regulators fitted ([`PneumaticForceElement::set_regulator`]) the command is the chambers' pressure
/// set-points instead of the valve command ([`crate::regulator`]); the valve's state then stays at rest.
#[derive(Debug, Clone)]
pub struct PneumaticForceElement {
    /// Cylinder, gas, valve and supply.
    pub actuator: Actuator,
    /// Chamber pressures and temperatures.
    pub chambers: ChamberState,
    /// Valve internal state (spool position, PWM clock).
    pub valve: ValveState,
    /// Valve command u in [-1, 1] held until changed (+1: supply to chamber A).
    command: f64,
    /// Chamber substeps per physics step (>= 1).
    substeps: u32,
    /// Time of the element's own clock, s (drives the PWM period of an on/off valve).
    time_s: f64,
    /// A pressure regulator in front of each chamber in place of the valve, or None (the valve).
    regulator: Option<PressureRegulator>,
    /// The regulators' set-points (A, B), Pa absolute, held until changed.
    setpoints_pa: (f64, f64),
}

impl PneumaticForceElement {
    /// How many numbers [`PneumaticForceElement::state`] writes: p_a, p_b, T_a, T_b, the valve's
    /// [`ValveState::LEN`] and the element's clock.
    pub const STATE_LEN: usize = 5 + ValveState::LEN;

    /// A force element with chambers `chambers`, valve at rest at spool 0, and `substeps` (>= 1; 0 is
    /// taken as 1) chamber substeps per physics step.
    pub fn new(actuator: Actuator, chambers: ChamberState, substeps: u32) -> Self {
        Self {
            actuator,
            chambers,
            valve: ValveState::default(),
            command: 0.0,
            substeps: substeps.max(1),
            time_s: 0.0,
            regulator: None,
            setpoints_pa: (chambers.p_a, chambers.p_b),
        }
    }

    /// Fits a pressure regulator in front of each chamber in place of the valve (`None`: back to the valve);
    /// the set-points start at the chambers' pressures (they hold them).
    pub fn set_regulator(&mut self, regulator: Option<PressureRegulator>) {
        self.regulator = regulator;
        self.setpoints_pa = (self.chambers.p_a, self.chambers.p_b);
    }

    /// The regulator in front of each chamber, if fitted.
    pub fn regulator(&self) -> Option<PressureRegulator> {
        self.regulator
    }

    /// Sets the regulators' set-points of chambers A and B, Pa absolute, held from the next step on (clamped
    /// to [atmosphere, supply] by the model; NaN passes no flow). Without regulators fitted they wait.
    pub fn set_pressure_command(&mut self, p_a_pa: f64, p_b_pa: f64) {
        self.setpoints_pa = (p_a_pa, p_b_pa);
    }

    /// The regulators' set-points (A, B), Pa absolute.
    pub fn pressure_command(&self) -> (f64, f64) {
        self.setpoints_pa
    }

    /// Set the valve command u in [-1, 1] (clamped; NaN closes the valve), held from the next step on.
    pub fn set_command(&mut self, u: f64) {
        self.command = if u.is_nan() { 0.0 } else { u.clamp(-1.0, 1.0) };
    }

    /// The valve command in force.
    pub fn command(&self) -> f64 {
        self.command
    }

    /// Chamber substeps per physics step.
    pub fn substeps(&self) -> u32 {
        self.substeps
    }

    /// Time of the element's own clock, s: the sum of its steps.
    pub fn time_s(&self) -> f64 {
        self.time_s
    }

    /// Chamber pressures (p_a, p_b), Pa absolute: what the rig's pressure sensors read.
    pub fn pressures(&self) -> (f64, f64) {
        (self.chambers.p_a, self.chambers.p_b)
    }

    /// Piston force for the current chamber state, N.
    pub fn piston_force(&self) -> f64 {
        self.actuator.piston_force(&self.chambers)
    }

    /// The evolving state as numbers, for a host that stores it in its own f64 buffer (MuJoCo's
    /// `plugin_state`): p_a, p_b (Pa), T_a, T_b (K), the valve ([`ValveState::to_array`]), the clock (s).
    /// The command and the parameters are not state: the host gives them.
    pub fn state(&self) -> [f64; Self::STATE_LEN] {
        let c = &self.chambers;
        let v = self.valve.to_array();
        [
            c.p_a,
            c.p_b,
            c.t_a,
            c.t_b,
            v[0],
            v[1],
            v[2],
            v[3],
            v[4],
            v[5],
            self.time_s,
        ]
    }

    /// Sets the state from [`PneumaticForceElement::state`]'s numbers. Refused (`false`, nothing changed)
    /// when they are not a state the element can be in: a pressure or temperature that is not finite and
    /// positive, a clock that is not finite, or a valve state [`ValveState::from_array`] refuses.
    pub fn set_state(&mut self, s: &[f64; Self::STATE_LEN]) -> bool {
        let valve: [f64; ValveState::LEN] = [s[4], s[5], s[6], s[7], s[8], s[9]];
        let Some(valve) = ValveState::from_array(&valve) else {
            return false;
        };
        if !(s[..4].iter().all(|v| v.is_finite() && *v > 0.0) && s[10].is_finite()) {
            return false;
        }
        self.chambers = ChamberState {
            p_a: s[0],
            p_b: s[1],
            t_a: s[2],
            t_b: s[3],
        };
        self.valve = valve;
        self.time_s = s[10];
        true
    }

    /// Advances valve and chambers by `dt` (s) while the flange moves from extension `x` (m) at velocity
    /// `x_dot` (m/s), under the command in force, and returns the mean piston force over the step, N
    /// (trapezoidal over each piece, so that the force an engine applies for the step is the one the
    /// chambers produced over it).
    pub fn step(&mut self, x: f64, x_dot: f64, dt: f64) -> f64 {
        let n = self.substeps;
        let h = dt / f64::from(n);
        if let Some(reg) = &self.regulator {
            let (a, b) = self.setpoints_pa;
            let k = RegulatedStep::new(&self.actuator, reg, a, b);
            let mut f_sum = 0.0;
            for i in 0..n {
                let f0 = self.actuator.piston_force(&self.chambers);
                rk4_chambers(
                    &k,
                    &mut self.chambers,
                    x + x_dot * h * f64::from(i),
                    x_dot,
                    h,
                );
                f_sum += 0.5 * (f0 + self.actuator.piston_force(&self.chambers));
                self.time_s += h;
            }
            return f_sum / f64::from(n);
        }
        let mut f_sum = 0.0;
        // Over the step: the chamber constants of the last spool position, and how long the spool holds
        // (while it does, `segment` would change nothing and is not called). Bit for bit the same.
        let mut consts: Option<(f64, ChamberStep)> = None;
        let mut hold = crate::SpoolHold::NONE;
        for i in 0..n {
            let xi = x + x_dot * h * f64::from(i);
            // The substep is split at every spool edge inside it (`ValveModel::segment`: the delayed PWM
            // edges of an on/off valve; never for the proportional valve): RK4 up to the edge with the
            // spool before it, on from it with the spool after it.
            let (t_sub, t_end) = (self.time_s, self.time_s + h);
            let (mut tau, mut rest) = (t_sub, h);
            loop {
                let valve = &self.actuator.valve;
                let (spool, edge) = if hold.covers(tau, rest) {
                    (self.valve.spool, None)
                } else {
                    let piece = valve.segment(&mut self.valve, self.command, tau, rest);
                    hold = valve.hold(&self.valve, tau);
                    piece
                };
                let len = edge.map_or(rest, |e| e - tau);
                // Average of the force at both ends of the piece (trapezoid over the physics step,
                // weighted by the piece's share of the substep: 1 for an unsplit substep).
                let f0 = self.actuator.piston_force(&self.chambers);
                let x_piece = if tau == t_sub {
                    xi
                } else {
                    xi + x_dot * (tau - t_sub)
                };
                let k = match &mut consts {
                    Some((s, k)) if s.to_bits() == spool.to_bits() => k,
                    c => &mut c.insert((spool, self.actuator.step_consts(spool))).1,
                };
                k.step(&mut self.chambers, x_piece, x_dot, len);
                f_sum += 0.5 * (f0 + self.actuator.piston_force(&self.chambers)) * (len / h);
                match edge {
                    Some(e) if e < t_end => {
                        tau = e;
                        rest = t_end - e;
                    }
                    _ => break,
                }
            }
            self.time_s += h;
        }
        f_sum / f64::from(n)
    }
}
