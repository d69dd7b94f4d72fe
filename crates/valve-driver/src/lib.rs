//! The I/O board's valve driver, written against embedded-hal 1.0 traits so that it runs on the board's
//! microcontroller (`thumbv7em-none-eabihf`) next to the same `pneuflex-control` controllers the host uses.
//!
//! - [`ValveDriver`] maps the signed valve command `u` in [-1, 1] to the solenoid coils' PWM duty
//!   ([`embedded_hal::pwm::SetDutyCycle`]) and a supply dump valve ([`embedded_hal::digital::OutputPin`]),
//!   and puts the valve in its safe state (vent or hold).
//! - [`AdcChannel`] is the ADC-reading trait embedded-hal 1.0 does not have; [`Sampler`] reads the board's
//!   four analog channels with it.
#![no_std]

use embedded_hal::digital::OutputPin;
use embedded_hal::pwm::SetDutyCycle;
use pneuflex_control::ValveCommand;

/// An ADC channel: one conversion, right-aligned counts (embedded-hal 1.0 has no ADC trait).
pub trait AdcChannel {
    /// The HAL's error.
    type Error: core::fmt::Debug;
    /// Converts once and returns the counts.
    fn read_counts(&mut self) -> Result<u16, Self::Error>;
}

impl<T: AdcChannel + ?Sized> AdcChannel for &mut T {
    type Error = T::Error;
    fn read_counts(&mut self) -> Result<u16, Self::Error> {
        (**self).read_counts()
    }
}

/// Which valve the board drives.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ValveType {
    /// Two-position five-way single-solenoid valve (the paper's A05PS25X-1P): coil A only, duty (1 + u) / 2
    /// of the energised position (supply to A) — the mapping of `pneuflex-pneumatics`' PWM valve model.
    SingleSolenoid52,
    /// Three-position five-way double-solenoid valve: coil A extends (u > 0), coil B retracts (u < 0),
    /// both off centres the spool (closed or exhaust centre, by the valve's build).
    DoubleSolenoid53 {
        /// |u| below this leaves both coils off (no chatter around zero).
        deadband: f64,
        /// Smallest duty that still moves the spool; |u| above the deadband maps to [min_duty, 1].
        min_duty: f64,
    },
}

/// The valve's safe state.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SafeMode {
    /// Both chambers to exhaust: coils off and the supply dump valve de-energised (supply cut and vented).
    Vent,
    /// Both chambers closed: coils off (closed-centre spool), supply left on.
    Hold,
}

/// What the driver last applied.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Applied {
    /// Duty fractions of coil A and coil B.
    Run {
        /// Coil A duty in [0, 1].
        coil_a: f64,
        /// Coil B duty in [0, 1].
        coil_b: f64,
    },
    /// In the safe state.
    Safe(SafeMode),
}

/// A driver error: which output failed.
#[derive(Debug, PartialEq)]
pub enum DriverError<EA, EB, ED> {
    /// Coil A's PWM.
    CoilA(EA),
    /// Coil B's PWM.
    CoilB(EB),
    /// The supply dump valve's pin.
    Dump(ED),
}

/// The result of a driver operation over outputs `A`, `B` (coils) and `D` (dump valve).
pub type DriverResult<T, A, B, D> = Result<
    T,
    DriverError<
        <A as embedded_hal::pwm::ErrorType>::Error,
        <B as embedded_hal::pwm::ErrorType>::Error,
        <D as embedded_hal::digital::ErrorType>::Error,
    >,
>;

/// The valve driver: two PWM coil outputs and the supply dump-valve pin.
pub struct ValveDriver<A, B, D> {
    coil_a: A,
    coil_b: B,
    dump: D,
    kind: ValveType,
    safe: SafeMode,
    applied: Applied,
}

/// Sets a PWM output to `frac` in [0, 1] of its maximum duty (rounded).
fn set_fraction<P: SetDutyCycle>(p: &mut P, frac: f64) -> Result<(), P::Error> {
    let max = p.max_duty_cycle();
    let f = if frac.is_nan() {
        0.0
    } else {
        frac.clamp(0.0, 1.0)
    };
    // Round half up without libm: max ≤ 65535 so the product is exact in f64.
    let duty = (f * f64::from(max) + 0.5) as u16;
    p.set_duty_cycle(duty.min(max))
}

impl<A: SetDutyCycle, B: SetDutyCycle, D: OutputPin> ValveDriver<A, B, D> {
    /// A driver that starts in the safe state.
    pub fn new(
        coil_a: A,
        coil_b: B,
        dump: D,
        kind: ValveType,
        safe: SafeMode,
    ) -> DriverResult<Self, A, B, D> {
        let mut d = Self {
            coil_a,
            coil_b,
            dump,
            kind,
            safe,
            applied: Applied::Safe(safe),
        };
        d.go_safe()?;
        Ok(d)
    }

