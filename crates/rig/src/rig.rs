//! The `Rig` trait — read time-stamped sensors, write a valve command — and the layers around it:
//! [`Watchdog`] (missing or stale data), [`Calibrated`] (counts to SI) and [`Limited`] (position, force,
//! pressure, NaN). Like embedded-hal's traits, a small interface with an error that has a `kind()`; like
//! ros2_control, limits live outside the controller.

use pneuflex_control::{Sensors, ValveCommand};

use crate::error::{ErrorKind, RigError};
use crate::protocol::SamplePayload;
use crate::rigfile::{Calibration, LimitsConfig, SafeState, WatchdogConfig};

/// Link-quality counters.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LinkStats {
    /// Decoder counters.
    pub decoder: pneuflex_protocol::DecoderStats,
    /// Samples received.
    pub samples: u64,
    /// Samples received but superseded by a newer one before the loop read them.
    pub superseded: u64,
    /// Samples missing according to the sequence numbers.
    pub seq_gaps: u64,
    /// Frames sent.
    pub sent: u64,
    /// Samples and applied echoes dropped from the record because nobody took them (more than
    /// `serial::RECORD_CAP` waiting).
    pub record_dropped: u64,
}

/// A raw sample as the board sent it, stamped with host and board time.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RawSample {
    /// Host monotonic time when the sample was read, s since the loop started.
    pub host_time_s: f64,
    /// Board time, s (unwrapped from the board's µs counter).
    pub board_time_s: f64,
    /// The counts.
    pub raw: SamplePayload,
}

/// The board's echo of a valve command it applied (docs/protocol.md, 0x07), on the samples' clock.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Applied {
    /// Board time when the command took effect, s (the clock of [`RawSample::board_time_s`]).
    pub board_time_s: f64,
    /// The host tick whose command it was.
    pub tick: u32,
    /// The duty now driven in [-1, 1] (0 in a safe state).
    pub u: f64,
    /// Run, or the safe state the valve is in.
    pub mode: crate::protocol::ValveMode,
}

/// One sample as the board sent it, for the record ([`Rig::take_sampled`]): its board time and counts, and
/// in SI once a [`Calibrated`] layer has seen it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BoardSample {
    /// Board time, s (the clock of [`RawSample::board_time_s`]).
    pub board_time_s: f64,
    /// The counts.
    pub raw: SamplePayload,
    /// Position, contact force and chamber pressures in SI (`x_dot` NaN: no filter runs on the record).
    pub si: Option<Sensors>,
}

/// A calibrated sample: the controller's [`Sensors`] plus what the limits need.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SiSample {
    /// Host monotonic time when the sample was read, s.
    pub host_time_s: f64,
    /// Board time, s.
    pub board_time_s: f64,
    /// Position, velocity, contact force and chamber pressures in SI (`t` = board time).
    pub sensors: Sensors,
    /// Supply pressure, Pa absolute.
    pub supply_pa: f64,
    /// The counts they came from.
    pub raw: SamplePayload,
}

/// A rig: time-stamped sensor samples in, valve commands out.
pub trait Rig {
    /// What `read` returns: raw counts or SI.
    type Sample: Copy;

    /// The newest sample that arrived since the last call (`None` if none did). `now_s` is host time, s.
    fn read(&mut self, now_s: f64) -> Result<Option<Self::Sample>, RigError>;

    /// Sends a valve command for control tick `tick`.
    fn write(&mut self, tick: u32, cmd: ValveCommand) -> Result<(), RigError>;

    /// Commands the valve's safe state.
    fn safe(&mut self, tick: u32, state: SafeState) -> Result<(), RigError>;

    /// Clears faults latched below this layer (and on the board).
    fn reset(&mut self) -> Result<(), RigError>;

    /// The link's counters (frames, CRC errors, sequence gaps), for a rig behind a serial link.
    fn link_stats(&self) -> Option<LinkStats> {
        None
    }

    /// The oldest echo of an applied valve command not taken yet, in the order the board applied them
    /// (`None` when none is waiting, or the rig sends none).
    fn take_applied(&mut self) -> Option<Applied> {
        None
    }

    /// The oldest sample the board sent that is not taken yet: every sample once, in order, whether or not
    /// `read` handed it to the loop (a late loop reads only the newest), for the trace's record of what the
    /// board measured. `None` when none is waiting, or the rig keeps no such record.
    fn take_sampled(&mut self) -> Option<BoardSample> {
        None
    }
}

