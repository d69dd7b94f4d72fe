//! Time for the loop and the emulator: the wall clock on a rig, or a simulated clock that the loop steps
//! (the emulator then runs in lockstep with it, so tests do not depend on how fast the machine is).

use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};

/// A monotonic clock in seconds since its start.
pub trait Clock {
    /// Seconds since the clock started.
    fn now(&self) -> f64;
    /// Returns at `t` or later: sleeps (and spins) on the wall clock, jumps on a simulated one.
    fn wait_until(&mut self, t: f64);
}

/// The host's monotonic clock; sleeps, then busy-waits the last `spin` before a deadline.
#[derive(Clone, Copy, Debug)]
pub struct WallClock {
    start: Instant,
    spin: Duration,
}

impl WallClock {
    /// A clock starting now.
    pub fn new(spin: Duration) -> Self {
        Self {
            start: Instant::now(),
            spin,
        }
    }
}

impl Clock for WallClock {
    fn now(&self) -> f64 {
        self.start.elapsed().as_secs_f64()
    }

    fn wait_until(&mut self, t: f64) {
        if !(t.is_finite() && t >= 0.0) {
            return;
        }
        let deadline = self.start + Duration::from_secs_f64(t);
        loop {
            let now = Instant::now();
            if now >= deadline {
                return;
            }
            let left = deadline - now;
            if left > self.spin {
                std::thread::sleep(left - self.spin);
            } else {
                std::hint::spin_loop();
            }
        }
    }
}

/// A simulated clock in whole nanoseconds, shared by clones: `wait_until` sets it forward at once.
#[derive(Clone, Debug, Default)]
pub struct SimClock(Arc<AtomicU64>);

impl SimClock {
    /// A clock at 0.
    pub fn new() -> Self {
        Self::default()
    }

    /// Nanoseconds since the start.
    pub fn now_ns(&self) -> u64 {
        self.0.load(Ordering::SeqCst)
    }
}

impl Clock for SimClock {
    fn now(&self) -> f64 {
        self.now_ns() as f64 * 1e-9
    }

    fn wait_until(&mut self, t: f64) {
        if t.is_finite() && t > 0.0 {
            let ns = (t * 1e9).round().min(u64::MAX as f64) as u64;
            self.0.fetch_max(ns, Ordering::SeqCst);
        }
    }
}

impl<C: Clock + ?Sized> Clock for &mut C {
    fn now(&self) -> f64 {
        (**self).now()
    }
    fn wait_until(&mut self, t: f64) {
        (**self).wait_until(t)
    }
}
