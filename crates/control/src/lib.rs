//! Controllers for a pneumatic compliant actuator: `#![no_std]`, no allocation.
//!
//! Every plant (ideal loop, 1-DOF pneumatic model, Rapier scene, the real rig) calls a
//! controller the same way: `sense → Controller::update → actuate → advance(dt)`.
#![no_std]

pub mod io;

pub use io::{Controller, Sensors, Setpoint, Telemetry, ValveCommand};
