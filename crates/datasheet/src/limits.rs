//! The range of each option of `new rig`, checked on the value as typed before anything is derived: a
//! value outside it is refused with the option, the range, why it is the range, and a value that would
//! work. The ranges are the ones of the hardware `new rig` designs for (a catalogue's pneumatic cylinders,
//! valves and sensors); the limits that depend on other options (rod against bore, mass against the air
//! springs, sensor spans against stroke and supply) are in `checks`.

/// One option's range, in the unit its messages use.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Range {
    /// The option, e.g. `--bore`.
    pub key: &'static str,
    /// Lowest and highest value accepted, in `unit`.
    pub lo: f64,
    pub hi: f64,
    /// A common value, offered when the value typed is no number at all.
    pub typical: f64,
    /// The unit of `lo` and `hi` as typed (`mm`), empty for a plain number.
    pub unit: &'static str,
    /// SI per `unit` (1e-3 for mm).
    pub si_per_unit: f64,
    /// Why these are the limits.
    pub why: &'static str,
}

const fn range(
    key: &'static str,
    lo: f64,
    hi: f64,
    typical: f64,
    unit: &'static str,
    si_per_unit: f64,
    why: &'static str,
) -> Range {
    Range {
        key,
        lo,
        hi,
        typical,
        unit,
        si_per_unit,
        why,
    }
}

