//! From what a datasheet gives to every value a sheet set needs: the given values kept, the rest derived
//! with the assumption said (each names the option that would replace it), the paper's experiment scaled
//! to the rig's force range (docs/your-rig.md, "What new rig assumes").

use pneuflex_pneumatics::flow::{ISO_RHO0_KG_M3, ISO_T0_K};

use crate::iso6358::{self, ATMOSPHERE_PA};
use crate::{DesignError, series};

/// The valve kinds a rig can have.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ValveKind {
    /// A 5/2 on/off solenoid valve driven by PWM (the paper's rig).
    Pwm,
    /// A proportional 5/3 servo valve.
    Proportional,
}

impl ValveKind {
    /// The value of `--valve` that chooses it.
    pub fn option(self) -> &'static str {
        match self {
            ValveKind::Pwm => "pwm",
            ValveKind::Proportional => "proportional",
        }
    }
}

/// How the datasheet rates the valve's flow.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum FlowRating {
    /// Standard nominal flow QN, m³/s ANR (6 → 5 bar gauge).
    Qn(f64),
    /// ISO 6358 sonic conductance C, m³/(s Pa).
    Conductance(f64),
    /// Kv, m³/h of water at 1 bar.
    Kv(f64),
    /// Cv, US gal/min of water at 1 psi.
    Cv(f64),
}

/// The values a user gives (SI; None: derive it and say so). The field names are the command's options.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Datasheet {
    /// The rig's name (`--name`); from the sizes when not given.
    pub name: Option<String>,
    /// `--bore`, m.
    pub bore_m: Option<f64>,
    /// `--iso-bore`, mm: a bore of ISO 15552 / ISO 6432, with its rod and port.
    pub iso_bore_mm: Option<f64>,
    /// `--rod`, m.
    pub rod_m: Option<f64>,
    /// `--stroke`, m.
    pub stroke_m: Option<f64>,
    /// `--supply`, Pa gauge.
    pub supply_gauge_pa: Option<f64>,
    /// `--valve`.
    pub valve: Option<ValveKind>,
    /// `--valve-flow`, `--valve-c`, `--valve-kv` or `--valve-cv`.
    pub flow: Option<FlowRating>,
    /// `--valve-b`.
    pub critical_pressure_ratio: Option<f64>,
    /// `--pwm-frequency`, Hz.
    pub pwm_frequency_hz: Option<f64>,
    /// `--switching-delay`, s (on/off valve).
    pub switching_delay_s: Option<f64>,
    /// `--response-time`, s (proportional valve).
    pub response_time_s: Option<f64>,
    /// `--position-range`, m: the position sensor's span (from 0).
    pub position_range_m: Option<f64>,
    /// `--pressure-range`, Pa: the differential transmitter's span (±).
    pub pressure_range_pa: Option<f64>,
    /// `--mass`, kg: everything that moves with the piston.
    pub moving_mass_kg: Option<f64>,
    /// `--incline`, degrees below the horizontal, the axis pointing downhill.
    pub incline_deg: Option<f64>,
    /// `--friction`, N: the seals' and guide's Coulomb friction.
    pub coulomb_n: Option<f64>,
    /// `--dead-volume`, m³ per chamber.
    pub dead_volume_m3: Option<f64>,
    /// `--tube-length`, m: valve to cylinder, each side.
    pub tube_length_m: Option<f64>,
    /// `--force`, N: the experiment's contact force.
    pub force_n: Option<f64>,
}

/// One value that was not given, what was taken, and the option that gives it.
#[derive(Clone, Debug, PartialEq)]
pub struct Assumption {
    /// The option.
    pub key: &'static str,
    /// What was taken and why.
    pub text: String,
}