impl<R: Rig + ?Sized> Rig for &mut R {
    type Sample = R::Sample;
    fn read(&mut self, now_s: f64) -> Result<Option<Self::Sample>, RigError> {
        (**self).read(now_s)
    }
    fn write(&mut self, tick: u32, cmd: ValveCommand) -> Result<(), RigError> {
        (**self).write(tick, cmd)
    }
    fn safe(&mut self, tick: u32, state: SafeState) -> Result<(), RigError> {
        (**self).safe(tick, state)
    }
    fn reset(&mut self) -> Result<(), RigError> {
        (**self).reset()
    }
    fn link_stats(&self) -> Option<LinkStats> {
        (**self).link_stats()
    }
    fn take_applied(&mut self) -> Option<Applied> {
        (**self).take_applied()
    }
    fn take_sampled(&mut self) -> Option<BoardSample> {
        (**self).take_sampled()
    }
}

/// The methods of [`Rig`] a layer passes to the rig it wraps (its `inner`) untouched, named one by one so that
/// what a layer does change stands written out in its impl.
macro_rules! pass_through {
    ($($method:ident),+) => {
        $(pass_through!(@$method);)+
    };
    (@link_stats) => {
        fn link_stats(&self) -> Option<LinkStats> {
            self.inner.link_stats()
        }
    };
    (@take_applied) => {
        fn take_applied(&mut self) -> Option<Applied> {
            self.inner.take_applied()
        }
    };
    (@take_sampled) => {
        fn take_sampled(&mut self) -> Option<BoardSample> {
            self.inner.take_sampled()
        }
    };
    (@write) => {
        fn write(&mut self, tick: u32, cmd: ValveCommand) -> Result<(), RigError> {
            self.inner.write(tick, cmd)
        }
    };
    (@safe) => {
        fn safe(&mut self, tick: u32, state: SafeState) -> Result<(), RigError> {
            self.inner.safe(tick, state)
        }
    };
}

/// Watchdog layer: a fault when no sample arrives for `timeout_ms`, or when every raw channel stays
/// bit-identical for `stale_ms` (a stuck sensor or a frozen ADC: real channels always carry some noise).
#[derive(Debug)]
pub struct Watchdog<R> {
    inner: R,
    timeout_s: f64,
    stale_s: f64,
    last_fresh_s: Option<f64>,
    changed_at_s: f64,
    last_raw: Option<[i64; 5]>,
}

fn channels(r: &SamplePayload) -> [i64; 5] {
    [
        i64::from(r.position),
        i64::from(r.p_a),
        i64::from(r.p_b),
        i64::from(r.p_supply),
        i64::from(r.load),
    ]
}

impl<R: Rig<Sample = RawSample>> Watchdog<R> {
    /// Wraps `inner` with the timeouts of `cfg`.
    pub fn new(inner: R, cfg: &WatchdogConfig) -> Self {
        Self {
            inner,
            timeout_s: cfg.timeout_ms * 1e-3,
            stale_s: cfg.stale_ms * 1e-3,
            last_fresh_s: None,
            changed_at_s: 0.0,
            last_raw: None,
        }
    }

    /// The wrapped rig.
    pub fn inner_mut(&mut self) -> &mut R {
        &mut self.inner
    }
}

impl<R: Rig<Sample = RawSample>> Rig for Watchdog<R> {
    type Sample = RawSample;

    pass_through!(link_stats, take_applied, take_sampled, write, safe);

    fn read(&mut self, now_s: f64) -> Result<Option<RawSample>, RigError> {
        let got = self.inner.read(now_s)?;
        // Arm on the first call: the timeout runs from when the loop first asked.
        let last = *self.last_fresh_s.get_or_insert(now_s);
        match got {
            Some(s) => {
                self.last_fresh_s = Some(now_s);
                let ch = channels(&s.raw);
                if self.last_raw != Some(ch) {
                    self.last_raw = Some(ch);
                    self.changed_at_s = now_s;
                } else if self.stale_s > 0.0 && now_s - self.changed_at_s > self.stale_s {
                    return Err(RigError::new(
                        ErrorKind::Stale,
                        format!(
                            "every sensor channel unchanged for {:.1} ms (limit {:.1} ms)",
                            (now_s - self.changed_at_s) * 1e3,
                            self.stale_s * 1e3
                        ),
                    ));
                }
                Ok(Some(s))
            }
            None => {
                if now_s - last > self.timeout_s {
                    Err(RigError::new(
                        ErrorKind::Timeout,
                        format!(
                            "no sample for {:.1} ms (limit {:.1} ms)",
                            (now_s - last) * 1e3,
                            self.timeout_s * 1e3
                        ),
                    ))
                } else {
                    Ok(None)
                }
            }
        }
    }

