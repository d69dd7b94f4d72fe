//! Seal friction from a bench test (issue 26, item 4): a cylinder held at a gauge pressure p while a drive
//! moves its rod back and forth, the rod force F, the pressure and the position logged (the Zillen 2021
//! printed cylinder, `data/zillen-2021-printed-cylinder/friction/circle_<P>bar.csv`, whitespace-separated:
//! time ms, three raw voltages, position mm, pressure bar gauge, force N).
//!
//! Friction per sample, the authors' reading: `f = F - p A` (A the piston area, p the sample's own
//! pressure). Velocity from the position: a 5-point running median (the laser has single-sample glitches of
//! 0.15-0.5 mm), then the central difference over +-3 samples on the real timestamps (the sampling is
//! uneven). Samples faster than `still_below` in either direction are "moving"; the others are left out.
//! Cells: (test, direction) means of f, p and v.
//!
//! Laws, fitted by least squares on the cell means (`s` the direction's sign, `p` the gauge pressure, which
//! is the pressure difference across the seal here: the other side is open):
//!
//! ```text
//! constant Coulomb:  f = s F_c             + o_i
//! pressure term:     f = s (F_c0 + k_p p)  + o_i      (pneuflex: coulomb_n, coulomb_pressure_n_per_pa)
//! ```
//!
//! `o_i` is a zero offset of `F - p A` per test (a force or pressure calibration offset: at rest, before
//! any motion, each file reads its offset), or one common offset, or none ([`Offsets`]). The report gives
//! each law's parameters, its residual per cell against the cell mean and the samples, what the pressure
//! term buys (the RMS with and without it), and whether the law explains the cell means to their precision.

use std::path::{Path, PathBuf};

use nalgebra::{DMatrix, DVector};

use crate::IdentifyError;

/// One bench test: a file's samples, SI.
#[derive(Clone, Debug, PartialEq)]
pub struct SealTest {
    /// The file.
    pub file: PathBuf,
    /// The pressure the test held, from the file name (`circle_<P>bar.csv`), Pa gauge.
    pub nominal_pa: f64,
    /// Time, s.
    pub t_s: Vec<f64>,
    /// Rod position, m.
    pub x_m: Vec<f64>,
    /// Chamber pressure, Pa gauge.
    pub gauge_pa: Vec<f64>,
    /// Rod force, N.
    pub force_n: Vec<f64>,
}

/// How the samples are prepared.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SealOptions {
    /// Piston bore, m (the data set's cylinder: 25 mm).
    pub bore_m: f64,
    /// Rows dropped at the start of each file (start-up transients; the authors drop 15).
    pub skip_rows: usize,
    /// Half-width of the running median of the position, samples.
    pub median_half_width: usize,
    /// Half-width of the central difference giving the velocity, samples.
    pub velocity_half_width: usize,
    /// Speed below which a sample is still (left out), m/s.
    pub still_below_m_per_s: f64,
}

impl Default for SealOptions {
    fn default() -> Self {
        Self {
            bore_m: 0.025,
            skip_rows: 15,
            median_half_width: 2,
            velocity_half_width: 3,
            still_below_m_per_s: 0.002,
        }
    }
}

impl SealOptions {
    /// Piston area `pi bore^2 / 4`, m^2.
    pub fn area_m2(&self) -> f64 {
        0.25 * core::f64::consts::PI * self.bore_m * self.bore_m
    }

    /// Refuses a bore or a speed threshold no bench has, naming the option.
    pub fn check(&self) -> Result<(), IdentifyError> {
        let key = |option, v: f64, message: String| IdentifyError::Key {
            option,
            key: crate::seal::shown(v),
            message,
        };
        if !(1e-3..=1.0).contains(&self.bore_m) {
            return Err(key(
                "--bore-m",
                self.bore_m,
                "the piston's bore in metres must be in [0.001, 1] m (a 25 mm bore is 0.025)"
                    .into(),
            ));
        }
        if !(self.still_below_m_per_s > 0.0 && self.still_below_m_per_s <= 1.0) {
            return Err(key(
                "--still-below",
                self.still_below_m_per_s,
                "the speed below which a sample is still, in m/s, must be in (0, 1] (2 mm/s is 0.002)".into(),
            ));
        }
        Ok(())
    }
}

/// A moving sample: friction with its pressure and velocity.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sample {
    /// Index of the test.
    pub test: usize,
    /// +1 (x increasing) or -1.
    pub direction: f64,
    /// Pressure, Pa gauge.
    pub gauge_pa: f64,
    /// Velocity, m/s.
    pub velocity_m_per_s: f64,
    /// Friction f = F - p A, N.
    pub friction_n: f64,
    /// Time, s.
    pub t_s: f64,
}

/// The statistics of one (test, direction) cell.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Cell {
    /// Index of the test.
    pub test: usize,
    /// The test's file name.
    pub file: String,
    /// The test's pressure, Pa gauge (from the file name).
    pub nominal_pa: f64,
    /// +1 (x increasing) or -1.
    pub direction: f64,
    /// Moving samples.
    pub samples: usize,
    /// Mean friction, N.
    pub mean_friction_n: f64,
    /// Sample standard deviation of the friction, N.
    pub std_friction_n: f64,
    /// Mean pressure, Pa gauge.
    pub mean_gauge_pa: f64,
    /// Mean velocity, m/s.
    pub mean_velocity_m_per_s: f64,
    /// Least-squares slope of the friction against time within the cell, N/s (wear-in, warming).
    pub drift_n_per_s: f64,
    /// Independent samples the cell's mean is worth: `n (1 - r1) / (1 + r1)`, r1 the lag-1
    /// autocorrelation of its friction samples in time order.
    pub effective_samples: f64,
}

impl Cell {
    /// Standard error of the cell's mean friction (from its effective samples), N.
    pub fn standard_error_n(&self) -> f64 {
        self.std_friction_n / self.effective_samples.max(1.0).sqrt()
    }
}

/// Which zero offsets of `F - p A` a law carries.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Offsets {
    /// None: friction is odd in the velocity.
    None,
    /// One for all tests.
    Common,
    /// One per test (file).
    PerTest,
}

/// A law's residual in one cell.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct CellResidual {
    /// The test's pressure, Pa gauge.
    pub nominal_pa: f64,
    /// +1 or -1.
    pub direction: f64,
    /// Cell mean minus the law at the cell's mean pressure, N.
    pub mean_residual_n: f64,
    /// RMS of sample minus the law at each sample's pressure, N.
    pub rms_samples_n: f64,
    /// The mean residual over the cell mean's standard error ([`Cell::standard_error_n`]).
    pub standard_errors: f64,
}

