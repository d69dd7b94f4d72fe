//! Adaptive position correction of eqs. (25)–(36): Δx_f = g + p·e + d·ẋ with the σ-modified
//! adaptation laws of eq. (35).
//!
//! Units convention: the paper's gains (λp = 1, λd = 8, μ1 = 0.01, μ2 = 1e-4, μ3 = 0.01,
//! σ = 0.1) carry no units. The law here runs on scaled signals ê = e / force_unit_n,
//! v̂ = ẋ / position_unit_m and produces Δx̂_f in position units, Δx_f = position_unit_m · Δx̂_f.
//! With force_unit_n = 1 and position_unit_m = 1 the gains are read in SI; with
//! position_unit_m = 1e-3 they are read with positions in mm (see docs/control.md for the
//! choice and the measurements behind it).
//!
//! Integration: each adaptive state q ∈ {g, p, d} obeys q' = -r q + u with its leakage rate
//! r (σ, or -σ1 for the as-printed anti-leakage sign) and a forcing u held over the period;
//! it is advanced exactly, q ← q e^{-r dt} + u (1 - e^{-r dt}) / r, so with e = ẋ = 0 the
//! states decay exactly as exp(-σ t) at any control period.

use crate::error::{ParamError, finite, non_negative, positive};

/// Sign of the velocity term inside χ (eq. (35)).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(rename_all = "snake_case")
)]
pub enum LambdaDSign {
    /// χ = -(λp e - λd ẋ): eq. (34)'s χ = -(λp e + λv ė) with ė = -k_e ẋ in contact,
    /// λd = λv k_e > 0. The velocity term then damps (d < 0) instead of anti-damping.
    FromEdot,
    /// χ = -(λp e + λd ẋ) exactly as printed in eq. (35).
    AsPrinted,
}

/// Sign of the σ1 term in the g law (eq. (35)).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(rename_all = "snake_case")
)]
pub enum Sigma1Sign {
    /// g' = -μ1 χ - σ1 g: σ-modification (leakage), like the p and d laws.
    Leakage,
    /// g' = -μ1 χ + σ1 g exactly as printed: anti-leakage, g grows as exp(+σ1 t).
    AsPrinted,
}

/// Velocity signal the adaptive law uses for ẋ in χ, the d law and d·ẋ (eqs. (35), (36)).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(rename_all = "snake_case")
)]
pub enum VelocitySource {
    /// The measured flange velocity ẋ (eq. (36) as printed).
    Measured,
    /// The impedance filter's velocity x_f' (eq. (22)): the velocity the target impedance commands, which
    /// the flange follows inside the force-loop bandwidth (x = x_r, eq. (23)). Free of the inner loop's
    /// valve ripple (unmodelled dynamics of the error model eq. (29)), which the measured ẋ carries.
    ImpedanceFilter,
}

/// Gains of the adaptive law (eq. (35)) and the units they are read in.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(
        from = "crate::adaptive::AdaptiveFile",
        into = "crate::adaptive::AdaptiveFile"
    )
)]
pub struct AdaptiveParams {
    /// λp, weight of the force error in χ.
    pub lambda_p: f64,
    /// λd, weight of the velocity in χ (sign chosen by `lambda_d_sign`).
    pub lambda_d: f64,
    /// μ1, adaptation gain of g.
    pub mu1: f64,
    /// μ2, adaptation gain of p.
    pub mu2: f64,
    /// μ3, adaptation gain of d.
    pub mu3: f64,
    /// σ1, leakage of g, 1/s.
    pub sigma1: f64,
    /// σ2, leakage of p, 1/s.
    pub sigma2: f64,
    /// σ3, leakage of d, 1/s.
    pub sigma3: f64,
    /// Force unit the gains are read in, N (1 = newtons).
    pub force_unit_n: f64,
    /// Position unit the gains are read in, m (1 = metres, 1e-3 = millimetres).
    pub position_unit_m: f64,
    /// Sign of λd inside χ.
    pub lambda_d_sign: LambdaDSign,
    /// Sign of the σ1 term.
    pub sigma1_sign: Sigma1Sign,
    /// Adapt g, p, d only while the flange is in contact (f_e > `contact_threshold_n`); out of contact they are
    /// held and Δx_f = g. Not in the paper, whose law is derived for contact only (eq. 21 and ė = -k_e ẋ): in free
    /// flight e = f_r winds g up, and the wound-up g overshoots when contact returns (the wood-to-iron swap).
    pub adapt_in_contact_only: bool,
    /// Contact force above which the flange counts as in contact, N.
    pub contact_threshold_n: f64,
    /// Velocity used for ẋ in eqs. (35)/(36). Default `Measured` (the paper).
    pub velocity_source: VelocitySource,
    /// Projection bound |g| <= g_max_m, m (parameter projection onto a known set; +inf = off, the default).
    pub g_max_m: f64,
    /// Projection bound 0 <= p <= p_max_m_per_n when finite, m/N (+inf = off, the default: p unbounded;
    /// 0 switches the p term off).
    pub p_max_m_per_n: f64,
    /// Projection bound on d when finite, s (+inf = off, the default: d unbounded): -d_max_s <= d <= 0 with
    /// `LambdaDSign::FromEdot` (the law drives d negative, a damping), 0 <= d <= d_max_s with `AsPrinted`;
    /// 0 switches the d term off.
    pub d_max_s: f64,
}

