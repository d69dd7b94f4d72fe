//! The mps2-an386 board as QEMU models it (ARM AN386, Cortex-M4 with FPU): UART0, a 25 MHz timer as the
//! board clock, the FPGA LED register as the supply dump-valve pin, and the coil PWM outputs.
//! Everything board-specific is in this file; a port to another MCU replaces it (docs/firmware.md).

use core::ptr::{read_volatile, write_volatile};
use core::sync::atomic::{AtomicBool, AtomicU8, AtomicU16, AtomicUsize, Ordering};

use embedded_hal::digital::{ErrorType as PinErrorType, OutputPin};
use embedded_hal::pwm::{ErrorType as PwmErrorType, SetDutyCycle};

/// CMSDK APB UART0 (AN386 memory map): DATA, STATE (bit 0 TX full, bit 1 RX full), CTRL (bit 0 TX enable,
/// bit 1 RX enable), BAUDDIV.
const UART0: usize = 0x4000_4000;
const UART_DATA: usize = UART0;
const UART_STATE: usize = UART0 + 0x04;
const UART_CTRL: usize = UART0 + 0x08;
const UART_INT: usize = UART0 + 0x0C;
const UART_BAUDDIV: usize = UART0 + 0x10;

/// CMSDK APB TIMER0: CTRL (bit 0 enable), VALUE (counts down at the 25 MHz peripheral clock), RELOAD.
const TIMER0: usize = 0x4000_0000;
const TIMER_CTRL: usize = TIMER0;
const TIMER_VALUE: usize = TIMER0 + 0x04;
const TIMER_RELOAD: usize = TIMER0 + 0x08;
/// The peripheral clock of the AN386 image: 25 MHz, one count = 40 ns.
const NS_PER_COUNT: u64 = 40;

/// CMSDK APB TIMER1: the watchdog's deadline (its interrupt sets [`DEADLINE`]).
const TIMER1: usize = 0x4000_1000;

/// Arms TIMER1 to interrupt `ns` from now (and every `ns` after).
pub fn arm_deadline(ns: u64) {
    let counts = (ns / NS_PER_COUNT).clamp(1, u64::from(u32::MAX)) as u32;
    wr(TIMER1, 0);
    wr(TIMER1 + 0x08, counts);
    wr(TIMER1 + 0x04, counts);
    wr(TIMER1 + 0x0C, 1);
    wr(TIMER1, 0b1001);
}

/// Bytes received by the interrupt handler, not yet taken by the main loop (single producer, single consumer).
static RX: [AtomicU8; 256] = [const { AtomicU8::new(0) }; 256];
static RX_HEAD: AtomicUsize = AtomicUsize::new(0);
static RX_TAIL: AtomicUsize = AtomicUsize::new(0);
/// Set by TIMER1's interrupt: the watchdog deadline passed.
static DEADLINE: AtomicBool = AtomicBool::new(false);

/// Enables UART0's receive interrupt and TIMER1's, in the NVIC too (AN386: UART0 RX is IRQ 0, TIMER1 IRQ 9;
/// [`on_interrupt`] does not depend on the numbers).
pub fn enable_interrupts() {
    // NVIC_ISER0: external interrupts 0-31.
    wr(0xE000_E100, u32::MAX);
    // SAFETY: the handlers only touch the atomics above and the UART/TIMER1 registers.
    unsafe { cortex_m::interrupt::enable() };
}

/// Set while the ring is full: the receive interrupt is off and the UART keeps its byte, so QEMU holds the
/// rest back (the flow control a one-byte UART gives for free).
static RX_PAUSED: AtomicBool = AtomicBool::new(false);

/// Moves received bytes into the ring; pauses reception when the ring is full.
fn drain_uart() {
    while rd(UART_STATE) & 0b10 != 0 {
        let head = RX_HEAD.load(Ordering::Relaxed);
        if head.wrapping_sub(RX_TAIL.load(Ordering::Acquire)) >= RX.len() {
            wr(UART_CTRL, 0b0011);
            RX_PAUSED.store(true, Ordering::Release);
            return;
        }
        RX[head % RX.len()].store(rd(UART_DATA) as u8, Ordering::Relaxed);
        RX_HEAD.store(head.wrapping_add(1), Ordering::Release);
    }
}

/// Every external interrupt: received bytes go into the ring, TIMER1's deadline sets its flag.
pub fn on_interrupt() {
    wr(UART_INT, 0b11);
    drain_uart();
    if rd(TIMER1 + 0x0C) & 1 != 0 {
        wr(TIMER1 + 0x0C, 1);
        DEADLINE.store(true, Ordering::Release);
    }
}

/// Waits for a received byte or the deadline, spinning on RAM only. Under QEMU -icount the spin advances the
/// board clock by one ns an instruction, so a deadline fires at an exact instruction count; and it touches no
/// device register, which would take QEMU's I/O lock on every read and starve the thread that delivers the
/// bytes (400 µs a byte measured when polling the UART's status register).
pub fn wait() -> Option<u8> {
    loop {
        let tail = RX_TAIL.load(Ordering::Relaxed);
        if RX_HEAD.load(Ordering::Acquire) != tail {
            let b = RX[tail % RX.len()].load(Ordering::Relaxed);
            RX_TAIL.store(tail.wrapping_add(1), Ordering::Release);
            if RX_PAUSED.load(Ordering::Acquire) {
                // Room again: take the byte the UART kept, and let it interrupt again.
                cortex_m::interrupt::free(|_| {
                    RX_PAUSED.store(false, Ordering::Release);
                    wr(UART_CTRL, 0b1011);
                    drain_uart();
                });
            }
            return Some(b);
        }
        if DEADLINE.swap(false, Ordering::AcqRel) {
            return None;
        }
        core::hint::spin_loop();
    }
}

