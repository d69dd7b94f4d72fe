//! Position-based impedance filter, eqs. (19)–(24): m_d x_f'' + b_d x_f' + k_d x_f = e.
//!
//! Discretisation: exact zero-order hold (ZOH). Over one control period the force error e is
//! held constant (it is sampled once per tick), so the filter state advances exactly by
//! `[x_f, v_f]_{k+1} = Φ [x_f, v_f]_k + Γ e_k`, Φ = exp(A dt), Γ = ∫_0^dt exp(A s) ds B.
//! This is unconditionally stable for any dt (Φ's eigenvalues are exp(λ dt), |·| < 1 for a
//! stable continuous filter) and has no truncation error for piecewise-constant input,
//! unlike explicit Euler (unstable once dt > 2ζ/ω) or RK4 (O(dt^5) per step).
//! Φ and Γ come from the exponential of the augmented 3x3 matrix [[A, B], [0, 0]] dt
//! (scaling and squaring with a Taylor series), which covers k_d = 0 (a pole at the origin)
//! and every damping case with one code path. They are cached and recomputed only when dt changes.

use crate::error::{ParamError, non_negative, positive};

/// Target impedance of eq. (19): inertia, damping and stiffness of the desired force/position relation.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(deny_unknown_fields)
)]
pub struct ImpedanceParams {
    /// Target inertia m_d, kg (paper: 2 kg).
    pub m_d_kg: f64,
    /// Target damping b_d, N·s/m (not given by the paper).
    pub b_d_ns_per_m: f64,
    /// Target stiffness k_d, N/m (not given by the paper; 0 gives zero static force error).
    pub k_d_n_per_m: f64,
}

impl Default for ImpedanceParams {
    /// m_d = 2 kg (paper), k_d = 0 (no static force error against any stiff environment),
    /// b_d = 52.4 N·s/m: damping ratio 0.7 of the force loop m_d s² + b_d s + k_e at k_e = 700 N/m
    /// (b_d = 2·0.7·sqrt(m_d·k_e)); after k_e → 1400 N/m the ratio drops to 0.495.
    fn default() -> Self {
        Self {
            m_d_kg: 2.0,
            b_d_ns_per_m: 2.0 * 0.7 * libm::sqrt(2.0 * 700.0),
            k_d_n_per_m: 0.0,
        }
    }
}

impl ImpedanceParams {
    /// Checks m_d > 0 and b_d, k_d >= 0, all finite.
    pub fn validate(&self) -> Result<(), ParamError> {
        positive("m_d_kg", self.m_d_kg)?;
        non_negative("b_d_ns_per_m", self.b_d_ns_per_m)?;
        non_negative("k_d_n_per_m", self.k_d_n_per_m)?;
        Ok(())
    }
}

/// Exact ZOH transition matrices of the filter for one period.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ZohStep {
    /// State transition Φ = exp(A dt), row-major.
    pub phi: [[f64; 2]; 2],
    /// Input vector Γ = ∫ exp(A s) B ds over one period.
    pub gamma: [f64; 2],
}

type M3 = [[f64; 3]; 3];

fn mat3_mul(a: &M3, b: &M3) -> M3 {
    let mut c = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            c[i][j] = a[i][0] * b[0][j] + a[i][1] * b[1][j] + a[i][2] * b[2][j];
        }
    }
    c
}

