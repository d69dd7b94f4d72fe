//! The safety supervisor: on any fault the valve is commanded to its safe state in the same tick, and the
//! fault stays latched (the safe command is repeated every tick) until [`Supervisor::reset`].

use pneuflex_control::ValveCommand;

use crate::error::{ErrorKind, RigError};
use crate::rig::Rig;
use crate::rigfile::SafeState;

/// A latched fault.
#[derive(Clone, Debug, PartialEq)]
pub struct Fault {
    /// What kind.
    pub kind: ErrorKind,
    /// What was seen.
    pub message: String,
    /// Control tick at which it was latched.
    pub tick: u64,
    /// Host time, s since the loop started.
    pub host_time_s: f64,
}

/// Wraps a rig: passes commands while healthy, the safe state once a fault is latched.
pub struct Supervisor<R: Rig> {
    rig: R,
    safe_state: SafeState,
    fault: Option<Fault>,
    /// Errors seen after the first fault (the first one stays latched).
    later_errors: u64,
}

impl<R: Rig> Supervisor<R> {
    /// A supervisor over `rig` with the valve's safe state.
    pub fn new(rig: R, safe_state: SafeState) -> Self {
        Self {
            rig,
            safe_state,
            fault: None,
            later_errors: 0,
        }
    }

    /// The latched fault, if any.
    pub fn fault(&self) -> Option<&Fault> {
        self.fault.as_ref()
    }

    /// Errors that occurred while a fault was already latched.
    pub fn later_errors(&self) -> u64 {
        self.later_errors
    }

    /// The supervised rig, read-only.
    pub fn rig(&self) -> &R {
        &self.rig
    }

    /// The supervised rig.
    pub fn rig_mut(&mut self) -> &mut R {
        &mut self.rig
    }

    /// Latches `err` (if nothing is latched yet) and commands the safe state now.
    pub fn trip(&mut self, tick: u64, now_s: f64, err: RigError) {
        if self.fault.is_none() {
            self.fault = Some(Fault {
                kind: err.kind(),
                message: err.message().to_string(),
                tick,
                host_time_s: now_s,
            });
        } else {
            self.later_errors += 1;
        }
        if self.rig.safe(tick as u32, self.safe_state).is_err() {
            self.later_errors += 1;
        }
    }

    /// Reads the rig; an error trips the supervisor. While latched, reads go on (for the trace).
    pub fn sense(&mut self, tick: u64, now_s: f64) -> Option<R::Sample> {
        match self.rig.read(now_s) {
            Ok(s) => s,
            Err(e) => {
                self.trip(tick, now_s, e);
                None
            }
        }
    }

    /// Sends `cmd` while healthy, the safe state while latched; returns what was applied (`None` = safe).
    pub fn actuate(&mut self, tick: u64, now_s: f64, cmd: ValveCommand) -> Option<ValveCommand> {
        if self.fault.is_some() {
            if self.rig.safe(tick as u32, self.safe_state).is_err() {
                self.later_errors += 1;
            }
            return None;
        }
        match self.rig.write(tick as u32, cmd) {
            Ok(()) => Some(cmd),
            Err(e) => {
                self.trip(tick, now_s, e);
                None
            }
        }
    }

    /// Commands the safe state without latching a fault (the normal end of a run).
    pub fn park(&mut self, tick: u64) -> Result<(), RigError> {
        self.rig.safe(tick as u32, self.safe_state)
    }

    /// Clears the latch after the operator has dealt with the cause; the layers below are reset too.
    pub fn reset(&mut self) -> Result<(), RigError> {
        self.rig.reset()?;
        self.fault = None;
        self.later_errors = 0;
        Ok(())
    }
}

impl<R: Rig> Drop for Supervisor<R> {
    /// Whatever ends the run — return, error or panic unwinding — the valve is left in its safe state.
    fn drop(&mut self) {
        let _ = self.rig.safe(u32::MAX, self.safe_state);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rig::tests::Scripted;

    #[test]
    fn fault_is_latched_and_safe_repeated() {
        let mut rig = Scripted::default();
        {
            let mut s = Supervisor::new(&mut rig, SafeState::Hold);
            assert_eq!(
                s.actuate(0, 0.0, ValveCommand { u: 0.3 }),
                Some(ValveCommand { u: 0.3 })
            );
            s.trip(1, 1e-3, RigError::new(ErrorKind::Limit, "x too far"));
            assert_eq!(s.actuate(1, 1e-3, ValveCommand { u: 0.5 }), None);
            assert_eq!(s.actuate(2, 2e-3, ValveCommand { u: 0.5 }), None);
            // A second fault does not overwrite the first.
            s.trip(3, 3e-3, RigError::new(ErrorKind::Timeout, "late"));
            assert_eq!(s.fault().unwrap().kind, ErrorKind::Limit);
            assert_eq!(s.fault().unwrap().tick, 1);
            s.reset().unwrap();
            assert!(s.fault().is_none());
            assert_eq!(
                s.actuate(4, 4e-3, ValveCommand { u: 0.1 }),
                Some(ValveCommand { u: 0.1 })
            );
        }
        assert_eq!(rig.writes, vec![(0, 0.3), (4, 0.1)]);
        // Safe at the trip (tick 1), every latched tick (1, 2), the second trip (3), and on drop.
        let ticks: Vec<u32> = rig.safes.iter().map(|s| s.0).collect();
        assert_eq!(ticks, vec![1, 1, 2, 3, u32::MAX]);
        assert!(rig.safes.iter().all(|s| s.1 == SafeState::Hold));
    }
}
