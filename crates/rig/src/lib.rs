//! Real-rig mode: the same `control` crate that runs in simulation drives the real valve.
//!
//! Layers, from the wire up:
//! - [`protocol`]: framed binary protocol to the I/O board (docs/protocol.md), streaming no-panic decoder;
//! - [`serial`]: the host driver over a serial port, a [`Rig`] of raw samples;
//! - [`rig`]: the `Rig` trait and its decorators: [`rig::Calibrated`] (counts to SI), [`rig::Limited`],
//!   [`rig::Watchdog`];
//! - [`supervisor`]: fault latch and valve safe state;
//! - [`clock`]: wall clock, or a simulated clock the emulator runs in lockstep with;
//! - [`rtloop`]: the fixed-rate `sense → Controller::update → actuate` loop with timing statistics;
//! - [`trace`]: the crash-safe `trace.csv` writer;
//! - [`record`]: one run into an output directory that never loses or overwrites data;
//! - [`emulator`]: the pneumatic plant behind a pseudo-terminal speaking the board's protocol, with fault injection.
//! - [`channel_board`]: several actuators on one board (docs/protocol.md §6): the emulated board of N plants
//!   and the host driver of its N-channel frames.

pub mod calib;
pub mod clock;
pub mod error;
// The wire format lives in its own no_std crate, shared with the firmware; these keep its old paths.
pub use pneuflex_protocol as protocol;
pub use pneuflex_protocol::crc;
pub mod rigfile;

pub use error::{ErrorKind, RigError};
pub use rigfile::{RigFile, RigFileError};
pub mod channel_board;
pub mod emulator;
pub mod plant;
pub mod record;
pub mod rig;
pub mod rtloop;
pub mod serial;
pub mod session;
pub mod supervisor;
pub mod trace;
