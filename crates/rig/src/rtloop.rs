//! The real-time loop: at a fixed rate, `sense → Controller::update → actuate → trace`, generic over any
//! controller and rig. It counts overruns and records the period error and the time spent in I/O and in the
//! controller.

use std::panic::{AssertUnwindSafe, catch_unwind};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, SystemTime, UNIX_EPOCH};

use pneuflex_control::{Controller, Sensors, Setpoint, Telemetry, ValveCommand};

use crate::clock::{Clock, WallClock};
use crate::error::{ErrorKind, RigError};
use crate::rig::{Rig, SiSample};
use crate::supervisor::{Fault, Supervisor};
use crate::trace::{TraceRow, TraceSink, TraceWriter};

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
    /// Control time reached, s (ticks × period).
    pub time_reached_s: f64,
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

/// Longest run `rig run` accepts, s (24 h: 8.6e7 ticks at 1 kHz, a trace of about 13 GB; the wire's u32
/// tick counter wraps only after 49 days at 1 kHz).
pub const MAX_DURATION_S: f64 = 86_400.0;

/// A run option out of range: which option, and what was expected and found.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("{option}: {message}")]
pub struct OptionError {
    /// The option (`duration`, `rate_hz`, `spin_us`, ...).
    pub option: &'static str,
    /// What was expected and what was found.
    pub message: String,
}

fn option_err(option: &'static str, message: String) -> OptionError {
    OptionError { option, message }
}

/// Checks a run length: finite, > 0 and at most [`MAX_DURATION_S`].
pub fn check_duration(d: f64) -> Result<(), OptionError> {
    if d.is_finite() && d > 0.0 && d <= MAX_DURATION_S {
        Ok(())
    } else {
        Err(option_err(
            "duration",
            format!(
                "expected a duration in seconds, finite, > 0 and at most {MAX_DURATION_S} (24 h); got {d}"
            ),
        ))
    }
}

impl RunOptions {
    /// Checks every option; the error names the option.
    pub fn validate(&self) -> Result<(), OptionError> {
        check_duration(self.duration_s)?;
        if !(self.rate_hz.is_finite() && (1.0..=20_000.0).contains(&self.rate_hz)) {
            return Err(option_err(
                "rate_hz",
                format!("expected 1..=20000 Hz, got {}", self.rate_hz),
            ));
        }
        if self.spin_us as f64 >= 1e6 / self.rate_hz {
            return Err(option_err(
                "spin_us",
                format!(
                    "{} µs is not below the control period {} µs",
                    self.spin_us,
                    1e6 / self.rate_hz
                ),
            ));
        }
        for (name, v, max) in [
            ("post_fault_s", self.post_fault_s, 60.0),
            ("first_sample_timeout_s", self.first_sample_timeout_s, 60.0),
        ] {
            if !(v.is_finite() && (0.0..=max).contains(&v)) {
                return Err(option_err(name, format!("expected 0..={max} s, got {v}")));
            }
        }
        Ok(())
    }
}

/// Streaming p50/p99/max/mean of non-negative times in constant memory, whatever the run length:
/// log-spaced bins 1 % wide from 1 ns up (values at or below 1 ns count as 0), so a percentile is within
/// 1 % of the nearest-rank value; max and mean are exact.
#[derive(Clone, Debug)]
pub struct TimingStats {
    bins: Vec<u64>,
    n: u64,
    sum: f64,
    max: f64,
}

const BIN_LO: f64 = 1e-9;
const BIN_GROWTH: f64 = 1.01;
/// 1 ns · 1.01^3240 ≈ 1e5 s; anything longer lands in the last bin (max stays exact).
const BINS: usize = 3241;

impl Default for TimingStats {
    fn default() -> Self {
        Self {
            bins: vec![0; BINS],
            n: 0,
            sum: 0.0,
            max: 0.0,
        }
    }
}

impl TimingStats {
    fn index(v: f64) -> usize {
        if v.is_nan() || v <= BIN_LO {
            0
        } else {
            (1 + ((v / BIN_LO).ln() / BIN_GROWTH.ln()).floor() as usize).min(BINS - 1)
        }
    }

    /// Adds one value, s.
    pub fn push(&mut self, v: f64) {
        let v = if v.is_finite() { v.max(0.0) } else { 0.0 };
        self.bins[Self::index(v)] += 1;
        self.n += 1;
        self.sum += v;
        self.max = self.max.max(v);
    }

    /// Values added.
    pub fn count(&self) -> u64 {
        self.n
    }