/// FPGA IO LED register (AN386: FPGAIO at 0x4002_8000, LED0 bit 0): drives the supply dump valve here.
const FPGAIO_LED: usize = 0x4002_8000;

fn rd(addr: usize) -> u32 {
    // SAFETY: `addr` is one of the board's memory-mapped registers above, 4-byte aligned.
    unsafe { read_volatile(addr as *const u32) }
}

fn wr(addr: usize, v: u32) {
    // SAFETY: as in `rd`.
    unsafe { write_volatile(addr as *mut u32, v) }
}

/// UART0 at 8N1 (the baud rate is the emulator's business; BAUDDIV ≥ 16 is what the CMSDK UART requires).
pub struct Uart;

impl Uart {
    /// Enables transmit and receive, and the receive interrupt (bytes arrive through [`on_interrupt`]).
    pub fn init() -> Self {
        wr(UART_BAUDDIV, 16);
        wr(UART_CTRL, 0b1011);
        Uart
    }

    /// Sends bytes, waiting while the transmit register is full.
    pub fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            while rd(UART_STATE) & 0b01 != 0 {}
            wr(UART_DATA, u32::from(b));
        }
    }
}

/// The board clock: TIMER0 free-running from 0xFFFF_FFFF, extended to 64 bits in software (it wraps every
/// 172 s; the main loop reads it far more often). Under `qemu -icount` it runs on virtual time.
pub struct Clock {
    last: u32,
    high: u64,
}

impl Clock {
    /// Starts the timer.
    pub fn init() -> Self {
        wr(TIMER_CTRL, 0);
        wr(TIMER_RELOAD, u32::MAX);
        wr(TIMER_VALUE, u32::MAX);
        wr(TIMER_CTRL, 1);
        Clock { last: 0, high: 0 }
    }

    /// Nanoseconds since `init`, 40 ns resolution.
    pub fn now_ns(&mut self) -> u64 {
        let up = u32::MAX - rd(TIMER_VALUE);
        if up < self.last {
            self.high += 1 << 32;
        }
        self.last = up;
        (self.high + u64::from(up)) * NS_PER_COUNT
    }
}

/// Coil duty registers. The AN386 image has no PWM peripheral, so the duty is kept in a word a debugger or
/// the panic handler can reach; on an STM32F4 this is a timer's capture/compare register (TIMx_CCRy).
static COIL_DUTY: [AtomicU16; 2 * crate::CHANNELS] = [const { AtomicU16::new(0) }; 2 * crate::CHANNELS];
/// Full duty of a coil output (a 10 kHz PWM from a 100 MHz timer clock would have 10 000).
pub const COIL_MAX_DUTY: u16 = 10_000;

/// One coil's PWM output (2 i = channel i's coil A, 2 i + 1 its coil B).
pub struct Coil(pub usize);

impl PwmErrorType for Coil {
    type Error = core::convert::Infallible;
}

impl SetDutyCycle for Coil {
    fn max_duty_cycle(&self) -> u16 {
        COIL_MAX_DUTY
    }
    fn set_duty_cycle(&mut self, duty: u16) -> Result<(), Self::Error> {
        COIL_DUTY[self.0].store(duty.min(COIL_MAX_DUTY), Ordering::SeqCst);
        Ok(())
    }
}

/// An analog input of the I/O-board mode. The AN386 image has no ADC, so every conversion reads 0 counts; a
/// real board converts its position sensor, pressure transmitters and load cell here.
pub struct Adc;

impl pneuflex_valve_driver::AdcChannel for Adc {
    type Error = core::convert::Infallible;
    fn read_counts(&mut self) -> Result<u16, Self::Error> {
        Ok(0)
    }
}

/// The supply dump valve: energised (high) = supply connected.
pub struct DumpValve;

impl PinErrorType for DumpValve {
    type Error = core::convert::Infallible;
}

impl OutputPin for DumpValve {
    fn set_low(&mut self) -> Result<(), Self::Error> {
        wr(FPGAIO_LED, rd(FPGAIO_LED) & !1);
        Ok(())
    }
    fn set_high(&mut self) -> Result<(), Self::Error> {
        wr(FPGAIO_LED, rd(FPGAIO_LED) | 1);
        Ok(())
    }
}

/// The safe state written straight to the outputs, without the driver object: for the panic handler.
/// `vent`: coils off and the dump valve de-energised; hold: coils off, supply kept.
pub fn force_safe(vent: bool) {
    for c in &COIL_DUTY {
        c.store(0, Ordering::SeqCst);
    }
    if vent {
        wr(FPGAIO_LED, rd(FPGAIO_LED) & !1);
    }
}

/// Stack bytes used so far: the distance from the stack top down to the lowest word no longer holding
/// cortex-m-rt's paint value.
pub fn stack_peak_bytes() -> u32 {
    unsafe extern "C" {
        static _stack_end: u32;
        static _stack_start: u32;
    }
    let lo = &raw const _stack_end as usize;
    let hi = &raw const _stack_start as usize;
    let mut a = lo;
    // SAFETY: every word between the linker symbols _stack_end and _stack_start is RAM.
    while a < hi && unsafe { read_volatile(a as *const u32) } == 0xCCCC_CCCC {
        a += 4;
    }
    (hi - a) as u32
}