    fn reset(&mut self) -> Result<(), RigError> {
        self.last_fresh_s = None;
        self.last_raw = None;
        self.inner.reset()
    }
}

/// Calibration layer: counts to SI, and the flange velocity from a filtered derivative of position.
#[derive(Debug)]
pub struct Calibrated<R> {
    inner: R,
    cal: Calibration,
    /// Velocity filter time constant, s.
    tau_s: f64,
    prev: Option<(f64, f64)>,
    v_filt: f64,
}

impl<R> Calibrated<R> {
    /// Wraps `inner`; `velocity_cutoff_hz` sets the first-order filter on the position derivative (a
    /// several-channel host keeps one `Calibrated<()>` per channel as its converter).
    pub fn new(inner: R, cal: Calibration, velocity_cutoff_hz: f64) -> Self {
        Self {
            inner,
            cal,
            tau_s: 1.0 / (2.0 * std::f64::consts::PI * velocity_cutoff_hz),
            prev: None,
            v_filt: 0.0,
        }
    }

    /// The wrapped rig.
    pub fn inner_mut(&mut self) -> &mut R {
        &mut self.inner
    }

    /// Position, contact force and pressures of raw counts, in SI (no velocity: `x_dot` NaN).
    pub fn sensors_of(&self, raw: &SamplePayload) -> Sensors {
        let c = &self.cal;
        let (p_a, p_b) = c.pressures(raw.p_a, raw.p_b);
        Sensors {
            t: f64::NAN,
            x: c.position.to_si(raw.position),
            x_dot: f64::NAN,
            f_e: c.load_to_si(raw.load),
            p_a,
            p_b,
        }
    }

    /// Converts one raw sample (updates the velocity filter).
    pub fn convert(&mut self, s: &RawSample) -> SiSample {
        let c = &self.cal;
        let x = c.position.to_si(s.raw.position);
        let t = s.board_time_s;
        if let Some((t0, x0)) = self.prev {
            let dt = t - t0;
            if dt > 0.0 {
                // First-order low-pass of the finite difference (backward Euler), robust to a missing sample.
                let raw_v = (x - x0) / dt;
                let a = dt / (self.tau_s + dt);
                self.v_filt += a * (raw_v - self.v_filt);
            }
        }
        self.prev = Some((t, x));
        let (p_a, p_b) = c.pressures(s.raw.p_a, s.raw.p_b);
        SiSample {
            host_time_s: s.host_time_s,
            board_time_s: t,
            sensors: Sensors {
                t,
                x,
                x_dot: self.v_filt,
                f_e: c.load_to_si(s.raw.load),
                p_a,
                p_b,
            },
            supply_pa: c.atmosphere_pa + c.supply.to_si(s.raw.p_supply),
            raw: s.raw,
        }
    }
}

impl<R: Rig<Sample = RawSample>> Rig for Calibrated<R> {
    type Sample = SiSample;

    pass_through!(link_stats, take_applied, write, safe);
    fn take_sampled(&mut self) -> Option<BoardSample> {
        self.inner.take_sampled().map(|mut b| {
            b.si = Some(self.sensors_of(&b.raw));
            b
        })
    }

    fn read(&mut self, now_s: f64) -> Result<Option<SiSample>, RigError> {
        Ok(self.inner.read(now_s)?.map(|s| self.convert(&s)))
    }
    fn reset(&mut self) -> Result<(), RigError> {
        self.prev = None;
        self.v_filt = 0.0;
        self.inner.reset()
    }
}

/// Limits layer: a sample outside the position, force or pressure limits, a supply below its minimum, or a
/// non-finite value is an error (carrying the offending sample); a non-finite command is refused.
#[derive(Debug)]
pub struct Limited<R> {
    inner: R,
    limits: LimitsConfig,
    rejected: Option<SiSample>,
}

impl<R: Rig<Sample = SiSample>> Limited<R> {
    /// Wraps `inner` with `limits`.
    pub fn new(inner: R, limits: LimitsConfig) -> Self {
        Self {
            inner,
            limits,
            rejected: None,
        }
    }

    /// The last sample refused by the limits (for the trace's fault row).
    pub fn rejected(&self) -> Option<SiSample> {
        self.rejected
    }