/// Every value the sheet set holds, SI.
#[derive(Clone, Debug, PartialEq)]
pub struct Design {
    pub name: String,
    /// Cylinder.
    pub bore_m: f64,
    pub rod_m: f64,
    pub stroke_m: f64,
    pub dead_volume_a_m3: f64,
    pub dead_volume_b_m3: f64,
    /// The ISO size the cylinder is, or is nearest to, for its port.
    pub size: series::Size,
    /// Supply and atmosphere, Pa absolute.
    pub supply_abs_pa: f64,
    pub atmosphere_pa: f64,
    /// Valve.
    pub valve: ValveKind,
    pub sonic_conductance_m3_per_s_pa: f64,
    pub critical_pressure_ratio: f64,
    pub pwm_frequency_hz: f64,
    pub switching_delay_s: f64,
    pub response_time_s: f64,
    /// How the flow was given, for the sheet's comment, and the option that gives it.
    pub flow_source: String,
    pub flow_key: &'static str,
    /// Sensors: position span from 0, differential span ±, m and Pa.
    pub position_range_m: f64,
    pub pressure_range_pa: f64,
    /// Mechanics.
    pub moving_mass_kg: f64,
    pub incline_deg: f64,
    pub coulomb_n: f64,
    pub viscous_n_s_per_m: f64,
    /// The experiment: the contact force step and its sine, the environment before and after the
    /// stiffness change, and where its surface is.
    pub force_n: f64,
    pub sine_amplitude_n: f64,
    pub stiffness_n_per_m: f64,
    pub stiffness_after_n_per_m: f64,
    pub surface_m: f64,
    /// The impedance filter: the paper's outer-loop frequency and damping on this environment.
    pub m_d_kg: f64,
    pub b_d_ns_per_m: f64,
    /// What was assumed.
    pub assumptions: Vec<Assumption>,
}

/// The paper's experiment, as ratios that carry to another rig: the contact force is 10 % of the force
/// range (10 N of ~100 N), the surface at 40 % of the stroke (20 of 50 mm), the softer environment takes
/// 34 % of the stroke at the largest force (12 N / 700 N/m = 17 mm of 50), the stiffer one is twice as stiff,
/// and the impedance filter keeps the paper's ω = √(700/2) rad/s and ζ = 52.4 / (2√(2·700)) on it.
pub const FORCE_OF_RANGE: f64 = 0.10;
pub const SURFACE_OF_STROKE: f64 = 0.40;
pub const COMPRESSION_OF_STROKE: f64 = 0.34;
pub const SINE_OF_FORCE: f64 = 0.2;
/// The impedance filter's outer frequency squared, (rad/s)²: the paper's √(700/2) = 18.7 rad/s.
pub const PAPER_OMEGA2: f64 = 700.0 / 2.0;
const PAPER_ZETA: f64 = 52.4 / (2.0 * 37.416_573_867_739_41);

/// The chamber fill time a valve is sized for when no flow is given: from the atmosphere to the supply at
/// mid stroke, choked. The paper's valve fills its chamber in ~14 ms; 40 ms is a common industrial sizing.
pub const DEFAULT_FILL_TIME_S: f64 = 0.04;

/// Two significant digits: the experiment's numbers read like a person chose them (and print without
/// binary noise: 5.8, not 5.800000000000001).
pub fn round2(v: f64) -> f64 {
    if v == 0.0 || !v.is_finite() {
        return v;
    }
    format!("{v:.1e}").parse().unwrap_or(v)
}

/// `v` > 0 to two significant digits, rounded down: a gain written under a limit stays under it (17.65 -> 17,
/// not 18, which is 5.8 dB under a 6 dB target).
pub fn floor2(v: f64) -> f64 {
    if v <= 0.0 || !v.is_finite() {
        return v;
    }
    let unit = 10f64.powi(v.log10().floor() as i32 - 1);
    // The 1e-9 keeps a value already on two digits (18 / 1 = 17.999999999) where it is.
    round2(((v / unit) * (1.0 + 1e-9)).floor() * unit)
}

/// A rod's diameter against the bore's, the least and most `new rig` takes.
pub const ROD_OF_BORE: (f64, f64) = (0.1, 0.7);
/// The stroke in bores, the least and most `new rig` designs for.
pub const STROKE_OF_BORE: (f64, f64) = (0.25, 25.0);

/// Air's gas constant, J/(kg K).
pub const R_AIR: f64 = 287.05;

impl Design {
    /// Piston area on the cap side, m².
    pub fn area_a(&self) -> f64 {
        std::f64::consts::FRAC_PI_4 * self.bore_m * self.bore_m
    }

    /// Annulus area on the rod side, m².
    pub fn area_b(&self) -> f64 {
        self.area_a() - std::f64::consts::FRAC_PI_4 * self.rod_m * self.rod_m
    }

    /// The largest extending force, N: supply gauge on the cap side.
    pub fn force_range_n(&self) -> f64 {
        (self.supply_abs_pa - self.atmosphere_pa) * self.area_a()
    }

