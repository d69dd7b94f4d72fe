//! The real-time loop: at a fixed rate, `sense → Controller::update → actuate → trace`, generic over any
//! controller and rig. It counts overruns and records the period error and the time spent in I/O and in the
//! controller.

use std::io::Write;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use pneuflex_control::{Controller, Sensors, Setpoint, Telemetry, ValveCommand};

use crate::error::{ErrorKind, RigError};
use crate::rig::{Rig, SiSample};
use crate::supervisor::{Fault, Supervisor};
use crate::trace::{TraceRow, TraceWriter};

/// How to run the loop.
#[derive(Clone, Debug, PartialEq)]
pub struct RunOptions {
    /// Control rate, Hz.
    pub rate_hz: f64,
    /// Busy-wait this long before each deadline, µs.
    pub spin_us: u64,
    /// Run length, s (the loop also ends `post_fault_s` after a fault).
    pub duration_s: f64,
    /// Time to keep tracing after a fault, s.
    pub post_fault_s: f64,
    /// How long to wait for the first sample before tick 0, s.
    pub first_sample_timeout_s: f64,
}

/// p50, p99 and max of a timing series, s.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Percentiles {
    /// Median.
    pub p50: f64,
    /// 99th percentile.
    pub p99: f64,
    /// Maximum.
    pub max: f64,
    /// Mean.
    pub mean: f64,
}

impl Percentiles {
    /// Percentiles of `v` (nearest-rank; empty gives zeros).
    pub fn of(v: &[f64]) -> Self {
        if v.is_empty() {
            return Self::default();
        }
        let mut s = v.to_vec();
        s.sort_by(f64::total_cmp);
        let rank = |q: f64| s[((q * s.len() as f64).ceil() as usize).clamp(1, s.len()) - 1];
        Self {
            p50: rank(0.50),
            p99: rank(0.99),
            max: s[s.len() - 1],
            mean: s.iter().sum::<f64>() / s.len() as f64,
        }
    }
}

/// What a run did.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LoopReport {
    /// Ticks executed (= trace rows).
    pub ticks: u64,
    /// Ticks whose work ended after the next tick's deadline.
    pub overruns: u64,
    /// Ticks in which no new sample had arrived (the previous one was used).
    pub ticks_without_sample: u64,
    /// |actual period - nominal period|, s.
    pub period_error: Percentiles,
    /// Lateness of each tick's start against its ideal time k·T, s.
    pub lateness: Percentiles,
    /// Host time per tick in I/O (sense + actuate), s.
    pub io: Percentiles,
    /// Host time per tick in the controller, s.
    pub controller: Percentiles,
    /// The latched fault, if any.
    pub fault: Option<Fault>,
}

impl std::fmt::Display for LoopReport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let us = |p: &Percentiles| {
            format!(
                "p50 {:.1} µs, p99 {:.1} µs, max {:.1} µs",
                p.p50 * 1e6,
                p.p99 * 1e6,
                p.max * 1e6
            )
        };
        writeln!(
            f,
            "ticks {}, overruns {}, ticks without a new sample {}",
            self.ticks, self.overruns, self.ticks_without_sample
        )?;
        writeln!(f, "period error   {}", us(&self.period_error))?;
        writeln!(f, "start lateness {}", us(&self.lateness))?;
        writeln!(f, "I/O per tick   {}", us(&self.io))?;
        writeln!(f, "controller     {}", us(&self.controller))?;
        match &self.fault {
            Some(x) => write!(f, "fault: {} at tick {}: {}", x.kind, x.tick, x.message),
            None => write!(f, "no fault"),
        }
    }
}

/// Sleeps, then spins, until `deadline`.
fn wait_until(deadline: Instant, spin: Duration) {
    loop {
        let now = Instant::now();
        if now >= deadline {
            return;
        }
        let left = deadline - now;
        if left > spin {
            std::thread::sleep(left - spin);
        } else {
            std::hint::spin_loop();
        }
    }
}

