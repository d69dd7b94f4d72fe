//! pneuflex firmware for the emulated mps2-an386 board (Cortex-M4F): the embedded-controller mode of the
//! serial protocol (docs/protocol.md §5, docs/firmware.md). The host uploads a scene run's controller
//! parameters and reference schedule, then sends one sensor sample per tick; the board runs the
//! `pneuflex-control` controller on it, drives the valve through `pneuflex-valve-driver` and answers with the
//! valve command and telemetry. No valid frame for the watchdog time, a storm of bad frames, or a panic →
//! the valve's safe state. A Config frame instead selects the I/O-board mode (`io_board.rs`, what `rig run`
//! talks to).
#![no_std]
#![no_main]

mod board;
mod io_board;
mod session;

use core::fmt::Write as _;
use core::sync::atomic::{AtomicBool, AtomicU8, AtomicU32, Ordering};

use cortex_m_rt::{entry, exception};
use pneuflex_protocol::ctrl::{ReadyPayload, SafePayload, TEXT_LEN, TextPayload, ready};
use pneuflex_protocol::{DecodeEvent, Decoder, MAX_FRAME, Message, ValveMode, encode, fault_code};
use pneuflex_valve_driver::{SafeMode, Sampler, ValveDriver, ValveType};

use board::{Clock, Coil, DumpValve, Uart};
use io_board::IoBoard;
use session::Session;

/// Sequence number of the next frame sent (shared with the panic handler).
/// Controllers the board runs, one per actuator channel (docs/protocol.md §5, "Several controllers"): the
/// gripper's two fingers. Each session's controller, setup and schedule live in `main`'s frame (RAM).
pub const CHANNELS: usize = 2;

static TX_SEQ: AtomicU8 = AtomicU8::new(0);
/// The safe state the panic handler applies: vent unless the host chose hold.
static VENTS: AtomicBool = AtomicBool::new(true);
/// Last tick the controller ran and the board time of the last received byte, µs, for the panic report.
static LAST_TICK: AtomicU32 = AtomicU32::new(0);
static NOW_US: AtomicU32 = AtomicU32::new(0);

fn send(uart: &mut Uart, m: &Message) {
    let mut buf = [0u8; MAX_FRAME];
    let n = encode(TX_SEQ.fetch_add(1, Ordering::Relaxed), m, &mut buf);
    uart.write(&buf[..n]);
}

#[entry]
fn main() -> ! {
    let mut uart = Uart::init();
    let mut clock = Clock::init();
    // The paper's valve (5/2 single solenoid), safe = vent until the host says otherwise.
    // One controller session per actuator channel, each with its own valve driver (coils 2 i and 2 i + 1; the
    // supply's dump valve is the board's one).
    let valve = |ch: usize| match ValveDriver::new(
        Coil(2 * ch),
        Coil(2 * ch + 1),
        DumpValve,
        ValveType::SingleSolenoid52,
        SafeMode::Vent,
    ) {
        Ok(v) => v,
        Err(_) => panic!("valve driver outputs failed"),
    };
    // Built in place (an array literal, not `from_fn`, whose temporaries cost a session's size of stack).
    let mut sessions: [Session<Coil, Coil, DumpValve>; CHANNELS] = [
        Session::new(valve(0), board::stack_peak_bytes),
        Session::new(valve(1), board::stack_peak_bytes),
    ];
    // The channel the controller frames address (None after an invalid CtrlChannel: dropped until a valid
    // one), and the channels addressed since power-up (a one-controller host only ever addresses 0).
    let mut current: Option<usize> = Some(0);
    let mut addressed = [false; CHANNELS];
    addressed[0] = true;
    let mut io = IoBoard::new(Sampler {
        position: board::Adc,
        channel_1: board::Adc,
        pressure_b: board::Adc,
        supply: board::Adc,
    });
    let mut decoder = Decoder::new();
    board::enable_interrupts();
    loop {
        // A byte, or None when the watchdog's deadline passed.
        let byte = board::wait();
        let now = clock.now_ns();
        NOW_US.store((now / 1000) as u32, Ordering::Relaxed);
        for s in sessions.iter_mut() {
            s.poll(now, &mut |m| send(&mut uart, m));
        }
        if byte.is_none() && io.period_ns().is_some() {
            io.on_period(now, sessions[0].valve(), &mut |m| send(&mut uart, m));
        }
        if let Some(b) = byte {
            let mut events = [None; 4];
            let mut n_ev = 0;
            decoder.feed(&[b], |ev| {
                if let Some(slot) = events.get_mut(n_ev) {
                    *slot = Some(ev);
                    n_ev += 1;
                }
            });
            for ev in events.into_iter().flatten() {
                if let DecodeEvent::Frame(f) = ev
                    && (io.period_ns().is_some()
                        || (matches!(f.msg, Message::Config(_)) && sessions[0].in_setup()))
                {
                    let before = io.period_ns();
                    io.on_message(&f.msg, now, sessions[0].valve(), &mut |m| send(&mut uart, m));
                    if let Some(p) = io.period_ns().filter(|&p| Some(p) != before) {
                        board::arm_deadline(p);
                    }
                    continue;
                }
                // Which sessions the event is for: CtrlChannel picks the channel; a safe command and Reset
                // reach every channel addressed; everything else the current channel.
                let mut to = [false; CHANNELS];
                match ev {
                    DecodeEvent::Frame(f) => match f.msg {
                        Message::CtrlChannel(c) => {
                            let c = usize::from(c);
                            if c < CHANNELS {
                                current = Some(c);
                                addressed[c] = true;
                            } else {
                                current = None;
                                send(
                                    &mut uart,
                                    &Message::CtrlReady(ReadyPayload {
                                        result: ready::START,
                                        detail: 3,
                                    }),
                                );
                            }
                            continue;
                        }
                        Message::Valve(v) if v.mode.is_safe() => to = addressed,
                        Message::Reset(_) => to = addressed,
                        _ => {
                            if let Some(c) = current {
                                to[c] = true;
                            }
                        }
                    },
                    _ => to[current.unwrap_or(0)] = true,
                }
                for (s, _) in sessions.iter_mut().zip(to).filter(|(_, t)| *t) {
                    let mut out: [Option<Message>; 2] = [None, None];
                    let mut k = 0;
                    let mut clk = || clock.now_ns();
                    s.on_event(ev, now, &mut clk, &mut |m: &Message| {
                        if let Some(slot) = out.get_mut(k) {
                            *slot = Some(*m);
                            k += 1;
                        }
                    });
                    for m in out.iter_mut().filter_map(Option::take) {
                        send(&mut uart, &m);
                    }
                }
            }
        }
        // One safe state for the board: a channel gone safe takes every running channel with it, now.
        if let Some((reason, latched)) = sessions.iter().find_map(Session::safe_reason)
            && sessions.iter().any(Session::running)
        {
            let now = clock.now_ns();
            for s in sessions.iter_mut().filter(|s| s.running()) {
                s.force_safe(reason, latched, now, &mut |m| send(&mut uart, m));
            }
        }
        if let Some(at) = sessions.iter_mut().filter_map(Session::take_deadline).min() {
            board::arm_deadline(at.saturating_sub(clock.now_ns()));
        }
        let used = || sessions.iter().zip(addressed).filter(|(_, a)| *a).map(|(s, _)| s);
        VENTS.store(used().any(Session::vents), Ordering::Relaxed);
        LAST_TICK.store(used().map(Session::last_tick).max().unwrap_or(0), Ordering::Relaxed);
    }
}