    /// Time to fill the cap-side chamber at mid stroke from the atmosphere to the supply, choked, s.
    pub fn fill_time_s(&self) -> f64 {
        fill_time(
            self.sonic_conductance_m3_per_s_pa,
            self.area_a() * 0.5 * self.stroke_m + self.dead_volume_a_m3,
            self.supply_abs_pa,
            self.atmosphere_pa,
        )
    }

    /// The two chambers' air springs at mid stroke, N/m: γ p (A²/V_a + A_b²/V_b) with the chambers halfway
    /// between atmosphere and supply, adiabatic (the actuator sheet's polytropic exponent).
    pub fn air_spring_n_per_m(&self) -> f64 {
        let p = 0.5 * (self.supply_abs_pa + self.atmosphere_pa);
        let v_a = self.area_a() * 0.5 * self.stroke_m + self.dead_volume_a_m3;
        let v_b = self.area_b() * 0.5 * self.stroke_m + self.dead_volume_b_m3;
        1.4 * p * (self.area_a().powi(2) / v_a + self.area_b().powi(2) / v_b)
    }

    /// The steel rod alone, kg: the least mass that moves with the piston (over the stroke and the bore).
    pub fn rod_mass_kg(&self) -> f64 {
        std::f64::consts::FRAC_PI_4
            * self.rod_m
            * self.rod_m
            * (self.stroke_m + self.bore_m)
            * 7850.0
    }

    /// Whether `key`'s value was assumed (not given).
    pub fn assumed(&self, key: &str) -> bool {
        self.assumptions.iter().any(|a| a.key == key)
    }

    /// The conductance that fills that chamber in `t` seconds.
    pub fn conductance_for_fill(&self, t: f64) -> f64 {
        self.sonic_conductance_m3_per_s_pa * self.fill_time_s() / t
    }
}

fn fill_time(c: f64, volume: f64, p_s: f64, p_atm: f64) -> f64 {
    let mass = (p_s - p_atm) * volume / (R_AIR * ISO_T0_K);
    mass / (c * ISO_RHO0_KG_M3 * p_s)
}

fn positive(key: &str, v: Option<f64>) -> Result<Option<f64>, DesignError> {
    let example = match key {
        "--position-range" => "125mm",
        "--pressure-range" => "0.8MPa",
        "--force" => "10N",
        _ => "a number > 0",
    };
    v.map(|x| {
        pneuflex_files::check::positive(x).map_err(|why| DesignError::Value {
            key: key.into(),
            value: format!("{x}"),
            why: format!("{why} (SI), e.g. {key} {example}"),
        })
    })
    .transpose()
}

/// An option's value outside its own range (`limits`), refused with the value in the option's unit.
fn in_range(key: &str, v: Option<f64>) -> Result<(), DesignError> {
    let (Some(x), Some(r)) = (v, crate::limits::of(key)) else {
        return Ok(());
    };
    r.check(x).map(|_| ()).map_err(|why| DesignError::Value {
        key: key.into(),
        value: r.typed(x / r.si_per_unit),
        why,
    })
}

/// The option of the flow rating given, with its value in SI.
pub fn flow_option(flow: &FlowRating) -> (&'static str, f64) {
    match *flow {
        FlowRating::Qn(q) => ("--valve-flow", q),
        FlowRating::Conductance(c) => ("--valve-c", c),
        FlowRating::Kv(k) => ("--valve-kv", k),
        FlowRating::Cv(c) => ("--valve-cv", c),
    }
}

