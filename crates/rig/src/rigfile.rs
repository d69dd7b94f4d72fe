//! The rig file (TOML): serial link, loop rate, calibration, limits, safe state, watchdog, emulator.

use std::path::{Path, PathBuf};

use serde::Deserialize;

use crate::protocol::{MAX_CHANNELS, ValveMode};

/// A rig file could not be used; every variant names the file.
#[derive(Debug, thiserror::Error)]
pub enum RigFileError {
    /// Not a regular file, too large, or not UTF-8 (the message names the file once).
    #[error(transparent)]
    Input(#[from] pneuflex_files::InputError),
    /// The TOML did not parse or did not match the schema (unknown key, missing field, wrong type).
    #[error("{file}: {message}")]
    Parse {
        /// The rig file.
        file: PathBuf,
        /// toml's message, which names the key and the line.
        message: String,
    },
    /// A value is out of range (shown as `file:line:col: key: message`, the pneuflex file-error convention).
    #[error("{}{}: {key}: {message}", file.display(), at.map(|p| format!(":{p}")).unwrap_or_default())]
    Invalid {
        /// The rig file.
        file: PathBuf,
        /// Line and column of the key, when the file's text is at hand.
        at: Option<pneuflex_files::Position>,
        /// Dotted key path.
        key: String,
        /// What was expected.
        message: String,
    },
}

/// Serial link to the I/O board.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct LinkConfig {
    /// Serial device, e.g. `/dev/ttyACM0`; the emulator's pty path is given on the command line instead.
    pub port: String,
    /// Baud rate, bit/s.
    pub baud: u32,
    /// How long to wait for the board to answer the opening heartbeat, ms.
    #[serde(default = "default_handshake_ms")]
    pub handshake_timeout_ms: u64,
}

fn default_handshake_ms() -> u64 {
    500
}

/// The real-time loop.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct LoopConfig {
    /// Control rate, Hz (1 kHz default).
    #[serde(default = "default_rate")]
    pub rate_hz: f64,
    /// Busy-wait this long before each deadline instead of sleeping, µs (0 = sleep only).
    #[serde(default)]
    pub spin_us: u64,
    /// Flush the trace every this many samples (and always on a fault and at exit).
    #[serde(default = "default_flush")]
    pub trace_flush_every: usize,
    /// After a fault, keep sensing (valve safe) and tracing this long before stopping, s.
    #[serde(default = "default_post_fault")]
    pub post_fault_s: f64,
    /// Cut-off of the filtered position derivative that gives the flange velocity, Hz.
    #[serde(default = "default_vel_cutoff")]
    pub velocity_cutoff_hz: f64,
}

fn default_rate() -> f64 {
    1000.0
}
fn default_flush() -> usize {
    100
}
fn default_post_fault() -> f64 {
    0.05
}
fn default_vel_cutoff() -> f64 {
    50.0
}

impl Default for LoopConfig {
    fn default() -> Self {
        Self {
            rate_hz: default_rate(),
            spin_us: 0,
            trace_flush_every: default_flush(),
            post_fault_s: default_post_fault(),
            velocity_cutoff_hz: default_vel_cutoff(),
        }
    }
}

/// What a transmitter outputs.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum SignalKind {
    /// A voltage, read by the ADC through an optional divider; `signal_*` in V.
    Voltage,
    /// A current loop (4–20 mA) read across a shunt resistor; `signal_*` in mA.
    Current,
}

/// One analog channel as written in the rig file: the ADC front end, and the transmitter's line either from
/// a sensor sheet in `pneumatics/` (`sheet`) or written out (`signal`, `signal_min`, ... `quantity_max`).
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct AnalogChannel {
    /// Sensor model, for the record (e.g. "MPS-0327STPO").
    #[serde(default)]
    pub sensor: String,
    /// A pneumatics sensor sheet (relative to the rig file) giving signal kind and both calibration points.
    #[serde(default)]
    pub sheet: Option<PathBuf>,
    /// ADC resolution, bits (full scale = 2^bits - 1 counts).
    pub adc_bits: u32,
    /// ADC reference voltage, V.
    pub adc_ref_v: f64,
    /// Voltage or current output (from the sheet if `sheet` is given).
    #[serde(default)]
    pub signal: Option<SignalKind>,
    /// Shunt resistor for a current output, Ω.
    #[serde(default)]
    pub shunt_ohm: Option<f64>,
    /// Voltage divider in front of the ADC for a voltage output: signal volts per ADC volt (default 1).
    #[serde(default)]
    pub divider_ratio: Option<f64>,
    /// Signal at `quantity_min` (V or mA).
    #[serde(default)]
    pub signal_min: Option<f64>,
    /// Signal at `quantity_max` (V or mA).
    #[serde(default)]
    pub signal_max: Option<f64>,
    /// Quantity at `signal_min` (m for position, Pa for pressure).
    #[serde(default)]
    pub quantity_min: Option<f64>,
    /// Quantity at `signal_max`.
    #[serde(default)]
    pub quantity_max: Option<f64>,
}

/// A resolved linear channel: ADC counts -> signal (V or mA) -> physical quantity (SI).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LinearChannel {
    /// ADC resolution, bits.
    pub adc_bits: u32,
    /// ADC reference voltage, V.
    pub adc_ref_v: f64,
    /// Signal units (V or mA) per ADC volt: divider ratio, or 1000/shunt for a current.
    pub signal_per_adc_volt: f64,
    /// Signal at `quantity_min`.
    pub signal_min: f64,
    /// Signal at `quantity_max`.
    pub signal_max: f64,
    /// Quantity at `signal_min`, SI.
    pub quantity_min: f64,
    /// Quantity at `signal_max`, SI.
    pub quantity_max: f64,
}

/// Load-cell bridge calibration: force = (counts - offset) * n_per_count.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct LoadCellChannel {
    /// Load-cell model, for the record.
    #[serde(default)]
    pub sensor: String,
    /// Newtons per count (negative flips the sign so that pushing on the environment is positive).
    pub n_per_count: f64,
    /// Counts at zero force.
    pub offset_counts: f64,
}

