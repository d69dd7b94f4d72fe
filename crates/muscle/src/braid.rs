//! The braided muscle's statics: geometry of the braid, bladder volume, the force against gauge pressure
//! and contraction (Chou & Hannaford 1996; Tondu & Lopez 2000), braid friction and the two end stops.
//!
//! Conventions: `length` L is the muscle's length between its end fittings (the anchors' distance when the
//! muscle is taut), m; contraction `eps = 1 - L / L0`, positive when shorter than at rest; the tension is
//! the force pulling the two anchors together, N, never negative (a muscle cannot push). Pressures here are
//! gauge, Pa (absolute minus atmosphere).
//!
//! Braid geometry (one fibre of length `b` winding `n` turns round a cylinder of diameter D and length L,
//! at angle theta to the axis; docs/muscles.md (M1)-(M3)):
//!
//! ```text
//! L = b cos(theta),   D = b sin(theta) / (n pi)                                        (M1)
//! V = pi D^2 L / 4 = b^3 sin^2(theta) cos(theta) / (4 pi n^2)                          (M2)
//! dV/dL = -(pi D0^2 / 4) (3 cos^2(theta) - 1),   D0 = b / (n pi)                       (M3)
//! ```
//!
//! Virtual work, `F dL = -p dV`, gives Chou & Hannaford's force `F = (pi D0^2 p / 4)(3 cos^2(theta) - 1)`
//! (M4) with `cos(theta) = (1 - eps) cos(alpha0)`. Written with the rest radius `r0 = D_rest / 2 =
//! D0 sin(alpha0) / 2` it is Tondu & Lopez's `F = pi r0^2 p [a (1 - eps)^2 - b]`, a = 3 / tan^2(alpha0),
//! b = 1 / sin^2(alpha0); their end-effect factor k (the ends are caps, not a cylinder) replaces
//! `(1 - eps)` by `(1 - k eps)` (M5). The force vanishes at `eps_max = (1 - 1 / (sqrt(3) cos alpha0)) / k`
//! (M6), the largest contraction.

use core::f64::consts::PI;

/// The braid angle at which a braided muscle neither contracts nor extends under pressure,
/// `atan(sqrt(2))` = 54.7356 deg: tan^2(theta) = 2 makes (M3) and the force (M4) zero, and the volume (M2)
/// largest.
pub const NEUTRAL_BRAID_ANGLE_RAD: f64 = 0.955_316_618_124_509_3;

/// Geometry of the braided sleeve and its bladder at rest (zero gauge pressure, no load).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Braid {
    /// Inner diameter at rest D_rest = 2 r0 (the catalogue's nominal diameter), m.
    pub rest_diameter_m: f64,
    /// Length at rest L0 between the end fittings, m.
    pub rest_length_m: f64,
    /// Braid angle at rest alpha0 between a fibre and the muscle's axis, rad, in (0, 54.7 deg).
    pub rest_braid_angle_rad: f64,
    /// Tondu & Lopez's end-effect factor k >= 1 (1: the ideal cylinder of Chou & Hannaford).
    pub end_effect_factor: f64,
}

impl Braid {
    /// Length of one braid fibre b = L0 / cos(alpha0), m (M1).
    pub fn fibre_length_m(&self) -> f64 {
        self.rest_length_m / self.rest_braid_angle_rad.cos()
    }

    /// Turns n of one fibre round the muscle: n = b sin(alpha0) / (pi D_rest) (M1).
    pub fn turns(&self) -> f64 {
        self.fibre_length_m() * self.rest_braid_angle_rad.sin() / (PI * self.rest_diameter_m)
    }

    /// Chou & Hannaford's D0 = b / (n pi), the diameter the sleeve would have at theta = 90 deg, m.
    pub fn full_diameter_m(&self) -> f64 {
        self.rest_diameter_m / self.rest_braid_angle_rad.sin()
    }