/// Every option given checked against its own range, and refused where it does not apply, before
/// anything is derived from it.
pub fn check_options(ds: &Datasheet) -> Result<(), DesignError> {
    for (key, v) in [
        ("--bore", ds.bore_m),
        ("--iso-bore", ds.iso_bore_mm),
        ("--rod", ds.rod_m),
        ("--stroke", ds.stroke_m),
        ("--supply", ds.supply_gauge_pa),
        ("--valve-b", ds.critical_pressure_ratio),
        ("--pwm-frequency", ds.pwm_frequency_hz),
        ("--switching-delay", ds.switching_delay_s),
        ("--response-time", ds.response_time_s),
        ("--mass", ds.moving_mass_kg),
        ("--incline", ds.incline_deg),
        ("--dead-volume", ds.dead_volume_m3),
        ("--tube-length", ds.tube_length_m),
    ] {
        in_range(key, v)?;
    }
    if let Some(f) = &ds.flow {
        let (key, v) = flow_option(f);
        in_range(key, Some(v))?;
    }
    for (key, v) in [
        ("--position-range", ds.position_range_m),
        ("--pressure-range", ds.pressure_range_pa),
        ("--force", ds.force_n),
        ("--friction", ds.coulomb_n),
    ] {
        in_range(key, v)?;
    }
    // An option that does not apply would be dropped without a word: refused, with what it applies to.
    let valve = ds.valve.unwrap_or(ValveKind::Pwm);
    let valve_said = if ds.valve.is_some() {
        "the valve given"
    } else {
        "the valve assumed without --valve"
    };
    let not_applying = |key: &str, applies: &str, fix: &str| DesignError::NotApplying {
        key: key.into(),
        why: format!("{applies}, and {valve_said} is {}: {fix}", valve.option()),
    };
    if valve == ValveKind::Proportional {
        for (key, given) in [
            ("--pwm-frequency", ds.pwm_frequency_hz.is_some()),
            ("--switching-delay", ds.switching_delay_s.is_some()),
        ] {
            if given {
                return Err(not_applying(
                    key,
                    "applies to an on/off valve under PWM (--valve pwm)",
                    &format!(
                        "leave {key} out, or give --valve pwm (a proportional valve's speed is --response-time)"
                    ),
                ));
            }
        }
    }
    if valve == ValveKind::Pwm && ds.response_time_s.is_some() {
        return Err(not_applying(
            "--response-time",
            "applies to a proportional valve's spool (--valve proportional)",
            "leave it out, or give --valve proportional (an on/off valve's speed is --switching-delay)",
        ));
    }
    if ds.tube_length_m.is_some() && ds.dead_volume_m3.is_some() {
        return Err(DesignError::NotApplying {
            key: "--tube-length".into(),
            why: "sizes the dead volume when --dead-volume is not given, and --dead-volume is: give one of \
                  the two"
                .into(),
        });
    }
    Ok(())
}

/// Resolves a datasheet into a design: every value given is kept, every other derived and listed.
pub fn resolve(ds: &Datasheet) -> Result<Design, DesignError> {
    let mut assumed = Vec::new();
    check_options(ds)?;
    let (bore_m, size, stroke_m, rod_m) = cylinder(ds, &mut assumed)?;
    let supply_gauge = ds.supply_gauge_pa.unwrap_or_else(|| {
        assume(
            &mut assumed,
            "--supply",
            "6 bar gauge, common shop air".into(),
        );
        6e5
    });
    let atmosphere_pa = ATMOSPHERE_PA;
    let supply_abs_pa = supply_gauge + atmosphere_pa;
    let valve = ds.valve.unwrap_or_else(|| {
        assume(
            &mut assumed,
            "--valve",
            "pwm: an on/off 5/2 solenoid valve under PWM, as the paper's rig".into(),
        );
        ValveKind::Pwm
    });

    let (area_a, dead_a, dead_b) = dead_volumes(ds, bore_m, rod_m, &size, &mut assumed);

    let (c, b, flow_source) = valve_flow(
        ds,
        area_a * 0.5 * stroke_m + dead_a,
        supply_abs_pa,
        atmosphere_pa,
        &mut assumed,
    )?;
    let (pwm_frequency_hz, switching_delay_s, response_time_s) =
        valve_timing(ds, valve, &mut assumed);

    let (position_range_m, pressure_range_pa) =
        sensor_ranges(ds, stroke_m, supply_gauge, &mut assumed);

    let force_range = supply_gauge * area_a;
    let (moving_mass_kg, incline_deg, coulomb_n, viscous) =
        mechanics(ds, bore_m, rod_m, stroke_m, force_range, &mut assumed)?;

    // The experiment.
    let force_n = ds.force_n.unwrap_or_else(|| {
        let f = round2(FORCE_OF_RANGE * force_range);
        assume(
            &mut assumed,
            "--force",
            format!("{f} N contact force: 10 % of the force range, as the paper's 10 N"),
        );
        f
    });
    let sine_amplitude_n = round2(SINE_OF_FORCE * force_n);
    // The stiffer environment, twice the softer one.
    let peak = force_n + sine_amplitude_n;
    let stiffness = round2(peak / (COMPRESSION_OF_STROKE * stroke_m));
    let surface_m = SURFACE_OF_STROKE * stroke_m;
    let m_d_kg = round2(stiffness / PAPER_OMEGA2);
    let b_d_ns_per_m = round2(2.0 * PAPER_ZETA * (stiffness * m_d_kg).sqrt());
    let name = rig_name(ds, bore_m, stroke_m, valve)?;
    Ok(Design {
        name,
        bore_m,
        rod_m,
        stroke_m,
        dead_volume_a_m3: dead_a,
        dead_volume_b_m3: dead_b,
        size,
        supply_abs_pa,
        atmosphere_pa,
        valve,
        sonic_conductance_m3_per_s_pa: c,
        critical_pressure_ratio: b,
        pwm_frequency_hz,
        switching_delay_s,
        response_time_s,
        flow_source,
        flow_key: ds
            .flow
            .as_ref()
            .map_or("--valve-flow", |f| flow_option(f).0),
        position_range_m,
        pressure_range_pa,
        moving_mass_kg,
        incline_deg,
        coulomb_n,
        viscous_n_s_per_m: viscous,
        force_n,
        sine_amplitude_n,
        stiffness_n_per_m: stiffness,
        stiffness_after_n_per_m: round2(2.0 * stiffness),
        surface_m,
        m_d_kg,
        b_d_ns_per_m,
        assumptions: assumed,
    })
}