/// Every option with a range of its own.
pub const RANGES: [Range; 21] = [
    // ISO 6432 round cylinders start at 8 mm, ISO 15552 ends at 320 mm; new rig knows the rods and ports
    // of exactly these sizes.
    range(
        "--bore",
        8.0,
        320.0,
        25.0,
        "mm",
        1e-3,
        "the bores of ISO 6432 (8–25 mm) and ISO 15552 (32–320 mm), whose rods and ports new rig knows",
    ),
    range(
        "--iso-bore",
        8.0,
        320.0,
        32.0,
        "",
        1.0,
        "a bore of ISO 6432 (8–25 mm) or ISO 15552 (32–320 mm), in mm",
    ),
    // Rods are checked against the bore (checks): here only a plausible size.
    range(
        "--rod",
        1.0,
        250.0,
        10.0,
        "mm",
        1e-3,
        "piston rods of ISO 6432 and ISO 15552 are 4–63 mm",
    ),
    // Catalogue strokes start at 10 mm; beyond 2 m linear drives are rodless, with other dynamics.
    range(
        "--stroke",
        10.0,
        2000.0,
        100.0,
        "mm",
        1e-3,
        "cylinder strokes of ISO 6432 and ISO 15552 catalogues run from 10 mm to 2 m",
    ),
    // Pilot-operated valves need ~1.5 bar, shop air is 6–7, pneumatic components are rated to 10–16 bar.
    range(
        "--supply",
        1.0,
        16.0,
        6.0,
        "bar",
        1e5,
        "a gauge supply of pneumatic components: shop air is 6–7 bar, components are rated to 10–16 bar",
    ),
    // From miniature solenoid valves (~10 l/min) to ISO 5599 size 3 (~10 000 l/min); the other flow
    // ratings span the same valves (C = QN / (p₁ φ), 4 dm³/(s bar) per Kv, Kv = 0.865 Cv).
    range(
        "--valve-flow",
        5.0,
        20_000.0,
        300.0,
        "l/min",
        1e-3 / 60.0,
        "from a miniature solenoid valve (~10 l/min) to an ISO 5599 size 3 valve (~10 000 l/min)",
    ),
    range(
        "--valve-c",
        0.02,
        80.0,
        1.0,
        "dm3/(s*bar)",
        1e-8,
        "from a miniature solenoid valve to an ISO 5599 size 3 valve; 1 dm³/(s bar) = 1e-8 m³/(s Pa)",
    ),
    range(
        "--valve-kv",
        0.005,
        20.0,
        0.3,
        "",
        1.0,
        "m³/h of water at 1 bar, from a miniature solenoid valve to an ISO 5599 size 3 valve",
    ),
    range(
        "--valve-cv",
        0.006,
        23.0,
        0.35,
        "",
        1.0,
        "US gal/min of water at 1 psi, from a miniature solenoid valve to an ISO 5599 size 3 valve",
    ),
    // ISO 6358 b of real valves is 0.1–0.5; an ideal convergent nozzle chokes at 0.528.
    range(
        "--valve-b",
        0.05,
        0.6,
        0.3,
        "",
        1.0,
        "ISO 6358 critical pressure ratios of valves are 0.1–0.5; an ideal nozzle chokes at 0.528",
    ),
    // Solenoid valves under PWM run at 10–200 Hz (the paper's at 40); above 250 Hz the 1 kHz control tick
    // has under 4 ticks a period to place the duty in. Measured: a 25 mm rig settles at 10 Hz, not at 5.
    range(
        "--pwm-frequency",
        10.0,
        250.0,
        40.0,
        "Hz",
        1.0,
        "PWM carriers of solenoid valves: under 10 Hz the carrier sits on the experiment's 1 Hz sine and 3 Hz \
         force loop, over 250 Hz the 1 kHz control tick has under 4 ticks a period",
    ),
    // Piezo valves switch in ~0.5 ms, large solenoid valves in ~50 ms.
    range(
        "--switching-delay",
        0.1,
        50.0,
        5.0,
        "ms",
        1e-3,
        "solenoid valves switch in 1–50 ms, piezo valves in under 1 ms",
    ),
    // Proportional spools respond in 2–10 ms (Festo MPYE: ~3 ms); faster than 0.5 ms is no spool. Measured: a
    // 25 mm rig settles with a 10 ms spool, not with 20 ms (the loop analysis finds no usable kp).
    range(
        "--response-time",
        0.5,
        10.0,
        5.0,
        "ms",
        1e-3,
        "spools of proportional valves respond in 2–10 ms; a slower one cannot follow the experiment's force loop",
    ),
    // Gravity along the axis: from straight up to straight down.
    range(
        "--incline",
        -90.0,
        90.0,
        30.0,
        "deg",
        1.0,
        "the axis's angle below the horizontal, from straight up (-90) to straight down (90)",
    ),
    // Tubes from a valve terminal reach a few metres; beyond 10 m the line's own wave dynamics (not in
    // the sheet set new rig writes) dominate.
    range(
        "--tube-length",
        0.0,
        10.0,
        0.5,
        "m",
        1.0,
        "valve to port: 0 for a valve on the cylinder, a few metres from a terminal; beyond 10 m the \
         line's waves dominate",
    ),
    // A chamber's dead volume: ports and tubes hold cm³; a litre is a reservoir (the floor is against
    // the bore, in checks).
    range(
        "--dead-volume",
        0.001,
        1000.0,
        3.0,
        "cm3",
        1e-6,
        "ports, end caps and tubes hold 0.01–100 cm³; a litre is a reservoir",
    ),
    // Everything that moves with the piston: a gram (a mini cylinder's rod) to a tonne.
    range(
        "--mass",
        0.001,
        1000.0,
        0.6,
        "kg",
        1.0,
        "a mini cylinder's rod weighs grams; the loads of pneumatic axes are under a tonne",
    ),
    // The sensors' spans and the forces have relative limits (stroke, supply, force range: in checks); these
    // only keep them to what any pneumatic rig has.
    range(
        "--position-range",
        1.0,
        20_000.0,
        125.0,
        "mm",
        1e-3,
        "position sensors of pneumatic axes span a few mm to a few m",
    ),
    range(
        "--pressure-range",
        0.01,
        16.0,
        0.8,
        "MPa",
        1e6,
        "pneumatic pressure transmitters span 0.1–16 bar",
    ),
    // ISO 15552's 320 mm bore at 16 bar pushes 129 kN.
    range(
        "--force",
        0.01,
        130_000.0,
        10.0,
        "N",
        1.0,
        "up to the 129 kN of a 320 mm bore at 16 bar",
    ),
    range(
        "--friction",
        0.0,
        130_000.0,
        3.0,
        "N",
        1.0,
        "a Coulomb friction force of seals and guides, up to the 129 kN of a 320 mm bore at 16 bar",
    ),
];