/// Runs the loop until `duration_s`, `stop` (Ctrl-C), or `post_fault_s` after a fault. Every tick is traced.
/// A controller panic, a NaN command, a set `stop` flag or any rig error latches a fault and puts the valve in
/// its safe state in that same tick. The valve is parked in its safe state at the end.
pub fn run<R, C, W>(
    sup: &mut Supervisor<R>,
    controller: &mut C,
    reference: &mut dyn FnMut(f64) -> Setpoint,
    trace: &mut TraceWriter<W>,
    opts: &RunOptions,
    stop: &AtomicBool,
) -> std::io::Result<LoopReport>
where
    R: Rig<Sample = SiSample>,
    C: Controller + ?Sized,
    W: Write,
{
    let period = Duration::from_secs_f64(1.0 / opts.rate_hz);
    let dt = period.as_secs_f64();
    let n_ticks = (opts.duration_s / dt).round() as u64;
    let post_fault_ticks = (opts.post_fault_s / dt).round() as u64;
    let spin = Duration::from_micros(opts.spin_us);
    let cap = (n_ticks + post_fault_ticks + 1) as usize;
    let mut period_err = Vec::with_capacity(cap);
    let mut lateness = Vec::with_capacity(cap);
    let mut io_t = Vec::with_capacity(cap);
    let mut ctrl_t = Vec::with_capacity(cap);
    let mut report = LoopReport::default();

    let t0 = Instant::now();
    let wall0 = SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map(|d| d.as_secs_f64())
        .unwrap_or(0.0);
    let host = |i: Instant| (i - t0).as_secs_f64();

    // Wait for the first sample so that tick 0 has sensors (the watchdog arms on the first read).
    let mut last: Option<SiSample> = None;
    while last.is_none() && sup.fault().is_none() {
        let now = Instant::now();
        if host(now) > opts.first_sample_timeout_s {
            sup.trip(
                0,
                host(now),
                RigError::new(ErrorKind::Timeout, "no first sample from the rig"),
            );
            break;
        }
        last = sup.sense(0, host(now));
        if last.is_none() {
            std::thread::sleep(Duration::from_micros(200));
        }
    }

    let start = Instant::now();
    let mut prev_start: Option<Instant> = None;
    let mut fault_tick: Option<u64> = None;
    let mut k: u64 = 0;
    let mut fault_label = String::new();
    loop {
        if k >= n_ticks && fault_tick.is_none() {
            break;
        }
        if let Some(kf) = fault_tick
            && k > kf + post_fault_ticks
        {
            break;
        }
        let deadline = start + period.mul_f64(k as f64);
        wait_until(deadline, spin);
        let t_start = Instant::now();
        lateness.push((t_start - deadline).as_secs_f64());
        if let Some(p) = prev_start {
            period_err.push(((t_start - p).as_secs_f64() - dt).abs());
        }
        prev_start = Some(t_start);
        let now_s = host(t_start);
        let t = k as f64 * dt;

        if stop.load(Ordering::Relaxed) && sup.fault().is_none() {
            sup.trip(
                k,
                now_s,
                RigError::new(ErrorKind::Interrupted, "stopped by the operator (Ctrl-C)"),
            );
        }

        // sense
        match sup.sense(k, now_s) {
            Some(s) => last = Some(s),
            None => report.ticks_without_sample += 1,
        }
        let t_sensed = Instant::now();

        // update
        let setpoint = reference(t);
        let mut cmd = ValveCommand::default();
        let mut telemetry = Telemetry::default();
        if sup.fault().is_none()
            && let Some(s) = last
        {
            let sensors = Sensors { t, ..s.sensors };
            match catch_unwind(AssertUnwindSafe(|| {
                controller.update(&sensors, &setpoint, dt)
            })) {
                Ok(c) if c.u.is_finite() => {
                    cmd = c;
                    telemetry = controller.telemetry();
                }
                Ok(c) => sup.trip(
                    k,
                    now_s,
                    RigError::new(
                        ErrorKind::NotANumber,
                        format!("controller output u = {}", c.u),
                    ),
                ),
                Err(_) => sup.trip(
                    k,
                    now_s,
                    RigError::new(ErrorKind::Panic, "the controller panicked"),
                ),
            }
        }
        let t_updated = Instant::now();

        // actuate
        let applied = sup.actuate(k, now_s, cmd);
        let t_done = Instant::now();
        io_t.push(((t_sensed - t_start) + (t_done - t_updated)).as_secs_f64());
        ctrl_t.push((t_updated - t_sensed).as_secs_f64());
        if t_done > deadline + period {
            report.overruns += 1;
        }

        // trace
        let fault_str: &str = match (sup.fault(), fault_tick) {
            (Some(f), None) => {
                fault_tick = Some(k);
                fault_label = f.kind.name().to_string();
                // The first faulty row carries the message.
                report.fault = Some(f.clone());
                let msg = format!("{}: {}", f.kind.name(), f.message);
                let sensors = last.map(|s| s.sensors).unwrap_or_default();
                trace.row(&row(
                    t,
                    &setpoint,
                    &sensors,
                    &telemetry,
                    0.0,
                    wall0 + now_s,
                    &msg,
                ))?;
                report.ticks += 1;
                k += 1;
                continue;
            }
            (Some(_), Some(_)) => &fault_label,
            (None, _) => "",
        };
        let sensors = last.map(|s| s.sensors).unwrap_or_default();
        let u = applied.map(|c| c.u).unwrap_or(0.0);
        trace.row(&row(
            t,
            &setpoint,
            &sensors,
            &telemetry,
            u,
            wall0 + now_s,
            fault_str,
        ))?;
        report.ticks += 1;
        k += 1;
    }
    if let Err(e) = sup.park(k)
        && report.fault.is_none()
    {
        report.fault = Some(Fault {
            kind: e.kind(),
            message: format!("could not park the valve at the end: {}", e.message()),
            tick: k,
            host_time_s: host(Instant::now()),
        });
    }
    trace.flush()?;
    report.period_error = Percentiles::of(&period_err);
    report.lateness = Percentiles::of(&lateness);
    report.io = Percentiles::of(&io_t);
    report.controller = Percentiles::of(&ctrl_t);
    Ok(report)
}

fn row<'a>(
    t: f64,
    sp: &Setpoint,
    s: &Sensors,
    tel: &Telemetry,
    u: f64,
    wall: f64,
    fault: &'a str,
) -> TraceRow<'a> {
    TraceRow {
        t,
        f_ref: sp.f_ref,
        f_e: s.f_e,
        x: s.x,
        x_r: tel.x_r,
        p_a: s.p_a,
        p_b: s.p_b,
        u,
        g: tel.g,
        p: tel.p,
        d: tel.d,
        wall_time: wall,
        fault,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn percentiles_nearest_rank() {
        let v: Vec<f64> = (1..=100).map(f64::from).collect();
        let p = Percentiles::of(&v);
        assert_eq!((p.p50, p.p99, p.max), (50.0, 99.0, 100.0));
        assert!((p.mean - 50.5).abs() < 1e-12);
        assert_eq!(Percentiles::of(&[]), Percentiles::default());
    }
}