impl AdaptiveParams {
    /// The paper's numbers (Section III-E) in the units convention and signs chosen by this crate
    /// (see docs/control.md): this is `Default`.
    pub fn paper() -> Self {
        Self {
            position_unit_m: 1.0,
            force_unit_n: 1.0,
            ..Self::paper_si_as_printed()
        }
        .with_signs(LambdaDSign::FromEdot, Sigma1Sign::Leakage)
    }

    /// The paper's numbers read in SI with the signs exactly as printed in eq. (35).
    pub fn paper_si_as_printed() -> Self {
        Self {
            lambda_p: 1.0,
            lambda_d: 8.0,
            mu1: 0.01,
            mu2: 0.0001,
            mu3: 0.01,
            sigma1: 0.1,
            sigma2: 0.1,
            sigma3: 0.1,
            force_unit_n: 1.0,
            position_unit_m: 1.0,
            lambda_d_sign: LambdaDSign::AsPrinted,
            sigma1_sign: Sigma1Sign::AsPrinted,
            adapt_in_contact_only: false,
            contact_threshold_n: 0.5,
            velocity_source: VelocitySource::Measured,
            g_max_m: f64::INFINITY,
            p_max_m_per_n: f64::INFINITY,
            d_max_s: f64::INFINITY,
        }
    }

    /// The same gains with other signs.
    pub fn with_signs(self, lambda_d_sign: LambdaDSign, sigma1_sign: Sigma1Sign) -> Self {
        Self {
            lambda_d_sign,
            sigma1_sign,
            ..self
        }
    }

    /// The same gains read in other units (force unit in N, position unit in m).
    pub fn with_units(self, force_unit_n: f64, position_unit_m: f64) -> Self {
        Self {
            force_unit_n,
            position_unit_m,
            ..self
        }
    }

    /// Checks every gain finite and >= 0, and the unit scales > 0.
    pub fn validate(&self) -> Result<(), ParamError> {
        non_negative("lambda_p", self.lambda_p)?;
        non_negative("lambda_d", self.lambda_d)?;
        non_negative("mu1", self.mu1)?;
        non_negative("mu2", self.mu2)?;
        non_negative("mu3", self.mu3)?;
        non_negative("sigma1", self.sigma1)?;
        non_negative("sigma2", self.sigma2)?;
        non_negative("sigma3", self.sigma3)?;
        positive("force_unit_n", self.force_unit_n)?;
        positive("position_unit_m", self.position_unit_m)?;
        non_negative("contact_threshold_n", self.contact_threshold_n)?;
        for (name, v) in [
            ("g_max_m", self.g_max_m),
            ("p_max_m_per_n", self.p_max_m_per_n),
            ("d_max_s", self.d_max_s),
        ] {
            if v.is_nan() || v < 0.0 {
                return Err(ParamError::Negative { name, value: v });
            }
        }
        Ok(())
    }
}

