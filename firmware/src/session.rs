//! The embedded-controller mode (docs/protocol.md §5), independent of the board: setup, one controller
//! update per CtrlSensors frame, the watchdog on the board clock, the bad-frame counter and the latched safe
//! state. The board's main loop feeds it decoded frames and the time; it answers through `send`.

use embedded_hal::digital::OutputPin;
use embedded_hal::pwm::SetDutyCycle;
use pneuflex_control::{Controller, Sensors, SetUpController, Setpoint, SetpointSchedule};
use pneuflex_protocol::ctrl::{
    MAX_SIGNALS, OutputPayload, ReadyPayload, SafePayload, SetupCollector, StartPayload, ready,
    status,
};
use pneuflex_protocol::{DecodeEvent, Message, RESET_MAGIC, ValveMode, fault_code};
use pneuflex_valve_driver::{SafeMode, ValveDriver};

/// More than this many bad frames (CRC or malformed) within [`BAD_FRAME_WINDOW_NS`] → safe state.
pub const BAD_FRAMES_MAX: usize = 8;
/// The bad-frame window, ns of board time.
pub const BAD_FRAME_WINDOW_NS: u64 = 100_000_000;

enum State {
    /// Collecting parameters and segments; the valve is safe, the watchdog off.
    Setup,
    /// The controller runs on every CtrlSensors frame.
    Run,
    /// In the safe state for `reason`; `latched` (a fault) until Reset, else until the next Start.
    Safe { reason: u8, latched: bool },
}

/// The session; `A`, `B`, `D` are the valve driver's coil PWMs and dump-valve pin.
pub struct Session<A, B, D> {
    state: State,
    setup: SetupCollector,
    controller: Option<SetUpController>,
    schedule: SetpointSchedule,
    dt_s: f64,
    watchdog_ns: u64,
    safe_mode: SafeMode,
    valve: ValveDriver<A, B, D>,
    last_valid_ns: u64,
    last_tick: u32,
    bad_frames: [u64; BAD_FRAMES_MAX + 1],
    bad_count: usize,
    crc_errors: u16,
    stack_peak: fn() -> u32,
    deadline: Option<u64>,
}

fn safe_code(m: SafeMode) -> ValveMode {
    match m {
        SafeMode::Vent => ValveMode::SafeVent,
        SafeMode::Hold => ValveMode::SafeHold,
    }
}

impl<A: SetDutyCycle, B: SetDutyCycle, D: OutputPin> Session<A, B, D> {
    /// A session waiting for its setup, the valve safe; `stack_peak` measures the stack's high-water mark.
    pub fn new(valve: ValveDriver<A, B, D>, stack_peak: fn() -> u32) -> Self {
        Self {
            state: State::Setup,
            setup: SetupCollector::default(),
            controller: None,
            schedule: SetpointSchedule::default(),
            dt_s: 0.0,
            watchdog_ns: 0,
            safe_mode: SafeMode::Vent,
            valve,
            last_valid_ns: 0,
            last_tick: 0,
            bad_frames: [0; BAD_FRAMES_MAX + 1],
            bad_count: 0,
            crc_errors: 0,
            stack_peak,
            deadline: None,
        }
    }

    /// When the watchdog is next due (board clock, ns), once per valid frame while running: the board arms
    /// a timer for it.
    pub fn take_deadline(&mut self) -> Option<u64> {
        self.deadline.take()
    }

    /// The safe state the panic handler must apply (vent unless the host chose hold).
    pub fn vents(&self) -> bool {
        self.safe_mode == SafeMode::Vent
    }

    /// Whether the session waits for a setup (no controller running, no fault latched): the board may
    /// then switch to the I/O-board mode.
    pub fn in_setup(&self) -> bool {
        matches!(self.state, State::Setup)
    }

    /// The valve driver (the I/O-board mode drives it too).
    pub fn valve(&mut self) -> &mut ValveDriver<A, B, D> {
        &mut self.valve
    }

    /// The last tick the controller ran.
    pub fn last_tick(&self) -> u32 {
        self.last_tick
    }

    /// Whether the controller runs (set up, started, not safe).
    pub fn running(&self) -> bool {
        matches!(self.state, State::Run)
    }

    /// The safe state's reason and latch, when the session is safe.
    pub fn safe_reason(&self) -> Option<(u8, bool)> {
        match self.state {
            State::Safe { reason, latched } => Some((reason, latched)),
            _ => None,
        }
    }