    /// Contraction eps = 1 - L / L0 at length `length_m`.
    pub fn contraction(&self, length_m: f64) -> f64 {
        1.0 - length_m / self.rest_length_m
    }

    /// cos(theta) = (1 - eps) cos(alpha0) at contraction `eps`, clamped to [0, 1] (a straight fibre at 1).
    pub fn cos_braid_angle(&self, eps: f64) -> f64 {
        ((1.0 - eps) * self.rest_braid_angle_rad.cos()).clamp(0.0, 1.0)
    }

    /// Tondu & Lopez's a = 3 / tan^2(alpha0) and b = 1 / sin^2(alpha0) (M5).
    pub fn tondu_lopez_coefficients(&self) -> (f64, f64) {
        let t = self.rest_braid_angle_rad.tan();
        let s = self.rest_braid_angle_rad.sin();
        (3.0 / (t * t), 1.0 / (s * s))
    }

    /// The largest contraction, where the force (M5) is zero at any pressure:
    /// eps_max = (1 - 1 / (sqrt(3) cos alpha0)) / k (M6).
    pub fn max_contraction(&self) -> f64 {
        geometric_max_contraction(self.rest_braid_angle_rad) / self.end_effect_factor
    }

    /// Force of the pressurised braid at gauge pressure `p_gauge_pa` and contraction `eps`, N (M5):
    /// pi r0^2 p [a (1 - k eps)^2 - b]. Negative beyond `max_contraction` (where the muscle goes slack: see
    /// [`Muscle::tension`]); with k = 1 it is Chou & Hannaford's (M4).
    pub fn pressure_force(&self, p_gauge_pa: f64, eps: f64) -> f64 {
        let (a, b) = self.tondu_lopez_coefficients();
        let r0 = 0.5 * self.rest_diameter_m;
        let s = 1.0 - self.end_effect_factor * eps;
        PI * r0 * r0 * p_gauge_pa * (a * s * s - b)
    }

    /// Bladder volume at contraction `eps`, m^3 (M2): b^3 sin^2(theta) cos(theta) / (4 pi n^2). The ideal
    /// cylinder: the end caps' shape (what k stands for in the force) is not in the volume.
    pub fn bladder_volume_m3(&self, eps: f64) -> f64 {
        let b = self.fibre_length_m();
        let n = self.turns();
        let c = self.cos_braid_angle(eps);
        b * b * b * (1.0 - c * c) * c / (4.0 * PI * n * n)
    }

    /// dV/dL at contraction `eps`, m^2 (M3): -(pi D0^2 / 4)(3 cos^2(theta) - 1).
    pub fn volume_per_length_m2(&self, eps: f64) -> f64 {
        let d0 = self.full_diameter_m();
        let c = self.cos_braid_angle(eps);
        -0.25 * PI * d0 * d0 * (3.0 * c * c - 1.0)
    }
}

/// The contraction at which an ideal braid (k = 1) of rest angle `alpha0_rad` reaches the neutral angle
/// 54.7 deg: 1 - 1 / (sqrt(3) cos alpha0) (M6 with k = 1).
pub fn geometric_max_contraction(alpha0_rad: f64) -> f64 {
    1.0 - 1.0 / (3f64.sqrt() * alpha0_rad.cos())
}

/// Friction between the braid's fibres and between braid and bladder: Coulomb-like, opposing the change of
/// length, rising with the pressure that presses the braid onto the bladder (Tondu & Lopez 2000 model it as
/// proportional to the pressure), smoothed by tanh so that the equations stay continuous at rest:
/// `F_f = (F_c + c_p p) tanh(L' / v_s)` (M7). Over a stretch-and-release cycle it gives the force's
/// hysteresis, 2 F_f wide.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BraidFriction {
    /// Pressure-independent part F_c, N.
    pub coulomb_n: f64,
    /// Rise with the gauge pressure c_p, N/Pa.
    pub coulomb_n_per_pa: f64,
    /// Velocity scale v_s of the tanh, m/s (> 0).
    pub smooth_velocity_m_per_s: f64,
}