impl Default for AdaptiveParams {
    fn default() -> Self {
        Self::paper()
    }
}

/// Exact one-period factors of q' = -r q + u: (e^{-r dt}, (1 - e^{-r dt}) / r).
fn leak_factors(r: f64, dt: f64) -> (f64, f64) {
    let decay = libm::exp(-r * dt);
    let gain = if r == 0.0 {
        dt
    } else {
        -libm::expm1(-r * dt) / r
    };
    (decay, gain)
}

/// State of the adaptive law: g, p, d in the scaled units of [`AdaptiveParams`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AdaptiveLaw {
    params: AdaptiveParams,
    g: f64,
    p: f64,
    d: f64,
    chi: f64,
    /// g0, p0, d0: where [`AdaptiveLaw::reset`] goes back to.
    initial: [f64; 3],
    /// A frozen law holds g, p, d at their initial values: the same controller without adaptation, to
    /// tell what the adaptation earns from what its parameter values (or their bounds) earn.
    frozen: bool,
    dt_cached: f64,
    /// (decay, gain) for g, p, d.
    factors: [(f64, f64); 3],
}

impl AdaptiveLaw {
    /// A law with g = p = d = 0 (g0 = p0 = d0 = 0, as the paper takes them).
    pub fn new(params: AdaptiveParams) -> Result<Self, ParamError> {
        params.validate()?;
        Ok(Self {
            params,
            g: 0.0,
            p: 0.0,
            d: 0.0,
            chi: 0.0,
            initial: [0.0; 3],
            frozen: false,
            dt_cached: f64::NAN,
            factors: [(1.0, 0.0); 3],
        })
    }

    /// A law starting from given g0, p0, d0 (scaled units); used to check the σ decay.
    pub fn with_initial(
        params: AdaptiveParams,
        g0: f64,
        p0: f64,
        d0: f64,
    ) -> Result<Self, ParamError> {
        finite("g0", g0)?;
        finite("p0", p0)?;
        finite("d0", d0)?;
        let mut law = Self::new(params)?;
        law.initial = [g0, p0, d0];
        law.reset();
        Ok(law)
    }

    /// A law held at g0, p0, d0 (scaled units) for the whole run: Δx_f = g0 + p0 e + d0 ẋ (eq. (36)) with
    /// no update of eq. (35). The projection bounds do not apply: the values are taken as given.
    pub fn frozen(params: AdaptiveParams, g0: f64, p0: f64, d0: f64) -> Result<Self, ParamError> {
        let mut law = Self::with_initial(params, g0, p0, d0)?;
        law.frozen = true;
        Ok(law)
    }

    /// Whether g, p, d are held (see [`AdaptiveLaw::frozen`]).
    pub fn is_frozen(&self) -> bool {
        self.frozen
    }

    /// The law's parameters.
    pub fn params(&self) -> &AdaptiveParams {
        &self.params
    }

