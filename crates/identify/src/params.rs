//! The parameters `identify` can fit: their keys (the actuator sheet's dotted keys, plus sensor offsets),
//! where each lives in the model, default bounds, and which experiment identifies each.

use pneuflex_pneumatics::{Friction, OneDofModel, ValveKind};

/// A parameter `--free` can name.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Key {
    /// ISO 6358 sonic conductance C of the valve paths, m^3/(s Pa) (eq. 11).
    SonicConductance,
    /// ISO 6358 critical pressure ratio b (eq. 11).
    CriticalRatio,
    /// Switching delay of an on/off valve, s.
    SwitchingDelay,
    /// Spool time constant of a proportional valve, s.
    ResponseTime,
    /// Dead volume of chamber A, m^3 (eqs. 9-10).
    DeadVolumeA,
    /// Dead volume of chamber B, m^3.
    DeadVolumeB,
    /// Moving mass m, kg (eq. 1).
    MovingMass,
    /// Viscous friction K_v, N s/m (eq. 1).
    Viscous,
    /// Coulomb friction F_c, N (eq. 1's f).
    Coulomb,
    /// Break-away friction F_s of the stick-slip law, N.
    Static,
    /// Offset of the chamber-A pressure reading, Pa (measured = true + offset).
    OffsetPa,
    /// Offset of the chamber-B pressure reading, Pa.
    OffsetPb,
    /// Offset of the position reading, m.
    OffsetX,
    /// Sonic conductance C of one valve path (0 supply -> A, 1 A -> exhaust, 2 supply -> B, 3 B -> exhaust:
    /// `pneuflex_pneumatics::PATHS`), m^3/(s Pa); written as `[valve.paths.<path>]` in the valve sheet.
    PathConductance(u8),
    /// Critical pressure ratio b of one valve path (as [`Key::PathConductance`]).
    PathCritical(u8),
}

/// The per-path keys' names, in the order of `pneuflex_pneumatics::PATHS`.
const PATH_C: [&str; 4] = [
    "valve.paths.supply_a.sonic_conductance_m3_per_s_pa",
    "valve.paths.a_exhaust.sonic_conductance_m3_per_s_pa",
    "valve.paths.supply_b.sonic_conductance_m3_per_s_pa",
    "valve.paths.b_exhaust.sonic_conductance_m3_per_s_pa",
];
const PATH_B: [&str; 4] = [
    "valve.paths.supply_a.critical_pressure_ratio",
    "valve.paths.a_exhaust.critical_pressure_ratio",
    "valve.paths.supply_b.critical_pressure_ratio",
    "valve.paths.b_exhaust.critical_pressure_ratio",
];

/// Every key, in the order of the report.
pub const ALL: [Key; 21] = [
    Key::SonicConductance,
    Key::CriticalRatio,
    Key::SwitchingDelay,
    Key::ResponseTime,
    Key::DeadVolumeA,
    Key::DeadVolumeB,
    Key::MovingMass,
    Key::Viscous,
    Key::Coulomb,
    Key::Static,
    Key::OffsetPa,
    Key::OffsetPb,
    Key::OffsetX,
    Key::PathConductance(0),
    Key::PathConductance(1),
    Key::PathConductance(2),
    Key::PathConductance(3),
    Key::PathCritical(0),
    Key::PathCritical(1),
    Key::PathCritical(2),
    Key::PathCritical(3),
];

/// Sensor offsets (not in the actuator sheet; reported, and subtracted from the readings in the replay).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Offsets {
    /// Chamber-A pressure offset, Pa.
    pub p_a: f64,
    /// Chamber-B pressure offset, Pa.
    pub p_b: f64,
    /// Position offset, m.
    pub x: f64,
}

