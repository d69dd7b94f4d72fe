//! A chamber's leak from its pressure decay (issue 26, item 4): a chamber filled and closed, its pressure
//! logged (the Zillen 2021 printed chambers, `data/zillen-2021-printed-cylinder/leakage/<material>.csv`,
//! ';'-separated: time in ms with '.' as the thousands separator and three decimals, `1.003.000` = 1003 ms;
//! pressure V; pressure bar gauge).
//!
//! The leak is an ISO 6358 orifice (eq. 11) of conductance C from a chamber of volume V at temperature
//! T. Choked while `p_atm / p <= b`: `M' = -C rho0 p sqrt(T0/T)` and, isothermal, `V p' = R T M'`, so
//!
//! ```text
//! p(t) = p0 exp(-k t),   k = C rho0 R sqrt(T T0) / V,   C / V = k / (rho0 R sqrt(T T0))   (1/(s Pa))
//! ```
//!
//! (`crates/pneumatics/tests/effects.rs` checks the model against this closed form). The fit is Gauss-Newton
//! on the gauge readings for (p0, k). Without the chamber's volume the data give C / V, the leak's
//! conductance per volume, which ranks chambers of any size. b is not identified while the whole log is
//! choked (`p_atm / p_min` below any plausible b): the report says so. The report also says whether the
//! decay is a leak at all: the residuals against the sensor's noise (from the sample-to-sample
//! differences) and the rate of each half of the log against the other.

use std::path::{Path, PathBuf};

use pneuflex_pneumatics::flow::{ISO_RHO0_KG_M3, ISO_T0_K};

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
}