/// Calibration of every channel the board samples, as written in the rig file.
///
/// Pressures: board channel 1 carries either a chamber-A gauge transmitter (`pressure_a`) or, as on the
/// paper's rig, the differential transmitter p_a - p_b (`differential`); channel 2 is chamber B (gauge).
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct CalibrationConfig {
    /// Atmospheric pressure added to gauge readings, Pa.
    #[serde(default = "default_atm")]
    pub atmosphere_pa: f64,
    /// Position sensor -> flange position, m.
    pub position: Option<AnalogChannel>,
    /// Channel 1 as a chamber-A transmitter -> gauge pressure, Pa.
    #[serde(default)]
    pub pressure_a: Option<AnalogChannel>,
    /// Channel 1 as the differential transmitter -> p_a - p_b, Pa.
    #[serde(default)]
    pub differential: Option<AnalogChannel>,
    /// Chamber B transmitter -> gauge pressure, Pa.
    pub pressure_b: Option<AnalogChannel>,
    /// Supply transmitter -> gauge pressure, Pa.
    pub supply: Option<AnalogChannel>,
    /// Load cell -> contact force, N.
    pub load_cell: Option<LoadCellChannel>,
}

fn default_atm() -> f64 {
    101_325.0
}

/// What board channel 1 measures.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ChannelA {
    /// Chamber A gauge pressure.
    Chamber(LinearChannel),
    /// Differential pressure p_a - p_b.
    Differential(LinearChannel),
}

/// The resolved calibration used by [`crate::rig::Calibrated`] and by the emulator (inverse).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Calibration {
    /// Atmospheric pressure, Pa.
    pub atmosphere_pa: f64,
    /// Position channel (m).
    pub position: LinearChannel,
    /// Channel 1 (Pa).
    pub channel_a: ChannelA,
    /// Chamber B channel (Pa gauge).
    pub pressure_b: LinearChannel,
    /// Supply channel (Pa gauge).
    pub supply: LinearChannel,
    /// Load cell.
    pub load_n_per_count: f64,
    /// Load-cell zero, counts.
    pub load_offset_counts: f64,
}

/// Safety limits, enforced outside the controller.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct LimitsConfig {
    /// Allowed flange position [min, max], m.
    pub position_m: [f64; 2],
    /// Allowed contact force [min, max], N.
    pub force_n: [f64; 2],
    /// Allowed chamber pressure [min, max], Pa absolute (both chambers).
    pub pressure_pa: [f64; 2],
    /// Supply below this is a fault (supply loss), Pa absolute.
    pub supply_min_pa: f64,
}

/// The watchdog and link-quality thresholds.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct WatchdogConfig {
    /// No new sample for this long is a fault (missing data, stalled board), ms.
    pub timeout_ms: f64,
    /// Raw counts of every analog channel unchanged for this long is a fault (stuck sensor), ms; 0 = off.
    #[serde(default)]
    pub stale_ms: f64,
    /// More CRC errors than this within `crc_window_ms` is a fault.
    pub crc_errors_max: u32,
    /// Window for counting CRC errors, ms.
    #[serde(default = "default_crc_window")]
    pub crc_window_ms: f64,
    /// The board's own watchdog: safe state if the host is silent this long, ms (sent in the Config message).
    #[serde(default = "default_board_wd")]
    pub board_watchdog_ms: u16,
}

fn default_crc_window() -> f64 {
    1000.0
}
fn default_board_wd() -> u16 {
    50
}

/// What the valve does in its safe state.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum SafeState {
    /// Both chambers to exhaust: the actuator goes limp.
    Vent,
    /// Both chambers closed: the piston holds where it is.
    Hold,
}

impl SafeState {
    /// The protocol's valve mode for this safe state.
    pub fn mode(self) -> ValveMode {
        match self {
            SafeState::Vent => ValveMode::SafeVent,
            SafeState::Hold => ValveMode::SafeHold,
        }
    }
}

/// The valve and its safe state.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ValveConfig {
    /// Valve model, for the record (e.g. "A05PS25X-1P").
    #[serde(default)]
    pub model: String,
    /// Safe state on a fault.
    pub safe_state: SafeState,
}

/// Fault to inject in the emulator.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, tag = "kind", rename_all = "snake_case")]
pub enum InjectedFault {
    /// Stop sending samples from `at_s` on (frames dropped on the wire).
    DropFrames {
        /// Emulator time the fault starts, s.
        at_s: f64,
    },
    /// From `at_s` on, corrupt the CRC of every frame sent.
    CorruptCrc {
        /// Emulator time the fault starts, s.
        at_s: f64,
    },
    /// The board stalls (sends nothing, reads nothing) for `for_s` seconds.
    Stall {
        /// Emulator time the fault starts, s.
        at_s: f64,
        /// How long, s.
        for_s: f64,
    },
    /// All analog readings freeze at their value at `at_s`.
    StuckSensor {
        /// Emulator time the fault starts, s.
        at_s: f64,
    },
    /// Supply pressure falls to atmosphere at `at_s`.
    SupplyLoss {
        /// Emulator time the fault starts, s.
        at_s: f64,
    },
    /// The board closes the link at `at_s`.
    CloseLink {
        /// Emulator time the fault starts, s.
        at_s: f64,
    },
}

/// The emulated environment: a linear spring f_e = k_e (x - x_e), eq. (21), whose stiffness may change once.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct EnvironmentConfig {
    /// Contact position x_e, m.
    pub x_e_m: f64,
    /// Stiffness before the change (wood), N/m.
    pub k_e_n_per_m: f64,
    /// Stiffness after the change (iron), N/m.
    #[serde(default)]
    pub k_e_after_n_per_m: Option<f64>,
    /// Emulator time of the change, s.
    #[serde(default)]
    pub change_at_s: Option<f64>,
}