/// The cylinder: its bore (given, or a standard size), that size's data, its stroke and its rod, m.
fn cylinder(
    ds: &Datasheet,
    assumed: &mut Vec<Assumption>,
) -> Result<(f64, series::Size, f64, f64), DesignError> {
    let (bore_m, size) = match (ds.bore_m, ds.iso_bore_mm) {
        (Some(_), Some(_)) => {
            return Err(DesignError::Value {
                key: "--iso-bore".into(),
                value: format!("{}", ds.iso_bore_mm.unwrap_or_default()),
                why: "give --bore or --iso-bore, not both".into(),
            });
        }
        (Some(b), None) => (b, series::nearest(b * 1e3)),
        (None, Some(mm)) => {
            let s = series::by_bore(mm).ok_or_else(|| DesignError::Value {
                key: "--iso-bore".into(),
                value: format!("{mm}"),
                why: format!(
                    "not a bore of ISO 6432 or ISO 15552 (mm: {}); give --bore for another size",
                    series::bores()
                ),
            })?;
            (mm * 1e-3, s)
        }
        (None, None) => {
            return Err(DesignError::Missing {
                key: "--bore".into(),
                why: "the cylinder's bore, e.g. --bore 25mm (or --iso-bore 32 for a standard size)"
                    .into(),
            });
        }
    };
    let stroke_m = ds.stroke_m.ok_or_else(|| DesignError::Missing {
        key: "--stroke".into(),
        why: "the cylinder's stroke, e.g. --stroke 100mm".into(),
    })?;
    let rod_m = match ds.rod_m {
        Some(r) => r,
        None if series::by_bore(bore_m * 1e3).is_some() => {
            assume(
                assumed,
                "--rod",
                format!(
                    "{} mm, the {} rod of a {} mm bore",
                    size.rod_mm, size.standard, size.bore_mm
                ),
            );
            size.rod_mm * 1e-3
        }
        None => {
            let r = round2(size.rod_mm / size.bore_mm * bore_m * 1e3) * 1e-3;
            assume(
                assumed,
                "--rod",
                format!(
                    "{:.1} mm: the rod-to-bore ratio of the nearest standard size ({} {} mm)",
                    r * 1e3,
                    size.standard,
                    size.bore_mm
                ),
            );
            r
        }
    };
    // Catalogue rods are 20–50 % of the bore (ISO 15552 320 mm: 63 mm; ISO 6432 8 mm: 4 mm): a thinner one
    // buckles, a thicker one leaves the rod side too little area to pull the load back.
    let ratio = rod_m / bore_m;
    if !(ROD_OF_BORE.0..=ROD_OF_BORE.1).contains(&ratio) {
        return Err(DesignError::Value {
            key: "--rod".into(),
            value: format!("{}mm", fmt_mm(rod_m)),
            why: format!(
                "{:.0} % of the {} mm bore; a rod of {:.0}–{:.0} % of the bore would work (catalogue rods are \
                 20–50 %: a thinner one buckles, a thicker one leaves the rod side no area to pull with), e.g. \
                 --rod {}mm, the rod of the {} {} mm size",
                ratio * 100.0,
                fmt_mm(bore_m),
                ROD_OF_BORE.0 * 100.0,
                ROD_OF_BORE.1 * 100.0,
                fmt_mm(size.rod_mm / size.bore_mm * bore_m),
                size.standard,
                size.bore_mm
            ),
        });
    }
    // The experiment scales with the stroke: a stroke under a quarter of the bore gives a force range too
    // large for the few mm the environment may compress, one over 25 bores (ISO 6432's 8 mm bore stops at
    // 200 mm) chambers whose air springs are too soft for the force loop.
    let strokes = stroke_m / bore_m;
    if !(STROKE_OF_BORE.0..=STROKE_OF_BORE.1).contains(&strokes) {
        let (lo, hi) = (STROKE_OF_BORE.0 * bore_m, STROKE_OF_BORE.1 * bore_m);
        return Err(DesignError::Value {
            key: "--stroke".into(),
            value: format!("{}mm", fmt_mm(stroke_m)),
            why: format!(
                "{:.2} bores on the {} mm bore; new rig designs for strokes of {}–{} bores ({}–{} mm here: a \
                 shorter stroke gives a force range too large for the few mm the experiment compresses, a longer \
                 one air springs too soft for its force loop); --stroke {}mm would work",
                strokes,
                fmt_mm(bore_m),
                STROKE_OF_BORE.0,
                STROKE_OF_BORE.1,
                fmt_mm(lo.max(0.01)),
                fmt_mm(hi.min(2.0)),
                fmt_mm(stroke_m.clamp(lo.max(0.01), hi.min(2.0)))
            ),
        });
    }
    Ok((bore_m, size, stroke_m, rod_m))
}

