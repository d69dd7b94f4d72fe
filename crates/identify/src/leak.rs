//! A chamber's leak from its pressure decay (issue 26, item 4): a chamber filled and closed, its pressure
//! logged (the Zillen 2021 printed chambers, `data/zillen-2021-printed-cylinder/leakage/<material>.csv`,
//! ';'-separated: time in ms with '.' as the thousands separator and three decimals, `1.003.000` = 1003 ms;
//! pressure V; pressure bar gauge).
//!
//! The leak is an ISO 6358 orifice (eq. 11, [`Orifice::phi`], the valve's law) of conductance C from a
//! chamber of volume V at temperature T: `M' = -C rho0 p sqrt(T0/T) phi(p_atm / p)` and, isothermal,
//! `V p' = R T M'`, so with `k = C rho0 R sqrt(T T0) / V`
//!
//! ```text
//! p' = -k p phi(p_atm / p),   C / V = k / (rho0 R sqrt(T T0))   (1/(s Pa))
//! p(t) = p0 exp(-k t)         while choked (p_atm / p <= b, phi = 1)
//! F(p(t)) = F(p0) - k t       through both regimes, F(p) = integral dp / (p phi(p_atm / p))
//! ```
//!
//! (`crates/pneumatics/tests/effects.rs` checks the model against the closed form). A chamber that empties
//! towards atmosphere passes from the choked into the subsonic (elliptic) branch: one k is fitted over the
//! whole decay with b given (`--critical-pressure-ratio`, not identified), and the report says which rows
//! were fitted, in which regime, and which were left out (the rows from where the chamber reads atmosphere:
//! the sensor's zero, not the leak). The fit is Gauss-Newton on the gauge readings for (p0, k). Without the
//! chamber's volume the data give C / V, the leak's conductance per volume, which ranks chambers of any
//! size. The report also says whether the decay is a leak at all: the residuals against the sensor's noise
//! (from the sample-to-sample differences) and the rate of each half of the fitted rows against the other.

use std::path::{Path, PathBuf};

use pneuflex_pneumatics::Orifice;
use pneuflex_pneumatics::flow::{ISO_RHO0_KG_M3, ISO_T0_K, LAMINAR_RATIO};

use crate::IdentifyError;

/// A pressure-decay log, SI.
#[derive(Clone, Debug, PartialEq)]
pub struct DecayLog {
    /// The file.
    pub file: PathBuf,
    /// The chamber's name (the file's stem).
    pub chamber: String,
    /// Time, s.
    pub t_s: Vec<f64>,
    /// Pressure, Pa gauge.
    pub gauge_pa: Vec<f64>,
    /// The file's line of each row (for messages; empty for a log made in memory).
    pub lines: Vec<usize>,
}

/// The conditions of the test.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LeakOptions {
    /// Atmospheric pressure, Pa absolute.
    pub atmosphere_pa: f64,
    /// Gas temperature in the chamber, K.
    pub temperature_k: f64,
    /// Specific gas constant, J/(kg K).
    pub gas_constant_j_per_kg_k: f64,
    /// The leak's critical pressure ratio b (ISO 6358), assumed: it sets where the flow out turns
    /// subsonic, and is not identified from a decay.
    pub critical_pressure_ratio: f64,
}

impl Default for LeakOptions {
    fn default() -> Self {
        Self {
            atmosphere_pa: pneuflex_pneumatics::P_ATM,
            temperature_k: ISO_T0_K,
            gas_constant_j_per_kg_k: pneuflex_pneumatics::R_AIR,
            critical_pressure_ratio: CHOKED_RATIO_MAX,
        }
    }
}

impl LeakOptions {
    /// Refuses conditions no bench has, naming the option: a temperature in degC, a gauge atmosphere.
    pub fn check(&self) -> Result<(), IdentifyError> {
        let key = |option, v: f64, message: String| IdentifyError::Key {
            option,
            key: crate::seal::shown(v),
            message,
        };
        if !(200.0..=400.0).contains(&self.temperature_k) {
            return Err(key(
                "--temperature-k",
                self.temperature_k,
                "the gas temperature in kelvin must be in [200, 400] K (20 degC is 293.15 K)"
                    .into(),
            ));
        }
        if !(3e4..=1.2e5).contains(&self.atmosphere_pa) {
            return Err(key(
                "--atmosphere-pa",
                self.atmosphere_pa,
                "the atmosphere in Pa absolute must be in [30000, 120000] Pa (sea level: 101325)"
                    .into(),
            ));
        }
        if !(self.gas_constant_j_per_kg_k.is_finite() && self.gas_constant_j_per_kg_k > 0.0) {
            return Err(key(
                "gas constant",
                self.gas_constant_j_per_kg_k,
                "must be > 0 J/(kg K)".into(),
            ));
        }
        let b = self.critical_pressure_ratio;
        if !(b > 0.0 && b <= CHOKED_RATIO_MAX) {
            return Err(key(
                "--critical-pressure-ratio",
                b,
                format!(
                    "the critical pressure ratio b of ISO 6358 is a ratio in (0, {CHOKED_RATIO_MAX}] (the ideal \
                     gas's {CHOKED_RATIO_MAX} is the largest; not a pressure)"
                ),
            ));
        }
        Ok(())
    }
}

/// The sample periods a decay log may have, s: a median outside is a time in another unit or a corrupt
/// clock (a slow decay may be logged every few minutes).
pub const PERIOD_RANGE_S: (f64, f64) = (1e-5, 600.0);

/// The ideal gas's critical pressure ratio, the largest b of any orifice, and the b a leak is given unless
/// told otherwise: with p_atm / p above b the flow out is subsonic.
pub const CHOKED_RATIO_MAX: f64 = 0.528;

/// The decay fitted to a span of a log (p0 and k of `p' = -k p phi(p_atm / p)`).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Decay {
    /// Initial absolute pressure p0, Pa.
    pub p0_pa: f64,
    /// Decay rate k, 1/s.
    pub rate_per_s: f64,
    /// Formal standard error of k (white residuals), 1/s.
    pub rate_std_error_per_s: f64,
    /// RMS residual, Pa.
    pub rms_pa: f64,
}

