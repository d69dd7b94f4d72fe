//! Whether the rig a datasheet describes can run the experiment: each finding names the option and a value
//! that would work. Errors stop `new rig` before anything is written; warnings go into the report.

use crate::design::{Design, ValveKind};
use crate::iso6358;

/// How serious a finding is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Severity {
    /// The rig cannot run the experiment as given.
    Error,
    /// It can, but a reader should know.
    Warning,
}

/// One finding.
#[derive(Clone, Debug, PartialEq)]
pub struct Finding {
    pub severity: Severity,
    /// The option it is about.
    pub key: &'static str,
    pub message: String,
}

impl std::fmt::Display for Finding {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let s = match self.severity {
            Severity::Error => "error",
            Severity::Warning => "warning",
        };
        write!(f, "{s}: {}: {}", self.key, self.message)
    }
}

/// A valve slower than this (the chamber fill time) cannot follow the experiment's 1 Hz sine.
pub const FILL_TIME_ERROR_S: f64 = 1.0;
/// Slower than this, the valve limits the loop's bandwidth: a warning.
pub const FILL_TIME_WARNING_S: f64 = 0.2;

/// Every check on a design: the errors, then the warnings.
pub fn check(d: &Design) -> Vec<Finding> {
    let mut out = errors(d);
    out.extend(warnings(d));
    out
}

/// What makes the design fail: a sensor that cannot see the stroke or the pressures, a valve too slow for
/// the bore or its PWM period, a load or a force the cylinder cannot hold, no room before the end stop.
fn errors(d: &Design) -> Vec<Finding> {
    let mut out = Vec::new();
    let mut err = |key, message| {
        out.push(Finding {
            severity: Severity::Error,
            key,
            message,
        })
    };
    let mm = |m: f64| m * 1e3;
    // The position sensor must see the whole stroke.
    if d.position_range_m < d.stroke_m {
        err(
            "--position-range",
            format!(
                "{:.1} mm is shorter than the {:.1} mm stroke: the piston leaves the sensor's range; a sensor of at \
                 least {:.0} mm would work (e.g. --position-range {:.0}mm)",
                mm(d.position_range_m),
                mm(d.stroke_m),
                mm(d.stroke_m),
                (mm(d.stroke_m) * 1.2 / 25.0).ceil() * 25.0
            ),
        );
    }
    // The differential transmitter must see the largest chamber difference, the supply's gauge pressure.
    let gauge = d.supply_abs_pa - d.atmosphere_pa;
    if d.pressure_range_pa < gauge {
        err(
            "--pressure-range",
            format!(
                "±{:.2} MPa is less than the {:.2} MPa gauge supply: the transmitter saturates when one chamber is at \
                 supply and the other vented; ±{:.1} MPa would work (--pressure-range {:.1}MPa)",
                d.pressure_range_pa * 1e-6,
                gauge * 1e-6,
                (gauge * 1.1 / 2e5).ceil() * 0.2,
                (gauge * 1.1 / 2e5).ceil() * 0.2
            ),
        );
    }
    // The valve against the bore: the time to fill a chamber.
    let t_fill = d.fill_time_s();
    let qn_for =
        |t: f64| iso6358::qn_from_c(d.conductance_for_fill(t), d.critical_pressure_ratio) * 6e4;
    if t_fill > FILL_TIME_ERROR_S {
        err(
            "--valve-flow",
            format!(
                "the valve fills a chamber at mid stroke in {t_fill:.2} s: too slow for the experiment's 1 Hz sine; \
                 a valve of QN ≥ {:.0} l/min (fill in {:.0} ms) would work",
                qn_for(0.1),
                100.0
            ),
        );
    }
    // Gravity on the incline against the retracting force (the rod side holds the load back).
    let g = d.moving_mass_kg * 9.80665 * d.incline_deg.to_radians().sin();
    let retract = gauge * d.area_b();
    if g.abs() > 0.5 * retract {
        err(
            "--mass",
            format!(
                "gravity along the axis ({:.1} N at {} deg) is over half the {:.1} N the rod side can pull at supply: \
                 the loop has no authority left; under {:.2} kg would work at this incline",
                g.abs(),
                d.incline_deg,
                retract,
                0.5 * retract / (9.80665 * d.incline_deg.to_radians().sin().abs())
            ),
        );
    }
    // The contact force inside the force range.
    let peak = d.force_n + d.sine_amplitude_n;
    if peak > 0.5 * d.force_range_n() {
        err(
            "--force",
            format!(
                "the experiment's largest force {peak:.1} N is over half the {:.1} N force range; at most {:.1} N \
                 would work",
                d.force_range_n(),
                0.5 * d.force_range_n() / (1.0 + crate::design::SINE_OF_FORCE)
            ),
        );
    }
    // End-stop room: the surface and the largest compression inside the stroke.
    let reach = d.surface_m + peak / d.stiffness_n_per_m;
    if reach > 0.9 * d.stroke_m {
        err(
            "--stroke",
            format!(
                "the flange reaches {:.1} mm at the largest force on the softer environment, within 10 % of the \
                 {:.1} mm stroke's end stop; a stroke of {:.0} mm would work",
                mm(reach),
                mm(d.stroke_m),
                (mm(reach) / 0.9).ceil()
            ),
        );
    }
    // An on/off valve must switch well inside its PWM period.
    if d.valve == ValveKind::Pwm && d.switching_delay_s > 0.25 / d.pwm_frequency_hz {
        err(
            "--pwm-frequency",
            format!(
                "a {:.1} ms switching delay is over a quarter of the {:.1} ms PWM period: the valve cannot follow \
                 the duty cycle; at most {:.0} Hz would work",
                d.switching_delay_s * 1e3,
                1e3 / d.pwm_frequency_hz,
                (0.25 / d.switching_delay_s).floor()
            ),
        );
    }
    out
}

/// What works but costs: a valve that limits the bandwidth, friction that dominates the force, a
/// transmitter that uses little of its span.
fn warnings(d: &Design) -> Vec<Finding> {
    let mut out = Vec::new();
    let gauge = d.supply_abs_pa - d.atmosphere_pa;
    let t_fill = d.fill_time_s();
    let qn_for =
        |t: f64| iso6358::qn_from_c(d.conductance_for_fill(t), d.critical_pressure_ratio) * 6e4;
    let mut warn = |key, message| {
        out.push(Finding {
            severity: Severity::Warning,
            key,
            message,
        })
    };
    if (FILL_TIME_WARNING_S..=FILL_TIME_ERROR_S).contains(&t_fill) {
        warn(
            "--valve-flow",
            format!(
                "the valve fills a chamber at mid stroke in {:.0} ms: it limits the loop's bandwidth; QN ≥ {:.0} l/min \
                 fills it in 50 ms",
                t_fill * 1e3,
                qn_for(0.05)
            ),
        );
    }
    if d.force_n < 5.0 * d.coulomb_n {
        warn(
            "--force",
            format!(
                "the contact force {:.1} N is under 5× the {:.1} N Coulomb friction: friction dominates the force \
                 error; {:.1} N or more would not",
                d.force_n,
                d.coulomb_n,
                5.0 * d.coulomb_n
            ),
        );
    }
    if d.pressure_range_pa > 4.0 * gauge {
        warn(
            "--pressure-range",
            format!(
                "±{:.1} MPa is over 4× the {:.2} MPa supply: the transmitter uses a quarter of its span",
                d.pressure_range_pa * 1e-6,
                gauge * 1e-6
            ),
        );
    }
    out
}