    fn rank(&self, q: f64) -> f64 {
        let r = ((q * self.n as f64).ceil() as u64).clamp(1, self.n);
        let mut seen = 0;
        for (i, &c) in self.bins.iter().enumerate() {
            seen += c;
            if seen >= r {
                if i == 0 {
                    return 0.0;
                }
                // Geometric middle of bin i = [lo·g^(i-1), lo·g^i).
                return (BIN_LO * BIN_GROWTH.powf(i as f64 - 0.5)).min(self.max);
            }
        }
        self.max
    }

    /// The summary (zeros when empty).
    pub fn percentiles(&self) -> Percentiles {
        if self.n == 0 {
            return Percentiles::default();
        }
        Percentiles {
            p50: self.rank(0.50),
            p99: self.rank(0.99),
            max: self.max,
            mean: self.sum / self.n as f64,
        }
    }
}

/// The real rig around the controller ([`pneuflex_control::tick::run_loop`]): each tick waits for its
/// deadline on the clock, reads the sensors and writes the valve through the supervisor (which latches
/// faults and commands the safe state), guards the controller against panics and NaN, streams the row to
/// the trace and the observer, and keeps the timing statistics. After a fault the loop runs on for
/// `post_fault_s` with the valve safe, tracing what the rig does.
struct RigHost<'a, R: Rig<Sample = SiSample>, W: TraceSink, K: Clock + ?Sized> {
    sup: &'a mut Supervisor<R>,
    trace: &'a mut TraceWriter<W>,
    clock: &'a mut K,
    observer: &'a mut dyn pneuflex_control::Sink<()>,
    stop: &'a AtomicBool,
    /// Clock reading at the loop's start, and the host time of tick 0, s.
    t0: f64,
    start: f64,
    /// Wall-clock time (UNIX) at t0, s.
    wall0: f64,
    dt: f64,
    n_ticks: u64,
    post_fault_ticks: u64,
    /// The last sample (the one before tick 0 included).
    last: Option<SiSample>,
    prev_start: Option<f64>,
    /// This tick's |start − last start − dt|, s.
    period_error: f64,
    /// Values of a row that go to the trace (the rest, the link's quality, only to observers).
    n_trace: usize,
    fault_tick: Option<u64>,
    fault_label: String,
    /// This tick's host times: its start, deadline, after sensing, after the controller.
    now_s: f64,
    deadline: f64,
    t_sensed: f64,
    t_updated: f64,
    period_err: &'a mut TimingStats,
    lateness: &'a mut TimingStats,
    io_t: &'a mut TimingStats,
    ctrl_t: &'a mut TimingStats,
    report: &'a mut LoopReport,
}

impl<R: Rig<Sample = SiSample>, W: TraceSink, K: Clock + ?Sized> RigHost<'_, R, W, K> {
    fn host_time(&self) -> f64 {
        self.clock.now() - self.t0
    }
}