/// A fitted law.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct LawFit {
    /// Whether the law has the pressure term.
    pub pressure_term: bool,
    /// The offsets it carries.
    pub offsets: Offsets,
    /// F_c (constant law) or F_c0 (pressure law), N.
    pub coulomb_n: f64,
    /// k_p, N/Pa (0 for the constant law).
    pub coulomb_pressure_n_per_pa: f64,
    /// The offsets, N: one per test, one, or none.
    pub offset_n: Vec<f64>,
    /// RMS of the cell residuals, N.
    pub rms_cell_means_n: f64,
    /// RMS over all moving samples, N.
    pub rms_samples_n: f64,
    /// Per cell.
    pub residuals: Vec<CellResidual>,
}

impl LawFit {
    /// The Coulomb force at gauge pressure `p` (Pa), N.
    pub fn coulomb_at(&self, p: f64) -> f64 {
        self.coulomb_n + self.coulomb_pressure_n_per_pa * p
    }
}

/// Whether a law explains the cell means to their precision.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Adequacy {
    /// Every cell residual within 3 standard errors of its cell mean.
    pub adequate: bool,
    /// The largest |residual| / standard error, and its cell (Pa gauge, direction).
    pub worst_standard_errors: f64,
    /// The cell of the worst residual: pressure, Pa gauge.
    pub worst_pa: f64,
    /// The cell of the worst residual: direction.
    pub worst_direction: f64,
    /// RMS of the samples about their own cell means, N: what no law of p and direction can explain.
    pub within_cell_rms_n: f64,
    /// What it says, in words.
    pub verdict: String,
}

/// The seal's report.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct SealReport {
    /// Piston area used, m^2.
    pub area_m2: f64,
    /// Moving samples in all.
    pub moving_samples: usize,
    /// The cells, by test and direction (+ first).
    pub cells: Vec<Cell>,
    /// Constant Coulomb and pressure law with per-test offsets.
    pub constant: LawFit,
    /// The pressure law with per-test offsets (the recommended law).
    pub pressure: LawFit,
    /// The same two laws without any offset.
    pub constant_no_offset: LawFit,
    /// The pressure law without any offset.
    pub pressure_no_offset: LawFit,
    /// 1 - RMS(pressure) / RMS(constant) on the cell means, with per-test offsets.
    pub pressure_term_rms_reduction: f64,
    /// The same on the samples.
    pub pressure_term_rms_reduction_samples: f64,
    /// Whether the pressure law explains the cell means.
    pub adequacy: Adequacy,
    /// Per test: the rest reading `F - p A` of its first row (before any motion) minus the midline of its
    /// two directions' means, N. Near 0: the asymmetry between the directions is a zero offset of the
    /// reading, which the per-test offsets take up.
    pub rest_minus_midline_n: Vec<f64>,
    /// Per-direction Coulomb friction, each test's zero taken from its rest reading ([`DirectionFit`]).
    pub direction: DirectionFit,
}

/// Per-direction Coulomb friction: `f - r_i = F_c+ + k_p p` moving towards +x, `-(F_c- + k_p p)` towards
/// -x, with `r_i` test i's rest reading of `F - p A` (its first row, before any motion) as its zero. The
/// per-test offsets of the other laws absorb any difference between the directions (an asymmetry common
/// to the tests is one more offset): the rest readings are what tells a seal's asymmetry from a zero
/// offset. Each test's own asymmetry is `a_i = (f+ - r_i) + (f- - r_i)` (its two cells); the asymmetry
/// `F_c+ - F_c-` is shown when their mean is outside its 95 % interval about 0 (Student's t over the
/// tests, the tests' scatter as the error: a paired comparison, since drift and session move both cells of
/// a test together).
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct DirectionFit {
    /// F_c+ at zero gauge pressure, N (motion towards +x).
    pub coulomb_positive_n: f64,
    /// F_c- at zero gauge pressure, N (motion towards -x).
    pub coulomb_negative_n: f64,
    /// k_p, N/Pa, one for both directions.
    pub coulomb_pressure_n_per_pa: f64,
    /// Per test: `a_i`, N.
    pub asymmetry_per_test_n: Vec<f64>,
    /// F_c+ - F_c-: the mean of `a_i`, N.
    pub asymmetry_n: f64,
    /// Its standard error (the tests' scatter / sqrt(tests)), N.
    pub asymmetry_standard_error_n: f64,
    /// The 95 % two-sided Student t quantile the asymmetry is judged against (tests - 1 degrees of freedom).
    pub t_quantile: f64,
    /// Whether the data show the asymmetry: |mean| > t_quantile x its standard error.
    pub shown: bool,
    /// RMS on the cell means (zeros from the rest readings) of the per-direction law, N.
    pub rms_cell_means_n: f64,
    /// The same of the symmetric law `s (F_c0 + k_p p)` with the same zeros, N.
    pub rms_cell_means_symmetric_n: f64,
    /// Symmetric F_c0 and k_p with those zeros (N, N/Pa).
    pub symmetric: [f64; 2],
    /// Per cell (+ first per test): cell mean minus its zero minus the per-direction law, N.
    pub residuals_n: Vec<f64>,
    /// The same for the symmetric law, N.
    pub residuals_symmetric_n: Vec<f64>,
}

/// The two-sided 95 % quantile of Student's t with `dof` degrees of freedom: the table's up to 10, then the
/// Cornish-Fisher expansion about the normal's 1.96 (2.2010 at 11, 2.0423 at 30: within 0.05 % there).
fn t_975(dof: usize) -> f64 {
    const TABLE: [f64; 10] = [
        12.7062, 4.3027, 3.1824, 2.7764, 2.5706, 2.4469, 2.3646, 2.3060, 2.2622, 2.2281,
    ];
    if (1..=10).contains(&dof) {
        return TABLE[dof - 1];
    }
    let z = 1.959_963_984_540_054f64;
    let n = dof.max(1) as f64;
    z + (z.powi(3) + z) / (4.0 * n)
        + (5.0 * z.powi(5) + 16.0 * z.powi(3) + 3.0 * z) / (96.0 * n * n)
        + (3.0 * z.powi(7) + 19.0 * z.powi(5) + 17.0 * z.powi(3) - 15.0 * z) / (384.0 * n.powi(3))
}