    /// Puts the valve in its safe state for `reason` (another channel's: a board of several actuators has one
    /// safe state), and says so.
    pub fn force_safe(&mut self, reason: u8, latched: bool, now_ns: u64, send: &mut impl FnMut(&Message)) {
        self.go_safe(reason, latched, now_ns, send);
    }

    /// Called often by the main loop: the watchdog.
    pub fn poll(&mut self, now_ns: u64, send: &mut impl FnMut(&Message)) {
        if matches!(self.state, State::Run)
            && now_ns.saturating_sub(self.last_valid_ns) > self.watchdog_ns
        {
            self.go_safe(fault_code::HOST_SILENT, true, now_ns, send);
        }
    }

    /// One decoder event at board time `now_ns`; `update_ns` times the controller update.
    pub fn on_event(
        &mut self,
        ev: DecodeEvent,
        now_ns: u64,
        clock: &mut impl FnMut() -> u64,
        send: &mut impl FnMut(&Message),
    ) {
        let msg = match ev {
            DecodeEvent::Frame(f) => f.msg,
            DecodeEvent::CrcError | DecodeEvent::Malformed { .. } => {
                if matches!(ev, DecodeEvent::CrcError) {
                    self.crc_errors = self.crc_errors.saturating_add(1);
                }
                self.bad_frame(now_ns, send);
                return;
            }
        };
        self.last_valid_ns = now_ns;
        match msg {
            Message::Heartbeat(c) => send(&Message::Heartbeat(c)),
            Message::CtrlParam(_) | Message::CtrlSegment(_) => {
                if matches!(self.state, State::Setup) {
                    self.setup.take(&msg);
                }
            }
            Message::CtrlStart(s) => self.start(&s, now_ns, send),
            Message::CtrlSensors(s) => {
                let sensors = Sensors {
                    t: s.t,
                    x: s.x,
                    x_dot: s.x_dot,
                    f_e: s.f_e,
                    p_a: s.p_a,
                    p_b: s.p_b,
                };
                let sp = self.schedule.at(s.t);
                let mut out = OutputPayload {
                    tick: s.tick,
                    u: 0.0,
                    x_r: 0.0,
                    f_ref: sp.f_ref,
                    x_d: sp.x_d,
                    board_time_us: 0,
                    update_ns: 0,
                    status: 0,
                    n_signals: 0,
                    signals: [0.0; MAX_SIGNALS],
                };
                match (&self.state, self.controller.as_mut()) {
                    (State::Run, Some(c)) => {
                        #[cfg(feature = "test-panic")]
                        if s.tick == 500 {
                            panic!("test-panic build: deliberate panic at tick {}", s.tick);
                        }
                        let t0 = clock();
                        let cmd = c.update(&sensors, &sp, self.dt_s);
                        let t1 = clock();
                        let tel = c.telemetry();
                        // The driver maps u to the coils; its outputs cannot fail on this board.
                        let _ = self.valve.apply(cmd);
                        self.last_tick = s.tick;
                        out.u = cmd.u;
                        out.x_r = tel.x_r;
                        // The controller's own signals as it declares them (Start refused more than
                        // fit in a frame).
                        let n = c.signals().len().min(MAX_SIGNALS);
                        c.record(&mut out.signals[..n]);
                        out.n_signals = n as u8;
                        out.update_ns = (t1 - t0).min(u64::from(u32::MAX)) as u32;
                    }
                    (State::Safe { latched, .. }, _) => {
                        out.status = status::SAFE | if *latched { status::LATCHED } else { 0 };
                    }
                    _ => out.status = status::SAFE,
                }
                out.board_time_us = (now_ns / 1000) as u32;
                send(&Message::CtrlOutput(out));
            }
            Message::Valve(v) if v.mode.is_safe() => {
                self.safe_mode = if v.mode == ValveMode::SafeHold {
                    SafeMode::Hold
                } else {
                    SafeMode::Vent
                };
                self.valve.set_safe_mode(self.safe_mode);
                let latched = matches!(self.state, State::Safe { latched: true, .. });
                let reason = match self.state {
                    State::Safe { reason, .. } if latched => reason,
                    _ => fault_code::HOST_REQUEST,
                };
                self.go_safe(reason, latched, now_ns, send);
            }
            Message::Reset(m) if m == RESET_MAGIC => {
                // Clears a latched fault; the valve stays safe until the next setup and Start.
                let _ = self.valve.go_safe();
                self.state = State::Setup;
                self.setup = SetupCollector::default();
                self.controller = None;
                self.bad_count = 0;
            }
            _ => {}
        }
        if matches!(self.state, State::Run) {
            // One timer count (40 ns) past the period, so that the check above sees it expired.
            self.deadline = Some(self.last_valid_ns + self.watchdog_ns + 40);
        }
    }