impl<R: Rig<Sample = SiSample>, W: TraceSink, K: Clock + ?Sized> pneuflex_control::tick::LoopHost
    for RigHost<'_, R, W, K>
{
    type Error = std::io::Error;

    fn begin_tick(&mut self, k: u64, _t: f64) -> std::io::Result<pneuflex_control::tick::Flow> {
        use pneuflex_control::tick::Flow;
        match self.fault_tick {
            None if k >= self.n_ticks => return Ok(Flow::Stop),
            Some(kf) if k > kf + self.post_fault_ticks => return Ok(Flow::Stop),
            _ => {}
        }
        self.deadline = self.start + k as f64 * self.dt;
        self.clock.wait_until(self.t0 + self.deadline);
        self.now_s = self.host_time();
        self.lateness.push(self.now_s - self.deadline);
        if let Some(p) = self.prev_start {
            self.period_error = (self.now_s - p - self.dt).abs();
            self.period_err.push(self.period_error);
        }
        self.prev_start = Some(self.now_s);
        if self.stop.load(Ordering::Relaxed) && self.sup.fault().is_none() {
            self.sup.trip(
                k,
                self.now_s,
                RigError::new(
                    ErrorKind::Interrupted,
                    "stopped by a signal (SIGINT/Ctrl-C, SIGTERM or SIGHUP)",
                ),
            );
        }
        Ok(Flow::Continue)
    }

    // One actuator on the rig (issue 43 brings several): `_actuator` is 0.
    fn sense(&mut self, k: u64, _t: f64, _actuator: usize) -> Option<Sensors> {
        match self.sup.sense(k, self.now_s) {
            Some(s) => self.last = Some(s),
            None => self.report.ticks_without_sample += 1,
        }
        self.t_sensed = self.host_time();
        self.t_updated = self.t_sensed;
        self.last.map(|s| s.sensors)
    }

    fn may_control(&self) -> bool {
        self.sup.fault().is_none()
    }

    fn record(&mut self, row: &mut [f64]) {
        if let (Some(l), [frames, crc, gaps, period, ..]) = (self.sup.rig().link_stats(), row) {
            *frames = l.decoder.frames as f64;
            *crc = l.decoder.crc_errors as f64;
            *gaps = l.seq_gaps as f64;
            *period = self.period_error;
        }
    }

    fn guard_update(
        &mut self,
        k: u64,
        _t: f64,
        _actuator: usize,
        update: &mut dyn FnMut() -> (ValveCommand, Telemetry),
    ) -> Option<(ValveCommand, Telemetry)> {
        let out = match catch_unwind(AssertUnwindSafe(update)) {
            Ok((c, tel)) if c.u.is_finite() => Some((c, tel)),
            Ok((c, _)) => {
                self.sup.trip(
                    k,
                    self.now_s,
                    RigError::new(
                        ErrorKind::NotANumber,
                        format!("controller output u = {}", c.u),
                    ),
                );
                None
            }
            Err(_) => {
                self.sup.trip(
                    k,
                    self.now_s,
                    RigError::new(ErrorKind::Panic, "the controller panicked"),
                );
                None
            }
        };
        self.t_updated = self.host_time();
        out
    }

    fn actuate(
        &mut self,
        k: u64,
        _t: f64,
        _actuator: usize,
        command: &ValveCommand,
        _tel: &Telemetry,
    ) -> f64 {
        let applied = self.sup.actuate(k, self.now_s, *command);
        let t_done = self.host_time();
        self.io_t
            .push((self.t_sensed - self.now_s) + (t_done - self.t_updated));
        self.ctrl_t.push(self.t_updated - self.t_sensed);
        if t_done > self.deadline + self.dt {
            self.report.overruns += 1;
        }
        applied.map(|c| c.u).unwrap_or(0.0)
    }

    fn end_tick(
        &mut self,
        k: u64,
        _t: f64,
        row: &mut [f64],
    ) -> std::io::Result<pneuflex_control::tick::Flow> {
        let wall_time = self.wall0 + self.now_s;
        // The board's record: the oldest sample and the oldest echo of an applied command (docs/protocol.md,
        // 0x07) not written yet, on the board's clock, so that a replay knows what the board measured and
        // what the valve did, and when, whatever this loop's timing.
        let sampled = self.sup.rig_mut().take_sampled();
        let applied = self.sup.rig_mut().take_applied();
        let written = match (self.sup.fault(), self.fault_tick) {
            (Some(f), None) => {
                self.fault_tick = Some(k);
                self.fault_label = f.kind.name().to_string();
                // The first faulty row carries the message, and is made durable at once; its command
                // reads 0 (the safe state is what the supervisor sent).
                self.report.fault = Some(f.clone());
                let msg = format!("{}: {}", f.kind.name(), f.message);
                row[pneuflex_control::signal::index::U] = 0.0;
                self.observer.event(
                    row[pneuflex_control::signal::index::T],
                    &format!("fault at tick {k}: {msg}; the valve is in its safe state"),
                );
                self.trace
                    .row(&TraceRow {
                        values: &row[..self.n_trace],
                        sampled,
                        applied,
                        wall_time,
                        fault: &msg,
                    })
                    .and_then(|()| self.trace.sync())
            }
            (fault, _) => {
                let label = if fault.is_some() {
                    &self.fault_label[..]
                } else {
                    ""
                };
                self.trace.row(&TraceRow {
                    values: &row[..self.n_trace],
                    sampled,
                    applied,
                    wall_time,
                    fault: label,
                })
            }
        };
        if let Err(e) = written {
            return Err(trace_failed(self.sup, k, self.now_s, e));
        }
        self.observer.row(row, &());
        self.report.ticks += 1;
        Ok(pneuflex_control::tick::Flow::Continue)
    }
}

/// Why a loop ended, for the trace's end marker.
fn end_reason(fault: Option<&Fault>) -> String {
    match fault {
        None => "complete".into(),
        Some(f) if f.kind == ErrorKind::Interrupted => "interrupted".into(),
        Some(f) => format!("fault {}", f.kind.name()),
    }
}

