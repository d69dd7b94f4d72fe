//! Excitation signals for identification experiments (`pneuflex rig excite`): PRBS, chirp and steps on the
//! valve command, as a [`Controller`] so that they run in the rig's real-time loop under its supervisor and
//! are logged in `rig run`'s trace format.
//!
//! A valve drives a cylinder like an integrator (the command sets a velocity), so a purely open-loop signal
//! walks the piston into a stop and the supervisor's position limit. The command is therefore the designed
//! signal plus a weak centring term: `u = clamp(u0 + a s(t) + k_c (x_c - x), -1, 1)`. Identification
//! replays the logged `u`, whatever produced it, so the centring term does not bias the fit; keep `k_c` small
//! so that the designed signal dominates. With `k_c = 0` and `x_c` beyond a stop the signal runs with the
//! piston held (a pressure-only experiment).

use pneuflex_control::{Controller, Sensors, Setpoint, Telemetry, ValveCommand};

/// The designed part s(t) of the command, in [-1, 1].
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Signal {
    /// Pseudo-random binary sequence: +-1, each bit `bit_s` long and drawn at random (seeded).
    Prbs {
        /// Bit length, s (at least a PWM period to matter on an on/off valve).
        bit_s: f64,
        /// Seed.
        seed: u64,
    },
    /// Linear chirp sin(2 pi (f0 t + (f1 - f0) t^2 / (2 T))) from `f0_hz` to `f1_hz` over the duration.
    Chirp {
        /// Start frequency, Hz.
        f0_hz: f64,
        /// End frequency, Hz.
        f1_hz: f64,
        /// Sweep duration T, s.
        duration_s: f64,
    },
    /// Steps to random levels in [-1, 1], each held `hold_s`.
    Steps {
        /// Hold time of each level, s.
        hold_s: f64,
        /// Seed.
        seed: u64,
    },
}

impl Signal {
    /// s(t).
    pub fn at(&self, t: f64) -> f64 {
        let t = t.max(0.0);
        match *self {
            Signal::Prbs { bit_s, seed } => {
                // Each bit +-1 with probability 1/2, independent of the others.
                let k = (t / bit_s) as u64;
                if hash(seed, k) & 1 == 0 { 1.0 } else { -1.0 }
            }
            Signal::Chirp {
                f0_hz,
                f1_hz,
                duration_s,
            } => {
                let ph = f0_hz * t + (f1_hz - f0_hz) * t * t / (2.0 * duration_s);
                (2.0 * core::f64::consts::PI * ph).sin()
            }
            Signal::Steps { hold_s, seed } => {
                let k = (t / hold_s) as u64;
                (hash(seed, k) >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
            }
        }
    }
}

/// splitmix64 of (seed, i): a deterministic pseudo-random word.
fn hash(seed: u64, i: u64) -> u64 {
    let mut z = seed
        .wrapping_mul(0x9E37_79B9_7F4A_7C15)
        .wrapping_add(i.wrapping_mul(0xBF58_476D_1CE4_E5B9))
        .wrapping_add(0x94D0_49BB_1331_11EB);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// An excitation experiment: `u = clamp(u0 + a s(t) + k_c (x_c - x), -1, 1)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Excitation {
    /// The designed signal.
    pub signal: Signal,
    /// Amplitude a, in command units.
    pub amplitude: f64,
    /// Command bias u0.
    pub bias: f64,
    /// Centring position x_c, m.
    pub centre_m: f64,
    /// Centring gain k_c, 1/m (0 = none).
    pub centring_per_m: f64,
    /// Soft start, s: the centre moves from the start position to `centre_m` and the amplitude grows from
    /// 0 over this time (a step of the centre would throw the piston into a stop).
    pub ramp_s: f64,
}

impl Excitation {
    /// Checks the amplitude, bias and gain; the message names the option.
    pub fn validate(&self) -> Result<(), String> {
        let fin = |name: &str, v: f64| {
            if v.is_finite() {
                Ok(())
            } else {
                Err(format!("{name}: must be a finite number, got {v}"))
            }
        };
        fin("--amplitude", self.amplitude)?;
        fin("--bias", self.bias)?;
        fin("--centre", self.centre_m)?;
        fin("--centring", self.centring_per_m)?;
        if !(self.ramp_s.is_finite() && self.ramp_s >= 0.0) {
            return Err(format!("--ramp: must be >= 0 s, got {}", self.ramp_s));
        }
        if !(0.0..=1.0).contains(&self.amplitude) {
            return Err(format!(
                "--amplitude: must be in [0, 1], got {}",
                self.amplitude
            ));
        }
        if !(-1.0..=1.0).contains(&self.bias) {
            return Err(format!("--bias: must be in [-1, 1], got {}", self.bias));
        }
        if self.centring_per_m < 0.0 {
            return Err(format!(
                "--centring: must be >= 0, got {}",
                self.centring_per_m
            ));
        }
        match self.signal {
            Signal::Prbs { bit_s, .. } if !(bit_s.is_finite() && bit_s > 0.0) => {
                Err(format!("PRBS bit length must be > 0 s, got {bit_s}"))
            }
            Signal::Steps { hold_s, .. } if !(hold_s.is_finite() && hold_s > 0.0) => {
                Err(format!("step hold time must be > 0 s, got {hold_s}"))
            }
            Signal::Chirp {
                f0_hz,
                f1_hz,
                duration_s,
            } if !(f0_hz >= 0.0 && f1_hz > 0.0 && duration_s > 0.0) => Err(format!(
                "chirp needs f0 >= 0, f1 > 0 and a duration > 0, got {f0_hz}, {f1_hz}, {duration_s}"
            )),
            _ => Ok(()),
        }
    }

    /// The command at time `t` (from the start) and position `x`, having started at `x_start`.
    pub fn command(&self, t: f64, x: f64, x_start: f64) -> f64 {
        let w = if self.ramp_s > 0.0 {
            (t / self.ramp_s).clamp(0.0, 1.0)
        } else {
            1.0
        };
        let centre = x_start + w * (self.centre_m - x_start);
        let u =
            self.bias + w * self.amplitude * self.signal.at(t) + self.centring_per_m * (centre - x);
        if u.is_nan() { 0.0 } else { u.clamp(-1.0, 1.0) }
    }
}

/// The excitation as a controller for the rig's loop (the setpoint is ignored; time from the sensors).
#[derive(Clone, Debug)]
pub struct Exciter {
    /// The experiment.
    pub excitation: Excitation,
    /// Time and position of the first update.
    start: Option<(f64, f64)>,
}

impl Exciter {
    /// A controller playing `excitation` from its first update on.
    pub fn new(excitation: Excitation) -> Self {
        Self {
            excitation,
            start: None,
        }
    }
}

impl Controller for Exciter {
    fn update(&mut self, sensors: &Sensors, _setpoint: &Setpoint, _dt: f64) -> ValveCommand {
        let (t0, x0) = *self.start.get_or_insert((sensors.t, sensors.x));
        ValveCommand {
            u: self.excitation.command(sensors.t - t0, sensors.x, x0),
        }
    }
    fn telemetry(&self) -> Telemetry {
        Telemetry {
            x_r: self.excitation.centre_m,
            ..Telemetry::default()
        }
    }
    fn reset(&mut self) {
        self.start = None;
    }
}
