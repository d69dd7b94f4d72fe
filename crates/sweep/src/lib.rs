//! Sweeps, robustness maps and automatic tuning of pneuflex scenes.
//!
//! A sweep sets scene keys (and actuator-sheet values) to the values of a grid or a sample
//! ([`points`]), writes each point's values into a copy of the scene's text ([`key`]) so that the scene's
//! own parser and validation judge every point before anything runs, then runs the points on a rayon pool
//! ([`engine`]): one table row per point and run, the same bytes whatever the number of threads.
//! `docs/sweeps.md` describes the command line, the key paths and the table.

pub mod engine;
pub mod key;
pub mod output;
pub mod points;
pub mod tune;
pub mod tune_output;

pub use engine::{Checking, MetricColumn, PointResult, RunRow, Status, Sweep, SweepError};
pub use key::{KeyPath, Value};
pub use points::{SetArg, Spec};
