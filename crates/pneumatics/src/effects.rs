//! Effects beyond the paper's model (issue 26), each optional and each from its own sheet key: Newton
//! cooling through the cylinder wall, leaks across the piston and to the atmosphere, the lines between the
//! valve and the ports, the valve spool's delays and travel, and seal friction that rises with the pressure
//! difference. Without any of them [`crate::OneDofModel::step`] runs the paper's model unchanged; with any,
//! it runs [`crate::extended`] (docs/pneumatics.md, "Effects beyond the paper").

use crate::flow::Orifice;

/// Newton cooling of the gas through the wall: `Q' = h A_w(x) (T_w - T)` (W), with the wall area of the
/// chamber as a cylinder of its own volume (end caps and barrel, [`crate::extended`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WallHeat {
    /// Heat transfer coefficient h, W/(m^2 K).
    pub coefficient_w_per_m2_k: f64,
    /// Wall temperature T_w, K.
    pub wall_temperature_k: f64,
}

/// The leak paths of a cylinder, in the order of [`Leaks::get`].
pub const LEAKS: [&str; 3] = ["piston", "a_atmosphere", "b_atmosphere"];

/// Leaks, each an ISO 6358 orifice (eq. 11): across the piston seal (A <-> B) and from each chamber to
/// the atmosphere (rod seal, port fittings).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Leaks {
    /// Across the piston, chamber A <-> chamber B.
    pub piston: Option<Orifice>,
    /// Chamber A <-> atmosphere.
    pub a_atmosphere: Option<Orifice>,
    /// Chamber B <-> atmosphere.
    pub b_atmosphere: Option<Orifice>,
}

impl Leaks {
    /// Leak `i` of [`LEAKS`].
    pub fn get(&self, i: usize) -> Option<Orifice> {
        [self.piston, self.a_atmosphere, self.b_atmosphere][i.min(2)]
    }
    /// Sets leak `i` of [`LEAKS`].
    pub fn set(&mut self, i: usize, o: Option<Orifice>) {
        match i {
            0 => self.piston = o,
            1 => self.a_atmosphere = o,
            _ => self.b_atmosphere = o,
        }
    }
    /// Whether no leak is given.
    pub fn is_none(&self) -> bool {
        self.piston.is_none() && self.a_atmosphere.is_none() && self.b_atmosphere.is_none()
    }
}

/// The two lines (tubes) between the valve's ports and the cylinder's, the same on both sides: a lumped
/// volume of gas between the valve and an ISO 6358 restriction into the chamber, and the transport delay
/// `L / c` after which a change at the valve reaches the port.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lines {
    /// Gas volume of one line, m^3.
    pub volume_m3: f64,
    /// The line's restriction between its volume and the chamber.
    pub orifice: Orifice,
    /// Length L, m (0: no transport delay).
    pub length_m: f64,
    /// Speed of sound c in the line, m/s.
    pub speed_of_sound_m_per_s: f64,
}

impl Lines {
    /// Transport delay `L / c`, s.
    pub fn delay_s(&self) -> f64 {
        self.length_m / self.speed_of_sound_m_per_s
    }
}

/// Valve dynamics beyond the valve sheet's `switching_delay_s` (on/off) or `response_time_s`
/// (proportional): the on/off valve's drop-out delay and its spool's first-order travel in each direction,
/// the proportional valve's dead time.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SpoolDynamics {
    /// On/off: delay of a de-energising edge, s (`None`: the switching delay, which then is the
    /// energising edge's delay only when this is given).
    pub release_delay_s: Option<f64>,
    /// On/off: first-order time constant of the spool's travel towards the energised position, s (0: a jump).
    pub spool_time_constant_s: f64,
    /// On/off: the same towards the spring position, s (`None`: `spool_time_constant_s`).
    pub release_time_constant_s: Option<f64>,
    /// Proportional: dead time between a command and the spool starting to follow it, s.
    pub dead_time_s: f64,
}

/// The effects a model carries beyond the paper's; `Effects::default()` carries none.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Effects {
    /// Newton cooling through the wall (cylinder sheet).
    pub wall_heat: Option<WallHeat>,
    /// Leaks (cylinder sheet).
    pub leaks: Leaks,
    /// Lines between valve and ports (actuator sheet).
    pub lines: Option<Lines>,
    /// Spool delays and travel (valve sheet).
    pub spool: Option<SpoolDynamics>,
    /// Rise of the Coulomb (and break-away) friction with the pressure difference across the piston,
    /// `F_c = F_c0 + k_p |p_a - p_b|`, N/Pa (actuator sheet).
    pub coulomb_pressure_n_per_pa: Option<f64>,
    /// The Coulomb force for motion towards -x, F_c-, N, when it differs from the law's F_c (then F_c+):
    /// a seal that rubs harder one way (its lips, the rod's side load); the break-away force moves by as
    /// much in that direction (actuator sheet, `mechanics.coulomb_negative_n`).
    pub coulomb_negative_n: Option<f64>,
}

impl Effects {
    /// Whether no effect is given (the paper's model).
    pub fn is_none(&self) -> bool {
        self.wall_heat.is_none()
            && self.leaks.is_none()
            && self.lines.is_none()
            && self.spool.is_none()
            && self.coulomb_pressure_n_per_pa.is_none()
            && self.coulomb_negative_n.is_none()
    }

    /// The sheet tables or keys of the effects given, for messages (`cylinder.wall_heat_transfer_w_per_m2_k`, ...).
    pub fn given(&self) -> Vec<String> {
        let mut out = Vec::new();
        if self.wall_heat.is_some() {
            out.push("cylinder.wall_heat_transfer_w_per_m2_k".to_string());
        }
        for (i, name) in LEAKS.iter().enumerate() {
            if self.leaks.get(i).is_some() {
                out.push(format!("[cylinder.leaks.{name}]"));
            }
        }
        if self.lines.is_some() {
            out.push("[lines]".into());
        }
        if let Some(s) = self.spool {
            let keys = [
                ("valve.release_delay_s", s.release_delay_s.is_some()),
                ("valve.spool_time_constant_s", s.spool_time_constant_s > 0.0),
                (
                    "valve.release_time_constant_s",
                    s.release_time_constant_s.is_some(),
                ),
                ("valve.dead_time_s", s.dead_time_s > 0.0),
            ];
            let named: Vec<&str> = keys.iter().filter(|k| k.1).map(|k| k.0).collect();
            out.push(if named.is_empty() {
                "valve.spool_time_constant_s".into()
            } else {
                named.join(", ")
            });
        }
        if self.coulomb_pressure_n_per_pa.is_some() {
            out.push("mechanics.coulomb_pressure_n_per_pa".into());
        }
        if self.coulomb_negative_n.is_some() {
            out.push("mechanics.coulomb_negative_n".into());
        }
        out
    }
}