/// The per-direction fit ([`DirectionFit`]) of the cells (+ then - per test), zeros `rest` per test.
fn fit_directions(cells: &[Cell], rest: &[f64]) -> Result<DirectionFit, IdentifyError> {
    let y = DVector::from_iterator(
        cells.len(),
        cells.iter().map(|c| c.mean_friction_n - rest[c.test]),
    );
    let rows = |c: &Cell| -> Vec<f64> {
        if c.direction > 0.0 {
            vec![1.0, 0.0, c.mean_gauge_pa]
        } else {
            vec![0.0, -1.0, -c.mean_gauge_pa]
        }
    };
    let x = DMatrix::from_fn(cells.len(), 3, |i, j| rows(&cells[i])[j]);
    let names = ["F_c+".to_string(), "F_c-".into(), "k_p p".into()];
    let b = least_squares(&x, &y, &names)?;
    let xs = DMatrix::from_fn(cells.len(), 2, |i, j| {
        let c = &cells[i];
        [c.direction, c.direction * c.mean_gauge_pa][j]
    });
    let bs = least_squares(&xs, &y, &names[..2])?;
    let residuals_n: Vec<f64> = (&y - &x * &b).iter().copied().collect();
    let residuals_symmetric_n: Vec<f64> = (&y - &xs * &bs).iter().copied().collect();
    let rms = |r: &[f64]| (r.iter().map(|e| e * e).sum::<f64>() / r.len().max(1) as f64).sqrt();
    let tests = rest.len();
    let asymmetry_per_test_n: Vec<f64> = (0..tests)
        .map(|i| {
            cells
                .iter()
                .filter(|c| c.test == i)
                .map(|c| c.mean_friction_n - rest[i])
                .sum()
        })
        .collect();
    let mean = asymmetry_per_test_n.iter().sum::<f64>() / tests as f64;
    let var = asymmetry_per_test_n
        .iter()
        .map(|a| (a - mean).powi(2))
        .sum::<f64>()
        / (tests.max(2) - 1) as f64;
    let se = (var / tests as f64).sqrt();
    let t_quantile = t_975(tests.saturating_sub(1));
    Ok(DirectionFit {
        coulomb_positive_n: b[0],
        coulomb_negative_n: b[1],
        coulomb_pressure_n_per_pa: b[2],
        asymmetry_n: mean,
        asymmetry_standard_error_n: se,
        t_quantile,
        shown: tests >= 2 && mean.abs() > t_quantile * se,
        asymmetry_per_test_n,
        rms_cell_means_n: rms(&residuals_n),
        rms_cell_means_symmetric_n: rms(&residuals_symmetric_n),
        symmetric: [bs[0], bs[1]],
        residuals_n,
        residuals_symmetric_n,
    })
}

fn log_err(
    file: &Path,
    line: Option<usize>,
    column: Option<&str>,
    message: String,
) -> IdentifyError {
    IdentifyError::Log {
        file: file.to_path_buf(),
        line,
        column: column.map(str::to_string),
        message,
    }
}

/// The columns of a friction file, in order.
const COLUMNS: [&str; 7] = [
    "time_ms",
    "laser_v",
    "pressure_v",
    "force_v",
    "position_mm",
    "pressure_bar",
    "force_n",
];

/// What a bench's sensors read at most: a reading beyond is a unit mistake (Pa or mbar where bar is
/// expected) or a corrupt row, refused at its line and column (`--max-pressure-bar`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sensors {
    /// The pressure sensor's full scale, Pa gauge (default 16 bar).
    pub max_gauge_pa: f64,
    /// The load cell's full scale, N (default 1e5 N).
    pub max_force_n: f64,
}

impl Default for Sensors {
    fn default() -> Self {
        Self {
            max_gauge_pa: 16e5,
            max_force_n: 1e5,
        }
    }
}

/// A number as a message shows it: plain in the range of readings, else in exponent form (1e300, not 301
/// digits).
pub fn shown(v: f64) -> String {
    if v == 0.0 || (1e-4..1e6).contains(&v.abs()) {
        format!("{v}")
    } else {
        format!("{v:e}")
    }
}

/// A gauge pressure below this is below vacuum (absolute 0 at sea level, with room for an offset), Pa.
pub const MIN_GAUGE_PA: f64 = -1.1e5;
/// The largest |position| of a bench's rod, mm (as a rig log's: 10 m).
const MAX_POSITION_MM: f64 = 1e4;
/// A reading further from its file's median than this many times (its middle half's spread + the floor
/// below) is a glitch, not a measurement: one such cell moves a cell mean by its size over the samples.
const SPIKE_SPREADS: f64 = 10.0;

/// Reads one friction file (whitespace-separated, seven numbers a row, blank lines skipped), with the
/// default [`Sensors`] and the held pressure `nominal_pa` it must show.
pub fn read_seal_test(path: &Path, nominal_pa: f64) -> Result<SealTest, IdentifyError> {
    read_seal_test_with(path, Some(nominal_pa), &Sensors::default())
}

/// The shortest test or decay log, s: strokes and decays take seconds.
pub const MIN_SPAN_S: f64 = 1.0;
/// The fastest mean speed of a cell, m/s: no seal bench drives a rod faster (a time or position unit slip).
const MAX_CELL_SPEED_M_PER_S: f64 = 5.0;

/// The sample period's plausible range, s (a time in another unit, a corrupt clock).
pub const PERIOD_RANGE_S: (f64, f64) = (1e-5, 1.0);

/// The median of `v`, and the spread of its middle half (interquartile range).
fn median_spread(v: &[f64]) -> (f64, f64) {
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    let q = |f: f64| s[((s.len() - 1) as f64 * f).round() as usize];
    (q(0.5), q(0.75) - q(0.25))
}

/// The first value of `v` further from its median than [`SPIKE_SPREADS`] times (its spread + `floor`):
/// its index, the median and the bound.
pub(crate) fn spike(v: &[f64], floor: f64) -> Option<(usize, f64, f64)> {
    if v.is_empty() {
        return None;
    }
    let (m, iqr) = median_spread(v);
    let bound = SPIKE_SPREADS * (iqr + floor);
    v.iter()
        .position(|x| (x - m).abs() > bound)
        .map(|i| (i, m, bound))
}

