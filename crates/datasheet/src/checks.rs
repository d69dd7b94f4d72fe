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

/// The largest valve `--valve-flow` takes, l/min: suggestions stay within it.
const QN_MAX_L_MIN: f64 = 20_000.0;

/// Coulomb friction over this fraction of the force range is refused.
pub const FRICTION_OF_RANGE: f64 = 0.2;
/// A contact force under this fraction of the force range is refused.
pub const FORCE_FLOOR_OF_RANGE: f64 = 0.01;

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
            d.flow_key,
            format!(
                "the valve fills a chamber at mid stroke ({:.1} cm³, {:.1} of it dead volume) in {t_fill:.2} s: too \
                 slow for the experiment's 1 Hz sine; a valve of QN ≥ {:.0} l/min (fill in {:.0} ms) would work \
                 (--valve-flow {:.0}l/min)",
                (d.area_a() * 0.5 * d.stroke_m + d.dead_volume_a_m3) * 1e6,
                d.dead_volume_a_m3 * 1e6,
                qn_for(0.1).min(QN_MAX_L_MIN),
                (0.1 * qn_for(0.1) / QN_MAX_L_MIN).max(0.1) * 1e3,
                qn_for(0.1).min(QN_MAX_L_MIN).ceil()
            ),
        );
    }
    // The sensors' spans against what they measure: a 12-bit ADC over ten times the stroke or the supply
    // resolves too coarsely for the loop (a count of a 100 mm stroke's 1 m span is 0.24 mm).
    if d.position_range_m > 10.0 * d.stroke_m {
        err(
            "--position-range",
            format!(
                "{:.0} mm is over ten times the {:.0} mm stroke: the 12-bit ADC resolves {:.2} mm a count; a sensor \
                 of {:.0} mm would work (--position-range {:.0}mm)",
                mm(d.position_range_m),
                mm(d.stroke_m),
                mm(d.position_range_m) / 4096.0,
                (mm(d.stroke_m) * 1.2 / 25.0).ceil() * 25.0,
                (mm(d.stroke_m) * 1.2 / 25.0).ceil() * 25.0
            ),
        );
    }
    if d.pressure_range_pa > 10.0 * gauge {
        err(
            "--pressure-range",
            format!(
                "±{:.2} MPa is over ten times the {:.2} MPa gauge supply: the 12-bit ADC resolves {:.0} Pa a count; \
                 ±{:.1} MPa would work (--pressure-range {:.1}MPa)",
                d.pressure_range_pa * 1e-6,
                gauge * 1e-6,
                2.0 * d.pressure_range_pa / 4096.0,
                (gauge * 1.1 / 2e5).ceil() * 0.2,
                (gauge * 1.1 / 2e5).ceil() * 0.2
            ),
        );
    }
    // Everything that moves with the piston weighs at least the rod; on the chambers' air springs it must
    // resonate above the experiment's force loop (the impedance filter's √(700/2) = 18.7 rad/s), or the
    // loop cannot be faster than the load (measured: a 25 mm bore, 100 mm stroke settles with 15 kg, not 30).
    let k_air = d.air_spring_n_per_m();
    let heaviest = k_air / crate::design::PAPER_OMEGA2;
    let rod = d.rod_mass_kg();
    let typical = (rod + d.area_a() * 0.5 * d.bore_m * 2700.0 + 0.5).min(0.8 * heaviest);
    if !d.assumed("--mass") && d.moving_mass_kg < rod {
        err(
            "--mass",
            format!(
                "{} kg is less than the steel rod alone ({:.3} kg: {} mm over the {} mm stroke and the bore); everything \
                 that moves with the piston weighs more, e.g. --mass {}kg",
                d.moving_mass_kg,
                rod,
                crate::design::fmt_mm(d.rod_m),
                crate::design::fmt_mm(d.stroke_m),
                crate::limits::num(crate::design::round2(typical.max(rod * 1.5)))
            ),
        );
    } else if d.moving_mass_kg > heaviest {
        let fix = if d.assumed("--mass") {
            "the mass was assumed (0.5 kg of flange and carriage with the rod and piston): give --mass if yours is \
             lighter, or a shorter --stroke or a larger --bore (stiffer air springs)"
        } else {
            "a lighter load, or a shorter --stroke or a larger --bore (stiffer air springs)"
        };
        err(
            "--mass",
            format!(
                "{} kg on the chambers' air springs ({:.0} N/m at mid stroke) resonates at {:.1} rad/s, under the \
                 experiment's {:.1} rad/s force loop: at most {} kg would work here (--mass {}kg); {fix}",
                d.moving_mass_kg,
                k_air,
                (k_air / d.moving_mass_kg).sqrt(),
                crate::design::PAPER_OMEGA2.sqrt(),
                crate::limits::num(crate::design::round2(0.95 * heaviest)),
                crate::limits::num(crate::design::round2(0.95 * heaviest))
            ),
        );
    }
    // Seal friction is 1–10 % of a cylinder's force (breakaway up to ~15 %); beyond a fifth the force loop
    // has nothing left to control with.
    if d.coulomb_n > FRICTION_OF_RANGE * d.force_range_n() {
        err(
            "--friction",
            format!(
                "{} N is over {:.0} % of the {:.1} N force range (seals take 1–10 %): the cylinder spends its force \
                 on friction; at most {} N would work (--friction {}N)",
                d.coulomb_n,
                FRICTION_OF_RANGE * 100.0,
                d.force_range_n(),
                crate::limits::num(crate::design::round2(0.1 * d.force_range_n())),
                crate::limits::num(crate::design::round2(0.1 * d.force_range_n()))
            ),
        );
    }
    // The end caps leave at least half a millimetre of bore at each end (cushioning and the port).
    let least_dead = d.area_a() * 0.0005;
    if !d.assumed("--dead-volume") && d.dead_volume_a_m3.min(d.dead_volume_b_m3) < least_dead {
        err(
            "--dead-volume",
            format!(
                "{} cm³ is less than half a millimetre of the {} mm bore ({:.3} cm³): the end cap and port alone hold \
                 more; e.g. --dead-volume {}cm3",
                crate::limits::num(d.dead_volume_a_m3 * 1e6),
                crate::design::fmt_mm(d.bore_m),
                least_dead * 1e6,
                crate::limits::num(crate::design::round2(d.area_a() * 0.002 * 1e6 * 2.0))
            ),
        );
    }
    // The contact force against the force range: under 1 % it is lost in the chambers' pressure noise.
    if d.force_n < FORCE_FLOOR_OF_RANGE * d.force_range_n() {
        err(
            "--force",
            format!(
                "{} N is under {:.0} % of the {:.1} N force range: the force is lost in friction and pressure noise; \
                 at least {} N would work (--force {}N)",
                d.force_n,
                FORCE_FLOOR_OF_RANGE * 100.0,
                d.force_range_n(),
                crate::limits::num(crate::design::round2(0.1 * d.force_range_n())),
                crate::limits::num(crate::design::round2(0.1 * d.force_range_n()))
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
        let period = format!(
            "a {:.1} ms switching delay is over a quarter of the {:.1} ms PWM period: the valve cannot follow \
             the duty cycle",
            d.switching_delay_s * 1e3,
            1e3 / d.pwm_frequency_hz,
        );
        let f_max = (0.25 / d.switching_delay_s).floor();
        let pwm_lo = crate::limits::of("--pwm-frequency").map_or(10.0, |r| r.lo);
        if f_max >= pwm_lo {
            err(
                "--pwm-frequency",
                format!(
                    "{period}; at most {f_max:.0} Hz would work (--pwm-frequency {f_max:.0}Hz)"
                ),
            );
        } else {
            // No carrier the valve can follow is slow enough: the valve is the one to change.
            let t = 0.25e3 / d.pwm_frequency_hz;
            err(
                "--switching-delay",
                format!(
                    "{period}; a valve switching in at most {t:.1} ms would work (--switching-delay {t:.1}ms)"
                ),
            );
        }
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
