//! The 1-DOF mechanics of eq. (1) coupled to the actuator: moving mass, viscous and Coulomb friction,
//! gravity along the incline, end stops, integrated with fixed-step RK4.
//!
//! eq. (1): `F_1 - F_2 + G_alpha - f = m x'' + K_v x'`, with F_1 - F_2 the net pneumatic force on the rod
//! ([`Actuator::piston_force`]) minus the environment's reaction, G_alpha = m g sin(alpha) and f the
//! Coulomb friction. Convention: alpha is the incline of the actuator axis below the horizontal, the axis
//! pointing downhill towards the environment, so gravity aids extension exactly as eq. (1) prints it. The
//! paper's Fig. 1 measures the platform angle from the vertical; that angle is 90 deg - alpha.
//! The environment's reaction enters as the external force `f_ext = -F_2` along +x.

use crate::actuator::{Actuator, ChamberState};
use crate::effects::Effects;
use crate::lanes::{Real, pick, tanh};
use crate::valve::ValveState;

/// Coulomb friction law of the piston and guide.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Friction {
    /// Smooth Coulomb friction `F_c tanh(v / v_s)` (no sticking, friendly to RK4).
    Smooth {
        /// Coulomb (kinetic) friction force F_c, N.
        coulomb_n: f64,
        /// Velocity scale v_s of the tanh, m/s.
        smooth_velocity_m_per_s: f64,
    },
    /// Karnopp stick-slip friction with a Stribeck drop from static to Coulomb friction.
    StickSlip {
        /// Coulomb (kinetic) friction force F_c, N.
        coulomb_n: f64,
        /// Break-away (static) friction F_s >= F_c, N.
        static_n: f64,
        /// Stribeck velocity of the static-to-kinetic drop, m/s.
        stribeck_velocity_m_per_s: f64,
        /// Half-width of the sticking band: below this speed the piston sticks if |drive| <= F_s, m/s.
        stick_velocity_m_per_s: f64,
    },
    /// LuGre dynamic friction (Canudas de Wit, Olsson, Astrom, Lischinsky, IEEE TAC 40(3), 1995, eqs.
    /// 2-4): bristles of deflection z, `dz/dt = v - sigma0 |v| z / g(v)`, `F = sigma0 z + sigma1 dz/dt`,
    /// with the Stribeck curve `g(v) = F_c + (F_s - F_c) exp(-(v/v_s)^2)`; the viscous term sigma2 v is
    /// eq. (1)'s K_v. In steady sliding dz/dt = 0 and F = g(v) sign(v): the Stribeck curve.
    LuGre {
        /// Coulomb (kinetic) friction force F_c > 0, N.
        coulomb_n: f64,
        /// Break-away (static) friction F_s >= F_c, N.
        static_n: f64,
        /// Stribeck velocity v_s, m/s.
        stribeck_velocity_m_per_s: f64,
        /// Bristle stiffness sigma0, N/m.
        bristle_stiffness_n_per_m: f64,
        /// Bristle damping sigma1, N s/m.
        bristle_damping_n_s_per_m: f64,
    },
}

impl Friction {
    /// The Coulomb force F_c of the law, N.
    pub fn coulomb_n(&self) -> f64 {
        match *self {
            Friction::Smooth { coulomb_n, .. }
            | Friction::StickSlip { coulomb_n, .. }
            | Friction::LuGre { coulomb_n, .. } => coulomb_n,
        }
    }

    /// The law with its Coulomb and break-away forces raised by `extra` N: a seal pressed harder by the
    /// pressure difference, `F_c = F_c0 + k_p |p_a - p_b|` (and `F_s` by as much; docs/pneumatics.md).
    #[inline]
    pub fn with_normal_force(&self, extra: f64) -> Self {
        self.map_forces(|f| f + extra)
    }

    /// The law with its Coulomb and break-away forces times `k` (velocities and bristle constants kept):
    /// a seal that grips harder or looser, as domain randomisation draws it.
    pub fn scaled(&self, k: f64) -> Self {
        self.map_forces(|f| f * k)
    }

    /// The law with `op` applied to its Coulomb and break-away forces.
    #[inline]
    fn map_forces(&self, op: impl Fn(f64) -> f64) -> Self {
        let mut f = *self;
        match &mut f {
            Friction::Smooth { coulomb_n, .. } => *coulomb_n = op(*coulomb_n),
            Friction::StickSlip {
                coulomb_n,
                static_n,
                ..
            }
            | Friction::LuGre {
                coulomb_n,
                static_n,
                ..
            } => {
                *coulomb_n = op(*coulomb_n);
                *static_n = op(*static_n);
            }
        }
        f
    }