/// The chambers' dead volumes (cap side, rod side), m³, with the cap side's piston area, m²: end-cap
/// clearance and port (2 mm of bore) plus the tube to the valve.
fn dead_volumes(
    ds: &Datasheet,
    bore_m: f64,
    rod_m: f64,
    size: &series::Size,
    assumed: &mut Vec<Assumption>,
) -> (f64, f64, f64) {
    let tube_length = ds.tube_length_m.unwrap_or_else(|| {
        if ds.dead_volume_m3.is_none() {
            assume(
                assumed,
                "--tube-length",
                "0.5 m of tube from the valve to each port".into(),
            );
        }
        0.5
    });
    let area_a = std::f64::consts::FRAC_PI_4 * bore_m * bore_m;
    let area_b = area_a - std::f64::consts::FRAC_PI_4 * rod_m * rod_m;
    let tube = std::f64::consts::FRAC_PI_4 * (size.tube_inner_mm * 1e-3).powi(2) * tube_length;
    let (dead_a, dead_b) = match ds.dead_volume_m3 {
        Some(v) => (v, v),
        None => {
            let (a, b) = (area_a * 0.002 + tube, area_b * 0.002 + tube);
            assume(
                assumed,
                "--dead-volume",
                format!(
                    "cap side {:.2} cm³, rod side {:.2} cm³: 2 mm of bore at the end cap and port, and {} m of \
                     {} mm bore tube (the push-in size of a {} port)",
                    a * 1e6,
                    b * 1e6,
                    tube_length,
                    size.tube_inner_mm,
                    size.port
                ),
            );
            (a, b)
        }
    };
    (area_a, dead_a, dead_b)
}