/// The emulator's plant, sensors and faults.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct EmulatorConfig {
    /// Board sample rate, Hz.
    #[serde(default = "default_rate")]
    pub sample_rate_hz: f64,
    /// Plant integration step, s (substeps of the sample period).
    #[serde(default = "default_plant_dt")]
    pub plant_dt_s: f64,
    /// Actuator sheet for the pneumatic plant (path relative to the working directory).
    #[serde(default)]
    pub actuator: Option<PathBuf>,
    /// Initial flange position, m.
    #[serde(default)]
    pub x0_m: f64,
    /// ADC noise, counts (uniform in ±noise; 0 = none).
    #[serde(default)]
    pub adc_noise_counts: u16,
    /// Noise seed (deterministic).
    #[serde(default)]
    pub seed: u64,
    /// Supply pressure, Pa absolute.
    pub supply_pa: f64,
    /// Transport delay between a valve command reaching the board and the valve applying it, s (rounded to
    /// whole sample periods; 0 = applied in the period it arrives). Models a slow fieldbus or driver.
    #[serde(default)]
    pub transport_delay_s: f64,
    /// The one-actuator emulator's environment spring (required there); the emulator of a scene with several
    /// actuators has the scene's contacts instead (`rig run --scene … --lockstep-truth`).
    #[serde(default)]
    pub environment: Option<EnvironmentConfig>,
    /// Faults to inject.
    #[serde(default)]
    pub faults: Vec<InjectedFault>,
}

fn default_plant_dt() -> f64 {
    1e-4
}

/// One actuator's channel on a board with several (docs/rig.md, "Several channels"): its name and, where
/// they differ from the rig file's top-level tables, its own calibration, limits and valve. A table given here
/// replaces the top-level one whole (no key-by-key merge: what a channel uses is one table to read).
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ChannelConfig {
    /// The actuator this channel drives (a scene's actuator name), unique in the rig file.
    pub name: String,
    /// This channel's sensors, if not the top-level `[calibration]`.
    #[serde(default)]
    pub calibration: Option<CalibrationConfig>,
    /// This channel's limits, if not the top-level `[limits]`.
    #[serde(default)]
    pub limits: Option<LimitsConfig>,
    /// This channel's valve and safe state, if not the top-level `[valve]`.
    #[serde(default)]
    pub valve: Option<ValveConfig>,
}

/// A channel as the host uses it: resolved calibration, limits and safe state.
#[derive(Clone, Debug, PartialEq)]
pub struct Channel {
    /// The actuator's name (`"actuator"` for a one-channel rig file).
    pub name: String,
    /// Counts to SI.
    pub cal: Calibration,
    /// Safety limits.
    pub limits: LimitsConfig,
    /// The valve's safe state.
    pub safe_state: SafeState,
}

/// The name of the one channel of a rig file without `[[channel]]` entries.
pub const SINGLE_CHANNEL_NAME: &str = "actuator";

/// A rig: link, loop, calibration, limits, watchdog, valve and (for the emulator) the plant.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct RigFile {
    /// The rig's name.
    pub name: String,
    /// Serial link.
    pub link: LinkConfig,
    /// Real-time loop.
    #[serde(default, rename = "loop")]
    pub rt: LoopConfig,
    /// Sensor calibration.
    pub calibration: CalibrationConfig,
    /// Safety limits.
    pub limits: LimitsConfig,
    /// Watchdog.
    pub watchdog: WatchdogConfig,
    /// Valve and safe state.
    pub valve: ValveConfig,
    /// Emulator settings (only `pneuflex rig emulate` reads them).
    #[serde(default)]
    pub emulator: Option<EmulatorConfig>,
    /// Several actuators on one board: one `[[channel]]` per actuator, in the order of the protocol's
    /// channels (docs/protocol.md §6). Empty: one channel, described by the top-level tables.
    #[serde(default, rename = "channel")]
    pub channels: Vec<ChannelConfig>,
    /// The calibration resolved against the sensor sheets (filled by `parse`).
    #[serde(skip)]
    resolved: Option<Calibration>,
    /// Each `[[channel]]`'s calibration resolved (filled by `parse`; empty for one channel).
    #[serde(skip)]
    resolved_channels: Vec<Calibration>,
    /// Directory of the rig file (relative paths in it are resolved from here).
    #[serde(skip)]
    dir: PathBuf,
}

/// A channel that reads NaN (only used if a RigFile is built without `parse`; the limits then trip at once).
const NAN_CHANNEL: LinearChannel = LinearChannel {
    adc_bits: 12,
    adc_ref_v: f64::NAN,
    signal_per_adc_volt: f64::NAN,
    signal_min: f64::NAN,
    signal_max: f64::NAN,
    quantity_min: f64::NAN,
    quantity_max: f64::NAN,
};

/// An error in a `[[channel]]` entry's own table: its key gets the entry's path.
fn in_channel(i: usize, e: RigFileError) -> RigFileError {
    match e {
        RigFileError::Invalid {
            file,
            at,
            key,
            message,
        } => RigFileError::Invalid {
            file,
            at,
            key: format!("channel[{i}].{key}"),
            message,
        },
        other => other,
    }
}

struct Check<'a> {
    file: &'a Path,
}