/// [`read_seal_test`] against `sensors`; `nominal_pa` None takes the held pressure from the readings
/// (their median). Every reading is checked against the sensors' range, the time's period against
/// [`PERIOD_RANGE_S`], a single reading far from the rest is refused at its line, and the readings'
/// median must be the held pressure the file is named or listed with.
pub fn read_seal_test_with(
    path: &Path,
    nominal_pa: Option<f64>,
    sensors: &Sensors,
) -> Result<SealTest, IdentifyError> {
    let text = pneuflex_files::read_text(path, pneuflex_files::InputKind::Trace)
        .map_err(|e| IdentifyError::Input(e.to_string()))?;
    let mut test = SealTest {
        file: path.to_path_buf(),
        nominal_pa: nominal_pa.unwrap_or(f64::NAN),
        t_s: Vec::new(),
        x_m: Vec::new(),
        gauge_pa: Vec::new(),
        force_n: Vec::new(),
    };
    let mut lines = Vec::new();
    for (i, line) in text.lines().enumerate() {
        if line.trim().is_empty() {
            continue;
        }
        let row = parse_row(path, i + 1, line)?;
        let t = row[0] * 1e-3;
        if test.t_s.last().is_some_and(|&last| t <= last) {
            return Err(log_err(
                path,
                Some(i + 1),
                Some(COLUMNS[0]),
                format!("time {} ms does not increase", row[0]),
            ));
        }
        let (lo, hi) = (MIN_GAUGE_PA / 1e5, sensors.max_gauge_pa / 1e5);
        if !(lo..=hi).contains(&row[5]) {
            return Err(log_err(
                path,
                Some(i + 1),
                Some(COLUMNS[5]),
                format!(
                    "{} bar gauge: outside the pressure sensor's range [{lo}, {hi}] bar (a column in Pa, kPa or \
                     mbar? a sensor of a larger range: --max-pressure-bar)",
                    shown(row[5])
                ),
            ));
        }
        if row[6].abs() > sensors.max_force_n {
            return Err(log_err(
                path,
                Some(i + 1),
                Some(COLUMNS[6]),
                format!(
                    "{:e} N: beyond a bench load cell's {:e} N",
                    row[6], sensors.max_force_n
                ),
            ));
        }
        if row[4].abs() > MAX_POSITION_MM {
            return Err(log_err(
                path,
                Some(i + 1),
                Some(COLUMNS[4]),
                format!(
                    "{:e} mm: beyond {MAX_POSITION_MM} mm, no rod's travel",
                    row[4]
                ),
            ));
        }
        lines.push(i + 1);
        test.t_s.push(t);
        test.x_m.push(row[4] * 1e-3);
        test.gauge_pa.push(row[5] * 1e5);
        test.force_n.push(row[6]);
    }
    if test.t_s.len() < 10 {
        return Err(log_err(
            path,
            None,
            None,
            format!("{} rows: a friction test needs many", test.t_s.len()),
        ));
    }
    let steps: Vec<f64> = test.t_s.windows(2).map(|w| w[1] - w[0]).collect();
    let period = median_spread(&steps).0;
    let (lo, hi) = PERIOD_RANGE_S;
    if !(lo..=hi).contains(&period) {
        return Err(log_err(
            path,
            Some(lines[1]),
            Some(COLUMNS[0]),
            format!(
                "the median sample period is {period:.3e} s, outside [{lo:e}, {hi}] s: no bench samples at that \
                 rate (the time is read in ms)"
            ),
        ));
    }
    // A test of strokes lasts seconds: less is a time in another unit (s read as ms).
    let span = test.t_s[test.t_s.len() - 1] - test.t_s[0];
    if span < MIN_SPAN_S {
        return Err(log_err(
            path,
            Some(lines[lines.len() - 1]),
            Some(COLUMNS[0]),
            format!(
                "the test spans {span:.3e} s: strokes of a rod take seconds (the time is read in ms; one in s \
                 would span a thousandth)"
            ),
        ));
    }
    for (column, v, floor, unit, scale) in [
        (6, &test.force_n, 1.0, "N", 1.0),
        (5, &test.gauge_pa, 0.1e5, "bar", 1e-5),
    ] {
        if let Some((k, m, bound)) = spike(v, floor) {
            return Err(log_err(
                path,
                Some(lines[k]),
                Some(COLUMNS[column]),
                format!(
                    "{} {unit} is {:.3} {unit} from the file's median {:.3} {unit}, beyond {:.3} {unit} (10 times \
                     the spread of its middle half): a glitch or a corrupt row, not a reading",
                    shown(v[k] * scale),
                    (v[k] - m).abs() * scale,
                    m * scale,
                    bound * scale
                ),
            ));
        }
    }
    let held = median_spread(&test.gauge_pa).0;
    match nominal_pa {
        None => test.nominal_pa = held,
        Some(n) if (held - n).abs() > (0.3e5f64).max(0.15 * n.abs()) => {
            return Err(log_err(
                path,
                None,
                Some(COLUMNS[5]),
                format!(
                    "the pressure reads {:.3} bar (median) where the test is named or listed at {} bar: a column \
                     in another unit, or the wrong file",
                    held / 1e5,
                    n / 1e5
                ),
            ));
        }
        Some(_) => {}
    }
    Ok(test)
}

fn parse_row(path: &Path, line_no: usize, line: &str) -> Result<[f64; 7], IdentifyError> {
    let fields: Vec<&str> = line.split_whitespace().collect();
    if fields.len() != COLUMNS.len() {
        return Err(log_err(
            path,
            Some(line_no),
            None,
            format!(
                "expected {} whitespace-separated numbers ({}), got {}",
                COLUMNS.len(),
                COLUMNS.join(", "),
                fields.len()
            ),
        ));
    }
    let mut row = [0.0; 7];
    for (j, f) in fields.iter().enumerate() {
        row[j] = f
            .parse::<f64>()
            .ok()
            .filter(|v| v.is_finite())
            .ok_or_else(|| {
                log_err(
                    path,
                    Some(line_no),
                    Some(COLUMNS[j]),
                    format!("not a finite number: {f:?}"),
                )
            })?;
    }
    Ok(row)
}

/// The held pressure of a file named `<seal>_<P>bar.csv` (P in bar gauge: digits with at most one '.'),
/// and the seal's name; None for another name.
pub fn seal_file_name(name: &str) -> Option<(&str, f64)> {
    let stem = name.strip_suffix("bar.csv")?;
    let (seal, bar) = stem.rsplit_once('_')?;
    let digits = |g: &str| !g.is_empty() && g.bytes().all(|b| b.is_ascii_digit());
    let ok = match bar.split_once('.') {
        Some((a, b)) => digits(a) && digits(b),
        None => digits(bar),
    };
    (!seal.is_empty() && ok)
        .then(|| bar.parse::<f64>().ok())
        .flatten()
        .map(|p| (seal, p * 1e5))
}

