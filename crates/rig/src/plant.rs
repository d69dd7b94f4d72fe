//! Plants the emulator can run: a small trait, and the pneumatic 1-DOF model of `pneuflex-pneumatics`
//! pushing the linear-spring environment of eq. (21).

use pneuflex_pneumatics::{ChamberState, OneDofModel, OneDofState};

use crate::rigfile::EnvironmentConfig;

/// What the board does to the valve.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ValveDrive {
    /// Normal operation: command u in [-1, 1].
    Run(f64),
    /// Safe state: both chambers to exhaust.
    Vent,
    /// Safe state: valve centred (closed on a closed-centre 5/3 valve).
    Hold,
}

/// The plant's measurable state, SI (pressures absolute).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PlantSample {
    /// Flange position, m.
    pub x: f64,
    /// Flange velocity, m/s.
    pub x_dot: f64,
    /// Chamber A pressure, Pa.
    pub p_a: f64,
    /// Chamber B pressure, Pa.
    pub p_b: f64,
    /// Supply pressure, Pa.
    pub supply_pa: f64,
}

/// A plant the emulator advances in real time.
pub trait EmulatedPlant: Send {
    /// Advances by `dt` under the valve drive and an external force on the flange `f_ext_n` (N, along +x).
    fn step(&mut self, drive: ValveDrive, f_ext_n: f64, dt: f64);
    /// The current state.
    fn sample(&self) -> PlantSample;
    /// Changes the supply pressure (supply loss), Pa absolute.
    fn set_supply_pa(&mut self, p: f64);
    /// Puts the plant back in the state it was made in (a new run starts from the scene's initial state,
    /// whatever the last run left: position, chambers, supply).
    fn restart(&mut self);
}

/// Several actuators coupled by one mechanism (a gripper's two fingers on one part): the plant of a board with
/// several channels, advanced as one under every channel's valve, each channel sensed on its own. The
/// mechanism's own contacts are its environment, and its own events (a part stiffening) come at their
/// experiment time.
pub trait CoupledPlant: Send {
    /// Channels (actuators), in the board's order.
    fn channels(&self) -> usize;
    /// Advances by `dt` from experiment time `t`, channel i's valve under `drives[i]`.
    fn step(&mut self, t: f64, drives: &[ValveDrive], dt: f64);
    /// Channel i's measurable state.
    fn sample(&self, i: usize) -> PlantSample;
    /// Channel i's load cell, N (positive = the actuator pushes on what it holds).
    fn load_n(&self, i: usize) -> f64;
    /// Changes channel i's supply pressure (supply loss), Pa absolute.
    fn set_supply_pa(&mut self, i: usize, p: f64);
    /// Back to the state it was made in (a new run: positions, chambers, supplies, the events not yet come).
    fn restart(&mut self);
}

/// The plant of one channel of a board whose channels share a [`CoupledPlant`]: it holds no physics, only
/// what the channel's board asked of its plant this period (a restart, a supply loss), for the coupled board
/// to pass on, and the channel's latest state.
#[derive(Clone, Debug, Default)]
pub struct Detached {
    /// The latest state of this channel of the mechanism.
    pub state: PlantSample,
    /// A new run was asked for (a Config frame).
    pub restart_asked: bool,
    /// A supply pressure was set (an injected supply loss), Pa absolute.
    pub supply_asked: Option<f64>,
}

impl EmulatedPlant for Detached {
    /// Never called: the coupled board advances the mechanism itself.
    fn step(&mut self, _drive: ValveDrive, _f_ext_n: f64, _dt: f64) {}

    fn sample(&self) -> PlantSample {
        self.state
    }

    fn set_supply_pa(&mut self, p: f64) {
        self.supply_asked = Some(p);
    }

    fn restart(&mut self) {
        self.restart_asked = true;
    }
}

/// The pneumatic 1-DOF plant (cylinder thermodynamics, valve flow, eq. (1) mechanics).
#[derive(Clone, Debug)]
pub struct PneumaticPlant {
    model: OneDofModel,
    state: OneDofState,
    supply_pa: f64,
    /// The state and supply it was made with, for [`EmulatedPlant::restart`].
    initial: (OneDofState, f64),
}

