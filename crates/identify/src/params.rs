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
    /// Wall heat transfer coefficient h, W/(m^2 K) (Newton cooling, docs/pneumatics.md).
    WallHeat,
    /// Wall temperature T_w, K.
    WallTemperature,
    /// Sonic conductance C of a leak (0 across the piston, 1 A -> atmosphere, 2 B -> atmosphere:
    /// `pneuflex_pneumatics::LEAKS`), m^3/(s Pa).
    LeakConductance(u8),
    /// Critical pressure ratio b of a leak (as [`Key::LeakConductance`]).
    LeakCritical(u8),
    /// Gas volume of each line, m^3.
    LineVolume,
    /// Sonic conductance C of each line's restriction, m^3/(s Pa).
    LineConductance,
    /// Critical pressure ratio b of each line's restriction.
    LineCritical,
    /// Length of each line, m (transport delay L / c).
    LineLength,
    /// Speed of sound in the lines, m/s.
    LineSoundSpeed,
    /// Delay of a de-energising edge of an on/off valve, s.
    ReleaseDelay,
    /// First-order time constant of an on/off spool's travel to the energised position, s.
    SpoolTimeConstant,
    /// The same towards the spring position, s.
    ReleaseTimeConstant,
    /// Dead time of a proportional valve, s.
    DeadTime,
    /// Rise of the Coulomb friction with |p_a - p_b|, N/Pa.
    CoulombPressure,
    /// LuGre bristle stiffness sigma0, N/m.
    BristleStiffness,
    /// LuGre bristle damping sigma1, N s/m.
    BristleDamping,
    /// Polytropic exponent n of the chamber process (1 isothermal, 1.4 adiabatic air; eqs. 5-10 with n
    /// for k): a chamber that exchanges heat with its wall, lumped.
    PolytropicExponent,
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

/// The leak keys' names, in the order of `pneuflex_pneumatics::LEAKS`.
const LEAK_C: [&str; 3] = [
    "cylinder.leaks.piston.sonic_conductance_m3_per_s_pa",
    "cylinder.leaks.a_atmosphere.sonic_conductance_m3_per_s_pa",
    "cylinder.leaks.b_atmosphere.sonic_conductance_m3_per_s_pa",
];
const LEAK_B: [&str; 3] = [
    "cylinder.leaks.piston.critical_pressure_ratio",
    "cylinder.leaks.a_atmosphere.critical_pressure_ratio",
    "cylinder.leaks.b_atmosphere.critical_pressure_ratio",
];