/// The range of `key`, if it has one of its own.
pub fn of(key: &str) -> Option<&'static Range> {
    RANGES.iter().find(|r| r.key == key)
}

/// A number for messages: short, without binary noise (0.3, 1e-9, 20000).
pub fn num(v: f64) -> String {
    if v == 0.0 || !v.is_finite() {
        return format!("{v}");
    }
    if v.abs() >= 1e6 || v.abs() < 1e-3 {
        return format!("{v:.3e}")
            .replace(".000e", "e")
            .replace("00e", "e")
            .replace("0e", "e");
    }
    let s = format!("{v:.4}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    s.to_string()
}

impl Range {
    /// A value typed with this option's unit, e.g. `320mm`.
    pub fn typed(&self, v: f64) -> String {
        format!("{}{}", num(v), self.unit)
    }

    /// `si` checked against the range: the reason and a value that would work when it is outside.
    pub fn check(&self, si: f64) -> Result<f64, String> {
        let v = si / self.si_per_unit;
        let shown = if self.unit.is_empty() {
            num(v)
        } else {
            format!("{} {}", num(v), self.unit)
        };
        let span = format!(
            "{}–{}{}",
            num(self.lo),
            num(self.hi),
            if self.unit.is_empty() {
                String::new()
            } else {
                format!(" {}", self.unit)
            }
        );
        if !v.is_finite() {
            return Err(format!(
                "not a finite number: give a value within {span} ({}), e.g. {} {}",
                self.why,
                self.key,
                self.typed(self.typical)
            ));
        }
        // The unit's factor there and back leaves binary noise (1000cm3 reads 1000.0000000000001 cm³): a
        // bound typed is the bound.
        let slack = 1e-9 * self.lo.abs().max(self.hi.abs());
        if v < self.lo - slack {
            return Err(format!(
                "{shown} is under {}, the least accepted ({span}: {}); {} {} would work",
                self.typed(self.lo),
                self.why,
                self.key,
                self.typed(self.lo)
            ));
        }
        if v > self.hi + slack {
            return Err(format!(
                "{shown} is over {}, the most accepted ({span}: {}); {} {} would work",
                self.typed(self.hi),
                self.why,
                self.key,
                self.typed(self.hi)
            ));
        }
        Ok(si)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_range_takes_its_bounds_and_typical_value_and_refuses_beyond() {
        for r in &RANGES {
            assert!(r.lo < r.hi, "{}", r.key);
            assert!((r.lo..=r.hi).contains(&r.typical), "{}", r.key);
            for v in [r.lo, r.typical, r.hi] {
                assert!(r.check(v * r.si_per_unit).is_ok(), "{} {v}", r.key);
            }
            let over = r.check(2.0 * r.hi.abs().max(1.0) * r.si_per_unit + r.hi * r.si_per_unit);
            let over = over.unwrap_err();
            assert!(
                over.contains(&format!("{} {} would work", r.key, r.typed(r.hi))),
                "{over}"
            );
            let nan = r.check(f64::NAN).unwrap_err();
            assert!(nan.contains("not a finite number"), "{nan}");
            assert!(nan.contains(&format!("e.g. {} {}", r.key, r.typed(r.typical))));
        }
    }

    #[test]
    fn every_option_has_one_range() {
        for r in &RANGES {
            assert_eq!(
                RANGES.iter().filter(|o| o.key == r.key).count(),
                1,
                "{}",
                r.key
            );
            assert_eq!(of(r.key), Some(r));
        }
        assert!(of("--name").is_none());
    }
}
