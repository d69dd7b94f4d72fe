//! How a recorded signal is shown: the unit a person reads (kPa, mm, N), the scale from the declared SI
//! unit, the series name that says the unit, and a colour that tells paired signals apart.

/// The display unit of a declared SI unit and the factor from SI to it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DisplayUnit {
    /// Multiply an SI value by this to get the displayed value.
    pub scale: f64,
    /// The displayed unit, as written in series names and plot titles.
    pub label: &'static str,
}

/// Display unit of a signal declared in `unit` (SI, as in `pneuflex_control::Signal::unit`): pressures
/// (absolute, as every recorded pressure is) in kPa, lengths in mm, forces in N, dimensionless as `-`.
pub fn display_unit(unit: &str) -> DisplayUnit {
    let (scale, label) = match unit {
        "Pa" => (1e-3, "kPa abs"),
        "m" => (1e3, "mm"),
        "m/s" => (1e3, "mm/s"),
        "m/N" => (1e3, "mm/N"),
        "N" => (1.0, "N"),
        "N/m" => (1.0, "N/m"),
        "s" => (1.0, "s"),
        "1" | "" => (1.0, "-"),
        other => {
            return DisplayUnit {
                scale: 1.0,
                label: leak_label(other),
            };
        }
    };
    DisplayUnit { scale, label }
}

/// An undeclared unit is shown as declared (a handful per process at most: one per distinct unit).
fn leak_label(unit: &str) -> &'static str {
    use std::collections::HashMap;
    use std::sync::{Mutex, OnceLock};
    static LABELS: OnceLock<Mutex<HashMap<String, &'static str>>> = OnceLock::new();
    let mut m = LABELS
        .get_or_init(|| Mutex::new(HashMap::new()))
        .lock()
        .unwrap_or_else(|e| e.into_inner());
    m.entry(unit.to_owned())
        .or_insert_with(|| Box::leak(unit.to_owned().into_boxed_str()))
}

/// `name [unit]`, the series name of a signal.
pub fn series_name(name: &str, unit: &str) -> String {
    format!("{name} [{}]", display_unit(unit).label)
}

/// Title of a plot of the signals of `group` declared in `units`: `group [unit]` when they share one.
pub fn plot_title(group: &str, units: &[&str]) -> String {
    let labels: Vec<&str> = units.iter().map(|u| display_unit(u).label).collect();
    match labels.first() {
        Some(first) if labels.iter().all(|l| l == first) => format!("{group} [{first}]"),
        _ => group.to_owned(),
    }
}

/// Line colour and width of a signal's series. Pairs differ in hue: the reference (f_ref, x_r) orange
/// against the measured value (f_e, x) blue, chamber A blue against chamber B red. A raw signal that has
/// a PWM-period average beside it is drawn light and thin, the average saturated and wider.
pub fn series_style(name: &str, averaged: bool) -> ([u8; 4], f32) {
    const ORANGE: [u8; 4] = [240, 140, 30, 255];
    const BLUE: [u8; 4] = [40, 120, 230, 255];
    const RED: [u8; 4] = [225, 50, 50, 255];
    const GREEN: [u8; 4] = [60, 180, 90, 255];
    const GREY: [u8; 4] = [150, 150, 160, 255];
    const VIOLET: [u8; 4] = [170, 100, 220, 255];
    let base = match name {
        "f_ref" | "x_r" => ORANGE,
        "f_e" | "x" | "p_a" => BLUE,
        "p_b" => RED,
        "u" => GREEN,
        "spool" => GREY,
        "g" => VIOLET,
        "p" => [0, 170, 170, 255],
        "d" => [200, 170, 40, 255],
        _ => GREY,
    };
    if name == "spool" {
        // Under PWM the spool switches every period: a pale band behind the command u.
        return ([150, 150, 160, 90], 1.0);
    }
    if averaged {
        // The raw chattering signal: a pale version of the colour, behind the average.
        let [r, g, b, _] = base;
        let pale = |c: u8| (c as u16 + (255 - c as u16) * 3 / 5) as u8;
        ([pale(r), pale(g), pale(b), 60], 1.0)
    } else {
        (base, 1.5)
    }
}

/// Style of the PWM-period average of the signal `name`: its colour, saturated and darker, wider.
pub fn average_style(name: &str) -> ([u8; 4], f32) {
    let ([r, g, b, _], _) = series_style(name, false);
    let dark = |c: u8| (c as u16 * 3 / 4) as u8;
    ([dark(r), dark(g), dark(b), 255], 2.5)
}

/// The signals whose PWM-period average is recorded beside them: the contact force and the pressures,
/// which chatter at the PWM frequency of an on/off valve.
pub fn is_averaged(name: &str, group: &str) -> bool {
    matches!((group, name), ("force", "f_e") | ("pressure", _))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn units_read_as_a_person_reads_them() {
        assert_eq!(display_unit("Pa").label, "kPa abs");
        assert!((600_000.0 * display_unit("Pa").scale - 600.0).abs() < 1e-9);
        assert!((0.02 * display_unit("m").scale - 20.0).abs() < 1e-12);
        assert_eq!(series_name("p_a", "Pa"), "p_a [kPa abs]");
        assert_eq!(series_name("u", "1"), "u [-]");
        assert_eq!(series_name("q", "furlong"), "q [furlong]");
        assert_eq!(plot_title("force", &["N", "N"]), "force [N]");
        assert_eq!(plot_title("valve", &["1", "1"]), "valve [-]");
        assert_eq!(plot_title("mixed", &["N", "m"]), "mixed");
    }

    #[test]
    fn paired_signals_have_distinct_colours() {
        for (a, b) in [
            ("f_ref", "f_e"),
            ("x", "x_r"),
            ("p_a", "p_b"),
            ("u", "spool"),
        ] {
            assert_ne!(
                series_style(a, false).0,
                series_style(b, false).0,
                "{a}/{b}"
            );
        }
        assert_ne!(series_style("p_a", true).0, average_style("p_a").0);
    }
}