    /// The coil duties for command `u` (NaN -> the centre/neutral duty, never an open valve by accident).
    pub fn duties(&self, u: f64) -> (f64, f64) {
        let u = if u.is_nan() { 0.0 } else { u.clamp(-1.0, 1.0) };
        match self.kind {
            ValveType::SingleSolenoid52 => ((1.0 + u) * 0.5, 0.0),
            ValveType::DoubleSolenoid53 { deadband, min_duty } => {
                let m = if u >= 0.0 { u } else { -u };
                if m < deadband {
                    return (0.0, 0.0);
                }
                // Map (deadband, 1] onto [min_duty, 1].
                let span = 1.0 - deadband;
                let frac = if span > 0.0 {
                    (m - deadband) / span
                } else {
                    1.0
                };
                let d = min_duty + (1.0 - min_duty) * frac;
                if u > 0.0 { (d, 0.0) } else { (0.0, d) }
            }
        }
    }

    /// Applies a valve command (supply on).
    pub fn apply(&mut self, cmd: ValveCommand) -> DriverResult<Applied, A, B, D> {
        let (a, b) = self.duties(cmd.u);
        self.dump.set_high().map_err(DriverError::Dump)?;
        // Switch the releasing coil off first so that both coils are never energised together.
        if a > 0.0 {
            set_fraction(&mut self.coil_b, b).map_err(DriverError::CoilB)?;
            set_fraction(&mut self.coil_a, a).map_err(DriverError::CoilA)?;
        } else {
            set_fraction(&mut self.coil_a, a).map_err(DriverError::CoilA)?;
            set_fraction(&mut self.coil_b, b).map_err(DriverError::CoilB)?;
        }
        self.applied = Applied::Run {
            coil_a: a,
            coil_b: b,
        };
        Ok(self.applied)
    }

    /// Puts the valve in its configured safe state: coils off, and for `Vent` the supply dump valve off.
    pub fn go_safe(&mut self) -> DriverResult<Applied, A, B, D> {
        self.coil_a
            .set_duty_cycle_fully_off()
            .map_err(DriverError::CoilA)?;
        self.coil_b
            .set_duty_cycle_fully_off()
            .map_err(DriverError::CoilB)?;
        match self.safe {
            SafeMode::Vent => self.dump.set_low().map_err(DriverError::Dump)?,
            SafeMode::Hold => self.dump.set_high().map_err(DriverError::Dump)?,
        }
        self.applied = Applied::Safe(self.safe);
        Ok(self.applied)
    }

    /// Changes the safe state (from the host's Config message).
    pub fn set_safe_mode(&mut self, safe: SafeMode) {
        self.safe = safe;
    }

    /// What was applied last.
    pub fn applied(&self) -> Applied {
        self.applied
    }

    /// Gives the peripherals back.
    pub fn release(self) -> (A, B, D) {
        (self.coil_a, self.coil_b, self.dump)
    }
}

/// Converts the protocol's Q15 duty (32767 = +1) to a valve command.
pub fn command_from_q15(q: i16) -> ValveCommand {
    let u = f64::from(q) / 32767.0;
    ValveCommand {
        u: if u < -1.0 { -1.0 } else { u },
    }
}

/// Reads the board's four analog channels in protocol order: position, channel 1 (p_a or p_a - p_b),
/// chamber B, supply.
pub struct Sampler<P, C1, CB, S> {
    /// Position sensor channel.
    pub position: P,
    /// Channel 1: chamber A or the differential transmitter.
    pub channel_1: C1,
    /// Chamber B transmitter.
    pub pressure_b: CB,
    /// Supply transmitter.
    pub supply: S,
}

/// Which channel failed.
#[derive(Debug, PartialEq, Eq, Clone, Copy)]
pub enum SampleError {
    /// Position channel.
    Position,
    /// Channel 1.
    Channel1,
    /// Chamber B channel.
    PressureB,
    /// Supply channel.
    Supply,
}

