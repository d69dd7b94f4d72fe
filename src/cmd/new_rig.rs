//! `pneuflex new rig`: the options parsed into a datasheet (with their units), the rig directory written
//! by `pneuflex_datasheet::new_rig`, its report printed.

use pneuflex_datasheet::units::{Dimension, parse};
use pneuflex_datasheet::{Datasheet, FlowRating, ValveKind};

use crate::cli::new::{NewRig, Valve};

fn quantity(key: &str, v: &Option<String>, dim: Dimension) -> anyhow::Result<Option<f64>> {
    Ok(match v {
        Some(t) => Some(parse(key, t, dim)?),
        None => None,
    })
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
    Ok(c * factor)
}

pub fn new_rig(a: &NewRig) -> anyhow::Result<()> {
    let flow = if let Some(q) = &a.valve_flow {
        Some(FlowRating::Qn(parse("--valve-flow", q, Dimension::Flow)?))
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
        pressure_range_pa: quantity("--pressure-range", &a.pressure_range, Dimension::Pressure)?,
        moving_mass_kg: quantity("--mass", &a.mass, Dimension::Mass)?,
        incline_deg: quantity("--incline", &a.incline, Dimension::Angle)?,
        coulomb_n: quantity("--friction", &a.friction, Dimension::Force)?,
        dead_volume_m3: quantity("--dead-volume", &a.dead_volume, Dimension::Volume)?,
        tube_length_m: quantity("--tube-length", &a.tube_length, Dimension::Length)?,
        force_n: quantity("--force", &a.force, Dimension::Force)?,
    };
    let command = std::iter::once("pneuflex".to_string())
        .chain(std::env::args().skip(1))
        .collect::<Vec<_>>()
        .join(" ");
    let report = pneuflex_datasheet::new_rig(&ds, &a.dir, &command)?;
    for w in &report.warnings {
        errln!("warning: {}: {}", w.key, w.message);
    }
    outln!(
        "{}: {} (README.md lists the {} assumptions)",
        report.dir.display(),
        "sheet set, scene.toml and rig.toml written",
        report.design.assumptions.len()
    );
    outln!(
        "gains: kp = {} /m, ki = {} /(m s): {}",
        report.gains.kp_per_m,
        report.gains.ki_per_m_s,
        report.gains.note
    );
    outln!("next: pneuflex run {}/scene.toml", report.dir.display());
    Ok(())
}