/// Every key, in the order of the report.
pub const ALL: [Key; 42] = [
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
    Key::WallHeat,
    Key::WallTemperature,
    Key::LeakConductance(0),
    Key::LeakConductance(1),
    Key::LeakConductance(2),
    Key::LeakCritical(0),
    Key::LeakCritical(1),
    Key::LeakCritical(2),
    Key::LineVolume,
    Key::LineConductance,
    Key::LineCritical,
    Key::LineLength,
    Key::LineSoundSpeed,
    Key::ReleaseDelay,
    Key::SpoolTimeConstant,
    Key::ReleaseTimeConstant,
    Key::DeadTime,
    Key::CoulombPressure,
    Key::BristleStiffness,
    Key::BristleDamping,
    Key::PolytropicExponent,
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
            Key::WallHeat => "cylinder.wall_heat_transfer_w_per_m2_k",
            Key::WallTemperature => "cylinder.wall_temperature_k",
            Key::LeakConductance(i) => LEAK_C[usize::from(i).min(2)],
            Key::LeakCritical(i) => LEAK_B[usize::from(i).min(2)],
            Key::LineVolume => "lines.volume_m3",
            Key::LineConductance => "lines.sonic_conductance_m3_per_s_pa",
            Key::LineCritical => "lines.critical_pressure_ratio",
            Key::LineLength => "lines.length_m",
            Key::LineSoundSpeed => "lines.speed_of_sound_m_per_s",
            Key::ReleaseDelay => "valve.release_delay_s",
            Key::SpoolTimeConstant => "valve.spool_time_constant_s",
            Key::ReleaseTimeConstant => "valve.release_time_constant_s",
            Key::DeadTime => "valve.dead_time_s",
            Key::CoulombPressure => "mechanics.coulomb_pressure_n_per_pa",
            Key::BristleStiffness => "mechanics.bristle_stiffness_n_per_m",
            Key::BristleDamping => "mechanics.bristle_damping_n_s_per_m",
            Key::PolytropicExponent => "gas.polytropic_exponent",
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
            | Key::PathCritical(_)
            | Key::ReleaseDelay
            | Key::SpoolTimeConstant
            | Key::ReleaseTimeConstant
            | Key::DeadTime => Some("valve"),
            Key::DeadVolumeA
            | Key::DeadVolumeB
            | Key::WallHeat
            | Key::WallTemperature
            | Key::LeakConductance(_)
            | Key::LeakCritical(_) => Some("cylinder"),
            Key::MovingMass
            | Key::Viscous
            | Key::Coulomb
            | Key::Static
            | Key::LineVolume
            | Key::LineConductance
            | Key::LineCritical
            | Key::LineLength
            | Key::LineSoundSpeed
            | Key::CoulombPressure
            | Key::BristleStiffness
            | Key::BristleDamping
            | Key::PolytropicExponent => Some("actuator"),
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
            (
                Key::ReleaseDelay | Key::SpoolTimeConstant | Key::ReleaseTimeConstant,
                ValveKind::Proportional { .. },
                _,
            ) => Err(
                "the valve is proportional; its lags are valve.response_time_s and valve.dead_time_s"
                    .into(),
            ),
            (Key::DeadTime, ValveKind::OnOffPwm { .. }, _) => Err(
                "the valve is on/off (PWM); its delays are valve.switching_delay_s and valve.release_delay_s"
                    .into(),
            ),
            (Key::Static, _, Friction::Smooth { .. }) => Err(
                "mechanics.friction is \"smooth\"; static_n applies to \"stick_slip\" and \"lugre\""
                    .into(),
            ),
            (Key::BristleStiffness | Key::BristleDamping, _, f)
                if !matches!(f, Friction::LuGre { .. }) =>
            {
                Err("mechanics.friction is not \"lugre\"; the bristles belong to LuGre".into())
            }
            _ => self.given(m),
        }
    }

    /// For an effect's key: whether the sheet gives the effect, with a value the fit can move (a factor
    /// of 0 is 0, and a start on the bound 0 cannot leave it).
    fn given(self, m: &OneDofModel) -> Result<(), String> {
        let e = &m.effects;
        let present = match self {
            Key::WallHeat | Key::WallTemperature => e.wall_heat.is_some(),
            Key::LeakConductance(i) | Key::LeakCritical(i) => e.leaks.get(usize::from(i)).is_some(),
            Key::LineVolume
            | Key::LineConductance
            | Key::LineCritical
            | Key::LineLength
            | Key::LineSoundSpeed => e.lines.is_some(),
            Key::CoulombPressure => e.coulomb_pressure_n_per_pa.is_some(),
            // The valve's kind and the friction law are checked above; their values default.
            Key::ReleaseDelay
            | Key::SpoolTimeConstant
            | Key::ReleaseTimeConstant
            | Key::DeadTime
            | Key::BristleStiffness
            | Key::BristleDamping => true,
            _ => return Ok(()),
        };
        let what = match self.file() {
            Some("cylinder") => "the cylinder sheet",
            Some("valve") => "the valve sheet",
            _ => "the actuator sheet",
        };
        if !present {
            return Err(format!(
                "{what} does not give this effect; add {} with a start value",
                self.name()
            ));
        }
        let v = self.get(m, &Offsets::default());
        if v > 0.0 {
            Ok(())
        } else {
            Err(format!(
                "is {v} in {what}; give a start value > 0 to fit or perturb it"
            ))
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
            Key::Coulomb => me.friction.coulomb_n(),
            Key::Static => match me.friction {
                Friction::StickSlip { static_n, .. } | Friction::LuGre { static_n, .. } => static_n,
                _ => f64::NAN,
            },
            Key::OffsetPa => o.p_a,
            Key::OffsetPb => o.p_b,
            Key::OffsetX => o.x,
            Key::PathConductance(i) => v.path(usize::from(i) & 3).sonic_conductance_m3_per_s_pa,
            Key::PathCritical(i) => v.path(usize::from(i) & 3).critical_pressure_ratio,
            Key::PolytropicExponent => m.actuator.gas.polytropic_exponent,
            _ => self.get_effect(m),
        }
    }

    /// The value of an effect's key (NaN where the model lacks the effect).
    fn get_effect(self, m: &OneDofModel) -> f64 {
        let e = &m.effects;
        let nan = f64::NAN;
        let heat = e.wall_heat;
        let line = e.lines;
        let spool = e.spool.unwrap_or_default();
        let leak = |i: u8| e.leaks.get(usize::from(i));
        let lugre = match m.mechanics.friction {
            Friction::LuGre {
                bristle_stiffness_n_per_m,
                bristle_damping_n_s_per_m,
                ..
            } => Some((bristle_stiffness_n_per_m, bristle_damping_n_s_per_m)),
            _ => None,
        };
        let switching = match m.actuator.valve.kind {
            ValveKind::OnOffPwm {
                switching_delay_s, ..
            } => switching_delay_s,
            _ => nan,
        };
        match self {
            Key::WallHeat => heat.map_or(nan, |h| h.coefficient_w_per_m2_k),
            Key::WallTemperature => heat.map_or(nan, |h| h.wall_temperature_k),
            Key::LeakConductance(i) => leak(i).map_or(nan, |o| o.sonic_conductance_m3_per_s_pa),
            Key::LeakCritical(i) => leak(i).map_or(nan, |o| o.critical_pressure_ratio),
            Key::LineVolume => line.map_or(nan, |l| l.volume_m3),
            Key::LineConductance => line.map_or(nan, |l| l.orifice.sonic_conductance_m3_per_s_pa),
            Key::LineCritical => line.map_or(nan, |l| l.orifice.critical_pressure_ratio),
            Key::LineLength => line.map_or(nan, |l| l.length_m),
            Key::LineSoundSpeed => line.map_or(nan, |l| l.speed_of_sound_m_per_s),
            Key::ReleaseDelay => spool.release_delay_s.unwrap_or(switching),
            Key::SpoolTimeConstant => spool.spool_time_constant_s,
            Key::ReleaseTimeConstant => spool
                .release_time_constant_s
                .unwrap_or(spool.spool_time_constant_s),
            Key::DeadTime => spool.dead_time_s,
            Key::CoulombPressure => e.coulomb_pressure_n_per_pa.unwrap_or(nan),
            Key::BristleStiffness => lugre.map_or(nan, |l| l.0),
            Key::BristleDamping => lugre.map_or(nan, |l| l.1),
            _ => nan,
        }
    }

    /// Sets an effect's key (a key whose effect the model lacks is ignored: [`Key::applies`] refuses it).
    fn set_effect(self, m: &mut OneDofModel, x: f64) {
        let e = &mut m.effects;
        match self {
            Key::WallHeat => {
                if let Some(h) = &mut e.wall_heat {
                    h.coefficient_w_per_m2_k = x;
                }
            }
            Key::WallTemperature => {
                if let Some(h) = &mut e.wall_heat {
                    h.wall_temperature_k = x;
                }
            }
            Key::LeakConductance(i) | Key::LeakCritical(i) => {
                let i = usize::from(i);
                if let Some(mut o) = e.leaks.get(i) {
                    if matches!(self, Key::LeakConductance(_)) {
                        o.sonic_conductance_m3_per_s_pa = x;
                    } else {
                        o.critical_pressure_ratio = x;
                    }
                    e.leaks.set(i, Some(o));
                }
            }
            Key::LineVolume
            | Key::LineConductance
            | Key::LineCritical
            | Key::LineLength
            | Key::LineSoundSpeed => {
                if let Some(l) = &mut e.lines {
                    match self {
                        Key::LineVolume => l.volume_m3 = x,
                        Key::LineConductance => l.orifice.sonic_conductance_m3_per_s_pa = x,
                        Key::LineCritical => l.orifice.critical_pressure_ratio = x,
                        Key::LineLength => l.length_m = x,
                        _ => l.speed_of_sound_m_per_s = x,
                    }
                }
            }
            Key::ReleaseDelay => e.spool.get_or_insert_default().release_delay_s = Some(x),
            Key::SpoolTimeConstant => e.spool.get_or_insert_default().spool_time_constant_s = x,
            Key::ReleaseTimeConstant => {
                e.spool.get_or_insert_default().release_time_constant_s = Some(x)
            }
            Key::DeadTime => e.spool.get_or_insert_default().dead_time_s = x,
            Key::CoulombPressure => e.coulomb_pressure_n_per_pa = Some(x),
            Key::BristleStiffness | Key::BristleDamping => {
                if let Friction::LuGre {
                    bristle_stiffness_n_per_m,
                    bristle_damping_n_s_per_m,
                    ..
                } = &mut m.mechanics.friction
                {
                    if self == Key::BristleStiffness {
                        *bristle_stiffness_n_per_m = x;
                    } else {
                        *bristle_damping_n_s_per_m = x;
                    }
                }
            }
            _ => {}
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
                Friction::Smooth { coulomb_n, .. }
                | Friction::StickSlip { coulomb_n, .. }
                | Friction::LuGre { coulomb_n, .. } => *coulomb_n = x,
            },
            Key::Static => {
                if let Friction::StickSlip { static_n, .. } | Friction::LuGre { static_n, .. } =
                    &mut me.friction
                {
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
            Key::PolytropicExponent => m.actuator.gas.polytropic_exponent = x,
            _ => self.set_effect(m, x),
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
            // LuGre's bristles relax towards F_c / sigma0: F_c must stay above 0.
            Key::Coulomb if matches!(m.mechanics.friction, Friction::LuGre { .. }) => {
                (0.2 * x0, 5.0 * x0)
            }
            Key::Viscous | Key::Coulomb | Key::Static => (0.0, (5.0 * x0).max(1.0)),
            Key::OffsetPa | Key::OffsetPb => (x0 - 20e3, x0 + 20e3),
            Key::OffsetX => (x0 - 2e-3, x0 + 2e-3),
            // The sheet's range: isothermal to monatomic (above 1.4 is not air, but a fit may say so).
            Key::PolytropicExponent => (1.0, 1.67),
            _ => self.effect_bounds(x0, m),
        }
    }

    /// Default bounds of an effect's key (and a factor 5 either way for the scale parameters), within
    /// the sheets' own limits so that the fitted sheet loads.
    fn effect_bounds(self, x0: f64, m: &OneDofModel) -> (f64, f64) {
        let period = match m.actuator.valve.kind {
            ValveKind::OnOffPwm {
                pwm_frequency_hz, ..
            } => 1.0 / pwm_frequency_hz,
            _ => 1.0,
        };
        match self {
            Key::WallHeat => (0.2 * x0, (5.0 * x0).min(1e4)),
            Key::WallTemperature => ((x0 - 30.0).max(200.0), (x0 + 30.0).min(400.0)),
            Key::LeakCritical(_) | Key::LineCritical => (0.01, 0.9),
            Key::LineSoundSpeed => ((0.5 * x0).max(50.0), (2.0 * x0).min(2000.0)),
            Key::ReleaseDelay => (0.0, 0.9 * period),
            Key::SpoolTimeConstant | Key::ReleaseTimeConstant => (0.0, (5.0 * x0).max(0.01)),
            Key::DeadTime => (0.0, (5.0 * x0).max(0.05)),
            Key::CoulombPressure => (0.0, (5.0 * x0).min(1e-3)),
            Key::BristleStiffness => (0.2 * x0, (5.0 * x0).min(1e8)),
            Key::BristleDamping => (0.0, 5.0 * x0),
            _ => (0.2 * x0, 5.0 * x0),
        }
    }

    /// A typical magnitude, for scaling the Jacobian (the start value, or a unit for offsets and zero starts).
    pub fn scale(self, x0: f64) -> f64 {
        let unit = match self {
            Key::OffsetPa | Key::OffsetPb => 1e3,
            Key::OffsetX => 1e-4,
            Key::SwitchingDelay
            | Key::ResponseTime
            | Key::ReleaseDelay
            | Key::SpoolTimeConstant
            | Key::ReleaseTimeConstant
            | Key::DeadTime => 1e-3,
            Key::Viscous | Key::Coulomb | Key::Static | Key::BristleDamping => 1.0,
            Key::CoulombPressure => 1e-6,
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
            Key::WallHeat | Key::WallTemperature => {
                "fills and exhausts followed by long holds with the valve shut or the piston held: the \
                 pressure relaxes as the gas reaches the wall's temperature (rig excite --signal steps \
                 --hold 1)"
            }
            Key::LeakConductance(0) | Key::LeakCritical(0) => {
                "a hold with A and B at different pressures and every valve path shut (closed-centre \
                 valve): the pressures converge through the piston seal"
            }
            Key::LeakConductance(_) | Key::LeakCritical(_) => {
                "a chamber filled and held shut for seconds: its pressure decay (a closed-chamber test, \
                 pneuflex leak)"
            }
            Key::LineVolume | Key::LineConductance | Key::LineCritical => {
                "fast command edges with the pressures logged at the full rate, the piston held and free \
                 (rig excite --signal prbs --hold 0.05)"
            }
            Key::LineLength | Key::LineSoundSpeed => {
                "fast command edges with the pressures logged at the full rate (rig excite --signal prbs \
                 --hold 0.05); the length and the speed of sound act only as their ratio"
            }
            Key::ReleaseDelay
            | Key::SpoolTimeConstant
            | Key::ReleaseTimeConstant
            | Key::DeadTime => {
                "fast command edges in both directions with the pressures logged at the full rate (rig \
                 excite --signal prbs --hold 0.05)"
            }
            Key::CoulombPressure => {
                "slow free motion with reversals at several chamber pressures (rig excite --signal \
                 chirp --amplitude 0.03 with different --bias)"
            }
            Key::BristleStiffness | Key::BristleDamping => {
                "small reversals below the break-away force: the pre-sliding displacement (rig excite \
                 --signal chirp --amplitude 0.01)"
            }
            Key::PolytropicExponent => {
                "fills and exhausts with the piston moving and held, fast and slow: the pressure's answer \
                 to a volume change against its answer to a flow (rig excite --signal steps)"
            }
        }
    }
}