/// The valve's flow, ISO 6358: (C, b, where they came from); `volume`, m³: a chamber at mid stroke, which a
/// valve sized here fills in `DEFAULT_FILL_TIME_S`.
fn valve_flow(
    ds: &Datasheet,
    volume: f64,
    supply_abs_pa: f64,
    atmosphere_pa: f64,
    assumed: &mut Vec<Assumption>,
) -> Result<(f64, f64, String), DesignError> {
    let b_given = ds.critical_pressure_ratio;
    Ok(match ds.flow {
        Some(FlowRating::Qn(q)) => {
            positive("--valve-flow", Some(q))?;
            let b = b_given.unwrap_or_else(|| {
                assume(
                    assumed,
                    "--valve-b",
                    "0.3, typical of a solenoid valve (QN alone does not give it)".into(),
                );
                0.3
            });
            (
                iso6358::c_from_qn(q, b),
                b,
                format!("QN {:.0} l/min (6 → 5 bar gauge) with b = {b}", q * 6e4),
            )
        }
        Some(FlowRating::Conductance(c)) => {
            positive("--valve-c", Some(c))?;
            let b = b_given.unwrap_or_else(|| {
                assume(
                    assumed,
                    "--valve-b",
                    "0.3, typical of a solenoid valve".into(),
                );
                0.3
            });
            (c, b, format!("C = {c:e} m³/(s Pa), b = {b}, as given"))
        }
        Some(FlowRating::Kv(kv)) | Some(FlowRating::Cv(kv)) => {
            let (key, kv, label) = match ds.flow {
                Some(FlowRating::Cv(cv)) => {
                    ("--valve-cv", iso6358::kv_from_cv(cv), format!("Cv {cv}"))
                }
                _ => ("--valve-kv", kv, format!("Kv {kv}")),
            };
            positive(key, Some(kv))?;
            let b = b_given.unwrap_or(iso6358::KV_CRITICAL_RATIO);
            (
                iso6358::c_from_kv(kv),
                b,
                format!("{label} through the VDI/VDE 2173 gas law (choked from b = {b})"),
            )
        }
        None => {
            let b = b_given.unwrap_or(0.3);
            // fill_time is proportional to 1/C: C = t(C = 1) / t.
            let sized =
                round2(fill_time(1.0, volume, supply_abs_pa, atmosphere_pa) / DEFAULT_FILL_TIME_S);
            // Within the valves there are (`--valve-c`'s range): a 320 mm bore over 2 m would need C = 1.7e-5,
            // which no valve has and the valve sheet refuses.
            let r = crate::limits::of("--valve-c").expect("--valve-c has a range");
            let c = sized.clamp(r.lo * r.si_per_unit, r.hi * r.si_per_unit);
            let fill = if c == sized {
                format!(
                    "fills a chamber at mid stroke in {} ms",
                    DEFAULT_FILL_TIME_S * 1e3
                )
            } else {
                format!(
                    "the nearest valve there is to one that fills a chamber at mid stroke in {} ms (C = {sized:.2e})",
                    DEFAULT_FILL_TIME_S * 1e3
                )
            };
            assume(
                assumed,
                "--valve-flow",
                format!(
                    "QN {:.0} l/min (C = {c:.2e} m³/(s Pa), b = {b}): a valve that {fill}",
                    iso6358::qn_from_c(c, b) * 6e4,
                ),
            );
            (c, b, "sized by new rig (no flow given)".into())
        }
    })
}

/// The valve's timing: PWM carrier frequency, Hz, switching delay and spool response time, s.
fn valve_timing(
    ds: &Datasheet,
    valve: ValveKind,
    assumed: &mut Vec<Assumption>,
) -> (f64, f64, f64) {
    let pwm_frequency_hz = match (valve, ds.pwm_frequency_hz) {
        (_, Some(f)) => f,
        (ValveKind::Pwm, None) => {
            assume(
                assumed,
                "--pwm-frequency",
                "40 Hz, the paper's carrier".into(),
            );
            40.0
        }
        (ValveKind::Proportional, None) => 40.0,
    };
    let switching_delay_s = match (valve, ds.switching_delay_s) {
        (_, Some(t)) => t,
        (ValveKind::Pwm, None) => {
            assume(
                assumed,
                "--switching-delay",
                "5 ms, a compact solenoid valve".into(),
            );
            0.005
        }
        (ValveKind::Proportional, None) => 0.005,
    };
    let response_time_s = match (valve, ds.response_time_s) {
        (_, Some(t)) => t,
        (ValveKind::Proportional, None) => {
            assume(
                assumed,
                "--response-time",
                "5 ms first-order spool response and 2 % underlap".into(),
            );
            0.005
        }
        (ValveKind::Pwm, None) => 0.005,
    };
    (pwm_frequency_hz, switching_delay_s, response_time_s)
}

/// The sensors' spans: the position sensor's from 0, m, and the differential pressure transmitter's, Pa;
/// `supply_gauge`, Pa.
fn sensor_ranges(
    ds: &Datasheet,
    stroke_m: f64,
    supply_gauge: f64,
    assumed: &mut Vec<Assumption>,
) -> (f64, f64) {
    let position_range_m = ds.position_range_m.unwrap_or_else(|| {
        let r = (stroke_m * 1.2 / 0.025).ceil() * 0.025;
        assume(
            assumed,
            "--position-range",
            format!(
                "0–{:.0} mm: the stroke with 20 % margin, to the next 25 mm",
                r * 1e3
            ),
        );
        r
    });
    let pressure_range_pa = ds.pressure_range_pa.unwrap_or_else(|| {
        let r = (supply_gauge * 1.1 / 2e5).ceil() * 2e5;
        assume(
            assumed,
            "--pressure-range",
            format!(
                "±{:.1} MPa differential transmitter: the supply with 10 % margin, to the next 0.2 MPa",
                r * 1e-6
            ),
        );
        r
    });
    (position_range_m, pressure_range_pa)
}