/// exp(M) of a 3x3 matrix by scaling and squaring with a degree-16 Taylor series.
fn expm3(m: &M3) -> M3 {
    // Infinity norm decides the scaling so that ||M / 2^s|| <= 0.5.
    let mut norm = 0.0_f64;
    for row in m {
        let r = libm::fabs(row[0]) + libm::fabs(row[1]) + libm::fabs(row[2]);
        norm = if r > norm { r } else { norm };
    }
    let mut s = 0u32;
    let mut scale = 1.0;
    while norm * scale > 0.5 && s < 1000 {
        scale *= 0.5;
        s += 1;
    }
    let mut a = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            a[i][j] = m[i][j] * scale;
        }
    }
    // Horner form of sum_{n=0}^{16} a^n / n!.
    let mut e = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    for n in (1..=16).rev() {
        let mut t = mat3_mul(&a, &e);
        for (i, row) in t.iter_mut().enumerate() {
            for v in row.iter_mut() {
                *v /= n as f64;
            }
            row[i] += 1.0;
        }
        e = t;
    }
    for _ in 0..s {
        e = mat3_mul(&e, &e);
    }
    e
}

impl ZohStep {
    /// Exact ZOH discretisation of m x'' + b x' + k x = u over `dt` seconds.
    pub fn new(m: f64, b: f64, k: f64, dt: f64) -> Self {
        // Augmented system d/dt [x, v, u] = [[0, 1, 0], [-k/m, -b/m, 1/m], [0, 0, 0]] [x, v, u].
        let aug = [
            [0.0, dt, 0.0],
            [-k / m * dt, -b / m * dt, dt / m],
            [0.0, 0.0, 0.0],
        ];
        let e = expm3(&aug);
        Self {
            phi: [[e[0][0], e[0][1]], [e[1][0], e[1][1]]],
            gamma: [e[0][2], e[1][2]],
        }
    }
}

/// Impedance filter state x_f, ẋ_f with its cached ZOH step.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ImpedanceFilter {
    params: ImpedanceParams,
    x_f: f64,
    v_f: f64,
    dt_cached: f64,
    step: ZohStep,
}

impl ImpedanceFilter {
    /// A filter at rest (x_f = ẋ_f = 0); parameters are validated.
    pub fn new(params: ImpedanceParams) -> Result<Self, ParamError> {
        params.validate()?;
        Ok(Self {
            params,
            x_f: 0.0,
            v_f: 0.0,
            dt_cached: f64::NAN,
            step: ZohStep {
                phi: [[1.0, 0.0], [0.0, 1.0]],
                gamma: [0.0, 0.0],
            },
        })
    }

    /// The filter's parameters.
    pub fn params(&self) -> &ImpedanceParams {
        &self.params
    }

    /// New parameters from the next step on, the state x_f, ẋ_f kept (a gain schedule, or a learned
    /// policy that retunes the target impedance); validated, the filter unchanged on error.
    pub fn set_params(&mut self, params: ImpedanceParams) -> Result<(), ParamError> {
        params.validate()?;
        self.params = params;
        // The ZOH step is recomputed at the next step.
        self.dt_cached = f64::NAN;
        Ok(())
    }

    /// Advances one period with the force error `e` (N) held constant; returns x_f (m) at the end
    /// of the period. eq. (22): x_f(s) = e(s) / (m_d s² + b_d s + k_d), discretised exactly (ZOH).
    pub fn step(&mut self, e: f64, dt: f64) -> f64 {
        if dt.to_bits() != self.dt_cached.to_bits() {
            let p = &self.params;
            self.step = ZohStep::new(p.m_d_kg, p.b_d_ns_per_m, p.k_d_n_per_m, dt);
            self.dt_cached = dt;
        }
        let ZohStep { phi, gamma } = self.step;
        let x = phi[0][0] * self.x_f + phi[0][1] * self.v_f + gamma[0] * e;
        let v = phi[1][0] * self.x_f + phi[1][1] * self.v_f + gamma[1] * e;
        self.x_f = x;
        self.v_f = v;
        x
    }

    /// Filter output x_f, m.
    pub fn x_f(&self) -> f64 {
        self.x_f
    }

    /// Filter velocity ẋ_f, m/s.
    pub fn v_f(&self) -> f64 {
        self.v_f
    }

    /// Back to rest (x_f = ẋ_f = 0).
    pub fn reset(&mut self) {
        self.x_f = 0.0;
        self.v_f = 0.0;
    }
}
