//! Controllers for a pneumatic compliant actuator: `#![no_std]`, no allocation.
//!
//! Every plant (ideal loop, 1-DOF pneumatic model, Rapier scene, the real rig) calls a
//! controller the same way: `sense → Controller::update → actuate → advance(dt)`.
//! Section III of the paper: impedance filter (eqs. (19)–(24)), adaptive correction
//! (eqs. (25)–(36)), Lyapunov check (eqs. (37)–(38)). Resolutions of the paper's gaps are at
//! each equation and collected in docs/control.md.
#![no_std]

pub mod adaptive;
pub mod controllers;
pub mod error;
pub mod impedance;
pub mod io;
pub mod lyapunov;
pub mod pid;
pub mod reference;
pub mod setup;
pub mod signal;
pub mod tick;

pub use adaptive::{AdaptiveLaw, AdaptiveParams, LambdaDSign, Sigma1Sign, VelocitySource};
pub use controllers::{AdaptiveImpedanceController, ImpedanceController};
pub use error::ParamError;
pub use impedance::{ImpedanceFilter, ImpedanceParams, ZohStep};
pub use io::{Controller, Sensors, Setpoint, Telemetry, ValveCommand};
pub use lyapunov::{
    LyapunovCheckParams, LyapunovReport, MracErrorSystem, MracState, lyapunov_check, solve_lyapunov,
};
pub use pid::{AntiWindup, Pid, PidParams};
pub use reference::{Reference, SCHEDULE_CAPACITY, Schedule, SetpointSchedule};
pub use setup::{ControllerSetup, SetUpController, SetupError};
pub use signal::{LOOP_SIGNALS, Signal, Sink};
pub use tick::{control_tick, run_loops, write_loop_row};
