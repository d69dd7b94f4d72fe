//! `pneuflex new rig DIR`: a rig from datasheet values (docs/your-rig.md). Quantities take unit suffixes
//! (`25mm`, `6bar`, `200l/min`); every value not given is derived and listed in DIR/README.md.

use std::path::PathBuf;

use clap::{Args, Subcommand, ValueEnum};
use pneuflex_datasheet::units::{Dimension, parse};
use pneuflex_datasheet::{Datasheet, DesignError, FlowRating, ValveKind, limits};

use crate::cmd;

/// Make something new from a few values.
#[derive(Subcommand)]
pub enum NewCommand {
    /// A rig from datasheet values: a commented sheet set, a scene running the paper's experiment on it
    /// with gains checked on the loop and in simulation, and a rig file (docs/your-rig.md).
    Rig(Box<NewRig>),
}

impl NewCommand {
    pub fn call(self) -> anyhow::Result<()> {
        match self {
            NewCommand::Rig(a) => cmd::new_rig::new_rig(&a.datasheet()?, &a.dir),
        }
    }
}

/// The valve kinds.
#[derive(Clone, Copy, ValueEnum)]
pub enum Valve {
    /// A 5/2 on/off solenoid valve under PWM.
    Pwm,
    /// A proportional 5/3 servo valve.
    Proportional,
}

#[derive(Args)]
pub struct NewRig {
    /// The directory to create (it must not exist).
    pub dir: PathBuf,
    /// The rig's name (default: the directory's, or from the sizes, e.g. rig-25x100-pwm).
    #[arg(long, allow_hyphen_values = true)]
    pub name: Option<String>,
    /// Cylinder bore, 8–320 mm, e.g. 25mm.
    #[arg(long, allow_hyphen_values = true)]
    pub bore: Option<String>,
    /// A bore of ISO 15552 (32–320) or ISO 6432 (8–25), mm: sets the bore, rod and port.
    #[arg(long, value_name = "MM", allow_negative_numbers = true)]
    pub iso_bore: Option<f64>,
    /// Piston rod diameter, 10–70 % of the bore (default: the standard rod of the bore).
    #[arg(long, allow_hyphen_values = true)]
    pub rod: Option<String>,
    /// Stroke, 10 mm–2 m and 0.25–25 bores, e.g. 100mm.
    #[arg(long, allow_hyphen_values = true)]
    pub stroke: Option<String>,
    /// Supply pressure, gauge, 1–16 bar, e.g. 6bar (default 6 bar).
    #[arg(long, allow_hyphen_values = true)]
    pub supply: Option<String>,
    /// The valve (default pwm).
    #[arg(long, value_enum)]
    pub valve: Option<Valve>,
    /// The valve's standard nominal flow QN (6 → 5 bar gauge), 5–20000 l/min, e.g. 200l/min.
    #[arg(long, group = "flow", allow_hyphen_values = true)]
    pub valve_flow: Option<String>,
    /// The valve's ISO 6358 sonic conductance C, m³/(s Pa) (e.g. 5e-9), or with a unit: 0.5dm3/(s*bar).
    #[arg(long, group = "flow", allow_hyphen_values = true)]
    pub valve_c: Option<String>,
    /// The valve's Kv, m³/h of water at 1 bar.
    #[arg(long, group = "flow", allow_negative_numbers = true)]
    pub valve_kv: Option<f64>,
    /// The valve's Cv, US gal/min of water at 1 psi.
    #[arg(long, group = "flow", allow_negative_numbers = true)]
    pub valve_cv: Option<f64>,
    /// The valve's ISO 6358 critical pressure ratio b, 0.05–0.6 (default 0.3; 0.5 with Kv or Cv).
    #[arg(long, allow_negative_numbers = true)]
    pub valve_b: Option<f64>,
    /// PWM carrier frequency of an on/off valve (--valve pwm only), 10–250 Hz, e.g. 40Hz.
    #[arg(long, allow_hyphen_values = true)]
    pub pwm_frequency: Option<String>,
    /// Switching delay of an on/off valve (--valve pwm only), 0.1–50 ms, e.g. 5ms.
    #[arg(long, allow_hyphen_values = true)]
    pub switching_delay: Option<String>,
    /// Spool response time of a proportional valve (--valve proportional only), 0.5–10 ms, e.g. 5ms.
    #[arg(long, allow_hyphen_values = true)]
    pub response_time: Option<String>,
    /// The position sensor's span from 0, e.g. 125mm.
    #[arg(long, allow_hyphen_values = true)]
    pub position_range: Option<String>,
    /// The differential pressure transmitter's span (±), e.g. 0.8MPa.
    #[arg(long, allow_hyphen_values = true)]
    pub pressure_range: Option<String>,
    /// Everything that moves with the piston, e.g. 0.6kg.
    #[arg(long, allow_hyphen_values = true)]
    pub mass: Option<String>,
    /// Incline of the axis below the horizontal, -90–90 deg, e.g. 30deg (default 0).
    #[arg(long, allow_hyphen_values = true)]
    pub incline: Option<String>,
    /// Coulomb friction of the seals and guide, e.g. 3N.
    #[arg(long, allow_hyphen_values = true)]
    pub friction: Option<String>,
    /// Dead volume of each chamber (port, end cap and tube), e.g. 3cm3.
    #[arg(long, allow_hyphen_values = true)]
    pub dead_volume: Option<String>,
    /// Tube length from the valve to each port, for the dead volume (not with --dead-volume), 0–10 m, e.g. 0.5m.
    #[arg(long, allow_hyphen_values = true)]
    pub tube_length: Option<String>,
    /// The experiment's contact force (default: 10 % of the force range), e.g. 30N.
    #[arg(long, allow_hyphen_values = true)]
    pub force: Option<String>,
}