impl PneumaticPlant {
    /// The plant at rest at `x0_m` with both chambers at atmosphere and the given supply pressure.
    pub fn new(mut model: OneDofModel, x0_m: f64, supply_pa: f64) -> Self {
        model.actuator.supply.supply_pressure_pa = supply_pa;
        let p0 = model.actuator.supply.atmosphere_pressure_pa;
        let state = OneDofState::at_rest(x0_m, ChamberState::new(p0, p0), 0.0);
        Self {
            initial: (state, supply_pa),
            state,
            model,
            supply_pa,
        }
    }

    /// The full model state.
    pub fn state(&self) -> &OneDofState {
        &self.state
    }
}

impl EmulatedPlant for PneumaticPlant {
    fn step(&mut self, drive: ValveDrive, f_ext_n: f64, dt: f64) {
        let u = match drive {
            ValveDrive::Run(u) => u,
            // Vent: the supply dump valve connects the supply port to atmosphere; with the spool at +1 both
            // chambers then see atmosphere (A through the supply port, B through the exhaust).
            ValveDrive::Vent => 1.0,
            ValveDrive::Hold => 0.0,
        };
        let p_s = if matches!(drive, ValveDrive::Vent) {
            self.model.actuator.supply.atmosphere_pressure_pa
        } else {
            self.supply_pa
        };
        self.model.actuator.supply.supply_pressure_pa = p_s;
        self.model.step(&mut self.state, u, f_ext_n, dt);
    }

    fn sample(&self) -> PlantSample {
        PlantSample {
            x: self.state.x,
            x_dot: self.state.x_dot,
            p_a: self.state.chambers.p_a,
            p_b: self.state.chambers.p_b,
            supply_pa: self.supply_pa,
        }
    }

    fn set_supply_pa(&mut self, p: f64) {
        self.supply_pa = p;
    }

    fn restart(&mut self) {
        let (state, supply_pa) = &self.initial;
        self.state = *state;
        self.supply_pa = *supply_pa;
        self.model.actuator.supply.supply_pressure_pa = *supply_pa;
    }
}

/// The environment spring of eq. (21), f_e = k_e (x - x_e), zero out of contact (x < x_e), with one
/// stiffness change (wood -> iron).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Environment {
    /// Contact position x_e, m.
    pub x_e_m: f64,
    /// Stiffness before the change, N/m.
    pub k_before: f64,
    /// Stiffness after the change, N/m.
    pub k_after: f64,
    /// Time of the change, s.
    pub change_at_s: f64,
}

impl Environment {
    /// No environment: never in contact.
    pub const NONE: Self = Self {
        x_e_m: f64::INFINITY,
        k_before: 0.0,
        k_after: 0.0,
        change_at_s: f64::INFINITY,
    };

    /// From the rig file's `[emulator.environment]`.
    pub fn from_config(c: &EnvironmentConfig) -> Self {
        Self {
            x_e_m: c.x_e_m,
            k_before: c.k_e_n_per_m,
            k_after: c.k_e_after_n_per_m.unwrap_or(c.k_e_n_per_m),
            change_at_s: c.change_at_s.unwrap_or(f64::INFINITY),
        }
    }

    /// Stiffness at time `t`, N/m.
    pub fn k_e(&self, t: f64) -> f64 {
        if t < self.change_at_s {
            self.k_before
        } else {
            self.k_after
        }
    }

    /// Contact force at time `t` and position `x`, N (positive = the flange pushes). eq. (21)
    pub fn force(&self, t: f64, x: f64) -> f64 {
        if x < self.x_e_m {
            0.0
        } else {
            self.k_e(t) * (x - self.x_e_m)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spring_contact_and_change() {
        let e = Environment {
            x_e_m: 0.02,
            k_before: 700.0,
            k_after: 1400.0,
            change_at_s: 6.0,
        };
        assert_eq!(e.force(0.0, 0.01), 0.0);
        assert!((e.force(1.0, 0.03) - 7.0).abs() < 1e-12);
        assert!((e.force(6.0, 0.03) - 14.0).abs() < 1e-12);
    }
}