    /// The Stribeck curve `g(v) = F_c + (F_s - F_c) exp(-(v/v_s)^2)` of a stick-slip or LuGre law, N
    /// (the smooth law: F_c).
    #[inline]
    pub fn stribeck_n(&self, v: f64) -> f64 {
        match *self {
            Friction::Smooth { coulomb_n, .. } => coulomb_n,
            Friction::StickSlip {
                coulomb_n,
                static_n,
                stribeck_velocity_m_per_s,
                ..
            }
            | Friction::LuGre {
                coulomb_n,
                static_n,
                stribeck_velocity_m_per_s,
                ..
            } => {
                let z = v / stribeck_velocity_m_per_s;
                coulomb_n + (static_n - coulomb_n) * decay(z * z)
            }
        }
    }

    /// LuGre's force (N) and bristle rate dz/dt (m/s) at velocity `v` and deflection `z`; `None` for the
    /// other laws. (Canudas de Wit et al. 1995, eqs. 2-4.)
    #[inline]
    pub fn lugre(&self, v: f64, z: f64) -> Option<(f64, f64)> {
        let Friction::LuGre {
            bristle_stiffness_n_per_m: s0,
            bristle_damping_n_s_per_m: s1,
            ..
        } = *self
        else {
            return None;
        };
        let g = self.stribeck_n(v).max(f64::MIN_POSITIVE);
        let dz = v - s0 * v.abs() * z / g;
        Some((s0 * z + s1 * dz, dz))
    }

    /// LuGre's bristle deflection after the piston moved `dx` in `dt` at a velocity held, `v = dx / dt`;
    /// `None` for the other laws. With v held, eq. (2) of Canudas de Wit et al. is linear in z and its
    /// solution is exact over any step: `dz/dx = sign(v) - sigma0 z / g(v)`, so
    /// `z = z_ss + (z0 - z_ss) exp(-sigma0 |dx| / g(v))` with `z_ss = sign(v) g(v) / sigma0`. Stable for any
    /// stiffness: an explicit step of `z' = v - sigma0 |v| z / g` diverges once `sigma0 |v| dt / g` passes
    /// 2.8 (RK4), i.e. at 0.4 m/s for 4e4 N/m bristles on a 0.6 N seal and a 0.1 ms step.
    #[inline]
    pub fn lugre_bristle_after(&self, z0: f64, dx: f64, dt: f64) -> Option<f64> {
        let Friction::LuGre {
            bristle_stiffness_n_per_m: s0,
            ..
        } = *self
        else {
            return None;
        };
        if dx == 0.0 || dt <= 0.0 {
            return Some(z0);
        }
        let g = self.stribeck_n(dx / dt).max(f64::MIN_POSITIVE);
        let z_ss = dx.signum() * g / s0;
        // 1 - exp(-q) without the cancellation of a small q (a slow creep over one step).
        let q = s0 * dx.abs() / g;
        Some(z0 + (z_ss - z0) * -(-q).exp_m1())
    }

    /// Friction force opposing motion (positive along +x resists positive velocity), N, given the
    /// velocity and the net driving force of everything except friction and viscosity. For LuGre, which
    /// needs its bristle state ([`Friction::lugre`]), the steady-sliding force `g(v) sign(v)`.
    #[inline]
    pub fn force(&self, v: f64, drive: f64) -> f64 {
        match *self {
            Friction::Smooth {
                coulomb_n,
                smooth_velocity_m_per_s,
            } => smooth_coulomb(coulomb_n, 1.0 / smooth_velocity_m_per_s, v),
            Friction::StickSlip {
                coulomb_n,
                static_n,
                stribeck_velocity_m_per_s,
                stick_velocity_m_per_s,
            } => {
                if v.abs() < stick_velocity_m_per_s {
                    // Karnopp: sticking friction balances the drive up to the break-away force.
                    drive.clamp(-static_n, static_n)
                } else {
                    let z = v / stribeck_velocity_m_per_s;
                    v.signum() * (coulomb_n + (static_n - coulomb_n) * decay(z * z))
                }
            }
            Friction::LuGre { .. } => {
                if v == 0.0 {
                    0.0
                } else {
                    v.signum() * self.stribeck_n(v)
                }
            }
        }
    }
}

/// Mechanical parameters of eq. (1).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Mechanics {
    /// Moving mass m (piston, rod, flange and what rides on it), kg.
    pub moving_mass_kg: f64,
    /// Viscous friction coefficient K_v, N s/m.
    pub viscous_n_s_per_m: f64,
    /// Coulomb friction law f.
    pub friction: Friction,
    /// Incline of the axis below the horizontal, rad (gravity aids extension for alpha > 0).
    pub alpha_rad: f64,
    /// Gravitational acceleration g, m/s^2.
    pub gravity_m_per_s2: f64,
}