    /// Advances g, p, d over one period with the force error `e_n` (N) and flange velocity
    /// `x_dot_m_s` (m/s) held; returns Δx_f in metres (eq. (36)).
    pub fn update(&mut self, e_n: f64, x_dot_m_s: f64, dt: f64) -> f64 {
        let a = &self.params;
        if dt.to_bits() != self.dt_cached.to_bits() {
            let r1 = match a.sigma1_sign {
                Sigma1Sign::Leakage => a.sigma1,
                Sigma1Sign::AsPrinted => -a.sigma1,
            };
            self.factors = [
                leak_factors(r1, dt),
                leak_factors(a.sigma2, dt),
                leak_factors(a.sigma3, dt),
            ];
            self.dt_cached = dt;
        }
        let e = e_n / a.force_unit_n;
        let v = x_dot_m_s / a.position_unit_m;
        // eq. (35), χ; the sign of λd is the resolution recorded in LambdaDSign.
        let chi = match a.lambda_d_sign {
            LambdaDSign::FromEdot => -(a.lambda_p * e - a.lambda_d * v),
            LambdaDSign::AsPrinted => -(a.lambda_p * e + a.lambda_d * v),
        };
        self.chi = chi;
        if self.frozen {
            return (self.g + self.p * e + self.d * v) * a.position_unit_m;
        }
        // eq. (35): g' = -μ1 χ ∓ σ1 g, p' = -μ2 χ e - σ2 p, d' = -μ3 χ ẋ - σ3 d.
        let [(dg, kg), (dp, kp), (dd, kd)] = self.factors;
        self.g = self.g * dg + kg * (-a.mu1 * chi);
        self.p = self.p * dp + kp * (-a.mu2 * chi * e);
        self.d = self.d * dd + kd * (-a.mu3 * chi * v);
        // Parameter projection onto a known set (not in the paper; off by default), applied after the exact
        // leakage step, which for a box is the projection. σ-modification alone bounds d only at
        // μ3 λd <ẋ²>/σ3, and p keeps feeding on the force ripple (ṗ ∝ μ2 λp e²): on a PWM-driven valve both
        // drift until p·e and d·ẋ inject the ripple into x_r (docs/control.md, "Projection").
        let gm = a.g_max_m / a.position_unit_m;
        self.g = self.g.clamp(-gm, gm);
        if a.p_max_m_per_n.is_finite() {
            self.p = self
                .p
                .clamp(0.0, a.p_max_m_per_n * a.force_unit_n / a.position_unit_m);
        }
        if a.d_max_s.is_finite() {
            // The box lies on the side the law drives d to (docs/control.md, "Projection"): d <= 0 (damping)
            // with the λd sign carried through from ė, d >= 0 with the sign as printed — so the bound limits
            // the term instead of silently switching it off. d_max = 0 switches it off on purpose.
            self.d = match a.lambda_d_sign {
                LambdaDSign::FromEdot => self.d.clamp(-a.d_max_s, 0.0),
                LambdaDSign::AsPrinted => self.d.clamp(0.0, a.d_max_s),
            };
        }
        // eq. (36): Δx_f = g + p e + d ẋ (scaled), back to metres.
        (self.g + self.p * e + self.d * v) * a.position_unit_m
    }

    /// Holds g, p, d (no adaptation this tick) and returns Δx_f = g in metres: the correction out of contact.
    pub fn hold(&mut self) -> f64 {
        self.chi = 0.0;
        self.g * self.params.position_unit_m
    }

    /// Auxiliary term g (position units of the params).
    pub fn g(&self) -> f64 {
        self.g
    }

    /// Proportional factor p (position unit per force unit).
    pub fn p(&self) -> f64 {
        self.p
    }

    /// Differential factor d (position unit per position unit/s, i.e. s).
    pub fn d(&self) -> f64 {
        self.d
    }

    /// χ of the last update.
    pub fn chi(&self) -> f64 {
        self.chi
    }

    /// Back to the initial g0, p0, d0 (zero unless given to [`AdaptiveLaw::with_initial`]).
    pub fn reset(&mut self) {
        [self.g, self.p, self.d] = self.initial;
        self.chi = 0.0;
    }
}

/// `AdaptiveParams` as scene files write it (`serde` feature): projection bounds as optional keys (absent =
/// off, +inf inside the law) and defaults for every key the paper leaves open. Unknown keys are rejected. Kept
/// here, beside the params, so the file form depends on `AdaptiveParams` and not the other way round.
#[cfg(feature = "serde")]
mod file_form {
    use serde::{Deserialize, Serialize};

    use super::{AdaptiveParams, LambdaDSign, Sigma1Sign, VelocitySource};

    fn one() -> f64 {
        1.0
    }
    fn half_newton() -> f64 {
        0.5
    }