/// The moving parts: mass, kg, incline, degrees below the horizontal, Coulomb and viscous friction;
/// `force_range`, N: the supply's gauge pressure on the cap-side area.
fn mechanics(
    ds: &Datasheet,
    bore_m: f64,
    rod_m: f64,
    stroke_m: f64,
    force_range: f64,
    assumed: &mut Vec<Assumption>,
) -> Result<(f64, f64, f64, f64), DesignError> {
    let area_a = std::f64::consts::FRAC_PI_4 * bore_m * bore_m;
    let moving_mass_kg = ds.moving_mass_kg.unwrap_or_else(|| {
        let rod = std::f64::consts::FRAC_PI_4 * rod_m * rod_m * (stroke_m + bore_m) * 7850.0;
        let piston = area_a * 0.5 * bore_m * 2700.0;
        let m = round2(rod + piston + 0.5);
        assume(
            assumed,
            "--mass",
            format!(
                "{m} kg: a steel rod ({:.3} kg), an aluminium piston ({:.3} kg) and 0.5 kg of flange and carriage",
                rod, piston
            ),
        );
        m
    });
    let incline_deg = ds.incline_deg.unwrap_or_else(|| {
        assume(assumed, "--incline", "0 deg: the axis horizontal".into());
        0.0
    });
    let coulomb_n = match ds.coulomb_n {
        Some(f) => f,
        None => {
            let f = round2(0.01 * force_range);
            assume(
                assumed,
                "--friction",
                format!("{f} N Coulomb friction: 1 % of the force range, low-friction seals"),
            );
            f
        }
    };
    // Viscous friction scales with the seal's circumference and the piston's area: the paper's 20 N s/m
    // on 16 mm, by area (an assumption said always: datasheets do not give it).
    let viscous = round2(20.0 * area_a / (std::f64::consts::FRAC_PI_4 * 0.016 * 0.016));
    assume(
        assumed,
        "viscous_n_s_per_m",
        format!(
            "{viscous} N s/m: the paper's 20 N s/m on a 16 mm bore, scaled by the piston area (edit the actuator sheet)"
        ),
    );
    Ok((moving_mass_kg, incline_deg, coulomb_n, viscous))
}

/// The rig's name: given, or from its bore, stroke and valve; letters, digits, '-', '_' and '.'.
fn rig_name(
    ds: &Datasheet,
    bore_m: f64,
    stroke_m: f64,
    valve: ValveKind,
) -> Result<String, DesignError> {
    let name = ds.name.clone().unwrap_or_else(|| {
        format!(
            "rig-{}x{}-{}",
            fmt_mm(bore_m),
            fmt_mm(stroke_m),
            match valve {
                ValveKind::Pwm => "pwm",
                ValveKind::Proportional => "proportional",
            }
        )
    });
    if !valid_name(&name) {
        return Err(DesignError::Value {
            key: "--name".into(),
            value: format!("`{name}`"),
            why: format!(
                "a rig name of up to {NAME_MAX} letters, digits, '-', '_' and '.', not starting with '.' or '-' (it \
                 names the scene and its output folder out/NAME; the default is the directory's name), e.g. --name \
                 my-rig"
            ),
        });
    }
    Ok(name)
}

/// The longest rig name (it names a folder, and a line of every file).
pub const NAME_MAX: usize = 64;

/// A rig name: letters, digits, '-', '_' and '.', not hidden (`.x`, `..`) nor an option (`-x`).
pub fn valid_name(name: &str) -> bool {
    !name.is_empty()
        && name.len() <= NAME_MAX
        && !name.starts_with(['.', '-'])
        && name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.'))
}

/// Notes what was taken for a value the datasheet does not give, and why.
fn assume(assumed: &mut Vec<Assumption>, key: &'static str, text: String) {
    assumed.push(Assumption { key, text });
}

/// A length in mm without trailing zeros (25, 12.5).
pub fn fmt_mm(m: f64) -> String {
    let mm = (m * 1e4).round() / 10.0;
    if mm.fract() == 0.0 {
        format!("{mm:.0}")
    } else {
        format!("{mm}")
    }
}