/// The tests of one seal in `dir` (or its `friction/` folder): every `<seal>_<P>bar.csv`, by pressure.
/// `seal` picks one when the folder holds several seals' tests; a file that ends in `bar.csv` without the
/// naming is refused (it would be left out without a word).
pub fn find_seal_tests(
    dir: &Path,
    seal: Option<&str>,
) -> Result<Vec<(PathBuf, f64)>, IdentifyError> {
    let sub = dir.join("friction");
    let dir = if sub.is_dir() { sub } else { dir.to_path_buf() };
    let entries = std::fs::read_dir(&dir)
        .map_err(|e| IdentifyError::Input(format!("{}: cannot read: {e}", dir.display())))?;
    let mut found: Vec<(String, f64, PathBuf)> = Vec::new();
    for e in entries.flatten() {
        let name = e.file_name().to_string_lossy().into_owned();
        match seal_file_name(&name) {
            Some((s, p)) => found.push((s.to_string(), p, e.path())),
            None if name.ends_with("bar.csv") => {
                return Err(IdentifyError::Input(format!(
                    "{}: not named <seal>_<P>bar.csv (P the held pressure in bar gauge, digits with at most one \
                     '.', e.g. circle_2.5bar.csv): rename it, or list the tests with --test FILE=P",
                    e.path().display()
                )));
            }
            None => {}
        }
    }
    let mut seals: Vec<&str> = found.iter().map(|f| f.0.as_str()).collect();
    seals.sort_unstable();
    seals.dedup();
    let count = |s: &str| found.iter().filter(|f| f.0 == s).count();
    let listed = || {
        seals
            .iter()
            .map(|s| format!("{s} ({} files)", count(s)))
            .collect::<Vec<_>>()
            .join(", ")
    };
    let chosen = match seal {
        Some(s) if seals.contains(&s) => s.to_string(),
        Some(s) => {
            return Err(IdentifyError::Input(format!(
                "--seal {s}: {} has no test {s}_<P>bar.csv; its seals: {}",
                dir.display(),
                if seals.is_empty() {
                    "none".into()
                } else {
                    listed()
                }
            )));
        }
        None => match seals.as_slice() {
            [one] => one.to_string(),
            [] => {
                return Err(IdentifyError::Input(format!(
                    "{}: no friction test (<seal>_<P>bar.csv, e.g. circle_3bar.csv) in it",
                    dir.display()
                )));
            }
            _ => {
                return Err(IdentifyError::Input(format!(
                    "{}: the tests of {} seals, {}: choose one with --seal NAME",
                    dir.display(),
                    seals.len(),
                    listed()
                )));
            }
        },
    };
    let mut tests: Vec<(PathBuf, f64)> = found
        .into_iter()
        .filter(|f| f.0 == chosen)
        .map(|f| (f.2, f.1))
        .collect();
    tests.sort_by(|a, b| a.1.total_cmp(&b.1).then_with(|| a.0.cmp(&b.0)));
    Ok(tests)
}

/// The friction tests in `dir` (or its `friction/` folder): every `<seal>_<P>bar.csv` of its one seal, by
/// pressure ([`find_seal_tests`], [`read_seal_list`]).
pub fn read_seal_tests(dir: &Path) -> Result<Vec<SealTest>, IdentifyError> {
    let list: Vec<(PathBuf, Option<f64>)> = find_seal_tests(dir, None)?
        .into_iter()
        .map(|(f, p)| (f, Some(p)))
        .collect();
    read_seal_list(&list, &Sensors::default())
}

/// Reads the tests `(file, held pressure Pa gauge or None: from the readings)` in order; the same file
/// twice (by path or by content) is refused with both.
pub fn read_seal_list(
    list: &[(PathBuf, Option<f64>)],
    sensors: &Sensors,
) -> Result<Vec<SealTest>, IdentifyError> {
    let mut tests: Vec<SealTest> = Vec::with_capacity(list.len());
    let mut real: Vec<PathBuf> = Vec::new();
    for (file, nominal) in list {
        let canonical = std::fs::canonicalize(file).unwrap_or_else(|_| file.clone());
        if let Some(k) = real.iter().position(|r| *r == canonical) {
            return Err(IdentifyError::Input(format!(
                "{}: given twice (also as {}): each test once",
                file.display(),
                tests[k].file.display()
            )));
        }
        let test = read_seal_test_with(file, *nominal, sensors)?;
        if let Some(twin) = tests
            .iter()
            .find(|t| t.t_s == test.t_s && t.force_n == test.force_n && t.gauge_pa == test.gauge_pa)
        {
            return Err(IdentifyError::Input(format!(
                "{}: the same measurements as {}: one test counted twice would weigh its cells double",
                file.display(),
                twin.file.display()
            )));
        }
        real.push(canonical);
        tests.push(test);
    }
    Ok(tests)
}

/// The median of `w` (a short window).
fn median(w: &[f64]) -> f64 {
    let mut v = w.to_vec();
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// The moving samples of test `index` (module doc).
pub fn moving_samples(test: &SealTest, index: usize, o: &SealOptions) -> Vec<Sample> {
    let start = o.skip_rows.min(test.t_s.len());
    let (t, x) = (&test.t_s[start..], &test.x_m[start..]);
    let (m, h) = (o.median_half_width, o.velocity_half_width);
    let n = t.len();
    if n < 2 * (m + h) + 1 {
        return Vec::new();
    }
    let xm: Vec<f64> = (m..n - m).map(|i| median(&x[i - m..=i + m])).collect();
    let area = o.area_m2();
    let mut out = Vec::new();
    for i in (m + h)..(n - m - h) {
        // xm[j] is the median at row j + m.
        let v = (xm[i + h - m] - xm[i - h - m]) / (t[i + h] - t[i - h]);
        if v.abs() < o.still_below_m_per_s {
            continue;
        }
        let k = start + i;
        out.push(Sample {
            test: index,
            direction: v.signum(),
            gauge_pa: test.gauge_pa[k],
            velocity_m_per_s: v,
            friction_n: test.force_n[k] - test.gauge_pa[k] * area,
            t_s: test.t_s[k],
        });
    }
    out
}

/// Mean, sample standard deviation and least-squares slope against `t` of `f`.
fn stats(f: &[f64], t: &[f64]) -> (f64, f64, f64) {
    let n = f.len() as f64;
    let mean = f.iter().sum::<f64>() / n;
    let var = f.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0).max(1.0);
    let mt = t.iter().sum::<f64>() / n;
    let stt: f64 = t.iter().map(|v| (v - mt).powi(2)).sum();
    let sft: f64 = t.iter().zip(f).map(|(a, b)| (a - mt) * (b - mean)).sum();
    let slope = if stt > 0.0 { sft / stt } else { 0.0 };
    (mean, var.sqrt(), slope)
}