/// Every external interrupt (UART0 receive, TIMER1): cortex-m-rt's default handler.
#[exception]
unsafe fn DefaultHandler(_irqn: i16) {
    board::on_interrupt();
}

/// A fixed buffer for the panic message (no allocation in a panic handler).
struct Text {
    buf: [u8; 160],
    len: usize,
}

impl core::fmt::Write for Text {
    fn write_str(&mut self, s: &str) -> core::fmt::Result {
        for &b in s.as_bytes() {
            if self.len < self.buf.len() {
                self.buf[self.len] = b;
                self.len += 1;
            }
        }
        Ok(())
    }
}

/// A panic puts the valve in its safe state first, then reports it over the link (Fault PANIC with the
/// line, the message as Text frames, a Safe frame) and stays safe until the board is reset.
#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    cortex_m::interrupt::disable();
    let vent = VENTS.load(Ordering::Relaxed);
    board::force_safe(vent);
    let mut uart = Uart::init();
    let line = info.location().map_or(0, |l| l.line());
    send(
        &mut uart,
        &Message::Fault {
            code: fault_code::PANIC,
            detail: line.min(u32::from(u16::MAX)) as u16,
        },
    );
    let mut text = Text {
        buf: [0; 160],
        len: 0,
    };
    let _ = write!(text, "{}", info.message());
    if let Some(l) = info.location() {
        let _ = write!(text, " at {}:{}", l.file(), l.line());
    }
    for piece in text.buf[..text.len].chunks(TEXT_LEN) {
        let mut bytes = [0u8; TEXT_LEN];
        bytes[..piece.len()].copy_from_slice(piece);
        send(
            &mut uart,
            &Message::Text(TextPayload {
                len: piece.len() as u8,
                bytes,
            }),
        );
    }
    let now_us = NOW_US.load(Ordering::Relaxed);
    send(
        &mut uart,
        &Message::Safe(SafePayload {
            reason: fault_code::PANIC,
            last_tick: LAST_TICK.load(Ordering::Relaxed),
            last_valid_us: now_us,
            safe_at_us: now_us,
            crc_errors: 0,
            mode: if vent {
                ValveMode::SafeVent
            } else {
                ValveMode::SafeHold
            },
            stack_peak_bytes: board::stack_peak_bytes().min(u32::from(u16::MAX)) as u16,
        }),
    );
    loop {
        // Keep the outputs safe whatever else wrote them.
        board::force_safe(vent);
        cortex_m::asm::nop();
    }
}