/// A chamber's leak.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct LeakFit {
    /// The chamber.
    pub chamber: String,
    /// Rows fitted.
    pub rows: usize,
    /// Span of the fitted rows, s.
    pub span_s: f64,
    /// The rows fitted, by the file's lines.
    pub fitted: Rows,
    /// The rows left out at the log's end, where the chamber reads atmosphere (or below): the sensor's
    /// zero carries nothing of the leak, and the ISO 6358 law ends at `p_atm / p` = 0.999.
    pub left_out: Option<Rows>,
    /// The critical pressure ratio b assumed (not identified).
    pub critical_pressure_ratio: f64,
    /// The regime of the fitted decay over the fitted rows.
    pub regime: Regime,
    /// The fitted rows where the fitted decay is choked (`p_atm / p <= b`).
    pub choked: Option<Rows>,
    /// The fitted rows where the fitted decay is subsonic (`p_atm / p > b`).
    pub subsonic: Option<Rows>,
    /// The fitted rows' decay.
    pub decay: Decay,
    /// C / V, 1/(s Pa): the leak's sonic conductance per chamber volume.
    pub conductance_per_volume: f64,
    /// Time to lose 10 % of the initial gauge pressure, s (extrapolated from the fit).
    pub t10_s: f64,
    /// The share of the initial gauge pressure the fitted decay loses over the log, 1.
    pub loss: f64,
    /// p_atm / p at the lowest fitted reading: the flow is choked for any b above this.
    pub choked_below_b: f64,
    /// The sensor's noise from the sample-to-sample differences (std / sqrt 2), Pa.
    pub noise_pa: f64,
    /// Lag-1 autocorrelation of the residuals (near 0 for noise, near 1 for residuals that wander).
    pub residual_autocorrelation: f64,
    /// The change of the gas temperature that moves the pressure by the RMS residual, K (p ~ T at
    /// constant mass and volume).
    pub rms_as_temperature_k: f64,
    /// The first and the second half of the fitted rows fitted alone.
    pub halves: [Decay; 2],
    /// Whether the leak explains the log: residuals within 1.5 times the noise and not wandering
    /// (lag-1 autocorrelation below 0.5), and the halves' rates within 3 standard errors of each other.
    pub adequate: bool,
    /// What it says, in words.
    pub verdict: String,
}

/// A run of a log's rows.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Rows {
    /// The file's line of the first row.
    pub first_line: usize,
    /// The file's line of the last row.
    pub last_line: usize,
    /// Rows.
    pub rows: usize,
    /// Time of the first row, s.
    pub from_s: f64,
    /// Time of the last row, s.
    pub to_s: f64,
}

impl Rows {
    fn of(log: &DecayLog, range: std::ops::Range<usize>) -> Option<Self> {
        let line = |k: usize| log.lines.get(k).copied().unwrap_or(k + 1);
        (!range.is_empty()).then(|| Self {
            first_line: line(range.start),
            last_line: line(range.end - 1),
            rows: range.len(),
            from_s: log.t_s[range.start],
            to_s: log.t_s[range.end - 1],
        })
    }

    /// `lines 1-1508 (0.0-151.3 s)`.
    pub fn shown(&self) -> String {
        format!(
            "lines {}-{} ({:.1}-{:.1} s, {} rows)",
            self.first_line, self.last_line, self.from_s, self.to_s, self.rows
        )
    }
}

/// The flow regime of a fitted decay over the fitted rows.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Regime {
    /// `p_atm / p <= b` throughout: `p = p0 exp(-k t)`, and b is not identified.
    Choked,
    /// Choked, then subsonic: the chamber empties towards atmosphere.
    ChokedThenSubsonic,
    /// Subsonic throughout: the chamber was filled to less than `p_atm / b`.
    Subsonic,
}

impl Regime {
    /// In words.
    pub fn words(self) -> &'static str {
        match self {
            Regime::Choked => "choked throughout",
            Regime::ChokedThenSubsonic => "choked, then subsonic",
            Regime::Subsonic => "subsonic throughout",
        }
    }
}

/// The isothermal decay of a closed chamber through an ISO 6358 leak in the time `s = k t`: `p' = -p
/// phi(p_atm / p)` ([`Orifice::phi`]), as `F(p(s)) = F(p0) - s` with `F(p) = ln p` while choked and `F`
/// tabulated below the critical pressure `p_atm / b` in `x = ln(p - p_atm)`, where `dF/dx = (p - p_atm) / (p
/// phi)` is smooth and bounded (the laminar tail makes it constant near atmosphere).
#[derive(Clone, Debug)]
pub struct DecayLaw {
    /// Atmospheric pressure, Pa absolute.
    pa: f64,
    orifice: Orifice,
    /// The critical pressure `p_atm / b`, Pa absolute.
    p_crit: f64,
    /// `x` at the critical pressure.
    x_top: f64,
    /// `F` and `dF/dx` at `x_top - i STEP`.
    f: Vec<f64>,
    g: Vec<f64>,
}

impl DecayLaw {
    /// The table's step in `x = ln(p - p_atm)`.
    const STEP: f64 = 2e-3;
    /// The table's end: 10 mPa above atmosphere.
    const X_BOTTOM: f64 = -4.6;

    /// The law of a leak of critical pressure ratio `b` into `atmosphere_pa`.
    pub fn new(atmosphere_pa: f64, b: f64) -> Self {
        let orifice = Orifice {
            sonic_conductance_m3_per_s_pa: 1.0,
            critical_pressure_ratio: b,
        };
        let p_crit = atmosphere_pa / b;
        let x_top = (p_crit - atmosphere_pa).ln();
        let slope = |x: f64| {
            let d = x.exp();
            let p = atmosphere_pa + d;
            d / (p * orifice.phi(atmosphere_pa / p))
        };
        let n = ((x_top - Self::X_BOTTOM) / Self::STEP).ceil() as usize + 1;
        let (mut f, mut g) = (Vec::with_capacity(n), Vec::with_capacity(n));
        f.push(p_crit.ln());
        g.push(slope(x_top));
        for i in 1..n {
            // Simpson over the cell, downwards.
            let (x0, x1) = (
                x_top - (i - 1) as f64 * Self::STEP,
                x_top - i as f64 * Self::STEP,
            );
            let g1 = slope(x1);
            let gm = slope(0.5 * (x0 + x1));
            f.push(f[i - 1] - Self::STEP / 6.0 * (g[i - 1] + 4.0 * gm + g1));
            g.push(g1);
        }
        Self {
            pa: atmosphere_pa,
            orifice,
            p_crit,
            x_top,
            f,
            g,
        }
    }

