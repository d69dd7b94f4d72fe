//! The identification commands' arguments: `identify`, `perturb`, and the bench-data fits `seal` and
//! `leak`, each handed to its `cmd` module.

use std::path::PathBuf;

use clap::Args;

use crate::cmd;

/// Fit actuator-sheet parameters to rig logs (docs/identification.md): replay the logged valve command
/// through the 1-DOF model, Levenberg-Marquardt, 95 % intervals, report, fitted sheet.
#[derive(Args)]
pub struct Identify {
    /// Rig traces (trace.csv of `rig run` / `rig excite`); repeat for several logs.
    #[arg(long = "log", required = true)]
    pub logs: Vec<PathBuf>,
    /// The actuator sheet to start from (pneumatics/*.toml).
    #[arg(long)]
    pub actuator: PathBuf,
    /// Parameters to fit, comma-separated dotted keys (valve.sonic_conductance_m3_per_s_pa, ...).
    #[arg(long, required = true)]
    pub free: Vec<String>,
    /// Bounds of a free parameter, KEY=[lo,hi]; repeat for several.
    #[arg(long)]
    pub bounds: Vec<String>,
    /// Output directory (default: out/identify/<folder of the first log>/, with `-NAME` for --channel NAME).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Fraction of each log held out at its end for validation.
    #[arg(long, default_value_t = 0.2)]
    pub validation: f64,
    /// Segment length of the replay, s (each segment restarts from the measured state).
    #[arg(long, default_value_t = 0.1)]
    pub segment: f64,
    /// Start of each segment left out of the comparison, s.
    #[arg(long, default_value_t = 0.015)]
    pub settle: f64,
    /// Largest number of data rows of one log (default 2,000,000); a longer log is refused.
    #[arg(long, value_name = "N", default_value_t = 2_000_000)]
    pub max_rows: usize,
    /// Longest time span of one log, s (default 3600); a longer log is refused.
    #[arg(long, value_name = "S", default_value_t = 3600.0)]
    pub max_log_s: f64,
    /// How the logs are written, when another tool wrote them: a TOML file with the separator, the decimal
    /// and thousands marks, the lines before the header and each signal's column and unit
    /// (docs/identification.md, "Other people's logs"). Default: pneuflex's trace.csv.
    #[arg(long, value_name = "FILE")]
    pub log_format: Option<PathBuf>,
    /// Structure selection: fit the sheet as given and with each effect it lacks switched on (leaks, wall
    /// heat, a polytropic chamber process, stick-slip or LuGre friction, a pressure-dependent seal, spool travel), their keys freed
    /// beside --free, and keep the lowest BIC whose held-out residual is no worse (docs/identification.md).
    #[arg(long)]
    pub select: bool,
    /// The validation figures' format: png (default), svg or pdf.
    #[arg(long, value_enum, default_value_t = super::FigureFormat::Png)]
    pub format: super::FigureFormat,
    /// Which actuator of a recording of several (a scene with [[actuators]], e.g. the gripper's `left` or
    /// `right`): its columns NAME.u, NAME.x, NAME.p_a, NAME.p_b, NAME.f_e are the log, fitted to --actuator
    /// (docs/identification.md, "Several actuators").
    #[arg(long, value_name = "NAME", conflicts_with = "log_format")]
    pub channel: Option<String>,
}

/// Write a hidden truth for identification tests: the sheet with KEYS each moved 20-40 % (seeded).
#[derive(Args)]
pub struct Perturb {
    /// The actuator sheet to perturb.
    #[arg(long)]
    pub actuator: PathBuf,
    /// Keys to perturb, comma-separated.
    #[arg(long, required = true)]
    pub keys: Vec<String>,
    /// Seed.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// New directory for the sheets and truth.json.
    #[arg(long)]
    pub out: PathBuf,
}