impl<P: AdcChannel, C1: AdcChannel, CB: AdcChannel, S: AdcChannel> Sampler<P, C1, CB, S> {
    /// One conversion of every channel: [position, channel 1, chamber B, supply] counts.
    pub fn sample(&mut self) -> Result<[u16; 4], SampleError> {
        Ok([
            self.position
                .read_counts()
                .map_err(|_| SampleError::Position)?,
            self.channel_1
                .read_counts()
                .map_err(|_| SampleError::Channel1)?,
            self.pressure_b
                .read_counts()
                .map_err(|_| SampleError::PressureB)?,
            self.supply.read_counts().map_err(|_| SampleError::Supply)?,
        ])
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use core::convert::Infallible;
    use std::vec::Vec;

    #[derive(Default)]
    struct Pwm {
        duty: u16,
        history: Vec<u16>,
    }
    impl embedded_hal::pwm::ErrorType for Pwm {
        type Error = Infallible;
    }
    impl SetDutyCycle for Pwm {
        fn max_duty_cycle(&self) -> u16 {
            1000
        }
        fn set_duty_cycle(&mut self, duty: u16) -> Result<(), Infallible> {
            self.duty = duty;
            self.history.push(duty);
            Ok(())
        }
    }
    #[derive(Default)]
    struct Pin(bool);
    impl embedded_hal::digital::ErrorType for Pin {
        type Error = Infallible;
    }
    impl OutputPin for Pin {
        fn set_low(&mut self) -> Result<(), Infallible> {
            self.0 = false;
            Ok(())
        }
        fn set_high(&mut self) -> Result<(), Infallible> {
            self.0 = true;
            Ok(())
        }
    }

    fn d53() -> ValveDriver<Pwm, Pwm, Pin> {
        ValveDriver::new(
            Pwm::default(),
            Pwm::default(),
            Pin::default(),
            ValveType::DoubleSolenoid53 {
                deadband: 0.05,
                min_duty: 0.2,
            },
            SafeMode::Vent,
        )
        .unwrap()
    }

    #[test]
    fn double_solenoid_picks_the_coil_by_sign() {
        let mut d = d53();
        d.apply(ValveCommand { u: 1.0 }).unwrap();
        let (a, b, dump) = d.release();
        assert_eq!((a.duty, b.duty, dump.0), (1000, 0, true));
        let mut d = d53();
        // u = -0.525: halfway through (0.05, 1] -> 0.2 + 0.8 * 0.5 = 0.6 on coil B.
        d.apply(ValveCommand { u: -0.525 }).unwrap();
        assert_eq!(
            d.applied(),
            Applied::Run {
                coil_a: 0.0,
                coil_b: 0.6000000000000001
            }
        );
        let (a, b, _) = d.release();
        assert_eq!((a.duty, b.duty), (0, 600));
        let d = d53();
        assert_eq!(d.duties(0.04), (0.0, 0.0));
        assert_eq!(d.duties(f64::NAN), (0.0, 0.0));
    }

    #[test]
    fn single_solenoid_duty_matches_the_pwm_valve_model() {
        let mut d = ValveDriver::new(
            Pwm::default(),
            Pwm::default(),
            Pin::default(),
            ValveType::SingleSolenoid52,
            SafeMode::Hold,
        )
        .unwrap();
        for (u, want) in [(-1.0, 0), (0.0, 500), (0.5, 750), (1.0, 1000)] {
            d.apply(ValveCommand { u }).unwrap();
            let Applied::Run { coil_a, .. } = d.applied() else {
                panic!()
            };
            assert_eq!(coil_a, (1.0 + u) / 2.0);
            let (a, b, dump) = d.release();
            assert_eq!((a.duty, b.duty, dump.0), (want, 0, true));
            d = ValveDriver::new(a, b, dump, ValveType::SingleSolenoid52, SafeMode::Hold).unwrap();
        }
    }

    #[test]
    fn safe_states() {
        let mut d = d53();
        d.apply(ValveCommand { u: 0.8 }).unwrap();
        assert_eq!(d.go_safe().unwrap(), Applied::Safe(SafeMode::Vent));
        let (a, b, dump) = d.release();
        assert_eq!(
            (a.duty, b.duty, dump.0),
            (0, 0, false),
            "vent: coils off, supply dumped"
        );
        let mut d =
            ValveDriver::new(a, b, dump, ValveType::SingleSolenoid52, SafeMode::Hold).unwrap();
        d.apply(ValveCommand { u: 0.3 }).unwrap();
        d.go_safe().unwrap();
        let (a, _, dump) = d.release();
        assert_eq!((a.duty, dump.0), (0, true), "hold: coils off, supply kept");
    }

    #[test]
    fn never_both_coils_on_during_a_reversal() {
        let mut d = d53();
        d.apply(ValveCommand { u: 0.9 }).unwrap();
        d.apply(ValveCommand { u: -0.9 }).unwrap();
        let (a, b, _) = d.release();
        // Coil A went off before coil B came on: the last A write is 0 and B's non-zero write came after.
        assert_eq!(*a.history.last().unwrap(), 0);
        assert!(b.duty > 0);
    }

    struct Adc(u16, bool);
    impl AdcChannel for Adc {
        type Error = ();
        fn read_counts(&mut self) -> Result<u16, ()> {
            if self.1 { Err(()) } else { Ok(self.0) }
        }
    }

    #[test]
    fn sampler_reads_in_protocol_order_and_names_a_failed_channel() {
        let mut s = Sampler {
            position: Adc(1, false),
            channel_1: Adc(2, false),
            pressure_b: Adc(3, false),
            supply: Adc(4, false),
        };
        assert_eq!(s.sample(), Ok([1, 2, 3, 4]));
        s.pressure_b.1 = true;
        assert_eq!(s.sample(), Err(SampleError::PressureB));
        assert_eq!(command_from_q15(-32768).u, -1.0);
        assert_eq!(command_from_q15(32767).u, 1.0);
    }
}
