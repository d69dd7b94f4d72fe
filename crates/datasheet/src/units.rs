//! Datasheet quantities with their units: `25mm`, `6bar`, `200l/min`, `0.6kg`. A number without a unit is
//! refused for every dimensioned quantity (is `25` a bore in mm or in m?), with the units that are accepted.

use crate::DesignError;

/// What a value measures, and the units it may be given in (factor to SI).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Dimension {
    /// Metres.
    Length,
    /// Pascals. A supply pressure is gauge (as regulators and datasheets give it).
    Pressure,
    /// Standard volume flow (ISO 8778 ANR, 20 °C and 100 kPa reference), m³/s.
    Flow,
    /// Kilograms.
    Mass,
    /// Hertz.
    Frequency,
    /// Seconds.
    Time,
    /// Degrees (kept in degrees: the sheets use degrees).
    Angle,
    /// Cubic metres.
    Volume,
    /// Newtons.
    Force,
    /// Newtons per metre.
    Stiffness,
}

impl Dimension {
    fn units(self) -> &'static [(&'static str, f64)] {
        match self {
            Dimension::Length => &[("mm", 1e-3), ("cm", 1e-2), ("m", 1.0), ("in", 0.0254)],
            Dimension::Pressure => &[
                ("mpa", 1e6),
                ("kpa", 1e3),
                ("pa", 1.0),
                ("bar", 1e5),
                ("psi", 6_894.757_293_168),
            ],
            Dimension::Flow => &[
                ("nl/min", 1e-3 / 60.0),
                ("l/min", 1e-3 / 60.0),
                ("slpm", 1e-3 / 60.0),
                ("m3/h", 1.0 / 3600.0),
                ("m3/s", 1.0),
            ],
            Dimension::Mass => &[("kg", 1.0), ("g", 1e-3)],
            Dimension::Frequency => &[("khz", 1e3), ("hz", 1.0)],
            Dimension::Time => &[("ms", 1e-3), ("us", 1e-6), ("s", 1.0)],
            Dimension::Angle => &[("deg", 1.0)],
            Dimension::Volume => &[("cm3", 1e-6), ("ml", 1e-6), ("mm3", 1e-9), ("m3", 1.0)],
            Dimension::Force => &[("kn", 1e3), ("n", 1.0)],
            Dimension::Stiffness => &[("kn/m", 1e3), ("n/mm", 1e3), ("n/m", 1.0)],
        }
    }

    const ALL: [Dimension; 10] = [
        Dimension::Length,
        Dimension::Pressure,
        Dimension::Flow,
        Dimension::Mass,
        Dimension::Frequency,
        Dimension::Time,
        Dimension::Angle,
        Dimension::Volume,
        Dimension::Force,
        Dimension::Stiffness,
    ];

    /// The dimension a unit (lower case) belongs to, if any.
    fn of_unit(unit: &str) -> Option<Dimension> {
        Self::ALL
            .into_iter()
            .find(|d| d.units().iter().any(|(u, _)| *u == unit))
    }

    /// What it measures, for messages.
    fn noun(self) -> &'static str {
        match self {
            Dimension::Length => "length",
            Dimension::Pressure => "pressure",
            Dimension::Flow => "flow",
            Dimension::Mass => "mass",
            Dimension::Frequency => "frequency",
            Dimension::Time => "time",
            Dimension::Angle => "angle",
            Dimension::Volume => "volume",
            Dimension::Force => "force",
            Dimension::Stiffness => "stiffness",
        }
    }

    fn example(self) -> &'static str {
        match self {
            Dimension::Length => "25mm",
            Dimension::Pressure => "6bar",
            Dimension::Flow => "200l/min",
            Dimension::Mass => "0.6kg",
            Dimension::Frequency => "40Hz",
            Dimension::Time => "5ms",
            Dimension::Angle => "30deg",
            Dimension::Volume => "3cm3",
            Dimension::Force => "10N",
            Dimension::Stiffness => "700N/m",
        }
    }
}