/// Latches an `Io` fault (safe state now), then returns the trace error, which names the file.
fn trace_failed<R: Rig<Sample = SiSample>>(
    sup: &mut Supervisor<R>,
    k: u64,
    now_s: f64,
    e: std::io::Error,
) -> std::io::Error {
    sup.trip(k, now_s, RigError::new(ErrorKind::Io, e.to_string()));
    e
}

/// [`run_with_clock`] on the host's wall clock, spinning `opts.spin_us` before each deadline.
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
    W: TraceSink,
{
    let mut clock = WallClock::new(Duration::from_micros(opts.spin_us));
    run_with_clock(sup, controller, reference, trace, opts, stop, &mut clock)
}

/// Runs the loop until `duration_s`, `stop` (SIGINT, SIGTERM, SIGHUP), or `post_fault_s` after a fault.
/// Every tick is traced. A controller panic, a NaN command, a set `stop` flag, a trace write error or any
/// rig error latches a fault and puts the valve in its safe state in that same tick. The valve is parked in
/// its safe state at the end, and the trace ends with its end marker, flushed and synced. Invalid options
/// are an `InvalidInput` error before anything is sent. A trace write error is returned (naming the file)
/// after the safe state was commanded.
pub fn run_with_clock<R, C, W, K>(
    sup: &mut Supervisor<R>,
    controller: &mut C,
    reference: &mut dyn FnMut(f64) -> Setpoint,
    trace: &mut TraceWriter<W>,
    opts: &RunOptions,
    stop: &AtomicBool,
    clock: &mut K,
) -> std::io::Result<LoopReport>
where
    R: Rig<Sample = SiSample>,
    C: Controller + ?Sized,
    W: TraceSink,
    K: Clock + ?Sized,
{
    run_observed(
        sup,
        controller,
        reference,
        trace,
        opts,
        stop,
        clock,
        &mut (),
    )
}