fn cell(index: usize, test: &SealTest, direction: f64, s: &[&Sample]) -> Cell {
    let f: Vec<f64> = s.iter().map(|s| s.friction_n).collect();
    let t: Vec<f64> = s.iter().map(|s| s.t_s).collect();
    let (mean, std, drift) = stats(&f, &t);
    let n = s.len() as f64;
    let cov: f64 = f.windows(2).map(|w| (w[0] - mean) * (w[1] - mean)).sum();
    let r1 = (cov / (std * std * (n - 1.0))).clamp(-0.99, 0.99);
    Cell {
        test: index,
        file: test
            .file
            .file_name()
            .map_or_else(String::new, |n| n.to_string_lossy().into_owned()),
        nominal_pa: test.nominal_pa,
        direction,
        samples: s.len(),
        mean_friction_n: mean,
        std_friction_n: std,
        mean_gauge_pa: s.iter().map(|s| s.gauge_pa).sum::<f64>() / n,
        mean_velocity_m_per_s: s.iter().map(|s| s.velocity_m_per_s).sum::<f64>() / n,
        drift_n_per_s: drift,
        effective_samples: n * (1.0 - r1) / (1.0 + r1),
    }
}

/// The regressors of a law at direction `s`, pressure `p` (Pa) and test `i` of `tests`: `[s, s p, offsets]`.
fn regressors(
    pressure: bool,
    offsets: Offsets,
    tests: usize,
    s: f64,
    p: f64,
    i: usize,
) -> Vec<f64> {
    let mut r = vec![s];
    if pressure {
        r.push(s * p);
    }
    match offsets {
        Offsets::None => {}
        Offsets::Common => r.push(1.0),
        Offsets::PerTest => r.extend((0..tests).map(|j| if j == i { 1.0 } else { 0.0 })),
    }
    r
}

/// Least squares `X b = y` with the columns scaled to unit norm (p in Pa is 1e5 times s); an error names
/// what the data cannot separate when X is rank-deficient.
fn least_squares(
    x: &DMatrix<f64>,
    y: &DVector<f64>,
    names: &[String],
) -> Result<DVector<f64>, IdentifyError> {
    let scale: Vec<f64> = (0..x.ncols())
        .map(|j| x.column(j).norm().max(f64::MIN_POSITIVE))
        .collect();
    let mut xs = x.clone();
    for (j, s) in scale.iter().enumerate() {
        xs.column_mut(j).unscale_mut(*s);
    }
    let svd = xs.clone().svd(true, true);
    let (max, min) = (svd.singular_values.max(), svd.singular_values.min());
    if x.nrows() < x.ncols() || min <= 1e-10 * max {
        return Err(IdentifyError::Fit(format!(
            "the friction law ({}) cannot be fitted: the cells do not separate its terms (rank-deficient: \
             {} cells for {} terms, condition {:.1e}); a pressure term needs tests at two pressures or more, \
             a per-test offset both directions in every test",
            names.join(", "),
            x.nrows(),
            x.ncols(),
            max / min.max(f64::MIN_POSITIVE)
        )));
    }
    let b = svd
        .solve(y, 0.0)
        .map_err(|e| IdentifyError::Fit(e.to_string()))?;
    Ok(DVector::from_iterator(
        b.len(),
        b.iter().zip(&scale).map(|(b, s)| b / s),
    ))
}

/// Fits one law to the cells; residuals against the cells and the samples.
pub fn fit_law(
    pressure: bool,
    offsets: Offsets,
    tests: usize,
    cells: &[Cell],
    samples: &[Sample],
) -> Result<LawFit, IdentifyError> {
    let rows: Vec<Vec<f64>> = cells
        .iter()
        .map(|c| {
            regressors(
                pressure,
                offsets,
                tests,
                c.direction,
                c.mean_gauge_pa,
                c.test,
            )
        })
        .collect();
    let x = DMatrix::from_fn(rows.len(), rows[0].len(), |i, j| rows[i][j]);
    let y = DVector::from_iterator(cells.len(), cells.iter().map(|c| c.mean_friction_n));
    let mut names = vec!["s F_c".to_string()];
    if pressure {
        names.push("s k_p p".into());
    }
    if offsets != Offsets::None {
        names.push("offsets".into());
    }
    let b = least_squares(&x, &y, &names)?;
    let law = |s: f64, p: f64, i: usize| {
        regressors(pressure, offsets, tests, s, p, i)
            .iter()
            .zip(b.iter())
            .map(|(r, b)| r * b)
            .sum::<f64>()
    };
    let lead = if pressure { 2 } else { 1 };
    let mut fit = LawFit {
        pressure_term: pressure,
        offsets,
        coulomb_n: b[0],
        coulomb_pressure_n_per_pa: if pressure { b[1] } else { 0.0 },
        offset_n: b.iter().skip(lead).copied().collect(),
        rms_cell_means_n: 0.0,
        rms_samples_n: 0.0,
        residuals: Vec::new(),
    };
    residuals(&mut fit, cells, samples, &law);
    Ok(fit)
}

fn residuals(
    fit: &mut LawFit,
    cells: &[Cell],
    samples: &[Sample],
    law: &dyn Fn(f64, f64, usize) -> f64,
) {
    let (mut sum_m, mut sum_s, mut n_s) = (0.0, 0.0, 0usize);
    for c in cells {
        let i = c.test;
        let r = c.mean_friction_n - law(c.direction, c.mean_gauge_pa, i);
        let own: Vec<f64> = samples
            .iter()
            .filter(|s| s.test == i && s.direction == c.direction)
            .map(|s| s.friction_n - law(s.direction, s.gauge_pa, i))
            .collect();
        let ss: f64 = own.iter().map(|e| e * e).sum();
        sum_m += r * r;
        sum_s += ss;
        n_s += own.len();
        fit.residuals.push(CellResidual {
            nominal_pa: c.nominal_pa,
            direction: c.direction,
            mean_residual_n: r,
            rms_samples_n: (ss / own.len().max(1) as f64).sqrt(),
            standard_errors: r / c.standard_error_n(),
        });
    }
    fit.rms_cell_means_n = (sum_m / cells.len() as f64).sqrt();
    fit.rms_samples_n = (sum_s / n_s.max(1) as f64).sqrt();
}