/// Fit friction laws (constant Coulomb, and rising with the pressure) to a seal's bench tests at held
/// pressures: force, pressure and position logs `<seal>_<P>bar.csv` (docs/identification.md, "Real data").
#[derive(Args)]
#[command(group(clap::ArgGroup::new("source").required(true).args(["data", "tests"])))]
pub struct Seal {
    /// Folder of the tests `<seal>_<P>bar.csv` (or its parent with a `friction/` folder), e.g.
    /// data/zillen-2021-printed-cylinder.
    #[arg(long)]
    pub data: Option<PathBuf>,
    /// Which seal's tests of --data, when the folder holds several (`circle` for circle_<P>bar.csv).
    #[arg(long, value_name = "NAME", requires = "data")]
    pub seal: Option<String>,
    /// A test file instead of --data, FILE=P with P the held pressure in bar gauge (FILE alone: from its
    /// name <seal>_<P>bar.csv, else the readings' median); repeat for each test.
    #[arg(long = "test", value_name = "FILE[=P]")]
    pub tests: Vec<String>,
    /// Piston bore, m (25 mm is 0.025).
    #[arg(long, allow_negative_numbers = true, default_value_t = 0.025)]
    pub bore_m: f64,
    /// Speed below which a sample is still and left out, m/s.
    #[arg(long, allow_negative_numbers = true, default_value_t = 0.002)]
    pub still_below: f64,
    /// The pressure sensor's full scale, bar gauge: a reading beyond is refused at its line.
    #[arg(
        long,
        allow_negative_numbers = true,
        value_name = "BAR",
        default_value_t = 16.0
    )]
    pub max_pressure_bar: f64,
    /// Print one JSON object (SI units) instead of tables.
    #[arg(long)]
    pub json: bool,
}

/// Fit an ISO 6358 leak (choked, and subsonic as the chamber nears atmosphere), as a conductance per
/// volume, to closed-chamber pressure-decay logs (';'-separated, time in ms with '.' as the thousands
/// separator) and rank the chambers.
#[derive(Args)]
pub struct Leak {
    /// Decay logs; repeat for several chambers.
    #[arg(long = "log", required = true)]
    pub logs: Vec<PathBuf>,
    /// Gas temperature in the chamber, K (20 degC is 293.15 K).
    #[arg(long, allow_negative_numbers = true, default_value_t = pneuflex_pneumatics::T_DEFAULT)]
    pub temperature_k: f64,
    /// Atmospheric pressure, Pa absolute.
    #[arg(long, allow_negative_numbers = true, default_value_t = pneuflex_pneumatics::P_ATM)]
    pub atmosphere_pa: f64,
    /// The pressure sensor's full scale, bar gauge: a reading beyond is refused at its line.
    #[arg(
        long,
        allow_negative_numbers = true,
        value_name = "BAR",
        default_value_t = 16.0
    )]
    pub max_pressure_bar: f64,
    /// The leak's critical pressure ratio b (ISO 6358), in (0, 0.528]: where the flow out turns subsonic
    /// (p_atm / p above b). Assumed, not identified.
    #[arg(
        long,
        allow_negative_numbers = true,
        value_name = "B",
        default_value_t = pneuflex_identify::leak::CHOKED_RATIO_MAX
    )]
    pub critical_pressure_ratio: f64,
    /// Print JSON (SI units) instead of a table.
    #[arg(long)]
    pub json: bool,
}

impl Identify {
    pub fn call(self) -> anyhow::Result<()> {
        cmd::identify::identify(
            self.logs,
            &self.actuator,
            self.out.as_deref(),
            cmd::identify::IdentifyArgs {
                free: self.free,
                bounds: self.bounds,
                validation: self.validation,
                segment_s: self.segment,
                settle_s: self.settle,
                limits: pneuflex_identify::log::LogLimits {
                    max_rows: self.max_rows,
                    max_span_s: self.max_log_s,
                },
                log_format: self.log_format,
                channel: self.channel,
                figure_format: self.format.into(),
                select: self.select,
            },
        )
    }
}

impl Perturb {
    pub fn call(self) -> anyhow::Result<()> {
        cmd::perturb::perturb(&self.actuator, &self.keys, self.seed, &self.out)
    }
}

impl Seal {
    pub fn call(self) -> anyhow::Result<()> {
        let source = match self.data {
            Some(dir) => cmd::seal::SealSource::Folder {
                dir,
                seal: self.seal,
            },
            None => cmd::seal::SealSource::List(self.tests),
        };
        cmd::seal::seal(
            &source,
            &pneuflex_identify::seal::SealOptions {
                bore_m: self.bore_m,
                still_below_m_per_s: self.still_below,
                ..Default::default()
            },
            self.max_pressure_bar,
            self.json,
        )
    }
}

impl Leak {
    pub fn call(self) -> anyhow::Result<()> {
        cmd::seal::leak(
            &self.logs,
            &pneuflex_identify::leak::LeakOptions {
                atmosphere_pa: self.atmosphere_pa,
                temperature_k: self.temperature_k,
                critical_pressure_ratio: self.critical_pressure_ratio,
                ..Default::default()
            },
            self.max_pressure_bar,
            self.json,
        )
    }
}