    /// Checks one sample against the limits.
    pub fn check(&self, s: &SiSample) -> Result<(), RigError> {
        check_limits(&self.limits, s)
    }
}

/// Checks one sample against `l`: every value finite, position, force and chamber pressures inside their
/// ranges, supply above its minimum ([`Limited`], and per channel the several-actuator supervisor).
pub fn check_limits(l: &LimitsConfig, s: &SiSample) -> Result<(), RigError> {
    let v = &s.sensors;
    let all = [
        ("x", v.x),
        ("x_dot", v.x_dot),
        ("f_e", v.f_e),
        ("p_a", v.p_a),
        ("p_b", v.p_b),
        ("p_supply", s.supply_pa),
    ];
    if let Some((name, val)) = all.iter().find(|(_, val)| !val.is_finite()) {
        return Err(RigError::new(
            ErrorKind::NotANumber,
            format!("sensor {name} is {val}"),
        ));
    }
    let out = |name: &str, val: f64, r: [f64; 2], unit: &str| {
        RigError::new(
            ErrorKind::Limit,
            format!("{name} = {val} {unit} outside [{}, {}]", r[0], r[1]),
        )
    };
    if !(l.position_m[0]..=l.position_m[1]).contains(&v.x) {
        return Err(out("position x", v.x, l.position_m, "m"));
    }
    if !(l.force_n[0]..=l.force_n[1]).contains(&v.f_e) {
        return Err(out("force f_e", v.f_e, l.force_n, "N"));
    }
    for (name, p) in [("pressure p_a", v.p_a), ("pressure p_b", v.p_b)] {
        if !(l.pressure_pa[0]..=l.pressure_pa[1]).contains(&p) {
            return Err(out(name, p, l.pressure_pa, "Pa"));
        }
    }
    if s.supply_pa < l.supply_min_pa {
        return Err(RigError::new(
            ErrorKind::Limit,
            format!(
                "supply pressure {} Pa below minimum {} Pa (supply lost?)",
                s.supply_pa, l.supply_min_pa
            ),
        ));
    }
    Ok(())
}

impl<R: Rig<Sample = SiSample>> Rig for Limited<R> {
    type Sample = SiSample;

    pass_through!(link_stats, take_applied, take_sampled, safe);

