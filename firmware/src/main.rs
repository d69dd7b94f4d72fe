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
use pneuflex_protocol::ctrl::{SafePayload, TEXT_LEN, TextPayload};
use pneuflex_protocol::{DecodeEvent, Decoder, MAX_FRAME, Message, ValveMode, encode, fault_code};
use pneuflex_valve_driver::{SafeMode, Sampler, ValveDriver, ValveType};

use board::{Clock, Coil, DumpValve, Uart};
use io_board::IoBoard;
use session::Session;

/// Sequence number of the next frame sent (shared with the panic handler).
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
    let valve = match ValveDriver::new(
        Coil(0),
        Coil(1),
        DumpValve,
        ValveType::SingleSolenoid52,
        SafeMode::Vent,
    ) {
        Ok(v) => v,
        Err(_) => panic!("valve driver outputs failed"),
    };
    let mut session = Session::new(valve, board::stack_peak_bytes);
    // The I/O-board mode (rig run's board), entered by a Config frame while no controller runs.
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
        session.poll(now, &mut |m| send(&mut uart, m));
        if byte.is_none() && io.period_ns().is_some() {
            io.on_period(now, session.valve(), &mut |m| send(&mut uart, m));
        }
        if let Some(b) = byte {
            // Answers are queued while the decoder holds the session's input, then sent.
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
                        || (matches!(f.msg, Message::Config(_)) && session.in_setup()))
                {
                    let before = io.period_ns();
                    io.on_message(&f.msg, now, session.valve(), &mut |m| send(&mut uart, m));
                    if let Some(p) = io.period_ns().filter(|&p| Some(p) != before) {
                        // Samples every period from now on (TIMER1 reloads itself).
                        board::arm_deadline(p);
                    }
                    continue;
                }
                let mut out: [Option<Message>; 2] = [None, None];
                let mut k = 0;
                let mut clk = || clock.now_ns();
                session.on_event(ev, now, &mut clk, &mut |m: &Message| {
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
        if let Some(at) = session.take_deadline() {
            board::arm_deadline(at.saturating_sub(clock.now_ns()));
        }
        VENTS.store(session.vents(), Ordering::Relaxed);
        LAST_TICK.store(session.last_tick(), Ordering::Relaxed);
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