impl Check<'_> {
    fn err(&self, field: &str, message: impl Into<String>) -> RigFileError {
        RigFileError::Invalid {
            file: self.file.to_path_buf(),
            at: None,
            key: field.to_string(),
            message: message.into(),
        }
    }
    fn finite(&self, field: &str, v: f64) -> Result<(), RigFileError> {
        pneuflex_files::check::finite(v)
            .map(drop)
            .map_err(|m| self.err(field, m))
    }
    fn positive(&self, field: &str, v: f64) -> Result<(), RigFileError> {
        pneuflex_files::check::positive(v)
            .map(drop)
            .map_err(|m| self.err(field, m))
    }
    fn within(
        &self,
        field: &str,
        v: f64,
        lo: f64,
        hi: f64,
        unit: &str,
    ) -> Result<(), RigFileError> {
        pneuflex_files::check::within(v, lo, hi, unit)
            .map(drop)
            .map_err(|m| self.err(field, m))
    }
    /// The limits table at `key` (`limits` or `channel[i].limits`).
    fn limits(&self, key: &str, l: &LimitsConfig) -> Result<(), RigFileError> {
        self.range(&format!("{key}.position_m"), l.position_m)?;
        self.range(&format!("{key}.force_n"), l.force_n)?;
        self.range(&format!("{key}.pressure_pa"), l.pressure_pa)?;
        self.finite(&format!("{key}.supply_min_pa"), l.supply_min_pa)
    }
    fn range(&self, field: &str, r: [f64; 2]) -> Result<(), RigFileError> {
        self.finite(field, r[0])?;
        self.finite(field, r[1])?;
        if r[0] < r[1] {
            Ok(())
        } else {
            Err(self.err(
                field,
                format!(
                    "limits inverted or empty: min {} must be below max {}",
                    r[0], r[1]
                ),
            ))
        }
    }
    /// Resolves one analog channel (sheet or explicit line) and checks every value.
    fn analog(
        &self,
        dir: &Path,
        name: &str,
        c: Option<&AnalogChannel>,
        sheet_quantity: Option<pneuflex_pneumatics::Quantity>,
    ) -> Result<LinearChannel, RigFileError> {
        let c = c.ok_or_else(|| {
            self.err(
                &format!("calibration.{name}"),
                "missing calibration: expected a [calibration.".to_string() + name + "] table",
            )
        })?;
        let f = |s: &str| format!("calibration.{name}.{s}");
        if !(8..=16).contains(&c.adc_bits) {
            return Err(self.err(
                &f("adc_bits"),
                format!("expected 8..=16, got {}", c.adc_bits),
            ));
        }
        self.positive(&f("adc_ref_v"), c.adc_ref_v)?;
        let explicit = [
            ("signal", c.signal.is_some()),
            ("signal_min", c.signal_min.is_some()),
            ("signal_max", c.signal_max.is_some()),
            ("quantity_min", c.quantity_min.is_some()),
            ("quantity_max", c.quantity_max.is_some()),
        ];
        let (signal, s_lo, s_hi, q_lo, q_hi) = match &c.sheet {
            Some(sheet) => {
                if let Some((k, _)) = explicit.iter().find(|(_, set)| *set) {
                    return Err(self.err(
                        &f(k),
                        "give either `sheet` or the signal/quantity fields, not both",
                    ));
                }
                let Some(want) = sheet_quantity else {
                    return Err(self.err(
                        &f("sheet"),
                        "no pneumatics sensor sheet describes this quantity; write signal and quantity fields",
                    ));
                };
                let path = dir.join(sheet);
                let s = pneuflex_pneumatics::SensorSheet::load(&path)
                    .map_err(|e| self.err(&f("sheet"), e.to_string()))?;
                if s.quantity != want {
                    return Err(self.err(
                        &f("sheet"),
                        format!(
                            "{} measures {:?}, expected {:?}",
                            path.display(),
                            s.quantity,
                            want
                        ),
                    ));
                }
                let kind = match s.signal {
                    pneuflex_pneumatics::SignalKind::CurrentMa => SignalKind::Current,
                    pneuflex_pneumatics::SignalKind::VoltageV => SignalKind::Voltage,
                    pneuflex_pneumatics::SignalKind::Counts => {
                        return Err(self.err(
                            &f("sheet"),
                            "a counts-output sensor is not an analog channel of the board",
                        ));
                    }
                };
                (
                    kind,
                    s.signal_min,
                    s.signal_max,
                    s.range_min_si,
                    s.range_max_si,
                )
            }
            None => {
                if let Some((k, _)) = explicit.iter().find(|(_, set)| !*set) {
                    return Err(self.err(
                        &f(k),
                        "missing calibration: give `sheet` or all of signal, signal_min, signal_max, quantity_min, quantity_max",
                    ));
                }
                (
                    c.signal.unwrap_or(SignalKind::Voltage),
                    c.signal_min.unwrap_or(f64::NAN),
                    c.signal_max.unwrap_or(f64::NAN),
                    c.quantity_min.unwrap_or(f64::NAN),
                    c.quantity_max.unwrap_or(f64::NAN),
                )
            }
        };
        self.finite(&f("signal_min"), s_lo)?;
        self.finite(&f("signal_max"), s_hi)?;
        self.finite(&f("quantity_min"), q_lo)?;
        self.finite(&f("quantity_max"), q_hi)?;
        if s_lo == s_hi {
            return Err(self.err(&f("signal_max"), "must differ from signal_min"));
        }
        if q_lo == q_hi {
            return Err(self.err(&f("quantity_max"), "must differ from quantity_min"));
        }
        let per_volt = match (signal, c.shunt_ohm, c.divider_ratio) {
            (SignalKind::Current, None, _) => {
                return Err(self.err(&f("shunt_ohm"), "required for a current (mA) signal"));
            }
            (SignalKind::Current, _, Some(_)) => {
                return Err(self.err(&f("divider_ratio"), "only meaningful for a voltage signal"));
            }
            (SignalKind::Current, Some(r), None) => {
                self.positive(&f("shunt_ohm"), r)?;
                1000.0 / r
            }
            (SignalKind::Voltage, Some(_), _) => {
                return Err(self.err(&f("shunt_ohm"), "only meaningful for a current signal"));
            }
            (SignalKind::Voltage, None, d) => {
                let d = d.unwrap_or(1.0);
                self.positive(&f("divider_ratio"), d)?;
                d
            }
        };
        let ch = LinearChannel {
            adc_bits: c.adc_bits,
            adc_ref_v: c.adc_ref_v,
            signal_per_adc_volt: per_volt,
            signal_min: s_lo,
            signal_max: s_hi,
            quantity_min: q_lo,
            quantity_max: q_hi,
        };
        // The whole measuring range must be readable by the ADC.
        let full_signal = c.adc_ref_v * per_volt;
        for (k, v) in [("signal_min", s_lo), ("signal_max", s_hi)] {
            if v < 0.0 || v > full_signal * (1.0 + 1e-9) {
                return Err(self.err(
                    &f(k),
                    format!(
                        "{v} is outside what the ADC can read (0..{full_signal:.4} with adc_ref_v and the divider/shunt)"
                    ),
                ));
            }
        }
        Ok(ch)
    }

    fn calibration(
        &self,
        dir: &Path,
        cal: &CalibrationConfig,
    ) -> Result<Calibration, RigFileError> {
        use pneuflex_pneumatics::Quantity;
        self.positive("calibration.atmosphere_pa", cal.atmosphere_pa)?;
        let position = self.analog(
            dir,
            "position",
            cal.position.as_ref(),
            Some(Quantity::Position),
        )?;
        let channel_a = match (&cal.pressure_a, &cal.differential) {
            (Some(a), None) => ChannelA::Chamber(self.analog(dir, "pressure_a", Some(a), None)?),
            (None, Some(d)) => ChannelA::Differential(self.analog(
                dir,
                "differential",
                Some(d),
                Some(Quantity::DifferentialPressure),
            )?),
            (None, None) => {
                return Err(self.err(
                    "calibration.differential",
                    "missing calibration: give [calibration.differential] (p_a - p_b) or [calibration.pressure_a]",
                ));
            }
            (Some(_), Some(_)) => {
                return Err(self.err(
                    "calibration.pressure_a",
                    "board channel 1 is either pressure_a or differential, not both",
                ));
            }
        };
        let pressure_b = self.analog(dir, "pressure_b", cal.pressure_b.as_ref(), None)?;
        let supply = self.analog(dir, "supply", cal.supply.as_ref(), None)?;
        let load = cal.load_cell.as_ref().ok_or_else(|| {
            self.err(
                "calibration.load_cell",
                "missing calibration: expected a [calibration.load_cell] table",
            )
        })?;
        self.finite("calibration.load_cell.n_per_count", load.n_per_count)?;
        if load.n_per_count == 0.0 {
            return Err(self.err("calibration.load_cell.n_per_count", "must not be zero"));
        }
        self.finite("calibration.load_cell.offset_counts", load.offset_counts)?;
        Ok(Calibration {
            atmosphere_pa: cal.atmosphere_pa,
            position,
            channel_a,
            pressure_b,
            supply,
            load_n_per_count: load.n_per_count,
            load_offset_counts: load.offset_counts,
        })
    }
}