impl Default for LeakOptions {
    fn default() -> Self {
        Self {
            atmosphere_pa: pneuflex_pneumatics::P_ATM,
            temperature_k: ISO_T0_K,
            gas_constant_j_per_kg_k: pneuflex_pneumatics::R_AIR,
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
        Ok(())
    }
}

/// The sample periods a decay log may have, s: a median outside is a time in another unit or a corrupt
/// clock (a slow decay may be logged every few minutes).
pub const PERIOD_RANGE_S: (f64, f64) = (1e-5, 600.0);

/// The ideal gas's critical pressure ratio, the largest b of any orifice: with p_atm / p above it the flow
/// out is not choked anywhere, and the choked law does not hold.
pub const CHOKED_RATIO_MAX: f64 = 0.528;

/// The choked decay fitted to a span of a log.
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
    /// Rows used.
    pub rows: usize,
    /// Span of the log, s.
    pub span_s: f64,
    /// The whole log's decay.
    pub decay: Decay,
    /// C / V, 1/(s Pa): the leak's sonic conductance per chamber volume.
    pub conductance_per_volume: f64,
    /// Time to lose 10 % of the initial gauge pressure, s (extrapolated from the fit).
    pub t10_s: f64,
    /// The share of the initial gauge pressure the fitted decay loses over the log, 1.
    pub loss: f64,
    /// p_atm / p at the lowest reading: the flow is choked for any b above this.
    pub choked_below_b: f64,
    /// The sensor's noise from the sample-to-sample differences (std / sqrt 2), Pa.
    pub noise_pa: f64,
    /// Lag-1 autocorrelation of the residuals (near 0 for noise, near 1 for residuals that wander).
    pub residual_autocorrelation: f64,
    /// The change of the gas temperature that moves the pressure by the RMS residual, K (p ~ T at
    /// constant mass and volume).
    pub rms_as_temperature_k: f64,
    /// The first and the second half of the log fitted alone.
    pub halves: [Decay; 2],
    /// Whether the choked leak explains the log: residuals within 1.5 times the noise and not wandering
    /// (lag-1 autocorrelation below 0.5), and the halves' rates within 3 standard errors of each other.
    pub adequate: bool,
    /// What it says, in words.
    pub verdict: String,
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
    if let Some((k, m, bound)) = crate::seal::spike(&log.gauge_pa, 0.1e5) {
        return Err(log_err(
            path,
            lines[k],
            "pressure_bar",
            format!(
                "{} bar is {:.3} bar from the log's median {:.3} bar, beyond {:.3} bar (10 times the spread of \
                 its middle half): a glitch or a corrupt row, not a reading",
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

/// Gauss-Newton for `p_g = p0 exp(-k t) - p_atm` over the rows `t`, `y` (gauge, Pa).
fn fit_decay(t: &[f64], y: &[f64], p_atm: f64) -> Result<Decay, IdentifyError> {
    let n = t.len() as f64;
    // Start: the straight line through the readings, its slope over the mean absolute pressure.
    let (mt, my) = (t.iter().sum::<f64>() / n, y.iter().sum::<f64>() / n);
    let stt: f64 = t.iter().map(|a| (a - mt).powi(2)).sum();
    let slope = t
        .iter()
        .zip(y)
        .map(|(a, b)| (a - mt) * (b - my))
        .sum::<f64>()
        / stt;
    let (mut p0, mut k) = (my - slope * mt + p_atm, -slope / (my + p_atm));
    for _ in 0..100 {
        let (mut a, mut b, mut c, mut g0, mut g1) = (0.0, 0.0, 0.0, 0.0, 0.0);
        for (&ti, &yi) in t.iter().zip(y) {
            let e = (-k * ti).exp();
            let r = yi - (p0 * e - p_atm);
            let (j0, j1) = (e, -p0 * ti * e);
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
        p0 += d0;
        k += d1;
        if d0.abs() <= 1e-13 * p0.abs() && d1.abs() <= 1e-13 * k.abs().max(1e-300) {
            break;
        }
    }
    let res: Vec<f64> = t
        .iter()
        .zip(y)
        .map(|(&ti, &yi)| yi - (p0 * (-k * ti).exp() - p_atm))
        .collect();
    let sse: f64 = res.iter().map(|r| r * r).sum();
    // Formal error: s^2 (J^T J)^-1 at the optimum.
    let (mut a, mut b, mut c) = (0.0, 0.0, 0.0);
    for &ti in t {
        let e = (-k * ti).exp();
        let (j0, j1) = (e, -p0 * ti * e);
        (a, b, c) = (a + j0 * j0, b + j0 * j1, c + j1 * j1);
    }
    let s2 = sse / (n - 2.0);
    Ok(Decay {
        p0_pa: p0,
        rate_per_s: k,
        rate_std_error_per_s: (s2 * a / (a * c - b * b)).sqrt(),
        rms_pa: (sse / n).sqrt(),
    })
}

/// Lag-1 autocorrelation of the residuals of `d` against the log.
fn autocorrelation(t: &[f64], y: &[f64], d: &Decay, p_atm: f64) -> f64 {
    let r: Vec<f64> = t
        .iter()
        .zip(y)
        .map(|(&ti, &yi)| yi - (d.p0_pa * (-d.rate_per_s * ti).exp() - p_atm))
        .collect();
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

/// Fits the choked leak to a decay log (module doc).
pub fn fit_leak(log: &DecayLog, o: &LeakOptions) -> Result<LeakFit, IdentifyError> {
    o.check()?;
    let (t, y) = (&log.t_s, &log.gauge_pa);
    if let Some(k) =
        (0..y.len()).find(|&k| o.atmosphere_pa / (y[k] + o.atmosphere_pa) > CHOKED_RATIO_MAX)
    {
        return Err(IdentifyError::Fit(format!(
            "{}:{}: column `pressure_bar`: {:.4} bar gauge, where p_atm / p = {:.3} is above {CHOKED_RATIO_MAX} \
             (with --atmosphere-pa {}): the flow out is not choked there and the choked leak does not hold; give \
             the part of the decay above {:.3} bar gauge",
            log.file.display(),
            log.lines.get(k).copied().unwrap_or(k + 1),
            y[k] / 1e5,
            o.atmosphere_pa / (y[k] + o.atmosphere_pa),
            o.atmosphere_pa,
            (o.atmosphere_pa / CHOKED_RATIO_MAX - o.atmosphere_pa) / 1e5
        )));
    }
    let decay = fit_decay(t, y, o.atmosphere_pa)?;
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
        fit_decay(&t[..h], &y[..h], o.atmosphere_pa)?,
        fit_decay(&t[h..], &y[h..], o.atmosphere_pa)?,
    ];
    // eq. (11), choked, isothermal: k = C rho0 R sqrt(T T0) / V.
    let per_volume = decay.rate_per_s
        / (ISO_RHO0_KG_M3 * o.gas_constant_j_per_kg_k * (o.temperature_k * ISO_T0_K).sqrt());
    let pg0 = decay.p0_pa - o.atmosphere_pa;
    let p_min = y.iter().copied().fold(f64::INFINITY, f64::min) + o.atmosphere_pa;
    let noise_pa = noise(y);
    let mut fit = LeakFit {
        chamber: log.chamber.clone(),
        rows: t.len(),
        span_s: t[t.len() - 1] - t[0],
        decay,
        conductance_per_volume: per_volume,
        t10_s: (decay.p0_pa / (decay.p0_pa - 0.1 * pg0)).ln() / decay.rate_per_s,
        loss: 1.0
            - (decay.p0_pa * (-decay.rate_per_s * (t[t.len() - 1] - t[0])).exp() - o.atmosphere_pa)
                / pg0,
        choked_below_b: o.atmosphere_pa / p_min,
        noise_pa,
        residual_autocorrelation: autocorrelation(t, y, &decay, o.atmosphere_pa),
        rms_as_temperature_k: o.temperature_k * decay.rms_pa / decay.p0_pa,
        halves,
        adequate: false,
        verdict: String::new(),
    };
    verdict(&mut fit);
    Ok(fit)
}

/// The adequacy verdict (see [`LeakFit::adequate`]).
fn verdict(f: &mut LeakFit) {
    let [a, b] = f.halves;
    let apart = (a.rate_per_s - b.rate_per_s).abs()
        / (a.rate_std_error_per_s.powi(2) + b.rate_std_error_per_s.powi(2)).sqrt();
    let ratio = f.decay.rms_pa / f.noise_pa;
    f.adequate = ratio <= 1.5 && f.residual_autocorrelation < 0.5 && apart <= 3.0;
    let b_note = format!(
        "b is not identified: the flow is choked throughout for any b above {:.3}",
        f.choked_below_b
    );
    f.verdict = if f.adequate {
        format!("a constant choked leak explains the log to the sensor's noise; {b_note}")
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