    /// The critical pressure `p_atm / b`, Pa absolute: the flow is choked above it.
    pub fn critical_pressure_pa(&self) -> f64 {
        self.p_crit
    }

    /// `p phi(p_atm / p)`, Pa: the pressure's rate of fall per unit k.
    fn p_phi(&self, p: f64) -> f64 {
        p * self.orifice.phi(self.pa / p)
    }

    /// The cubic Hermite interpolant of F on cell `i` at `u` in [0, 1] (from node i to i + 1), and dF/du.
    fn cell(&self, i: usize, u: f64) -> (f64, f64) {
        let h = -Self::STEP;
        let (f0, f1, m0, m1) = (self.f[i], self.f[i + 1], self.g[i] * h, self.g[i + 1] * h);
        let (u2, u3) = (u * u, u * u * u);
        let v = (2.0 * u3 - 3.0 * u2 + 1.0) * f0
            + (u3 - 2.0 * u2 + u) * m0
            + (-2.0 * u3 + 3.0 * u2) * f1
            + (u3 - u2) * m1;
        let dv = (6.0 * u2 - 6.0 * u) * f0
            + (3.0 * u2 - 4.0 * u + 1.0) * m0
            + (-6.0 * u2 + 6.0 * u) * f1
            + (3.0 * u2 - 2.0 * u) * m1;
        (v, dv)
    }

    /// F(p) for `p > p_atm`.
    fn big_f(&self, p: f64) -> f64 {
        if p >= self.p_crit {
            return p.ln();
        }
        let x = (p - self.pa).ln();
        let last = self.f.len() - 1;
        let pos = (self.x_top - x) / Self::STEP;
        if pos >= last as f64 {
            let x_last = self.x_top - last as f64 * Self::STEP;
            return self.f[last] - (x_last - x) * self.g[last];
        }
        let i = (pos.floor() as usize).min(last - 1);
        self.cell(i, pos - i as f64).0
    }

    /// The p of F(p) = `target` (`target < ln p_crit`).
    fn inverse(&self, target: f64) -> f64 {
        let last = self.f.len() - 1;
        if target <= self.f[last] {
            let x = self.x_top - last as f64 * Self::STEP - (self.f[last] - target) / self.g[last];
            return self.pa + x.exp();
        }
        // F falls with i: the cell whose ends bracket the target.
        let i = self.f.partition_point(|&v| v > target).clamp(1, last) - 1;
        let (f0, f1) = (self.f[i], self.f[i + 1]);
        let mut u = ((f0 - target) / (f0 - f1)).clamp(0.0, 1.0);
        for _ in 0..4 {
            let (v, dv) = self.cell(i, u);
            if dv == 0.0 {
                break;
            }
            u = (u - (v - target) / dv).clamp(0.0, 1.0);
        }
        self.pa + (self.x_top - (i as f64 + u) * Self::STEP).exp()
    }

    /// The pressure at `t` of the decay from `p0` at rate `k`, with its derivatives by p0 and by k.
    pub fn pressure(&self, p0: f64, k: f64, t: f64) -> (f64, f64, f64) {
        let e = (-k * t).exp();
        let p = p0 * e;
        if p >= self.p_crit {
            // Choked: the closed form, as it always was.
            return (p, e, -p0 * t * e);
        }
        let p = self.inverse(self.big_f(p0) - k * t);
        let q = self.p_phi(p);
        (p, q / self.p_phi(p0), -t * q)
    }

    /// The pressure a time `s` per unit k before the pressure is `p`: `F^-1(F(p) + s)`.
    fn before(&self, p: f64, s: f64) -> f64 {
        let target = self.big_f(p) + s;
        if target >= self.p_crit.ln() {
            target.exp()
        } else {
            self.inverse(target)
        }
    }

    /// The time per unit k, `F(p_from) - F(p_to)`, for the pressure to fall from `p_from` to `p_to`.
    pub fn elapsed(&self, p_from: f64, p_to: f64) -> f64 {
        if p_to >= self.p_crit {
            (p_from / p_to).ln()
        } else {
            self.big_f(p_from) - self.big_f(p_to)
        }
    }
}

fn log_err(file: &Path, line: usize, column: &str, message: String) -> IdentifyError {
    IdentifyError::Log {
        file: file.to_path_buf(),
        line: Some(line),
        column: Some(column.to_string()),
        message,
    }
}

/// Parses a time in ms written with '.' as the thousands separator and three decimals (`1.003.000` =
/// 1003 ms, `0.000` = 0), to s.
pub fn parse_thousands_ms(s: &str) -> Option<f64> {
    let groups: Vec<&str> = s.trim().split('.').collect();
    let (first, rest) = groups.split_first()?;
    let digits = |g: &str| !g.is_empty() && g.bytes().all(|b| b.is_ascii_digit());
    if rest.is_empty()
        || !digits(first)
        || first.len() > 3
        || !rest.iter().all(|g| g.len() == 3 && digits(g))
    {
        return None;
    }
    // Every group after the first is three digits: the concatenation is the time in us.
    let us: u64 = groups.concat().parse().ok()?;
    Some(us as f64 / 1e6)
}

/// Reads a pressure-decay log (';'-separated, three columns, CRLF or LF, blank lines skipped) against
/// the default [`crate::seal::Sensors`].
pub fn read_decay_log(path: &Path) -> Result<DecayLog, IdentifyError> {
    read_decay_log_with(path, &crate::seal::Sensors::default())
}

/// Reads the decay logs in order; the same file twice (by path or by content) and two chambers of one
/// name (the ranking would not tell them apart) are refused with both files.
pub fn read_decay_logs(
    paths: &[PathBuf],
    sensors: &crate::seal::Sensors,
) -> Result<Vec<DecayLog>, IdentifyError> {
    let mut logs: Vec<DecayLog> = Vec::with_capacity(paths.len());
    let mut real: Vec<PathBuf> = Vec::new();
    for p in paths {
        let canonical = std::fs::canonicalize(p).unwrap_or_else(|_| p.clone());
        if let Some(k) = real.iter().position(|r| *r == canonical) {
            return Err(IdentifyError::Input(format!(
                "{}: given twice (also as {}): each chamber once",
                p.display(),
                logs[k].file.display()
            )));
        }
        let log = read_decay_log_with(p, sensors)?;
        if let Some(twin) = logs
            .iter()
            .find(|l| l.t_s == log.t_s && l.gauge_pa == log.gauge_pa)
        {
            return Err(IdentifyError::Input(format!(
                "{}: the same measurements as {}: one chamber ranked against itself",
                p.display(),
                twin.file.display()
            )));
        }
        if let Some(twin) = logs.iter().find(|l| l.chamber == log.chamber) {
            return Err(IdentifyError::Input(format!(
                "{}: the chamber name {:?} of {} too: the ranking names chambers by their file's stem; rename one",
                p.display(),
                log.chamber,
                twin.file.display()
            )));
        }
        real.push(canonical);
        logs.push(log);
    }
    Ok(logs)
}