impl RigFile {
    /// Reads, parses and validates a rig file.
    pub fn load(path: &Path) -> Result<Self, RigFileError> {
        // Bounded: a FIFO or a device is an error, not a hang (crates/files input.rs).
        let text = pneuflex_files::read_text(path, pneuflex_files::InputKind::RigFile)?;
        Self::parse(&text, path)
    }

    /// Parses and validates rig-file text; `path` is used in messages.
    pub fn parse(text: &str, path: &Path) -> Result<Self, RigFileError> {
        let mut rig: RigFile = toml::from_str(text).map_err(|e| RigFileError::Parse {
            file: path.to_path_buf(),
            message: e.to_string(),
        })?;
        rig.dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
        // A value error points at the line of its key (the text is at hand here).
        let locate = |e: RigFileError| match e {
            RigFileError::Invalid {
                file,
                at: None,
                key,
                message,
            } => RigFileError::Invalid {
                at: pneuflex_files::toml_key_position(text, &key),
                file,
                key,
                message,
            },
            other => other,
        };
        rig.validate(path).map_err(locate)?;
        let c = Check { file: path };
        rig.resolved = Some(c.calibration(&rig.dir, &rig.calibration).map_err(locate)?);
        let mut resolved = Vec::with_capacity(rig.channels.len());
        for (i, ch) in rig.channels.iter().enumerate() {
            let cal = match &ch.calibration {
                Some(own) => c
                    .calibration(&rig.dir, own)
                    .map_err(|e| in_channel(i, e))
                    .map_err(locate)?,
                None => rig.cal(),
            };
            resolved.push(cal);
        }
        rig.resolved_channels = resolved;
        Ok(rig)
    }