impl BraidFriction {
    /// No friction.
    pub const NONE: Self = Self {
        coulomb_n: 0.0,
        coulomb_n_per_pa: 0.0,
        smooth_velocity_m_per_s: 1.0,
    };

    /// The friction force added to the tension while the length changes at `length_rate` (m/s) under gauge
    /// pressure `p_gauge_pa`, N (M7): positive while the muscle is stretched, negative while it shortens.
    pub fn force(&self, p_gauge_pa: f64, length_rate: f64) -> f64 {
        let level = self.coulomb_n + self.coulomb_n_per_pa * p_gauge_pa.max(0.0);
        level * (length_rate / self.smooth_velocity_m_per_s).tanh()
    }
}

/// A McKibben muscle: braid, friction, the stiffness of the braid stretched past its rest length, and the
/// dead volume of its fittings and tubing.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Muscle {
    /// Braid and bladder geometry.
    pub braid: Braid,
    /// Braid friction (M7).
    pub friction: BraidFriction,
    /// Tensile stiffness of braid and bladder when the muscle is longer than at rest (L > L0), N/m: the
    /// lower end stop (M8).
    pub stretch_stiffness_n_per_m: f64,
    /// Volume of the end fitting, port and tubing up to the valve, m^3.
    pub dead_volume_m3: f64,
}

impl Muscle {
    /// Whether the muscle at length `length_m` is slack: shorter than its largest contraction allows, so
    /// the anchors are closer than the muscle's own length and nothing pulls them together (M8).
    pub fn is_slack(&self, length_m: f64) -> bool {
        self.braid.contraction(length_m) >= self.braid.max_contraction()
    }

    /// Tension at rest at gauge pressure `p_gauge_pa` and length `length_m`, N (M5, M8): the braid's force,
    /// plus the stretch stiffness past the rest length, never below zero; zero when slack.
    pub fn static_tension(&self, p_gauge_pa: f64, length_m: f64) -> f64 {
        self.tension(p_gauge_pa, length_m, 0.0)
    }

    /// Tension at gauge pressure `p_gauge_pa`, length `length_m` and lengthening rate `length_rate` (m/s),
    /// N: (M5) + (M7) + (M8), never below zero (a muscle pulls only), zero when slack.
    pub fn tension(&self, p_gauge_pa: f64, length_m: f64, length_rate: f64) -> f64 {
        if self.is_slack(length_m) {
            return 0.0;
        }
        let eps = self.braid.contraction(length_m);
        let stretch =
            (length_m - self.braid.rest_length_m).max(0.0) * self.stretch_stiffness_n_per_m;
        let f = self.braid.pressure_force(p_gauge_pa, eps)
            + stretch
            + self.friction.force(p_gauge_pa, length_rate);
        f.max(0.0)
    }

    /// Chamber volume V and its rate dV/dt at length `length_m` moving at `length_rate`, m^3 and m^3/s:
    /// dead volume plus bladder (M2, M3). A slack muscle stays at its largest contraction, so its volume
    /// stops changing there; so does a muscle stretched until its fibres are straight.
    pub fn chamber_volume(&self, length_m: f64, length_rate: f64) -> (f64, f64) {
        let b = &self.braid;
        let eps_max = b.max_contraction();
        let eps = b.contraction(length_m);
        // Stretched until the fibres lie along the axis (cos theta = 1): the bladder is flat, V stays.
        let eps_straight = 1.0 - 1.0 / b.rest_braid_angle_rad.cos();
        let (eps, rate) = if eps >= eps_max {
            (eps_max, 0.0)
        } else if eps <= eps_straight {
            (eps_straight, 0.0)
        } else {
            (eps, b.volume_per_length_m2(eps) * length_rate)
        };
        (self.dead_volume_m3 + b.bladder_volume_m3(eps), rate)
    }
}