/// [`read_decay_log`] against `sensors`: every pressure within the sensor's range, the sample period
/// within [`PERIOD_RANGE_S`] and even, no single reading far from the rest, each refused at its line.
pub fn read_decay_log_with(
    path: &Path,
    sensors: &crate::seal::Sensors,
) -> Result<DecayLog, IdentifyError> {
    let text = pneuflex_files::read_text(path, pneuflex_files::InputKind::Trace)
        .map_err(|e| IdentifyError::Input(e.to_string()))?;
    let mut log = DecayLog {
        file: path.to_path_buf(),
        chamber: path
            .file_stem()
            .map_or_else(String::new, |s| s.to_string_lossy().into_owned()),
        t_s: Vec::new(),
        gauge_pa: Vec::new(),
        lines: Vec::new(),
    };
    let mut lines = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() {
            continue;
        }
        let f: Vec<&str> = line.split(';').collect();
        if f.len() != 3 {
            return Err(IdentifyError::Log {
                file: path.to_path_buf(),
                line: Some(i + 1),
                column: None,
                message: format!(
                    "expected 3 ';'-separated fields (time_ms; pressure_v; pressure_bar), got {}",
                    f.len()
                ),
            });
        }
        let t = parse_thousands_ms(f[0]).ok_or_else(|| {
            log_err(path, i + 1, "time_ms", format!(
                "{:?}: expected milliseconds with '.' as the thousands separator and three decimals \
                 (1.003.000 = 1003 ms)",
                f[0]
            ))
        })?;
        if log.t_s.last().is_some_and(|&last| t <= last) {
            return Err(log_err(
                path,
                i + 1,
                "time_ms",
                format!("time {} s does not increase", t),
            ));
        }
        let bar = f[2]
            .trim()
            .parse::<f64>()
            .ok()
            .filter(|v| v.is_finite())
            .ok_or_else(|| {
                log_err(
                    path,
                    i + 1,
                    "pressure_bar",
                    format!("not a finite number: {:?}", f[2]),
                )
            })?;
        let (lo, hi) = (crate::seal::MIN_GAUGE_PA / 1e5, sensors.max_gauge_pa / 1e5);
        if !(lo..=hi).contains(&bar) {
            return Err(log_err(
                path,
                i + 1,
                "pressure_bar",
                format!(
                    "{} bar gauge: outside the pressure sensor's range [{lo}, {hi}] bar (a column in Pa, kPa \
                     or mbar? a sensor of a larger range: --max-pressure-bar)",
                    crate::seal::shown(bar)
                ),
            ));
        }
        log.t_s.push(t);
        log.gauge_pa.push(bar * 1e5);
        lines.push(i + 1);
    }
    if log.t_s.len() < 10 {
        return Err(IdentifyError::Fit(format!(
            "{}: {} rows; a decay needs at least 10",
            path.display(),
            log.t_s.len()
        )));
    }
    let mut steps: Vec<f64> = log.t_s.windows(2).map(|w| w[1] - w[0]).collect();
    let first = steps.clone();
    steps.sort_by(f64::total_cmp);
    let period = steps[steps.len() / 2];
    let (lo, hi) = PERIOD_RANGE_S;
    if !(lo..=hi).contains(&period) {
        return Err(log_err(
            path,
            lines[1],
            "time_ms",
            format!(
                "the median sample period is {period:.3e} s, outside [{lo:e}, {hi}] s: no logger samples a \
                 decay at that rate (the time is read in ms, '.' the thousands separator)"
            ),
        ));
    }
    // A decay is logged over seconds at least: less is a time in another unit (s read as ms).
    let span = log.t_s[log.t_s.len() - 1] - log.t_s[0];
    if span < crate::seal::MIN_SPAN_S {
        return Err(log_err(
            path,
            lines[lines.len() - 1],
            "time_ms",
            format!(
                "the log spans {span:.3e} s: a leak's decay takes seconds at least (the time is read in ms with \
                 '.' as the thousands separator, 1.003.000 = 1003 ms; a time in s would span a thousandth)"
            ),
        ));
    }
    if let Some(k) = first.iter().position(|d| *d < 0.01 * period) {
        return Err(log_err(
            path,
            lines[k + 1],
            "time_ms",
            format!(
                "a step of {:e} s where the median sample period is {period:e} s: the clock does not tick \
                 evenly (a repeated or corrupt time stamp)",
                first[k]
            ),
        ));
    }
    if let Some((k, m, bound)) = glitch(&log.gauge_pa) {
        return Err(log_err(
            path,
            lines[k],
            "pressure_bar",
            format!(
                "{} bar is {:.3} bar from the median {:.3} bar of its neighbours (5 rows either side), beyond \
                 {:.3} bar (10 times their middle half's spread + 0.1 bar): a glitch or a corrupt row, not a \
                 reading",
                crate::seal::shown(log.gauge_pa[k] / 1e5),
                (log.gauge_pa[k] - m).abs() / 1e5,
                m / 1e5,
                bound / 1e5
            ),
        ));
    }
    log.lines = lines;
    Ok(log)
}

/// The first reading further from the median of its neighbours (5 rows either side) than 10 times (the
/// spread of their middle half + 0.1 bar): its index, that median and the bound. Local, so a chamber that
/// empties in seconds and then reads atmosphere for minutes is a decay, not a log of glitches around a
/// median of 0; the middle half, so two or three corrupt rows together do not hide each other.
fn glitch(y: &[f64]) -> Option<(usize, f64, f64)> {
    (0..y.len()).find_map(|i| {
        let mut w: Vec<f64> = (i.saturating_sub(5)..(i + 6).min(y.len()))
            .filter(|&j| j != i)
            .map(|j| y[j])
            .collect();
        w.sort_by(f64::total_cmp);
        let n = w.len();
        let m = 0.5 * (w[(n - 1) / 2] + w[n / 2]);
        let bound = 10.0 * (w[n - 1 - n / 4] - w[n / 4] + 0.1e5);
        ((y[i] - m).abs() > bound).then_some((i, m, bound))
    })
}