    /// Checks every value; the error names the file and the field.
    pub fn validate(&self, path: &Path) -> Result<(), RigFileError> {
        let c = Check { file: path };
        if self.link.port.trim().is_empty() {
            return Err(c.err("link.port", "expected a serial device path"));
        }
        if self.link.baud == 0 {
            return Err(c.err("link.baud", "expected a positive baud rate"));
        }
        if self.link.handshake_timeout_ms == 0 || self.link.handshake_timeout_ms > 60_000 {
            return Err(c.err(
                "link.handshake_timeout_ms",
                format!(
                    "expected 1..=60000 ms, got {}",
                    self.link.handshake_timeout_ms
                ),
            ));
        }
        // Timing options: bounded so that a typo cannot busy-wait forever, buffer without bound or make the
        // loop's period meaningless.
        c.within("loop.rate_hz", self.rt.rate_hz, 1.0, 20_000.0, "Hz")?;
        let period_us = 1e6 / self.rt.rate_hz;
        if self.rt.spin_us as f64 >= period_us {
            return Err(c.err(
                "loop.spin_us",
                format!(
                    "{} µs is not below the control period 1/rate_hz = {period_us} µs (the spin is the busy-wait before each deadline)",
                    self.rt.spin_us
                ),
            ));
        }
        if !(1..=100_000).contains(&self.rt.trace_flush_every) {
            return Err(c.err(
                "loop.trace_flush_every",
                format!(
                    "expected 1..=100000 rows, got {}",
                    self.rt.trace_flush_every
                ),
            ));
        }
        c.within("loop.post_fault_s", self.rt.post_fault_s, 0.0, 60.0, "s")?;
        c.positive("loop.velocity_cutoff_hz", self.rt.velocity_cutoff_hz)?;
        if self.rt.velocity_cutoff_hz >= self.rt.rate_hz / 2.0 {
            return Err(c.err(
                "loop.velocity_cutoff_hz",
                format!(
                    "{} Hz is not below the Nyquist frequency rate_hz/2 = {} Hz",
                    self.rt.velocity_cutoff_hz,
                    self.rt.rate_hz / 2.0
                ),
            ));
        }
        c.limits("limits", &self.limits)?;
        if self.channels.len() > MAX_CHANNELS {
            return Err(c.err(
                &format!("channel[{MAX_CHANNELS}]"),
                format!(
                    "{} channels: a board frame carries at most {MAX_CHANNELS} (docs/protocol.md §6)",
                    self.channels.len()
                ),
            ));
        }
        for (i, ch) in self.channels.iter().enumerate() {
            if ch.name.trim().is_empty() {
                return Err(c.err(
                    &format!("channel[{i}].name"),
                    "expected the actuator's name",
                ));
            }
            if let Some(j) = self.channels[..i].iter().position(|o| o.name == ch.name) {
                return Err(c.err(
                    &format!("channel[{i}].name"),
                    format!("'{}' is also channel[{j}]'s name", ch.name),
                ));
            }
            if let Some(l) = &ch.limits {
                c.limits(&format!("channel[{i}].limits"), l)?;
            }
        }
        c.positive("watchdog.timeout_ms", self.watchdog.timeout_ms)?;
        c.within(
            "watchdog.timeout_ms",
            self.watchdog.timeout_ms,
            0.0,
            60_000.0,
            "ms",
        )?;
        c.within(
            "watchdog.stale_ms",
            self.watchdog.stale_ms,
            0.0,
            60_000.0,
            "ms (0 = off)",
        )?;
        c.positive("watchdog.crc_window_ms", self.watchdog.crc_window_ms)?;
        c.within(
            "watchdog.crc_window_ms",
            self.watchdog.crc_window_ms,
            0.0,
            3_600_000.0,
            "ms",
        )?;
        if let Some(e) = &self.emulator {
            c.within(
                "emulator.sample_rate_hz",
                e.sample_rate_hz,
                1.0,
                20_000.0,
                "Hz",
            )?;
            c.positive("emulator.plant_dt_s", e.plant_dt_s)?;
            if e.plant_dt_s > 1.0 / e.sample_rate_hz {
                return Err(c.err(
                    "emulator.plant_dt_s",
                    "must not exceed the sample period 1/sample_rate_hz",
                ));
            }
            // Each sample period runs period/plant_dt RK4 steps in real time.
            if 1.0 / e.sample_rate_hz / e.plant_dt_s > 10_000.0 {
                return Err(c.err(
                    "emulator.plant_dt_s",
                    format!(
                        "{} s gives more than 10000 plant steps per sample period",
                        e.plant_dt_s
                    ),
                ));
            }
            c.finite("emulator.x0_m", e.x0_m)?;
            c.positive("emulator.supply_pa", e.supply_pa)?;
            c.within(
                "emulator.transport_delay_s",
                e.transport_delay_s,
                0.0,
                1.0,
                "s",
            )?;
            if let Some(env) = &e.environment {
                c.finite("emulator.environment.x_e_m", env.x_e_m)?;
                c.positive("emulator.environment.k_e_n_per_m", env.k_e_n_per_m)?;
                if let Some(k) = env.k_e_after_n_per_m {
                    c.positive("emulator.environment.k_e_after_n_per_m", k)?;
                }
                if let Some(t) = env.change_at_s {
                    c.finite("emulator.environment.change_at_s", t)?;
                }
            }
            for (i, f) in e.faults.iter().enumerate() {
                let (at, dur) = match *f {
                    InjectedFault::Stall { at_s, for_s } => (at_s, Some(for_s)),
                    InjectedFault::DropFrames { at_s }
                    | InjectedFault::CorruptCrc { at_s }
                    | InjectedFault::StuckSensor { at_s }
                    | InjectedFault::SupplyLoss { at_s }
                    | InjectedFault::CloseLink { at_s } => (at_s, None),
                };
                c.within(&format!("emulator.faults[{i}].at_s"), at, 0.0, 1e6, "s")?;
                if let Some(d) = dur {
                    c.positive(&format!("emulator.faults[{i}].for_s"), d)?;
                }
            }
        }
        Ok(())
    }

    /// The calibration resolved against the sensor sheets.
    pub fn cal(&self) -> Calibration {
        // `parse` always fills it; a hand-built RigFile without it gets a clear panic-free fallback below.
        self.resolved.unwrap_or(Calibration {
            atmosphere_pa: f64::NAN,
            position: NAN_CHANNEL,
            channel_a: ChannelA::Chamber(NAN_CHANNEL),
            pressure_b: NAN_CHANNEL,
            supply: NAN_CHANNEL,
            load_n_per_count: f64::NAN,
            load_offset_counts: f64::NAN,
        })
    }

    /// Every channel, in the protocol's order: the `[[channel]]` entries with the top-level tables filling
    /// what an entry does not give, or, without entries, one channel named [`SINGLE_CHANNEL_NAME`] made of the
    /// top-level tables (a one-channel rig file reads as it always did).
    pub fn channels(&self) -> Vec<Channel> {
        if self.channels.is_empty() {
            return vec![Channel {
                name: SINGLE_CHANNEL_NAME.to_string(),
                cal: self.cal(),
                limits: self.limits.clone(),
                safe_state: self.valve.safe_state,
            }];
        }
        self.channels
            .iter()
            .enumerate()
            .map(|(i, ch)| Channel {
                name: ch.name.clone(),
                cal: self
                    .resolved_channels
                    .get(i)
                    .copied()
                    .unwrap_or_else(|| self.cal()),
                limits: ch.limits.clone().unwrap_or_else(|| self.limits.clone()),
                safe_state: ch.valve.as_ref().unwrap_or(&self.valve).safe_state,
            })
            .collect()
    }

    /// A path from the rig file, resolved against the rig file's directory.
    pub fn resolve_path(&self, p: &Path) -> PathBuf {
        self.dir.join(p)
    }

