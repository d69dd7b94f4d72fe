//! pneuflex-pneumatics: a lumped-parameter model of a pneumatic compliant actuator (Section II of the
//! paper): double-acting cylinder thermodynamics (eqs. 2-10), ISO 6358 valve flow (eq. 11) and its
//! linearisation (eq. 12), a proportional 5/3 valve and a PWM-driven 5/2 on/off valve, the mechanics of
//! eq. (1) with friction, incline and end stops, the transfer function of eqs. (16)-(17), component data
//! sheets as TOML, the cylinder as a force element for an external rigid-body engine, and a pressure
//! regulator in front of each chamber in place of the valve (a pressure command).
//!
//! Units are SI throughout, pressures absolute. `x` is the piston extension from the cap end; chamber A
//! is the cap side, chamber B the rod side; valve command `u = +1` connects supply to A and B to exhaust.
//! See docs/pneumatics.md for the model, the conventions and every resolution of the paper.

pub mod actuator;
pub mod components;
pub mod effects;
pub mod extended;
pub mod flow;
pub mod force_element;
pub(crate) mod lanes;
pub mod mechanics;
mod moves;
mod one_dof;
pub mod regulator;
mod spool;
pub mod tf;
pub mod valve;

pub use actuator::{
    Actuator, ChamberState, Cylinder, Gas, P_ATM, PortFlows, R_AIR, STANDARD_GRAVITY, Supply,
    T_DEFAULT,
};
pub use components::{
    ActuatorSheet, ComponentError, CylinderSheet, FileOverlay, Quantity, SensorSheet, SignalKind,
    SupplySheet, ValveSheet, find_actuator_sheet, load_actuator_sheet,
};
pub use effects::{Effects, LEAKS, Leaks, Lines, SpoolDynamics, WallHeat};
pub use flow::Orifice;
pub use force_element::PneumaticForceElement;
pub use mechanics::ExtendedState;
pub use mechanics::{Friction, Mechanics, OneDofModel, OneDofState};
pub use one_dof::{PACK, Together, advance_together};
pub use regulator::PressureRegulator;
pub use tf::{Linearisation, OperatingPoint, OperatingPointError, TfParams, TransferFunction};
pub use valve::{Openings, PATHS, SpoolHold, ValveKind, ValveModel, ValveState};