    fn read(&mut self, now_s: f64) -> Result<Option<SiSample>, RigError> {
        match self.inner.read(now_s)? {
            Some(s) => match self.check(&s) {
                Ok(()) => Ok(Some(s)),
                Err(e) => {
                    self.rejected = Some(s);
                    Err(e)
                }
            },
            None => Ok(None),
        }
    }
    fn write(&mut self, tick: u32, cmd: ValveCommand) -> Result<(), RigError> {
        if !cmd.u.is_finite() {
            return Err(RigError::new(
                ErrorKind::NotANumber,
                format!("valve command u is {}", cmd.u),
            ));
        }
        self.inner.write(tick, cmd)
    }
    fn reset(&mut self) -> Result<(), RigError> {
        self.rejected = None;
        self.inner.reset()
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use std::collections::VecDeque;

    /// A scripted rig: returns queued samples, records writes.
    #[derive(Default)]
    pub struct Scripted {
        pub samples: VecDeque<Option<RawSample>>,
        pub writes: Vec<(u32, f64)>,
        pub safes: Vec<(u32, SafeState)>,
    }

    impl Rig for Scripted {
        type Sample = RawSample;
        fn read(&mut self, _now_s: f64) -> Result<Option<RawSample>, RigError> {
            Ok(self.samples.pop_front().flatten())
        }
        fn write(&mut self, tick: u32, cmd: ValveCommand) -> Result<(), RigError> {
            self.writes.push((tick, cmd.u));
            Ok(())
        }
        fn safe(&mut self, tick: u32, state: SafeState) -> Result<(), RigError> {
            self.safes.push((tick, state));
            Ok(())
        }
        fn reset(&mut self) -> Result<(), RigError> {
            Ok(())
        }
    }

    fn raw(pos: u16, t: f64) -> RawSample {
        RawSample {
            host_time_s: t,
            board_time_s: t,
            raw: SamplePayload {
                position: pos,
                ..SamplePayload::default()
            },
        }
    }

    fn wd_cfg(timeout_ms: f64, stale_ms: f64) -> WatchdogConfig {
        WatchdogConfig {
            timeout_ms,
            stale_ms,
            crc_errors_max: 3,
            crc_window_ms: 1000.0,
            board_watchdog_ms: 50,
        }
    }

    #[test]
    fn watchdog_trips_after_timeout_not_before() {
        let mut s = Scripted::default();
        s.samples.push_back(Some(raw(1, 0.0)));
        let mut w = Watchdog::new(s, &wd_cfg(5.0, 0.0));
        assert!(w.read(0.0).unwrap().is_some());
        // 1 ms ticks with nothing arriving: fine up to 5 ms, fault at 6 ms.
        for k in 1..=5 {
            assert!(w.read(k as f64 * 1e-3).unwrap().is_none(), "tick {k}");
        }
        let e = w.read(6e-3).unwrap_err();
        assert_eq!(e.kind(), ErrorKind::Timeout);
    }

    #[test]
    fn watchdog_detects_frozen_channels() {
        let mut s = Scripted::default();
        for k in 0..20 {
            // Noisy until tick 5, then frozen.
            let pos = if k < 5 { 100 + (k % 2) as u16 } else { 100 };
            s.samples.push_back(Some(raw(pos, k as f64 * 1e-3)));
        }
        let mut w = Watchdog::new(s, &wd_cfg(5.0, 10.0));
        let mut tripped_at = None;
        for k in 0..20 {
            if let Err(e) = w.read(k as f64 * 1e-3) {
                assert_eq!(e.kind(), ErrorKind::Stale);
                tripped_at = Some(k);
                break;
            }
        }
        // Last change at tick 4 (101 -> 100); stale once more than 10 ms have passed: tick 15.
        assert_eq!(tripped_at, Some(15));
    }

    pub fn limits() -> LimitsConfig {
        LimitsConfig {
            position_m: [0.0, 0.05],
            force_n: [-5.0, 40.0],
            pressure_pa: [50e3, 800e3],
            supply_min_pa: 300e3,
        }
    }

    fn si(x: f64, f: f64, p: f64, ps: f64) -> SiSample {
        SiSample {
            sensors: Sensors {
                x,
                f_e: f,
                p_a: p,
                p_b: p,
                ..Sensors::default()
            },
            supply_pa: ps,
            ..SiSample::default()
        }
    }

    #[test]
    fn limits_classify() {
        let l = Limited::new(NoRig, limits());
        assert!(l.check(&si(0.01, 10.0, 2e5, 6e5)).is_ok());
        assert_eq!(
            l.check(&si(0.06, 10.0, 2e5, 6e5)).unwrap_err().kind(),
            ErrorKind::Limit
        );
        assert_eq!(
            l.check(&si(0.01, 41.0, 2e5, 6e5)).unwrap_err().kind(),
            ErrorKind::Limit
        );
        assert_eq!(
            l.check(&si(0.01, 10.0, 9e5, 6e5)).unwrap_err().kind(),
            ErrorKind::Limit
        );
        assert_eq!(
            l.check(&si(0.01, 10.0, 2e5, 1e5)).unwrap_err().kind(),
            ErrorKind::Limit
        );
        assert_eq!(
            l.check(&si(f64::NAN, 10.0, 2e5, 6e5)).unwrap_err().kind(),
            ErrorKind::NotANumber
        );
    }

    struct NoRig;
    impl Rig for NoRig {
        type Sample = SiSample;
        fn read(&mut self, _: f64) -> Result<Option<SiSample>, RigError> {
            Ok(None)
        }
        fn write(&mut self, _: u32, _: ValveCommand) -> Result<(), RigError> {
            Ok(())
        }
        fn safe(&mut self, _: u32, _: SafeState) -> Result<(), RigError> {
            Ok(())
        }
        fn reset(&mut self) -> Result<(), RigError> {
            Ok(())
        }
    }

    #[test]
    fn velocity_of_a_ramp() {
        // Position ramps at 0.02 m/s; the filtered derivative converges to it.
        let cal = crate::rigfile::tests::calibration();
        let mut s = Scripted::default();
        let n = 400;
        for k in 0..n {
            let t = k as f64 * 1e-3;
            let counts = cal.position.from_si(0.005 + 0.02 * t);
            s.samples.push_back(Some(raw(counts, t)));
        }
        let mut c = Calibrated::new(s, cal, 50.0);
        let mut last = None;
        for k in 0..n {
            last = c.read(k as f64 * 1e-3).unwrap();
        }
        let v = last.unwrap().sensors.x_dot;
        // Quantisation of one count over 1 ms is filtered by the 50 Hz pole; allow 5 %.
        assert!((v - 0.02).abs() < 0.001, "v = {v}");
    }
}