/// Parses `text` as a quantity of `dimension` for the option `key`; returns SI (degrees for an angle).
pub fn parse(key: &str, text: &str, dimension: Dimension) -> Result<f64, DesignError> {
    let t = text.trim();
    let split = t
        .find(|c: char| !(c.is_ascii_digit() || matches!(c, '.' | '-' | '+' | 'e' | 'E')))
        .unwrap_or(t.len());
    // An exponent's `e` belongs to the number only when digits follow it (`2e-3m`, not `3em`).
    let (number, unit) = t.split_at(split);
    let unit = unit.trim().to_ascii_lowercase();
    let accepted = || {
        dimension
            .units()
            .iter()
            .map(|(u, _)| *u)
            .collect::<Vec<_>>()
            .join(", ")
    };
    let value: f64 = number.parse().map_err(|_| DesignError::Value {
        key: key.into(),
        value: text.into(),
        why: format!(
            "not a number with a unit (e.g. {}; units: {})",
            dimension.example(),
            accepted()
        ),
    })?;
    // A decimal comma (`2,5mm`) reads as the number 2 with the unit `,5mm`: say what it is.
    if unit.starts_with(',') && unit[1..].starts_with(|c: char| c.is_ascii_digit()) {
        return Err(DesignError::Value {
            key: key.into(),
            value: text.into(),
            why: format!(
                "a decimal comma: write the number with a point, e.g. {key} {}",
                t.replacen(',', ".", 1)
            ),
        });
    }
    if unit.is_empty() {
        return Err(DesignError::Value {
            key: key.into(),
            value: text.into(),
            why: format!(
                "give a unit, e.g. {} (units: {})",
                dimension.example(),
                accepted()
            ),
        });
    }
    let factor = dimension
        .units()
        .iter()
        .find(|(u, _)| *u == unit)
        .map(|(_, f)| *f)
        .ok_or_else(|| DesignError::Value {
            key: key.into(),
            value: text.into(),
            why: match Dimension::of_unit(&unit) {
                // A unit of another kind (`--bore 3bar`): say what it measures and what the option takes.
                Some(other) => format!(
                    "`{unit}` is a unit of {}, and {key} takes {}: e.g. {key} {} (units: {})",
                    other.noun(),
                    dimension.noun(),
                    dimension.example(),
                    accepted()
                ),
                None => format!(
                    "unknown unit `{unit}` (units: {}), e.g. {key} {}",
                    accepted(),
                    dimension.example()
                ),
            },
        })?;
    let si = value * factor;
    if !si.is_finite() {
        return Err(DesignError::Value {
            key: key.into(),
            value: text.into(),
            why: format!("not a finite number, e.g. {key} {}", dimension.example()),
        });
    }
    Ok(si)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn units_convert_to_si() {
        assert_eq!(parse("--bore", "25mm", Dimension::Length).unwrap(), 0.025);
        assert_eq!(parse("--bore", " 1in ", Dimension::Length).unwrap(), 0.0254);
        assert_eq!(parse("--supply", "6bar", Dimension::Pressure).unwrap(), 6e5);
        assert_eq!(
            parse("--supply", "0.5MPa", Dimension::Pressure).unwrap(),
            5e5
        );
        let q = parse("--valve-flow", "60l/min", Dimension::Flow).unwrap();
        assert!((q - 1e-3).abs() < 1e-15);
        assert_eq!(parse("--mass", "600g", Dimension::Mass).unwrap(), 0.6);
        assert_eq!(parse("--x", "2e-3m", Dimension::Length).unwrap(), 2e-3);
    }

    #[test]
    fn a_bare_number_or_an_unknown_unit_is_refused_with_the_key() {
        let e = parse("--bore", "25", Dimension::Length)
            .unwrap_err()
            .to_string();
        assert!(e.contains("--bore") && e.contains("give a unit"), "{e}");
        let e = parse("--supply", "6atm", Dimension::Pressure)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("--supply") && e.contains("unknown unit `atm`"),
            "{e}"
        );
        let e = parse("--mass", "NaNkg", Dimension::Mass)
            .unwrap_err()
            .to_string();
        assert!(e.contains("--mass"), "{e}");
    }
}