/// Gauss-Newton for `p_g = p(t; p0, k) - p_atm` of `law` over the rows `t`, `y` (gauge, Pa), with the
/// residuals. A step that raises the squared residuals is halved (a decay into the subsonic branch starts
/// far from its optimum); a log choked throughout converges on full steps as the closed form always did.
fn fit_decay(t: &[f64], y: &[f64], law: &DecayLaw) -> Result<(Decay, Vec<f64>), IdentifyError> {
    let p_atm = law.pa;
    let n = t.len() as f64;
    let (mut p0, mut k) = if y.iter().all(|v| v + p_atm >= law.p_crit) {
        // Start: the straight line through the readings, its slope over the mean absolute pressure.
        let (mt, my) = (t.iter().sum::<f64>() / n, y.iter().sum::<f64>() / n);
        let stt: f64 = t.iter().map(|a| (a - mt).powi(2)).sum();
        let slope = t
            .iter()
            .zip(y)
            .map(|(a, b)| (a - mt) * (b - my))
            .sum::<f64>()
            / stt;
        (my - slope * mt + p_atm, -slope / (my + p_atm))
    } else {
        // Start: the law through the first and the last reading, p0 taken back to t = 0.
        let (a, z) = (y[0].max(1.0) + p_atm, y[y.len() - 1].max(1.0) + p_atm);
        let k = law.elapsed(a, z.min(a)) / (t[t.len() - 1] - t[0]);
        (law.before(a, k * t[0]), k)
    };
    let sse_of = |p0: f64, k: f64| -> f64 {
        t.iter()
            .zip(y)
            .map(|(&ti, &yi)| (yi - (law.pressure(p0, k, ti).0 - p_atm)).powi(2))
            .sum()
    };
    let mut sse = sse_of(p0, k);
    for _ in 0..200 {
        let (mut a, mut b, mut c, mut g0, mut g1) = (0.0, 0.0, 0.0, 0.0, 0.0);
        for (&ti, &yi) in t.iter().zip(y) {
            let (p, j0, j1) = law.pressure(p0, k, ti);
            let r = yi - (p - p_atm);
            (a, b, c) = (a + j0 * j0, b + j0 * j1, c + j1 * j1);
            (g0, g1) = (g0 + j0 * r, g1 + j1 * r);
        }
        let det = a * c - b * b;
        if !(det.is_finite() && det > 0.0) {
            return Err(IdentifyError::Fit(
                "the decay's normal equations are singular".into(),
            ));
        }
        let (d0, d1) = ((c * g0 - b * g1) / det, (a * g1 - b * g0) / det);
        if d0.abs() <= 1e-13 * p0.abs() && d1.abs() <= 1e-13 * k.abs().max(1e-300) {
            p0 += d0;
            k += d1;
            break;
        }
        let mut step = 1.0;
        loop {
            let (q0, q1) = (p0 + step * d0, k + step * d1);
            let next = if q0 > p_atm && q1.is_finite() {
                sse_of(q0, q1)
            } else {
                f64::INFINITY
            };
            // Rounding may raise a converging step's sum by a few ulps: only a clear rise is refused.
            if next <= sse * (1.0 + 1e-9) || step < 1e-6 {
                (p0, k, sse) = (q0, q1, next);
                break;
            }
            step *= 0.5;
        }
        if !(p0 > p_atm && k.is_finite()) {
            return Err(IdentifyError::Fit(
                "the decay's fit left the chamber at or below atmosphere at t = 0".into(),
            ));
        }
    }
    let res: Vec<f64> = t
        .iter()
        .zip(y)
        .map(|(&ti, &yi)| yi - (law.pressure(p0, k, ti).0 - p_atm))
        .collect();
    let sse: f64 = res.iter().map(|r| r * r).sum();
    // Formal error: s^2 (J^T J)^-1 at the optimum.
    let (mut a, mut b, mut c) = (0.0, 0.0, 0.0);
    for &ti in t {
        let (_, j0, j1) = law.pressure(p0, k, ti);
        (a, b, c) = (a + j0 * j0, b + j0 * j1, c + j1 * j1);
    }
    let s2 = sse / (n - 2.0);
    Ok((
        Decay {
            p0_pa: p0,
            rate_per_s: k,
            rate_std_error_per_s: (s2 * a / (a * c - b * b)).sqrt(),
            rms_pa: (sse / n).sqrt(),
        },
        res,
    ))
}

/// Lag-1 autocorrelation of the residuals `r`.
fn autocorrelation(r: &[f64]) -> f64 {
    let m = r.iter().sum::<f64>() / r.len() as f64;
    let var: f64 = r.iter().map(|v| (v - m).powi(2)).sum();
    let cov: f64 = r.windows(2).map(|w| (w[0] - m) * (w[1] - m)).sum();
    cov / var
}

/// The sensor's noise from the sample-to-sample differences: std(diff) / sqrt 2, Pa.
fn noise(y: &[f64]) -> f64 {
    let d: Vec<f64> = y.windows(2).map(|w| w[1] - w[0]).collect();
    let n = d.len() as f64;
    let m = d.iter().sum::<f64>() / n;
    (d.iter().map(|v| (v - m).powi(2)).sum::<f64>() / (n - 1.0)).sqrt() / 2f64.sqrt()
}

/// The sensor's noise from the second differences' median absolute deviation, Pa: blind to a smooth decay
/// of any speed and to a few jumps (a refill), as the atmosphere's threshold needs.
fn robust_noise(y: &[f64]) -> f64 {
    let median = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let mut d2: Vec<f64> = y.windows(3).map(|w| w[2] - 2.0 * w[1] + w[0]).collect();
    let m = median(&mut d2);
    let mut dev: Vec<f64> = d2.iter().map(|v| (v - m).abs()).collect();
    // MAD to std (x 1.4826), and a second difference has 6 times the readings' variance.
    1.4826 * median(&mut dev) / 6f64.sqrt()
}

/// The gauge pressure below which (the median of five readings from a row) a chamber reads atmosphere: where the ISO 6358 law ends (`p_atm / p` =
/// [`LAMINAR_RATIO`]) or within 3 times the sensor's noise of 0, Pa.
fn atmosphere_reading_pa(p_atm: f64, noise_pa: f64) -> f64 {
    (p_atm * (1.0 / LAMINAR_RATIO - 1.0)).max(3.0 * noise_pa)
}