/// [`run_with_clock`] with an observer of every row — the same [`pneuflex_control::Sink`] the
/// simulation's runner calls (a live viewer, a progress display): the loop's columns and the controller's,
/// each tick's values as written to the trace (the command as applied).
#[allow(clippy::too_many_arguments)]
pub fn run_observed<R, C, W, K>(
    sup: &mut Supervisor<R>,
    controller: &mut C,
    reference: &mut dyn FnMut(f64) -> Setpoint,
    trace: &mut TraceWriter<W>,
    opts: &RunOptions,
    stop: &AtomicBool,
    clock: &mut K,
    observer: &mut dyn pneuflex_control::Sink<()>,
) -> std::io::Result<LoopReport>
where
    R: Rig<Sample = SiSample>,
    C: Controller + ?Sized,
    W: TraceSink,
    K: Clock + ?Sized,
{
    opts.validate()
        .map_err(|e| std::io::Error::new(std::io::ErrorKind::InvalidInput, e))?;
    let dt = 1.0 / opts.rate_hz;
    let n_ticks = (opts.duration_s / dt).round() as u64;
    let post_fault_ticks = (opts.post_fault_s / dt).round() as u64;
    // Streaming statistics: constant memory whatever the duration.
    let mut period_err = TimingStats::default();
    let mut lateness = TimingStats::default();
    let mut io_t = TimingStats::default();
    let mut ctrl_t = TimingStats::default();
    let mut report = LoopReport::default();

    let wall0 = SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map(|d| d.as_secs_f64())
        .unwrap_or(0.0);
    let t0 = clock.now();
    let host = |clock: &K| clock.now() - t0;

    // Wait for the first sample so that tick 0 has sensors (the watchdog arms on the first read).
    let mut last: Option<SiSample> = None;
    while last.is_none() && sup.fault().is_none() {
        let now = host(clock);
        if now > opts.first_sample_timeout_s {
            sup.trip(
                0,
                now,
                RigError::new(ErrorKind::Timeout, "no first sample from the rig"),
            );
            break;
        }
        last = sup.sense(0, now);
        if last.is_none() {
            clock.wait_until(t0 + now + 200e-6);
        }
    }

    // The trace's columns: the loop's signals and the controller's own, as each declares them.
    let own = controller.signals();
    trace.columns(own)?;
    // Observers also see the link's quality, when the rig is behind a serial link (not in the trace).
    let n_trace = pneuflex_control::LOOP_SIGNALS.len() + own.len();
    let link: &[pneuflex_control::Signal] = match sup.rig().link_stats() {
        Some(_) => &crate::serial::LINK_SIGNALS,
        None => &[],
    };
    let mut values = vec![0.0; n_trace + link.len()];
    let columns: Vec<pneuflex_control::Signal> = pneuflex_control::LOOP_SIGNALS
        .iter()
        .chain(own)
        .chain(link)
        .copied()
        .collect();
    observer.begin("rig", &columns, &());

    let start = host(clock);
    let mut rig = RigHost {
        sup: &mut *sup,
        trace: &mut *trace,
        clock: &mut *clock,
        observer: &mut *observer,
        stop,
        t0,
        start,
        wall0,
        dt,
        n_ticks,
        post_fault_ticks,
        last,
        prev_start: None,
        period_error: 0.0,
        n_trace,
        fault_tick: None,
        fault_label: String::new(),
        now_s: 0.0,
        deadline: 0.0,
        t_sensed: 0.0,
        t_updated: 0.0,
        period_err: &mut period_err,
        lateness: &mut lateness,
        io_t: &mut io_t,
        ctrl_t: &mut ctrl_t,
        report: &mut report,
    };
    let k = pneuflex_control::tick::run_loop(&mut rig, controller, reference, dt, &mut values)?;
    if let Err(e) = sup.park(k)
        && report.fault.is_none()
    {
        report.fault = Some(Fault {
            kind: e.kind(),
            message: format!("could not park the valve at the end: {}", e.message()),
            tick: k,
            host_time_s: host(clock),
        });
    }
    observer.end(report.fault.as_ref().map(|f| f.message.as_str()));
    report.time_reached_s = k as f64 * dt;
    report.period_error = period_err.percentiles();
    report.lateness = lateness.percentiles();
    report.io = io_t.percentiles();
    report.controller = ctrl_t.percentiles();
    let now = host(clock);
    trace
        .finish(&end_reason(report.fault.as_ref()))
        .map_err(|e| trace_failed(sup, k, now, e))?;
    Ok(report)
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

    #[test]
    fn streaming_stats_match_nearest_rank_within_one_percent() {
        // Loop-like times: mostly µs, a tail of ms, a few zeros.
        let mut x: u64 = 0x9E37_79B9_7F4A_7C15;
        let mut v = Vec::new();
        let mut st = TimingStats::default();
        for i in 0..20_000 {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            let u = (x % 1_000_000) as f64 / 1e6;
            let t = if i % 97 == 0 {
                0.0
            } else {
                1e-7 * (1e5f64).powf(u * u)
            };
            v.push(t);
            st.push(t);
        }
        let (a, b) = (Percentiles::of(&v), st.percentiles());
        for (name, exact, est) in [("p50", a.p50, b.p50), ("p99", a.p99, b.p99)] {
            assert!(
                (est - exact).abs() <= 0.01 * exact + 1e-9,
                "{name}: {est} vs {exact}"
            );
        }
        assert_eq!(a.max, b.max);
        assert!((a.mean - b.mean).abs() <= 1e-12 * a.mean.max(1.0));
        assert_eq!(st.count(), 20_000);
        assert_eq!(TimingStats::default().percentiles(), Percentiles::default());
    }

    #[test]
    fn options_are_checked_before_anything_runs() {
        let ok = RunOptions {
            rate_hz: 1000.0,
            spin_us: 150,
            duration_s: 1.0,
            post_fault_s: 0.2,
            first_sample_timeout_s: 0.5,
        };
        assert!(ok.validate().is_ok());
        // 1e10 s used to preallocate 4 × 1e13 timing values and abort; now refused (and streamed anyway).
        for d in [
            f64::NAN,
            -1.0,
            0.0,
            1e10,
            f64::INFINITY,
            MAX_DURATION_S * 1.001,
        ] {
            let e = RunOptions {
                duration_s: d,
                ..ok.clone()
            }
            .validate()
            .unwrap_err();
            assert!(e.to_string().contains("duration"), "{e}");
        }
        assert!(
            RunOptions {
                duration_s: MAX_DURATION_S,
                ..ok.clone()
            }
            .validate()
            .is_ok()
        );
        let e = RunOptions {
            spin_us: 10_000_000,
            ..ok.clone()
        }
        .validate()
        .unwrap_err();
        assert!(e.to_string().contains("spin_us"), "{e}");
        let e = RunOptions {
            post_fault_s: 1e9,
            ..ok.clone()
        }
        .validate()
        .unwrap_err();
        assert!(e.to_string().contains("post_fault_s"), "{e}");
    }
}