    /// `[runs.adaptive]`: gains of the σ-modified adaptive law, eq. (35), and the units they are read in.
    #[derive(Clone, Copy, Debug, PartialEq, Deserialize, Serialize)]
    #[serde(deny_unknown_fields)]
    pub struct AdaptiveFile {
        /// Force unit the gains are read in, N.
        #[serde(default = "one")]
        pub force_unit_n: f64,
        /// Position unit the gains are read in, m.
        #[serde(default = "one")]
        pub position_unit_m: f64,
        /// Sign of λ_d inside χ.
        #[serde(default = "from_edot")]
        pub lambda_d_sign: LambdaDSign,
        /// Sign of the σ_1 term.
        #[serde(default = "leakage")]
        pub sigma1_sign: Sigma1Sign,
        /// λ_p.
        pub lambda_p: f64,
        /// λ_d.
        pub lambda_d: f64,
        /// μ_1.
        pub mu1: f64,
        /// μ_2.
        pub mu2: f64,
        /// μ_3.
        pub mu3: f64,
        /// σ_1, 1/s.
        pub sigma1: f64,
        /// σ_2, 1/s.
        pub sigma2: f64,
        /// σ_3, 1/s.
        pub sigma3: f64,
        /// Adapt only while in contact.
        #[serde(default)]
        pub adapt_in_contact_only: bool,
        /// Contact force above which the flange counts as in contact, N.
        #[serde(default = "half_newton")]
        pub contact_threshold_n: f64,
        /// Velocity used for ẋ in eqs. (35)/(36).
        #[serde(default = "measured")]
        pub velocity_source: VelocitySource,
        /// Projection bound |g| <= g_max_m, m (absent = unbounded).
        #[serde(default)]
        pub g_max_m: Option<f64>,
        /// Projection bound 0 <= p <= p_max_m_per_n, m/N (absent = unbounded).
        #[serde(default)]
        pub p_max_m_per_n: Option<f64>,
        /// Projection bound -d_max_s <= d <= 0, s (absent = unbounded).
        #[serde(default)]
        pub d_max_s: Option<f64>,
    }

    fn from_edot() -> LambdaDSign {
        LambdaDSign::FromEdot
    }
    fn leakage() -> Sigma1Sign {
        Sigma1Sign::Leakage
    }
    fn measured() -> VelocitySource {
        VelocitySource::Measured
    }

    /// Absent = off = +inf inside the law.
    fn bound(b: Option<f64>) -> f64 {
        b.unwrap_or(f64::INFINITY)
    }

    fn optional(b: f64) -> Option<f64> {
        (b != f64::INFINITY).then_some(b)
    }

    impl From<AdaptiveFile> for AdaptiveParams {
        fn from(f: AdaptiveFile) -> Self {
            Self {
                lambda_p: f.lambda_p,
                lambda_d: f.lambda_d,
                mu1: f.mu1,
                mu2: f.mu2,
                mu3: f.mu3,
                sigma1: f.sigma1,
                sigma2: f.sigma2,
                sigma3: f.sigma3,
                force_unit_n: f.force_unit_n,
                position_unit_m: f.position_unit_m,
                lambda_d_sign: f.lambda_d_sign,
                sigma1_sign: f.sigma1_sign,
                adapt_in_contact_only: f.adapt_in_contact_only,
                contact_threshold_n: f.contact_threshold_n,
                velocity_source: f.velocity_source,
                g_max_m: bound(f.g_max_m),
                p_max_m_per_n: bound(f.p_max_m_per_n),
                d_max_s: bound(f.d_max_s),
            }
        }
    }

    impl From<AdaptiveParams> for AdaptiveFile {
        fn from(a: AdaptiveParams) -> Self {
            Self {
                force_unit_n: a.force_unit_n,
                position_unit_m: a.position_unit_m,
                lambda_d_sign: a.lambda_d_sign,
                sigma1_sign: a.sigma1_sign,
                lambda_p: a.lambda_p,
                lambda_d: a.lambda_d,
                mu1: a.mu1,
                mu2: a.mu2,
                mu3: a.mu3,
                sigma1: a.sigma1,
                sigma2: a.sigma2,
                sigma3: a.sigma3,
                adapt_in_contact_only: a.adapt_in_contact_only,
                contact_threshold_n: a.contact_threshold_n,
                velocity_source: a.velocity_source,
                g_max_m: optional(a.g_max_m),
                p_max_m_per_n: optional(a.p_max_m_per_n),
                d_max_s: optional(a.d_max_s),
            }
        }
    }
}

#[cfg(feature = "serde")]
pub use file_form::AdaptiveFile;