/// The cells of every test, + direction first; an error names a test without motion in a direction.
pub fn cells(tests: &[SealTest], samples: &[Sample]) -> Result<Vec<Cell>, IdentifyError> {
    let mut out = Vec::new();
    for (i, t) in tests.iter().enumerate() {
        for d in [1.0, -1.0] {
            let own: Vec<&Sample> = samples
                .iter()
                .filter(|s| s.test == i && s.direction == d)
                .collect();
            if own.len() < 2 {
                return Err(IdentifyError::Fit(format!(
                    "{}: {} moving samples towards {} x: a friction law needs both directions in every test (the \
                     position is read in mm; samples slower than --still-below are left out)",
                    t.file.display(),
                    own.len(),
                    if d > 0.0 { "+" } else { "-" }
                )));
            }
            out.push(cell(i, t, d, &own));
        }
    }
    Ok(out)
}

/// Whether `fit` explains the cell means to their standard errors (3 sigma).
fn adequacy(fit: &LawFit, cells: &[Cell], samples: &[Sample]) -> Adequacy {
    let worst = fit
        .residuals
        .iter()
        .max_by(|a, b| a.standard_errors.abs().total_cmp(&b.standard_errors.abs()))
        .expect("cells");
    let within: f64 = samples
        .iter()
        .map(|s| {
            let c = cells
                .iter()
                .find(|c| c.test == s.test && c.direction == s.direction)
                .expect("a cell per test and direction");
            (s.friction_n - c.mean_friction_n).powi(2)
        })
        .sum();
    let within = (within / samples.len() as f64).sqrt();
    let drift = cells
        .iter()
        .max_by(|a, b| a.drift_n_per_s.abs().total_cmp(&b.drift_n_per_s.abs()))
        .expect("cells");
    let adequate = worst.standard_errors.abs() <= 3.0;
    let verdict = if adequate {
        format!(
            "the law explains every cell mean within 3 standard errors (worst {:.1})",
            worst.standard_errors.abs()
        )
    } else {
        format!(
            "the law does not explain the data to its precision: the cell at {:.0} bar, {} x is off by \
             {:+.3} N, {:.0} standard errors of its mean (from its effective samples); the cell means differ from the law by {:.3} N RMS, more than \
             pressure and direction explain. The friction drifts within a run by up to {:+.2} N/min ({:.0} \
             bar, {} x), and the samples scatter {:.3} N RMS about their own cell means",
            worst.nominal_pa / 1e5,
            if worst.direction > 0.0 { "+" } else { "-" },
            worst.mean_residual_n,
            worst.standard_errors.abs(),
            fit.rms_cell_means_n,
            60.0 * drift.drift_n_per_s,
            drift.nominal_pa / 1e5,
            if drift.direction > 0.0 { "+" } else { "-" },
            within
        )
    };
    Adequacy {
        adequate,
        worst_standard_errors: worst.standard_errors.abs(),
        worst_pa: worst.nominal_pa,
        worst_direction: worst.direction,
        within_cell_rms_n: within,
        verdict,
    }
}

/// The checks a fitted seal must pass to be a seal's friction: each cell's friction within the force the
/// load cell read, a Coulomb force that opposes the motion at every tested pressure, and offsets that do
/// not grow with the pressure as a wrong piston area makes them.
fn plausible(
    tests: &[SealTest],
    cells: &[Cell],
    law: &LawFit,
    o: &SealOptions,
) -> Result<(), IdentifyError> {
    let area = o.area_m2();
    let hint = format!(
        "A = {area:.4e} m^2 from --bore-m {} (m, not mm); check it and the pressure's and force's units and sign",
        o.bore_m
    );
    for c in cells {
        let t = &tests[c.test];
        if c.mean_velocity_m_per_s.abs() > MAX_CELL_SPEED_M_PER_S {
            return Err(IdentifyError::Fit(format!(
                "{}: the rod moves at {:.3} m/s on average towards {} x, faster than any seal bench drives it \
                 ({MAX_CELL_SPEED_M_PER_S} m/s): the time is read in ms and the position in mm",
                t.file.display(),
                c.mean_velocity_m_per_s,
                if c.direction > 0.0 { "+" } else { "-" }
            )));
        }
        let start = o.skip_rows.min(t.force_n.len());
        let max_f = t.force_n[start..]
            .iter()
            .fold(0.0f64, |m, f| m.max(f.abs()));
        if c.mean_friction_n.abs() > max_f {
            return Err(IdentifyError::Fit(format!(
                "{}: the friction F - p A averages {:.4} N towards {} x, more than the largest force the load \
                 cell read ({:.4} N), with p A = {:.4} N at its mean pressure: {hint}",
                t.file.display(),
                c.mean_friction_n,
                if c.direction > 0.0 { "+" } else { "-" },
                max_f,
                c.mean_gauge_pa * area
            )));
        }
    }
    for (i, t) in tests.iter().enumerate() {
        let p = 0.5 * (cells[2 * i].mean_gauge_pa + cells[2 * i + 1].mean_gauge_pa);
        let f = law.coulomb_at(p);
        if f <= 0.0 {
            return Err(IdentifyError::Fit(format!(
                "{}: the fitted Coulomb force at {:.3} bar is {f:.4} N: friction that pushes the rod along its \
                 motion is no seal's; {hint}",
                t.file.display(),
                p / 1e5
            )));
        }
    }
    // F = p A_true + f + o: with the wrong A, F - p A carries p (A_true - A), which per-test offsets take up
    // as a slope against the pressure.
    if law.offsets == Offsets::PerTest && tests.len() >= 2 {
        let p: Vec<f64> = (0..tests.len())
            .map(|i| 0.5 * (cells[2 * i].mean_gauge_pa + cells[2 * i + 1].mean_gauge_pa))
            .collect();
        let span = p.iter().fold(f64::NEG_INFINITY, |a, &b| a.max(b))
            - p.iter().fold(f64::INFINITY, |a, &b| a.min(b));
        // Judged where the offsets' change across the tests stands out of their scatter (~1 N here).
        let coulomb =
            cells.iter().map(|c| c.mean_friction_n.abs()).sum::<f64>() / cells.len() as f64;
        if span > 0.0 {
            let n = p.len() as f64;
            let (mp, mo) = (
                p.iter().sum::<f64>() / n,
                law.offset_n.iter().sum::<f64>() / n,
            );
            let spp: f64 = p.iter().map(|v| (v - mp).powi(2)).sum();
            let slope = p
                .iter()
                .zip(&law.offset_n)
                .map(|(a, b)| (a - mp) * (b - mo))
                .sum::<f64>()
                / spp;
            if slope.abs() > 0.1 * area && slope.abs() * span > (0.5 * coulomb).max(1.0) {
                let fits = area + slope;
                let bore = if fits > 0.0 {
                    format!(
                        "a bore of {:.1} mm fits them",
                        1e3 * (4.0 * fits / core::f64::consts::PI).sqrt()
                    )
                } else {
                    "no area fits them".into()
                };
                return Err(IdentifyError::Fit(format!(
                    "the zero offsets of F - p A change by {:+.3} N/bar with the pressure over the tests ({}): a piston \
                     area {:.0} % off would do that ({bore}); {hint}",
                    slope * 1e5,
                    tests
                        .iter()
                        .map(|t| t
                            .file
                            .file_name()
                            .unwrap_or_default()
                            .to_string_lossy()
                            .into_owned())
                        .collect::<Vec<_>>()
                        .join(", "),
                    100.0 * slope / area
                )));
            }
        }
    }
    Ok(())
}