/// Fits the leak to a decay log (module doc): the rows up to where the chamber reads atmosphere, through
/// the choked and the subsonic branch with one k.
pub fn fit_leak(log: &DecayLog, o: &LeakOptions) -> Result<LeakFit, IdentifyError> {
    o.check()?;
    let law = DecayLaw::new(o.atmosphere_pa, o.critical_pressure_ratio);
    let noise_all = robust_noise(&log.gauge_pa);
    let floor = atmosphere_reading_pa(o.atmosphere_pa, noise_all);
    let line = |k: usize| log.lines.get(k).copied().unwrap_or(k + 1);
    // The first row below the threshold from which the median of five readings is below it too: one
    // reading dipping by its noise does not end a decay.
    let y_all = &log.gauge_pa;
    let end = (0..y_all.len())
        .find(|&k| {
            let mut w: Vec<f64> = y_all[k..(k + 5).min(y_all.len())].to_vec();
            w.sort_by(f64::total_cmp);
            y_all[k] < floor && w[w.len() / 2] < floor
        })
        .unwrap_or(y_all.len());
    if end < 10 {
        let k = end.min(log.gauge_pa.len() - 1);
        return Err(log_err(
            &log.file,
            line(k),
            "pressure_bar",
            format!(
                "{} bar gauge: the chamber reads atmosphere (or below it) from this row on (the median of five \
                 readings below {:.0} Pa gauge: 3 times the sensor's {:.0} Pa noise, or where the ISO 6358 law \
                 ends), leaving {end} rows of decay; a leak needs at least 10 (a chamber that \
                 empties in fewer rows needs a faster logger; a log of a closed chamber filled above \
                 atmosphere)",
                crate::seal::shown(log.gauge_pa[k] / 1e5),
                floor,
                noise_all
            ),
        ));
    }
    // A reading well above atmosphere after the chamber read atmosphere (beyond 4 times the threshold, 12
    // times the noise): a refill or a second test.
    if let Some(k) = (end..log.gauge_pa.len()).find(|&k| log.gauge_pa[k] > 4.0 * floor) {
        return Err(log_err(
            &log.file,
            line(k),
            "pressure_bar",
            format!(
                "{} bar gauge after the chamber read atmosphere from line {} on (the median of five readings \
                 below {:.0} Pa gauge): the pressure rises again, a refill or a second test in one log; give one \
                 decay per file",
                crate::seal::shown(log.gauge_pa[k] / 1e5),
                line(end),
                floor
            ),
        ));
    }
    // Time from the first row: p0 is the pressure there (a logger's clock may not start at 0).
    let t0 = log.t_s[0];
    let t_rel: Vec<f64> = log.t_s[..end].iter().map(|ti| ti - t0).collect();
    let t = &t_rel[..];
    let y = &log.gauge_pa[..end];
    let named = |e: IdentifyError| match e {
        IdentifyError::Fit(m) => IdentifyError::Fit(format!("{}: {m}", log.file.display())),
        e => e,
    };
    let (decay, residuals) = fit_decay(t, y, &law).map_err(named)?;
    if !(decay.rate_per_s.is_finite() && decay.rate_per_s > 0.0) {
        return Err(IdentifyError::Fit(format!(
            "{}: the pressure does not decay (fitted rate {:e} 1/s): no leak to fit",
            log.file.display(),
            decay.rate_per_s
        )));
    }
    // A rate within two standard errors of 0 is the sensor's noise, not a leak: its C/V and t10 would be noise.
    if decay.rate_per_s < 2.0 * decay.rate_std_error_per_s {
        return Err(IdentifyError::Fit(format!(
            "{}: the fitted decay rate {:.3e} 1/s is within two standard errors ({:.3e} 1/s) of 0: no leak \
             this log can tell from the sensor's noise (a longer log, or a leakier chamber)",
            log.file.display(),
            decay.rate_per_s,
            decay.rate_std_error_per_s
        )));
    }
    let h = t.len() / 2;
    let halves = [
        fit_decay(&t[..h], &y[..h], &law).map_err(named)?.0,
        fit_decay(&t[h..], &y[h..], &law).map_err(named)?.0,
    ];
    // eq. (11), isothermal: k = C rho0 R sqrt(T T0) / V, in either branch.
    let per_volume = decay.rate_per_s
        / (ISO_RHO0_KG_M3 * o.gas_constant_j_per_kg_k * (o.temperature_k * ISO_T0_K).sqrt());
    let pg0 = decay.p0_pa - o.atmosphere_pa;
    let p_min = y.iter().copied().fold(f64::INFINITY, f64::min) + o.atmosphere_pa;
    let noise_pa = noise(y);
    let span = t[t.len() - 1] - t[0];
    // The fitted decay's regime at each row: choked while its pressure is at or above p_atm / b.
    let choked_rows = t
        .iter()
        .take_while(|&&ti| law.pressure(decay.p0_pa, decay.rate_per_s, ti).0 >= law.p_crit)
        .count();
    let regime = match choked_rows {
        c if c == t.len() => Regime::Choked,
        0 => Regime::Subsonic,
        _ => Regime::ChokedThenSubsonic,
    };
    let mut fit = LeakFit {
        chamber: log.chamber.clone(),
        rows: t.len(),
        span_s: span,
        fitted: Rows::of(log, 0..end).expect("at least 10 rows"),
        left_out: Rows::of(log, end..log.t_s.len()),
        critical_pressure_ratio: o.critical_pressure_ratio,
        regime,
        choked: Rows::of(log, 0..choked_rows),
        subsonic: Rows::of(log, choked_rows..end),
        decay,
        conductance_per_volume: per_volume,
        t10_s: law.elapsed(decay.p0_pa, decay.p0_pa - 0.1 * pg0) / decay.rate_per_s,
        loss: 1.0 - (law.pressure(decay.p0_pa, decay.rate_per_s, span).0 - o.atmosphere_pa) / pg0,
        choked_below_b: o.atmosphere_pa / p_min,
        noise_pa,
        residual_autocorrelation: autocorrelation(&residuals),
        rms_as_temperature_k: o.temperature_k * decay.rms_pa / decay.p0_pa,
        halves,
        adequate: false,
        verdict: String::new(),
    };
    verdict(&mut fit, floor);
    Ok(fit)
}

