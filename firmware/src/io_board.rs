//! The I/O-board mode (docs/protocol.md §2–3): what `rig run` talks to. The host runs the controller; the
//! board sends a Sample every `sample_period_us`, applies the newest Valve command through the valve driver,
//! echoes Heartbeats, and goes to its safe state on its own watchdog (no Valve or Heartbeat for
//! `watchdog_ms` after the first Run command), latched until Reset. Entered by a Config frame.
//!
//! The emulated AN386 has no ADC: the analog channels come from the board's `AdcChannel`s, which read 0
//! there (a real board reads its converters; docs/firmware.md).

use embedded_hal::digital::OutputPin;
use embedded_hal::pwm::SetDutyCycle;
use pneuflex_protocol::{
    AppliedPayload, ConfigPayload, Message, RESET_MAGIC, SamplePayload, ValveMode, fault_code,
    status,
};
use pneuflex_valve_driver::{AdcChannel, SafeMode, Sampler, ValveDriver, command_from_q15};

/// The I/O board's state.
pub struct IoBoard<P, C1, CB, S> {
    config: Option<ConfigPayload>,
    sampler: Sampler<P, C1, CB, S>,
    /// Board time of the last Valve or Heartbeat, ns; None until the first Run command.
    last_cmd_ns: Option<u64>,
    last_cmd_tick: u32,
    duty_q15: i16,
    safe: bool,
    latched: bool,
}

impl<P: AdcChannel, C1: AdcChannel, CB: AdcChannel, S: AdcChannel> IoBoard<P, C1, CB, S> {
    /// An I/O board reading `sampler`; inactive until a Config arrives.
    pub fn new(sampler: Sampler<P, C1, CB, S>) -> Self {
        Self {
            config: None,
            sampler,
            last_cmd_ns: None,
            last_cmd_tick: 0,
            duty_q15: 0,
            safe: true,
            latched: false,
        }
    }

    /// Whether a Config put the board in this mode; then its sample period, ns.
    pub fn period_ns(&self) -> Option<u64> {
        self.config
            .map(|c| u64::from(c.sample_period_us.max(1)) * 1000)
    }

    /// What the valve does now, as the Applied echo reports it (a safe state is the board's configured one,
    /// as the Sample's status bits report it).
    fn mode(&self) -> ValveMode {
        match (self.safe, self.safe_mode()) {
            (false, _) => ValveMode::Run,
            (true, SafeMode::Hold) => ValveMode::SafeHold,
            (true, SafeMode::Vent) => ValveMode::SafeVent,
        }
    }

    fn safe_mode(&self) -> SafeMode {
        match self.config.map(|c| c.safe_mode) {
            Some(ValveMode::SafeHold) => SafeMode::Hold,
            _ => SafeMode::Vent,
        }
    }

    /// A valid frame for the I/O board.
    pub fn on_message<A: SetDutyCycle, B: SetDutyCycle, D: OutputPin>(
        &mut self,
        msg: &Message,
        now_ns: u64,
        valve: &mut ValveDriver<A, B, D>,
        send: &mut impl FnMut(&Message),
    ) {
        match *msg {
            Message::Config(c) => {
                self.config = Some(c);
                valve.set_safe_mode(self.safe_mode());
            }
            Message::Heartbeat(c) => {
                if self.last_cmd_ns.is_some() {
                    self.last_cmd_ns = Some(now_ns);
                }
                send(&Message::Heartbeat(c));
            }
            Message::Valve(v) => {
                self.last_cmd_tick = v.tick;
                if v.mode == ValveMode::Run && self.last_cmd_ns.is_none() {
                    // The watchdog starts with the first Run command.
                    self.last_cmd_ns = Some(now_ns);
                }
                if self.last_cmd_ns.is_some() {
                    self.last_cmd_ns = Some(now_ns);
                }
                // A latched fault keeps the valve safe; the command's tick is still echoed.
                if !self.latched {
                    self.apply(&v, valve);
                }
                // What the valve now does, by the samples' clock (docs/protocol.md §3, 0x07).
                send(&Message::Applied(AppliedPayload {
                    board_time_us: (now_ns / 1000) as u32,
                    tick: v.tick,
                    duty_q15: self.duty_q15,
                    mode: self.mode(),
                }));
            }
            Message::Reset(m) if m == RESET_MAGIC => {
                // Clears the latch; the valve stays safe until the next Run command.
                self.latched = false;
            }
            _ => {}
        }
    }

    /// Drives the valve as a Valve frame says.
    fn apply<A: SetDutyCycle, B: SetDutyCycle, D: OutputPin>(
        &mut self,
        v: &pneuflex_protocol::ValvePayload,
        valve: &mut ValveDriver<A, B, D>,
    ) {
        if v.mode == ValveMode::Run {
            let _ = valve.apply(command_from_q15(v.duty_q15));
            self.duty_q15 = v.duty_q15;
            self.safe = false;
        } else {
            valve.set_safe_mode(if v.mode == ValveMode::SafeHold {
                SafeMode::Hold
            } else {
                SafeMode::Vent
            });
            let _ = valve.go_safe();
            self.duty_q15 = 0;
            self.safe = true;
        }
    }

    /// Every sample period: the watchdog, then one Sample.
    pub fn on_period<A: SetDutyCycle, B: SetDutyCycle, D: OutputPin>(
        &mut self,
        now_ns: u64,
        valve: &mut ValveDriver<A, B, D>,
        send: &mut impl FnMut(&Message),
    ) {
        let Some(cfg) = self.config else { return };
        let watchdog_ns = u64::from(cfg.watchdog_ms) * 1_000_000;
        if let Some(last) = self.last_cmd_ns
            && cfg.watchdog_ms > 0
            && !self.latched
            && now_ns.saturating_sub(last) > watchdog_ns
        {
            valve.set_safe_mode(self.safe_mode());
            let _ = valve.go_safe();
            self.duty_q15 = 0;
            self.safe = true;
            self.latched = true;
            send(&Message::Fault {
                code: fault_code::HOST_SILENT,
                detail: cfg.watchdog_ms,
            });
        }
        let (counts, adc_failed) = match self.sampler.sample() {
            Ok(c) => (c, false),
            Err(_) => ([0; 4], true),
        };
        if adc_failed && !self.latched {
            let _ = valve.go_safe();
            self.duty_q15 = 0;
            self.safe = true;
            self.latched = true;
            send(&Message::Fault {
                code: fault_code::ADC,
                detail: 0,
            });
        }
        let mut st = 0;
        if self.safe {
            st |= status::SAFE;
            if self.safe_mode() == SafeMode::Hold {
                st |= status::SAFE_HOLD;
            }
        }
        if self.latched {
            st |= status::BOARD_FAULT;
            if !adc_failed {
                st |= status::WATCHDOG;
            }
        }
        send(&Message::Sample(SamplePayload {
            board_time_us: (now_ns / 1000) as u32,
            last_cmd_tick: self.last_cmd_tick,
            position: counts[0],
            p_a: counts[1],
            p_b: counts[2],
            p_supply: counts[3],
            load: 0,
            duty_q15: self.duty_q15,
            status: st,
        }));
    }
}