impl Key {
    /// The dotted key as in the sheets (`offset.*` for sensor offsets).
    pub fn name(self) -> &'static str {
        match self {
            Key::SonicConductance => "valve.sonic_conductance_m3_per_s_pa",
            Key::CriticalRatio => "valve.critical_pressure_ratio",
            Key::SwitchingDelay => "valve.switching_delay_s",
            Key::ResponseTime => "valve.response_time_s",
            Key::DeadVolumeA => "cylinder.dead_volume_a_m3",
            Key::DeadVolumeB => "cylinder.dead_volume_b_m3",
            Key::MovingMass => "mechanics.moving_mass_kg",
            Key::Viscous => "mechanics.viscous_n_s_per_m",
            Key::Coulomb => "mechanics.coulomb_n",
            Key::Static => "mechanics.static_n",
            Key::OffsetPa => "offset.p_a_pa",
            Key::OffsetPb => "offset.p_b_pa",
            Key::OffsetX => "offset.x_m",
            Key::PathConductance(i) => PATH_C[usize::from(i) & 3],
            Key::PathCritical(i) => PATH_B[usize::from(i) & 3],
        }
    }

    /// The key named `s` (its full dotted name, or the last part, e.g. `dead_volume_a_m3`).
    pub fn parse(s: &str) -> Option<Key> {
        let s = s.trim();
        ALL.iter()
            .copied()
            .find(|k| k.name() == s || k.name().rsplit('.').next() == Some(s))
    }

    /// Which component file holds the key (`None` for sensor offsets): `valve`, `cylinder` or the
    /// actuator sheet itself (`actuator`).
    pub fn file(self) -> Option<&'static str> {
        match self {
            Key::SonicConductance
            | Key::CriticalRatio
            | Key::SwitchingDelay
            | Key::ResponseTime
            | Key::PathConductance(_)
            | Key::PathCritical(_) => Some("valve"),
            Key::DeadVolumeA | Key::DeadVolumeB => Some("cylinder"),
            Key::MovingMass | Key::Viscous | Key::Coulomb | Key::Static => Some("actuator"),
            Key::OffsetPa | Key::OffsetPb | Key::OffsetX => None,
        }
    }

    /// Whether the key applies to this model (a switching delay needs an on/off valve, ...); the reason if not.
    pub fn applies(self, m: &OneDofModel) -> Result<(), String> {
        match (self, m.actuator.valve.kind, m.mechanics.friction) {
            (Key::SwitchingDelay, ValveKind::Proportional { .. }, _) => {
                Err("the valve is proportional; its lag is valve.response_time_s".into())
            }
            (Key::ResponseTime, ValveKind::OnOffPwm { .. }, _) => {
                Err("the valve is on/off (PWM); its lag is valve.switching_delay_s".into())
            }
            (Key::Static, _, Friction::Smooth { .. }) => {
                Err("mechanics.friction is \"smooth\"; static_n applies to \"stick_slip\"".into())
            }
            _ => Ok(()),
        }
    }

    /// The value in `m` (offsets from `o`).
    pub fn get(self, m: &OneDofModel, o: &Offsets) -> f64 {
        let v = &m.actuator.valve;
        let c = &m.actuator.cylinder;
        let me = &m.mechanics;
        match self {
            Key::SonicConductance => v.orifice.sonic_conductance_m3_per_s_pa,
            Key::CriticalRatio => v.orifice.critical_pressure_ratio,
            Key::SwitchingDelay => match v.kind {
                ValveKind::OnOffPwm {
                    switching_delay_s, ..
                } => switching_delay_s,
                _ => f64::NAN,
            },
            Key::ResponseTime => match v.kind {
                ValveKind::Proportional { response_time_s } => response_time_s,
                _ => f64::NAN,
            },
            Key::DeadVolumeA => c.dead_volume_a_m3,
            Key::DeadVolumeB => c.dead_volume_b_m3,
            Key::MovingMass => me.moving_mass_kg,
            Key::Viscous => me.viscous_n_s_per_m,
            Key::Coulomb => match me.friction {
                Friction::Smooth { coulomb_n, .. } | Friction::StickSlip { coulomb_n, .. } => {
                    coulomb_n
                }
            },
            Key::Static => match me.friction {
                Friction::StickSlip { static_n, .. } => static_n,
                _ => f64::NAN,
            },
            Key::OffsetPa => o.p_a,
            Key::OffsetPb => o.p_b,
            Key::OffsetX => o.x,
            Key::PathConductance(i) => v.path(usize::from(i) & 3).sonic_conductance_m3_per_s_pa,
            Key::PathCritical(i) => v.path(usize::from(i) & 3).critical_pressure_ratio,
        }
    }

    /// Sets the value in `m` (offsets in `o`).
    pub fn set(self, m: &mut OneDofModel, o: &mut Offsets, x: f64) {
        let v = &mut m.actuator.valve;
        let c = &mut m.actuator.cylinder;
        let me = &mut m.mechanics;
        match self {
            Key::SonicConductance => v.orifice.sonic_conductance_m3_per_s_pa = x,
            Key::CriticalRatio => v.orifice.critical_pressure_ratio = x,
            Key::SwitchingDelay => {
                if let ValveKind::OnOffPwm {
                    switching_delay_s, ..
                } = &mut v.kind
                {
                    *switching_delay_s = x;
                }
            }
            Key::ResponseTime => {
                if let ValveKind::Proportional { response_time_s } = &mut v.kind {
                    *response_time_s = x;
                }
            }
            Key::DeadVolumeA => c.dead_volume_a_m3 = x,
            Key::DeadVolumeB => c.dead_volume_b_m3 = x,
            Key::MovingMass => me.moving_mass_kg = x,
            Key::Viscous => me.viscous_n_s_per_m = x,
            Key::Coulomb => match &mut me.friction {
                Friction::Smooth { coulomb_n, .. } | Friction::StickSlip { coulomb_n, .. } => {
                    *coulomb_n = x
                }
            },
            Key::Static => {
                if let Friction::StickSlip { static_n, .. } = &mut me.friction {
                    *static_n = x;
                }
            }
            Key::OffsetPa => o.p_a = x,
            Key::OffsetPb => o.p_b = x,
            Key::OffsetX => o.x = x,
            // A path of its own from here on (the valve's C and b no longer reach it).
            Key::PathConductance(i) => {
                let i = usize::from(i) & 3;
                let mut p = v.path(i);
                p.sonic_conductance_m3_per_s_pa = x;
                v.paths[i] = Some(p);
            }
            Key::PathCritical(i) => {
                let i = usize::from(i) & 3;
                let mut p = v.path(i);
                p.critical_pressure_ratio = x;
                v.paths[i] = Some(p);
            }
        }
    }

    /// Default bounds around the start value `x0`: a factor 5 either way for scale parameters (the sheets'
    /// values are assumptions, issue 16), the model's validity range for b, less than the PWM period for a
    /// switching delay, +-20 kPa / +-2 mm for offsets.
    pub fn default_bounds(self, x0: f64, m: &OneDofModel) -> (f64, f64) {
        match self {
            Key::CriticalRatio | Key::PathCritical(_) => (0.01, 0.9),
            Key::SwitchingDelay => {
                let period = match m.actuator.valve.kind {
                    ValveKind::OnOffPwm {
                        pwm_frequency_hz, ..
                    } => 1.0 / pwm_frequency_hz,
                    _ => 1.0,
                };
                (0.0, 0.9 * period)
            }
            Key::ResponseTime => (0.0, (5.0 * x0).max(0.05)),
            Key::Viscous | Key::Coulomb | Key::Static => (0.0, (5.0 * x0).max(1.0)),
            Key::OffsetPa | Key::OffsetPb => (x0 - 20e3, x0 + 20e3),
            Key::OffsetX => (x0 - 2e-3, x0 + 2e-3),
            _ => (0.2 * x0, 5.0 * x0),
        }
    }

    /// A typical magnitude, for scaling the Jacobian (the start value, or a unit for offsets and zero starts).
    pub fn scale(self, x0: f64) -> f64 {
        let unit = match self {
            Key::OffsetPa | Key::OffsetPb => 1e3,
            Key::OffsetX => 1e-4,
            Key::SwitchingDelay | Key::ResponseTime => 1e-3,
            Key::Viscous | Key::Coulomb | Key::Static => 1.0,
            _ => 0.0,
        };
        if x0.abs() > unit {
            x0.abs()
        } else {
            unit.max(f64::MIN_POSITIVE)
        }
    }

    /// The experiment that identifies this parameter, for the warnings.
    pub fn experiment(self) -> &'static str {
        match self {
            Key::SonicConductance | Key::CriticalRatio => {
                "full steps between supply and exhaust with the piston held (at an end stop or against the \
                 block): choked and subsonic flow in both directions (rig excite --signal steps, contact)"
            }
            Key::PathConductance(0 | 1) | Key::PathCritical(0 | 1) => {
                "full fills and exhausts of chamber A with the piston held (at an end stop or against the \
                 block), each through to the subsonic end (rig excite --signal steps --hold 0.2, contact)"
            }
            Key::PathConductance(_) | Key::PathCritical(_) => {
                "full fills and exhausts of chamber B with the piston held (at an end stop or against the \
                 block), each through to the subsonic end (rig excite --signal steps --hold 0.2, contact)"
            }
            Key::SwitchingDelay | Key::ResponseTime => {
                "fast command edges with the pressures logged at the full rate (rig excite --signal prbs)"
            }
            Key::DeadVolumeA | Key::DeadVolumeB => {
                "pressure transients at several piston positions, including near each end of the stroke \
                 (rig excite --signal steps with different centres)"
            }
            Key::MovingMass => {
                "free motion with large accelerations: fast, large steps or PRBS away from the stops \
                 (rig excite --signal prbs --amplitude 1)"
            }
            Key::Viscous => {
                "free motion at several speeds (rig excite --signal chirp, free motion)"
            }
            Key::Coulomb | Key::Static => {
                "slow free motion with reversals (rig excite --signal chirp at a small amplitude)"
            }
            Key::OffsetPa | Key::OffsetPb => {
                "a stretch at rest with the valve vented (both chambers at atmosphere) at the start of a log"
            }
            Key::OffsetX => "a stretch at rest against a stop of known position",
        }
    }
}