/// The largest change of a filled, closed chamber's gas temperature a misfit is put down to, K: beyond it
/// the decay is not a leak with thermal drift (the room moves the gas by tenths of a kelvin).
pub const DRIFT_MAX_K: f64 = 2.0;

/// The adequacy verdict (see [`LeakFit::adequate`]) and which part of the log was fitted, in which regime.
fn verdict(f: &mut LeakFit, floor_pa: f64) {
    let [a, b] = f.halves;
    let apart = (a.rate_per_s - b.rate_per_s).abs()
        / (a.rate_std_error_per_s.powi(2) + b.rate_std_error_per_s.powi(2)).sqrt();
    let ratio = f.decay.rms_pa / f.noise_pa;
    f.adequate = ratio <= 1.5 && f.residual_autocorrelation < 0.5 && apart <= 3.0;
    let b_note = match (f.regime, f.subsonic) {
        (Regime::Choked, _) => format!(
            "b is not identified: the flow is choked throughout for any b above {:.3}",
            f.choked_below_b
        ),
        (Regime::ChokedThenSubsonic, Some(sub)) => format!(
            "the fitted decay is choked to line {} ({:.1} s) and subsonic from line {} ({:.1} s) on: one \
             conductance over both regimes, with b = {} assumed (--critical-pressure-ratio; not identified)",
            f.choked.map_or(sub.first_line, |c| c.last_line),
            f.choked.map_or(sub.from_s, |c| c.to_s),
            sub.first_line,
            sub.from_s,
            f.critical_pressure_ratio
        ),
        _ => format!(
            "the fitted decay is subsonic throughout (p_atm / p above b = {} assumed, --critical-pressure-ratio; \
             not identified): C/V depends on that b",
            f.critical_pressure_ratio
        ),
    };
    let mut text = if !f.adequate && f.rms_as_temperature_k > DRIFT_MAX_K {
        format!(
            "the decay is not one leak to atmosphere: residuals {:.0} Pa RMS, {:.1} times the sensor's {:.0} Pa \
             noise, lag-1 autocorrelation {:.2}; the halves decay at {:.3e} and {:.3e} 1/s, {:.0} standard \
             errors apart. The residual would need the gas temperature to change by {:.1} K, beyond what a \
             filled, closed chamber's gas drifts (tenths of a kelvin with the room): a pressure levelling off \
             above atmosphere (a leak into another volume, the sensor's offset), a chamber still being filled, \
             or a valve moved during the log. k and C/V ({:.3e} 1/(s Pa)) are no leak's; {b_note}",
            f.decay.rms_pa,
            ratio,
            f.noise_pa,
            f.residual_autocorrelation,
            a.rate_per_s,
            b.rate_per_s,
            apart,
            f.rms_as_temperature_k,
            f.conductance_per_volume
        )
    } else if f.adequate {
        let law = if f.regime == Regime::Choked {
            "a constant choked leak"
        } else {
            "a constant ISO 6358 leak"
        };
        format!("{law} explains the log to the sensor's noise; {b_note}")
    } else {
        format!(
            "a constant leak does not explain the log: residuals {:.0} Pa RMS, {:.1} times the sensor's \
             {:.0} Pa noise, lag-1 autocorrelation {:.2} (noise: 0); the halves decay at {:.3e} and \
             {:.3e} 1/s, {:.0} standard errors apart. The residual is what a change of the gas temperature \
             by {:.2} K would do, so k and C/V are this log's average decay, leak and thermal drift \
             together, and their formal errors ({:.1} %) are too small; {b_note}",
            f.decay.rms_pa,
            ratio,
            f.noise_pa,
            f.residual_autocorrelation,
            a.rate_per_s,
            b.rate_per_s,
            apart,
            f.rms_as_temperature_k,
            100.0 * f.decay.rate_std_error_per_s / f.decay.rate_per_s
        )
    };
    if let Some(out) = f.left_out {
        text += &format!(
            "; {} left out: the chamber reads atmosphere from there (below {:.0} Pa gauge), the sensor's zero, \
             not the leak",
            out.shown(),
            floor_pa
        );
    }
    f.verdict = text;
}

/// One step of a ranking: the next chamber leaks more than the previous one.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct RankStep {
    /// The tighter chamber.
    pub tighter: String,
    /// The leakier chamber.
    pub leakier: String,
    /// C/V of the leakier over C/V of the tighter.
    pub ratio: f64,
    /// Whether the two chambers' rates (whole log and each half) lie in ranges that do not overlap: the
    /// order holds whichever part of the logs is believed.
    pub settled: bool,
}

/// The range of decay rates a fit admits: the whole log's and each half's, 1/s.
fn rate_range(f: &LeakFit) -> (f64, f64) {
    let r = [
        f.decay.rate_per_s,
        f.halves[0].rate_per_s,
        f.halves[1].rate_per_s,
    ];
    (
        r.iter().copied().fold(f64::INFINITY, f64::min),
        r.iter().copied().fold(f64::NEG_INFINITY, f64::max),
    )
}