impl Mechanics {
    /// Gravity component along +x, G_alpha = m g sin(alpha), N (eq. 1).
    #[inline]
    pub fn gravity_force(&self) -> f64 {
        self.moving_mass_kg * self.gravity_m_per_s2 * self.alpha_rad.sin()
    }
}

/// The 1-DOF pneumatic actuator: pneumatics plus mechanics.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OneDofModel {
    /// Cylinder, valve, gas and supply.
    pub actuator: Actuator,
    /// Mass, friction, incline.
    pub mechanics: Mechanics,
    /// Effects beyond the paper (none: the paper's model, integrated as before).
    pub effects: Effects,
}

/// Full state of the 1-DOF model.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OneDofState {
    /// Simulation time, s.
    pub t: f64,
    /// Piston extension from the cap end, m.
    pub x: f64,
    /// Piston velocity, m/s.
    pub x_dot: f64,
    /// Chamber pressures and temperatures.
    pub chambers: ChamberState,
    /// Valve spool and PWM state.
    pub valve: ValveState,
    /// Lines and LuGre bristles, for a model with those effects.
    pub extra: ExtendedState,
}

impl OneDofState {
    /// A state at rest at `x` with the given chambers and the valve spool at `spool`, t = 0 (lines, if the
    /// model has them, at their chambers' state; LuGre bristles relaxed).
    pub fn at_rest(x: f64, chambers: ChamberState, spool: f64) -> Self {
        Self {
            t: 0.0,
            x,
            x_dot: 0.0,
            chambers,
            valve: ValveState::at_spool(spool),
            extra: ExtendedState::default(),
        }
    }
}

/// The state of the extended model beyond the paper's (part of [`OneDofState`]).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ExtendedState {
    /// Gas in the lines to A (`p_a`, `t_a`) and to B (`p_b`, `t_b`); `None` until a step with lines:
    /// the lines then start at their chambers' state.
    pub lines: Option<ChamberState>,
    /// LuGre bristle deflection z, m.
    pub bristle_m: f64,
}

impl OneDofModel {
    /// Net force on the moving mass except friction and viscosity, N: pneumatic + gravity + external.
    #[inline]
    pub fn drive_force(&self, chambers: &ChamberState, f_ext: f64) -> f64 {
        self.actuator.piston_force(chambers) + self.mechanics.gravity_force() + f_ext
    }
    /// Whether the model is the paper's (no [`Effects`], no LuGre friction): [`Self::step`] then integrates
    /// it exactly as before the effects existed; otherwise [`crate::extended`].
    #[inline]
    pub fn is_paper_model(&self) -> bool {
        self.effects.is_none() && !matches!(self.mechanics.friction, Friction::LuGre { .. })
    }
    /// Static balance (eq. 1 with x' = x'' = 0, no friction): the chamber-A pressure (Pa absolute) that
    /// holds the flange still against chamber-B pressure `p_b`, gravity and the external force `f_ext`.
    pub fn static_balance(&self, p_b: f64, f_ext: f64) -> f64 {
        let c = &self.actuator.cylinder;
        let p_atm = self.actuator.supply.atmosphere_pressure_pa;
        // p_a S_a - p_b S_b - p_atm S_rod + G_alpha + f_ext = 0.
        (p_b * c.area_b() + p_atm * c.area_rod() - self.mechanics.gravity_force() - f_ext)
            / c.area_a()
    }
}

/// [`Friction::Smooth`]'s `F_c tanh(v / v_s)` for one plant or a pack of them ([`crate::advance_together`]),
/// given `1 / v_s`: a product, not a division, on the chain from each RK4 stage's velocity to its
/// acceleration.
#[inline(always)]
pub(crate) fn smooth_coulomb<R: Real>(coulomb_n: R, inv_smooth_velocity: R, v: R) -> R {
    let y = v * inv_smooth_velocity;
    let zero = R::splat(0.0);
    // tanh rounds to exactly +-1 for |y| >= 20 (1 - tanh < 1e-17), and without Coulomb friction (the loop
    // analysis removes it) only the sign of the zero matters: one plant skips the tanh.
    let beyond = R::or(
        R::splat(20.0).le(y.abs()),
        R::and(coulomb_n.le(zero), zero.le(coulomb_n)),
    );
    let [t] = pick!(R; beyond => [y.signum()], [tanh(y)]);
    coulomb_n * t
}

/// `exp(-q)` for `q >= 0`, 0 past q = 700: there `exp` underflows into libm's slow path (12 % of an
/// identification with stick-slip friction, the Stribeck term exp(-(v/v_s)^2) of fast motion), and the
/// value, below 1e-304, no longer changes a sum with any force or spool position of the model.
#[inline(always)]
pub(crate) fn decay(q: f64) -> f64 {
    if q > 700.0 { 0.0 } else { (-q).exp() }
}