    /// The control period, s.
    pub fn dt(&self) -> f64 {
        1.0 / self.rt.rate_hz
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    pub const PAPER: &str = include_str!("../../../rigs/paper-rig.toml");
    pub const EMULATED: &str = include_str!("../../../rigs/emulated.toml");

    /// Where the shipped rig files are, so that their sheet paths resolve.
    pub fn rigs_dir() -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../rigs")
    }

    pub fn calibration() -> Calibration {
        RigFile::parse(PAPER, &rigs_dir().join("paper-rig.toml"))
            .unwrap()
            .cal()
    }

    fn err(text: &str) -> String {
        RigFile::parse(text, &rigs_dir().join("bad.toml"))
            .unwrap_err()
            .to_string()
    }

    #[test]
    fn shipped_rig_files_load() {
        let p = RigFile::parse(PAPER, &rigs_dir().join("paper-rig.toml")).unwrap();
        assert_eq!(p.rt.rate_hz, 1000.0);
        assert!(p.emulator.is_none());
        let e = RigFile::parse(EMULATED, &rigs_dir().join("emulated.toml")).unwrap();
        let env = e.emulator.unwrap().environment.unwrap();
        assert_eq!(
            (env.k_e_n_per_m, env.k_e_after_n_per_m),
            (700.0, Some(1400.0))
        );
    }

    #[test]
    fn unknown_key_names_file_and_key() {
        let m = err(&PAPER.replace("baud = 921600", "baud = 921600\nbaudrate = 9600"));
        assert!(m.contains("bad.toml") && m.contains("baudrate"), "{m}");
    }

    #[test]
    fn missing_calibration_names_file_and_field() {
        let start = PAPER.find("[calibration.load_cell]").unwrap();
        let end = PAPER.find("[limits]").unwrap();
        let text = format!("{}{}", &PAPER[..start], &PAPER[end..]);
        let m = err(&text);
        assert!(m.contains("bad.toml") && m.contains("load_cell"), "{m}");
    }

    #[test]
    fn inverted_limits_name_file_and_field() {
        let m = err(&PAPER.replace("force_n = [-5.0, 30.0]", "force_n = [30.0, -5.0]"));
        assert!(
            m.contains("bad.toml") && m.contains("limits.force_n") && m.contains("inverted"),
            "{m}"
        );
    }

    #[test]
    fn nan_and_missing_shunt_are_rejected() {
        let m = err(&PAPER.replace(
            "adc_ref_v = 3.3\ndivider_ratio",
            "adc_ref_v = nan\ndivider_ratio",
        ));
        assert!(m.contains("calibration.position.adc_ref_v"), "{m}");
        let m = err(&PAPER.replacen("shunt_ohm = 150.0\n", "", 1));
        assert!(m.contains("calibration.differential.shunt_ohm"), "{m}");
        let m = err(&PAPER.replacen("signal_max = 20.0", "signal_max = 4.0", 1));
        assert!(m.contains("calibration.pressure_b.signal_max"), "{m}");
    }

    #[test]
    fn missing_table_or_field_names_it() {
        let start = PAPER.find("[calibration.position]").unwrap();
        let end = PAPER.find("# Board channel 1").unwrap();
        let m = err(&format!("{}{}", &PAPER[..start], &PAPER[end..]));
        assert!(
            m.contains("calibration.position") && m.contains("missing calibration"),
            "{m}"
        );
        let m = err(&PAPER.replacen("quantity_max = 800000.0\n", "", 1));
        assert!(
            m.contains("calibration.pressure_b.quantity_max") && m.contains("missing"),
            "{m}"
        );
        let m = err(&PAPER.replace(
            "divider_ratio = 3.125",
            "divider_ratio = 3.125\nsignal = \"voltage\"",
        ));
        assert!(
            m.contains("calibration.position.signal") && m.contains("not both"),
            "{m}"
        );
        let m = err(&PAPER.replace("mps-0327-position-sensor.toml", "nope.toml"));
        assert!(
            m.contains("calibration.position.sheet") && m.contains("nope.toml"),
            "{m}"
        );
        // A sheet whose range the ADC cannot reach (no divider: 10 V into a 3.3 V ADC).
        let m = err(&PAPER.replace("divider_ratio = 3.125", ""));
        assert!(m.contains("calibration.position.signal_max"), "{m}");
    }

    #[test]
    fn timing_options_out_of_range_name_file_and_key() {
        for (from, to, key) in [
            ("spin_us = 150", "spin_us = 10000000", "loop.spin_us"),
            ("spin_us = 150", "spin_us = 1000", "loop.spin_us"),
            ("rate_hz = 1000.0", "rate_hz = 0.001", "loop.rate_hz"),
            ("rate_hz = 1000.0", "rate_hz = inf", "loop.rate_hz"),
            (
                "trace_flush_every = 100",
                "trace_flush_every = 1000000000",
                "loop.trace_flush_every",
            ),
            (
                "post_fault_s = 0.2",
                "post_fault_s = 1e9",
                "loop.post_fault_s",
            ),
            (
                "velocity_cutoff_hz = 50.0",
                "velocity_cutoff_hz = 600.0",
                "loop.velocity_cutoff_hz",
            ),
            (
                "handshake_timeout_ms = 500",
                "handshake_timeout_ms = 0",
                "link.handshake_timeout_ms",
            ),
            (
                "timeout_ms = 20.0",
                "timeout_ms = 1e9",
                "watchdog.timeout_ms",
            ),
            ("stale_ms = 50.0", "stale_ms = -1.0", "watchdog.stale_ms"),
            (
                "crc_window_ms = 1000.0",
                "crc_window_ms = 1e12",
                "watchdog.crc_window_ms",
            ),
            (
                "plant_dt_s = 0.0001",
                "plant_dt_s = 1e-12",
                "emulator.plant_dt_s",
            ),
            (
                "sample_rate_hz = 1000.0",
                "sample_rate_hz = 1e9",
                "emulator.sample_rate_hz",
            ),
            (
                "faults = []",
                "faults = [{ kind = \"stall\", at_s = -1.0, for_s = 0.1 }]",
                "emulator.faults[0].at_s",
            ),
        ] {
            assert!(EMULATED.contains(from), "{from}");
            let m = RigFile::parse(&EMULATED.replace(from, to), &rigs_dir().join("bad.toml"))
                .unwrap_err()
                .to_string();
            assert!(m.contains("bad.toml") && m.contains(key), "{to}: {m}");
        }
    }