/// Sorts the chambers' leaks tightest first (by C / V) and says which steps of the order are settled.
pub fn rank(fits: &mut [LeakFit]) -> Vec<RankStep> {
    fits.sort_by(|a, b| {
        a.conductance_per_volume
            .total_cmp(&b.conductance_per_volume)
    });
    fits.windows(2)
        .map(|w| RankStep {
            tighter: w[0].chamber.clone(),
            leakier: w[1].chamber.clone(),
            ratio: w[1].conductance_per_volume / w[0].conductance_per_volume,
            settled: rate_range(&w[0]).1 < rate_range(&w[1]).0,
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A closed chamber of volume `v` emptying through an ISO 6358 orifice of conductance `c` and critical
    /// ratio `b`, isothermal, integrated by RK4 on the gas mass with the valve's own flow
    /// ([`Orifice::mass_flow`]), read every 0.1 s with a deterministic +-`noise` Pa pattern.
    fn emptying_log(c: f64, v: f64, b: f64, p0: f64, rows: usize, noise: f64) -> DecayLog {
        let o = LeakOptions::default();
        let leak = Orifice {
            sonic_conductance_m3_per_s_pa: c,
            critical_pressure_ratio: b,
        };
        let (t_k, r, pa) = (o.temperature_k, o.gas_constant_j_per_kg_k, o.atmosphere_pa);
        let out = |m: f64| leak.mass_flow(1.0, m * r * t_k / v, t_k, pa, t_k).0;
        let mut m = p0 * v / (r * t_k);
        let (mut t_s, mut gauge_pa) = (Vec::new(), Vec::new());
        let h = 1e-3;
        for i in 0..rows {
            t_s.push(i as f64 * 0.1);
            // A pattern of zero mean with no trend: the sensor's noise, reproducible.
            let n = noise * [0.3, -0.8, 1.0, -0.5, 0.1, -0.1][i % 6];
            gauge_pa.push(m * r * t_k / v - pa + n);
            for _ in 0..100 {
                let k1 = -out(m);
                let k2 = -out(m + 0.5 * h * k1);
                let k3 = -out(m + 0.5 * h * k2);
                let k4 = -out(m + h * k3);
                m += h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4);
            }
        }
        DecayLog {
            file: PathBuf::from("synthetic.csv"),
            chamber: "synthetic".into(),
            t_s,
            gauge_pa,
            lines: Vec::new(),
        }
    }

    #[test]
    fn a_decay_through_the_choked_and_the_subsonic_branch_gives_its_conductance_back() {
        // 8.3 bar abs to atmosphere in ~2 min: choked to ~70 s, then subsonic, then at atmosphere.
        let (c, v) = (3e-11, 1.5e-4);
        let log = emptying_log(c, v, CHOKED_RATIO_MAX, 8.3e5, 1500, 150.0);
        let f = fit_leak(&log, &LeakOptions::default()).unwrap();
        let err = f.conductance_per_volume / (c / v) - 1.0;
        assert!(
            err.abs() < 0.01,
            "C/V {} vs {}: {err:e}",
            f.conductance_per_volume,
            c / v
        );
        assert_eq!(f.regime, Regime::ChokedThenSubsonic, "{}", f.verdict);
        let (ch, sub) = (f.choked.unwrap(), f.subsonic.unwrap());
        assert_eq!(ch.first_line, 1);
        assert_eq!(sub.first_line, ch.last_line + 1);
        assert_eq!(sub.last_line, f.fitted.last_line);
        // The rows at atmosphere are left out, and the verdict says which.
        let out = f.left_out.expect("rows at atmosphere left out");
        assert_eq!(out.first_line, f.fitted.last_line + 1);
        assert_eq!(out.last_line, 1500);
        assert!(f.verdict.contains("subsonic from line"), "{}", f.verdict);
        assert!(f.verdict.contains("left out"), "{}", f.verdict);
        assert!(f.adequate, "{}", f.verdict);
        assert!(!f.verdict.contains("thermal drift"), "{}", f.verdict);
    }

    #[test]
    fn a_decay_choked_throughout_gives_its_conductance_back_by_the_closed_form() {
        let (c, v) = (3e-13, 1.5e-4);
        let log = emptying_log(c, v, CHOKED_RATIO_MAX, 8.3e5, 1500, 150.0);
        let f = fit_leak(&log, &LeakOptions::default()).unwrap();
        let err = f.conductance_per_volume / (c / v) - 1.0;
        assert!(
            err.abs() < 0.01,
            "C/V {} vs {}: {err:e}",
            f.conductance_per_volume,
            c / v
        );
        assert_eq!(f.regime, Regime::Choked);
        assert_eq!((f.subsonic, f.left_out), (None, None));
        assert_eq!(f.fitted.rows, 1500);
        assert!(f.verdict.contains("choked throughout"), "{}", f.verdict);
    }

    #[test]
    fn a_chamber_filled_below_the_critical_pressure_decays_subsonic_throughout() {
        let (c, v, b) = (3e-11, 1.5e-4, 0.3);
        let log = emptying_log(c, v, b, 2.5e5, 600, 50.0);
        let o = LeakOptions {
            critical_pressure_ratio: b,
            ..Default::default()
        };
        let f = fit_leak(&log, &o).unwrap();
        let err = f.conductance_per_volume / (c / v) - 1.0;
        assert!(
            err.abs() < 0.01,
            "C/V {} vs {}: {err:e}",
            f.conductance_per_volume,
            c / v
        );
        assert_eq!(f.regime, Regime::Subsonic, "{}", f.verdict);
        assert!(f.verdict.contains("C/V depends on that b"), "{}", f.verdict);
    }

    #[test]
    fn the_law_follows_the_valves_flow_function_and_its_derivatives() {
        let law = DecayLaw::new(101_325.0, 0.4);
        let (p0, k) = (6e5, 0.05);
        // p' = -k p phi: a central difference of p(t) against the valve's phi.
        let o = Orifice {
            sonic_conductance_m3_per_s_pa: 1.0,
            critical_pressure_ratio: 0.4,
        };
        // Choked to 17 s, subsonic after; near atmosphere (p - p_atm < 1 kPa) the differences are rounding.
        for t in [1.0, 10.0, 17.0, 18.0, 22.0, 26.0, 30.0, 34.0] {
            let (p, dp0, dk) = law.pressure(p0, k, t);
            assert!(p - 101_325.0 > 1e3, "t {t}: {p}");
            let h = 1e-4;
            let slope = (law.pressure(p0, k, t + h).0 - law.pressure(p0, k, t - h).0) / (2.0 * h);
            let want = -k * p * o.phi(101_325.0 / p);
            assert!(
                (slope / want - 1.0).abs() < 1e-5,
                "t {t}: {slope} vs {want}"
            );
            let by_p0 = (law.pressure(p0 + 1.0, k, t).0 - law.pressure(p0 - 1.0, k, t).0) / 2.0;
            let by_k = (law.pressure(p0, k + 1e-7, t).0 - law.pressure(p0, k - 1e-7, t).0) / 2e-7;
            assert!((by_p0 / dp0 - 1.0).abs() < 1e-4, "t {t}: {by_p0} vs {dp0}");
            assert!((by_k / dk - 1.0).abs() < 1e-4, "t {t}: {by_k} vs {dk}");
        }
    }

    #[test]
    fn a_log_at_atmosphere_from_its_start_is_refused_at_its_line() {
        let mut log = emptying_log(3e-11, 1.5e-4, CHOKED_RATIO_MAX, 8.3e5, 200, 150.0);
        log.gauge_pa.iter_mut().for_each(|g| *g = -0.05e5);
        let e = fit_leak(&log, &LeakOptions::default())
            .unwrap_err()
            .to_string();
        assert!(e.contains("synthetic.csv:1"), "{e}");
        assert!(e.contains("reads atmosphere"), "{e}");
    }
}