/// Fits the seal's friction laws to the tests (module doc).
pub fn fit_seal(tests: &[SealTest], o: &SealOptions) -> Result<SealReport, IdentifyError> {
    o.check()?;
    // The pressure term and the per-test offsets need two held pressures: say which tests were given.
    if let Some(first) = tests.first()
        && tests
            .iter()
            .all(|t| (t.nominal_pa - first.nominal_pa).abs() < 1e3)
    {
        return Err(IdentifyError::Fit(format!(
            "{} test(s), all at {:.3} bar ({}): a friction law of the pressure cannot be fitted; it needs \
             tests at two held pressures or more",
            tests.len(),
            first.nominal_pa / 1e5,
            tests
                .iter()
                .map(|t| t.file.display().to_string())
                .collect::<Vec<_>>()
                .join(", ")
        )));
    }
    let samples: Vec<Sample> = tests
        .iter()
        .enumerate()
        .flat_map(|(i, t)| moving_samples(t, i, o))
        .collect();
    let cells = cells(tests, &samples)?;
    let n = tests.len();
    let constant = fit_law(false, Offsets::PerTest, n, &cells, &samples)?;
    let pressure = fit_law(true, Offsets::PerTest, n, &cells, &samples)?;
    plausible(tests, &cells, &pressure, o)?;
    let adequacy = adequacy(&pressure, &cells, &samples);
    let rest: Vec<f64> = tests
        .iter()
        .map(|t| t.force_n[0] - t.gauge_pa[0] * o.area_m2())
        .collect();
    let rest_minus_midline_n = (0..n)
        .map(|i| {
            let mid = 0.5 * (cells[2 * i].mean_friction_n + cells[2 * i + 1].mean_friction_n);
            rest[i] - mid
        })
        .collect();
    Ok(SealReport {
        rest_minus_midline_n,
        direction: fit_directions(&cells, &rest)?,
        area_m2: o.area_m2(),
        moving_samples: samples.len(),
        constant_no_offset: fit_law(false, Offsets::None, n, &cells, &samples)?,
        pressure_no_offset: fit_law(true, Offsets::None, n, &cells, &samples)?,
        pressure_term_rms_reduction: 1.0 - pressure.rms_cell_means_n / constant.rms_cell_means_n,
        pressure_term_rms_reduction_samples: 1.0 - pressure.rms_samples_n / constant.rms_samples_n,
        cells,
        constant,
        pressure,
        adequacy,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_test_file_is_named_seal_underscore_pressure_bar() {
        assert_eq!(seal_file_name("circle_3bar.csv"), Some(("circle", 3e5)));
        assert_eq!(seal_file_name("o_ring_2.5bar.csv"), Some(("o_ring", 2.5e5)));
        for bad in [
            "circle_bar.csv",
            "_3bar.csv",
            "circle_-1bar.csv",
            "circle_1e300bar.csv",
            "circle_inf bar.csv",
            "circle_1.bar.csv",
            "circle_3bar.txt",
            "circle3bar.csv",
        ] {
            assert_eq!(seal_file_name(bad), None, "{bad}");
        }
    }

    /// The t quantile against the table (two-sided 95 %).
    #[test]
    fn t_quantiles_match_the_table() {
        for (dof, table) in [
            (3, 3.1824),
            (6, 2.4469),
            (11, 2.2010),
            (15, 2.1314),
            (30, 2.0423),
        ] {
            assert!(
                (t_975(dof) / table - 1.0).abs() < 3e-3,
                "{dof}: {}",
                t_975(dof)
            );
        }
    }

    /// A planted asymmetry is found and recovered, and a symmetric seal's is not shown: cells of a law
    /// `F_c+- = F_c0 (+- d) + k_p p` at five pressures, zeros of +-2 N per test, 0.05 N of scatter.
    #[test]
    fn a_planted_asymmetry_is_recovered_and_none_is_not_shown() {
        for delta in [0.0, 0.8] {
            let rest = [1.5, -2.0, 0.3, 2.0, -0.7];
            let mut cells = Vec::new();
            for (i, &r) in rest.iter().enumerate() {
                let p = (i + 1) as f64 * 1e5;
                for (k, d) in [1.0, -1.0].into_iter().enumerate() {
                    let fc = 3.0 + 0.5 * delta * d + 8e-6 * p;
                    let scatter =
                        0.05 * [0.3, -0.8, 1.0, -0.4, 0.6, -1.0, 0.2, 0.9, -0.5, -0.3][2 * i + k];
                    cells.push(Cell {
                        test: i,
                        file: format!("t{i}"),
                        nominal_pa: p,
                        direction: d,
                        samples: 100,
                        mean_friction_n: r + d * fc + scatter,
                        std_friction_n: 0.1,
                        mean_gauge_pa: p,
                        mean_velocity_m_per_s: 0.01 * d,
                        drift_n_per_s: 0.0,
                        effective_samples: 100.0,
                    });
                }
            }
            let f = fit_directions(&cells, &rest).unwrap();
            assert_eq!(f.shown, delta > 0.0, "{f:?}");
            assert!((f.asymmetry_n - delta).abs() < 0.1, "{f:?}");
            assert!(((f.coulomb_positive_n - f.coulomb_negative_n) - delta).abs() < 0.1);
            assert!((f.coulomb_pressure_n_per_pa / 8e-6 - 1.0).abs() < 0.05);
        }
    }

    #[test]
    fn a_glitch_is_found_and_a_spread_of_readings_is_not() {
        let mut v: Vec<f64> = (0..200).map(|k| 50.0 + (k % 9) as f64).collect();
        assert_eq!(spike(&v, 1.0), None);
        v[77] = 2000.0;
        assert_eq!(spike(&v, 1.0).map(|s| s.0), Some(77));
    }
}