    #[test]
    fn a_directory_is_not_read() {
        let dir = std::env::temp_dir().join(format!("pneuflex-rigfile-{}", std::process::id()));
        let _ = std::fs::create_dir_all(&dir);
        let m = RigFile::load(&dir).unwrap_err().to_string();
        assert!(m.contains("not a regular file"), "{m}");
        let _ = std::fs::remove_dir(&dir);
    }

    #[test]
    fn unreadable_file_names_it() {
        let m = RigFile::load(Path::new("/nonexistent/rig.toml"))
            .unwrap_err()
            .to_string();
        assert!(m.contains("/nonexistent/rig.toml"), "{m}");
    }

    /// PAPER with two `[[channel]]` entries: the left finger inherits every table, the right one has its own
    /// limits and safe state, and `extra` appended to the right one.
    fn two_fingers(extra: &str) -> String {
        format!(
            "{PAPER}\n[[channel]]\nname = \"left\"\n\n[[channel]]\nname = \"right\"\n{extra}\n\
             [channel.limits]\nposition_m = [0.0, 0.02]\nforce_n = [-5.0, 20.0]\n\
             pressure_pa = [60000.0, 800000.0]\nsupply_min_pa = 350000.0\n\
             [channel.valve]\nsafe_state = \"hold\"\n"
        )
    }

    #[test]
    fn a_one_channel_rig_file_is_one_channel_of_its_top_level_tables() {
        let p = RigFile::parse(PAPER, &rigs_dir().join("paper-rig.toml")).unwrap();
        let ch = p.channels();
        assert_eq!(ch.len(), 1);
        assert_eq!(ch[0].name, SINGLE_CHANNEL_NAME);
        assert_eq!(
            (ch[0].cal, &ch[0].limits, ch[0].safe_state),
            (p.cal(), &p.limits, p.valve.safe_state)
        );
    }

    #[test]
    fn two_channels_each_with_its_own_limits_and_safe_state() {
        let text = two_fingers("");
        let r = RigFile::parse(&text, &rigs_dir().join("two.toml")).unwrap();
        let ch = r.channels();
        assert_eq!(
            ch.iter().map(|c| c.name.as_str()).collect::<Vec<_>>(),
            ["left", "right"]
        );
        // The left inherits the top-level tables, the right replaces limits and valve (not calibration).
        assert_eq!(ch[0].limits, r.limits);
        assert_eq!(ch[0].safe_state, SafeState::Vent);
        assert_eq!(ch[1].limits.position_m, [0.0, 0.02]);
        assert_eq!(ch[1].limits.force_n, [-5.0, 20.0]);
        assert_eq!(ch[1].safe_state, SafeState::Hold);
        assert_eq!((ch[0].cal, ch[1].cal), (r.cal(), r.cal()));
        // A channel's own calibration table replaces the top-level one: here a 10-bit position ADC on the
        // right finger, the 12-bit one of [calibration] on the left, the same sheet's line on both.
        let pos = PAPER.find("[calibration.position]").unwrap();
        let end = PAPER[pos..].find("\n\n").unwrap() + pos;
        let own = PAPER[pos..end]
            .replace("[calibration.position]", "[channel.calibration.position]")
            .replace("adc_bits = 12", "adc_bits = 10");
        let mut rest = String::new();
        for t in ["differential", "pressure_b", "supply", "load_cell"] {
            let s = PAPER.find(&format!("[calibration.{t}]")).unwrap();
            let e = PAPER[s..]
                .find("\n\n")
                .map(|e| e + s)
                .unwrap_or(PAPER.len());
            rest.push_str(&PAPER[s..e].replace("[calibration.", "[channel.calibration."));
            rest.push_str("\n\n");
        }
        let text = two_fingers(&format!("{own}\n\n{rest}"));
        let r = RigFile::parse(&text, &rigs_dir().join("two.toml")).unwrap();
        let ch = r.channels();
        let span =
            |c: &LinearChannel| (c.quantity_max - c.quantity_min) / (c.signal_max - c.signal_min);
        assert_eq!(ch[1].cal.position.adc_bits, 10);
        assert_eq!(ch[0].cal.position.adc_bits, 12);
        assert_eq!(span(&ch[1].cal.position), span(&ch[0].cal.position));
    }

    #[test]
    fn bad_channels_name_file_line_and_key() {
        let text = two_fingers("").replace("position_m = [0.0, 0.02]", "position_m = [0.02, 0.0]");
        let m = err(&text);
        let line = text
            .lines()
            .position(|l| l.starts_with("position_m = [0.02"))
            .unwrap()
            + 1;
        assert!(
            m.contains(&format!("bad.toml:{line}:")) && m.contains("channel[1].limits.position_m"),
            "{m}"
        );
        let m = err(&two_fingers("").replace("name = \"right\"", "name = \"left\""));
        assert!(
            m.contains("channel[1].name") && m.contains("also channel[0]"),
            "{m}"
        );
        let m = err(&format!(
            "{PAPER}\n{}",
            "[[channel]]\nname = \"c\"\n".repeat(MAX_CHANNELS + 1)
        ));
        assert!(m.contains("channel[6]") && m.contains("at most 6"), "{m}");
        let m = err(&two_fingers(
            "[channel.calibration.position]\nadc_bits = 12\n",
        ));
        assert!(m.contains("bad.toml") && m.contains("adc_ref_v"), "{m}");
        let m = err(&two_fingers("gain = 2.0"));
        assert!(m.contains("bad.toml") && m.contains("gain"), "{m}");
    }
}
