//! What a scene's runs may cost, estimated before anything runs: ticks, integration steps, trace memory.

use super::{ControllerKind, Scene};
use crate::error::SceneError;

/// What a run may cost before it starts; beyond either limit `run` refuses with the estimate and the flag
/// that raises it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Limits {
    /// Largest number of integration steps per run (RK4 substeps or physics steps, the finest of them).
    pub max_steps_per_run: u64,
    /// Largest memory the traces of all runs may take, bytes.
    pub max_trace_bytes: u64,
}

impl Default for Limits {
    fn default() -> Self {
        // 1e9 steps is ~3 min of the 1-DOF plant or ~3 h of the multibody rig on this project's reference
        // machine; 2 GiB of traces is 24 M rows of 11 columns.
        Self {
            max_steps_per_run: 1_000_000_000,
            max_trace_bytes: 2 << 30,
        }
    }
}

/// The size of a scene's runs, estimated before anything runs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Budget {
    /// Control ticks per run.
    pub ticks_per_run: u64,
    /// Finest integration steps per run (chamber RK4 substeps, or physics steps times chamber substeps).
    pub steps_per_run: u64,
    /// Memory of all runs' traces, bytes.
    pub trace_bytes: u64,
}

impl Scene {
    /// Estimates the ticks, integration steps and trace memory of the scene's runs.
    pub fn budget(&self) -> Budget {
        let ticks = (self.duration_s / self.dt_s).round().max(0.0);
        let fine_per_tick = self.plant.steps_per_tick(self.dt_s);
        // Rows are ticks + 1; 11 columns of f64 for adaptive runs, 8 otherwise.
        let row_bytes: f64 = self
            .runs
            .iter()
            .map(|r| {
                if r.controller == ControllerKind::Adaptive {
                    88.0
                } else {
                    64.0
                }
            })
            .sum();
        let sat = |x: f64| {
            if x >= u64::MAX as f64 {
                u64::MAX
            } else {
                x as u64
            }
        };
        Budget {
            ticks_per_run: sat(ticks),
            steps_per_run: sat(ticks * fine_per_tick),
            trace_bytes: sat((ticks + 1.0) * row_bytes),
        }
    }

    /// Refuses a scene whose runs would exceed `limits`, with the estimate and how to raise the limit.
    pub fn check_budget(&self, limits: &Limits) -> Result<Budget, SceneError> {
        let b = self.budget();
        if b.steps_per_run > limits.max_steps_per_run {
            let key = self.plant.step_key();
            return Err(self.invalid(
                key,
                format!(
                    "the scene needs {:.3e} integration steps per run (duration_s = {} s, dt_s = {} s, and this key), \
                     more than the limit of {:.3e}; use a coarser step or a shorter duration, or raise the limit with \
                     `--max-steps {}`",
                    b.steps_per_run as f64,
                    self.duration_s,
                    self.dt_s,
                    limits.max_steps_per_run as f64,
                    b.steps_per_run
                ),
            ));
        }
        if b.trace_bytes > limits.max_trace_bytes {
            return Err(self.invalid(
                "duration_s",
                format!(
                    "the traces of {} run(s) of {} ticks need {:.0} MiB, more than the limit of {:.0} MiB; \
                     shorten the run or raise the limit with `--max-trace-mb {}`",
                    self.runs.len(),
                    b.ticks_per_run,
                    b.trace_bytes as f64 / 1048576.0,
                    limits.max_trace_bytes as f64 / 1048576.0,
                    b.trace_bytes.div_ceil(1 << 20)
                ),
            ));
        }
        Ok(b)
    }
}