/// The option's value in SI, refused with the text typed when it has no unit of `dim` or lies outside the
/// option's own range (`pneuflex_datasheet::limits`), before anything is derived from it.
fn quantity(key: &str, v: &Option<String>, dim: Dimension) -> anyhow::Result<Option<f64>> {
    Ok(match v {
        Some(t) => Some(in_range(key, t, parse(key, t, dim)?)?),
        None => None,
    })
}

fn in_range(key: &str, typed: &str, si: f64) -> Result<f64, DesignError> {
    match limits::of(key) {
        Some(r) => r.check(si).map_err(|why| DesignError::Value {
            key: key.into(),
            value: typed.into(),
            why,
        }),
        None => Ok(si),
    }
}

/// The sonic conductance: a plain number in m³/(s Pa), or dm³/(s bar) with its unit.
fn conductance(text: &str) -> anyhow::Result<f64> {
    let t = text.trim();
    let lower = t.to_ascii_lowercase().replace(' ', "");
    let (number, factor) = if let Some(n) = lower.strip_suffix("dm3/(s*bar)") {
        (n.to_string(), 1e-8)
    } else if let Some(n) = lower.strip_suffix("m3/(s*pa)") {
        (n.to_string(), 1.0)
    } else {
        (lower.clone(), 1.0)
    };
    let c: f64 = number.parse().map_err(|_| {
        anyhow::anyhow!(
            "--valve-c {text}: a sonic conductance in m³/(s Pa) (e.g. 5e-9) or dm³/(s bar) with its unit \
             (e.g. 0.5dm3/(s*bar))"
        )
    })?;
    Ok(in_range("--valve-c", text, c * factor)?)
}

impl NewRig {
    /// The datasheet these options give, each quantity parsed with its unit (errors name the option).
    pub fn datasheet(&self) -> anyhow::Result<Datasheet> {
        let a = self;
        let flow = if let Some(q) = &a.valve_flow {
            Some(FlowRating::Qn(in_range(
                "--valve-flow",
                q,
                parse("--valve-flow", q, Dimension::Flow)?,
            )?))
        } else if let Some(c) = &a.valve_c {
            Some(FlowRating::Conductance(conductance(c)?))
        } else if let Some(kv) = a.valve_kv {
            Some(FlowRating::Kv(kv))
        } else {
            a.valve_cv.map(FlowRating::Cv)
        };
        let ds = Datasheet {
            name: a.name.clone(),
            bore_m: quantity("--bore", &a.bore, Dimension::Length)?,
            iso_bore_mm: a.iso_bore,
            rod_m: quantity("--rod", &a.rod, Dimension::Length)?,
            stroke_m: quantity("--stroke", &a.stroke, Dimension::Length)?,
            supply_gauge_pa: quantity("--supply", &a.supply, Dimension::Pressure)?,
            valve: a.valve.map(|v| match v {
                Valve::Pwm => ValveKind::Pwm,
                Valve::Proportional => ValveKind::Proportional,
            }),
            flow,
            critical_pressure_ratio: a.valve_b,
            pwm_frequency_hz: quantity("--pwm-frequency", &a.pwm_frequency, Dimension::Frequency)?,
            switching_delay_s: quantity("--switching-delay", &a.switching_delay, Dimension::Time)?,
            response_time_s: quantity("--response-time", &a.response_time, Dimension::Time)?,
            position_range_m: quantity("--position-range", &a.position_range, Dimension::Length)?,
            pressure_range_pa: quantity(
                "--pressure-range",
                &a.pressure_range,
                Dimension::Pressure,
            )?,
            moving_mass_kg: quantity("--mass", &a.mass, Dimension::Mass)?,
            incline_deg: quantity("--incline", &a.incline, Dimension::Angle)?,
            coulomb_n: quantity("--friction", &a.friction, Dimension::Force)?,
            dead_volume_m3: quantity("--dead-volume", &a.dead_volume, Dimension::Volume)?,
            tube_length_m: quantity("--tube-length", &a.tube_length, Dimension::Length)?,
            force_n: quantity("--force", &a.force, Dimension::Force)?,
        };
        Ok(ds)
    }
}