    fn start(&mut self, s: &StartPayload, now_ns: u64, send: &mut impl FnMut(&Message)) {
        let answer = |send: &mut dyn FnMut(&Message), r: ReadyPayload| send(&Message::CtrlReady(r));
        if !matches!(self.state, State::Setup) {
            // Running, or safe: a new run needs Reset first (a latched fault is never cleared by Start).
            answer(
                send,
                ReadyPayload {
                    result: ready::START,
                    detail: 1,
                },
            );
            return;
        }
        let built = self.setup.finish(s).and_then(|setup| {
            setup.build().map_err(|_| ReadyPayload {
                result: ready::PARAM,
                detail: 0,
            })
        });
        let safe = match s.safe_mode {
            ValveMode::SafeHold => SafeMode::Hold,
            _ => SafeMode::Vent,
        };
        // A controller with more signals than a CtrlOutput carries would lose some: refused.
        let built = built.and_then(|c| {
            if c.signals().len() > MAX_SIGNALS {
                Err(ReadyPayload {
                    result: ready::START,
                    detail: 2,
                })
            } else {
                Ok(c)
            }
        });
        match built {
            Ok(mut c) if s.safe_mode.is_safe() => {
                // Warm-up: the first update computes and caches the period's exact ZOH and leakage factors
                // (a 3x3 matrix exponential, ~90 000 instructions); reset() restores the initial state and
                // keeps the caches, so no control tick pays for them.
                // The sample is "in contact" (f_e above any contact threshold) so that the adaptive law's
                // path runs too, not only its hold.
                let ctl = &mut c;
                let contact = Sensors {
                    f_e: 1e6,
                    ..Sensors::default()
                };
                ctl.update(&contact, &Setpoint::default(), s.dt_s);
                ctl.reset();
                self.controller = Some(c);
                self.schedule = self.setup.schedule;
                self.dt_s = s.dt_s;
                self.watchdog_ns = u64::from(s.watchdog_ms) * 1_000_000;
                self.safe_mode = safe;
                self.valve.set_safe_mode(safe);
                self.last_valid_ns = now_ns;
                self.bad_count = 0;
                self.state = State::Run;
                answer(
                    send,
                    ReadyPayload {
                        result: ready::OK,
                        detail: 0,
                    },
                );
            }
            Ok(_) => answer(
                send,
                ReadyPayload {
                    result: ready::START,
                    detail: 0,
                },
            ),
            Err(r) => {
                // A refused setup starts over.
                self.setup = SetupCollector::default();
                answer(send, r);
            }
        }
    }

    fn bad_frame(&mut self, now_ns: u64, send: &mut impl FnMut(&Message)) {
        // Times of the last BAD_FRAMES_MAX + 1 bad frames, oldest first.
        if self.bad_count == self.bad_frames.len() {
            self.bad_frames.copy_within(1.., 0);
            self.bad_count -= 1;
        }
        self.bad_frames[self.bad_count] = now_ns;
        self.bad_count += 1;
        let storm =
            self.bad_count > BAD_FRAMES_MAX && now_ns - self.bad_frames[0] <= BAD_FRAME_WINDOW_NS;
        if storm && matches!(self.state, State::Run) {
            self.go_safe(fault_code::CRC, true, now_ns, send);
        }
    }

    fn go_safe(&mut self, reason: u8, latched: bool, now_ns: u64, send: &mut impl FnMut(&Message)) {
        let _ = self.valve.go_safe();
        self.state = State::Safe { reason, latched };
        send(&Message::Safe(SafePayload {
            reason,
            last_tick: self.last_tick,
            last_valid_us: (self.last_valid_ns / 1000) as u32,
            safe_at_us: (now_ns / 1000) as u32,
            crc_errors: self.crc_errors,
            mode: safe_code(self.safe_mode),
            stack_peak_bytes: (self.stack_peak)().min(u32::from(u16::MAX)) as u16,
        }));
    }
}
