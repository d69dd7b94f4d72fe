//! Lyapunov stability check of the MRAC error system, Section III-D (eqs. (29)–(38)).
//!
//! Adjustable system (eq. (30)): ë + a_p ė + b_p e = w_p; reference model (eq. (31)):
//! ë_m + a_m ė_m + b_m e_m = 0; error E_e = E_m - E_p (eq. (33)). With P solving
//! A_mᵀP + PA_m = -Q and χ = p2 (e_m - e) + p3 (ė_m - ė), the unmodified laws
//! ȧ_p = -χ ė / β1, ḃ_p = -χ e / β0, ẇ_p = χ / β2 give V̇ = -½ E_eᵀ Q E_e ≤ 0 for the V of eq. (37).
//! Paper resolutions: eq. (38) prints +½ E_eᵀQE_e (the derivative is -½ E_eᵀQE_e, as the text
//! after it says); eq. (37)'s Z prints a_p - b_m (it is a_p - a_m, as in V's expansion);
//! "P is the singular positive definite matrix" means non-singular (positive definite).

use crate::error::{ParamError, finite, positive};

/// A symmetric 2x2 matrix [[p1, p2], [p2, p3]] in row-major form.
pub type Mat2 = [[f64; 2]; 2];

/// Reference model matrix A_m = [[0, 1], [-b_m, -a_m]] (eq. (32)).
pub fn reference_matrix(a_m: f64, b_m: f64) -> Mat2 {
    [[0.0, 1.0], [-b_m, -a_m]]
}

/// Residual A_mᵀP + PA_m + Q, for checking a solution.
pub fn lyapunov_residual(a_m: f64, b_m: f64, p: &Mat2, q: &Mat2) -> Mat2 {
    let a = reference_matrix(a_m, b_m);
    let mut r = [[0.0; 2]; 2];
    for i in 0..2 {
        for j in 0..2 {
            let mut s = q[i][j];
            for k in 0..2 {
                s += a[k][i] * p[k][j] + p[i][k] * a[k][j];
            }
            r[i][j] = s;
        }
    }
    r
}

/// Solves A_mᵀP + PA_m = -Q in closed form for the 2x2 companion matrix A_m.
///
/// Expanding with P = [[p1, p2], [p2, p3]]: (1,1): -2 b_m p2 = -q11; (2,2): 2 (p2 - a_m p3) = -q22;
/// (1,2): p1 - a_m p2 - b_m p3 = -q12.
pub fn solve_lyapunov(a_m: f64, b_m: f64, q: &Mat2) -> Result<Mat2, ParamError> {
    finite("a_m", a_m)?;
    finite("b_m", b_m)?;
    if !(a_m > 0.0 && b_m > 0.0) {
        return Err(ParamError::UnstableReferenceModel { a_m, b_m });
    }
    for row in q {
        for &v in row {
            finite("q", v)?;
        }
    }
    let det = q[0][0] * q[1][1] - q[0][1] * q[1][0];
    if q[0][1] != q[1][0] || q[0][0] <= 0.0 || det <= 0.0 {
        return Err(ParamError::QNotPositiveDefinite);
    }
    let p2 = q[0][0] / (2.0 * b_m);
    let p3 = (p2 + 0.5 * q[1][1]) / a_m;
    let p1 = -q[0][1] + a_m * p2 + b_m * p3;
    Ok([[p1, p2], [p2, p3]])
}

/// State of the MRAC error system: plant error, model error and adjustable parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MracState {
    /// Force error e of the adjustable system, N.
    pub e: f64,
    /// ė, N/s.
    pub e_dot: f64,
    /// Reference-model error e_m.
    pub e_m: f64,
    /// ė_m.
    pub e_m_dot: f64,
    /// a_p(t), adjustable damping coefficient.
    pub a_p: f64,
    /// b_p(t), adjustable stiffness coefficient.
    pub b_p: f64,
    /// w_p(t), adjustable input (eq. (28)).
    pub w_p: f64,
}

impl MracState {
    fn axpy(&self, h: f64, k: &MracState) -> MracState {
        MracState {
            e: self.e + h * k.e,
            e_dot: self.e_dot + h * k.e_dot,
            e_m: self.e_m + h * k.e_m,
            e_m_dot: self.e_m_dot + h * k.e_m_dot,
            a_p: self.a_p + h * k.a_p,
            b_p: self.b_p + h * k.b_p,
            w_p: self.w_p + h * k.w_p,
        }
    }
}

/// Settings of the Lyapunov check: reference model, Q, the β weights, the initial state, the run.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LyapunovCheckParams {
    /// Reference-model damping coefficient a_m, 1/s.
    pub a_m: f64,
    /// Reference-model stiffness coefficient b_m, 1/s².
    pub b_m: f64,
    /// Positive definite Q.
    pub q: Mat2,
    /// β0 (weight of b_p - b_m).
    pub beta0: f64,
    /// β1 (weight of a_p - a_m).
    pub beta1: f64,
    /// β2 (weight of w_p).
    pub beta2: f64,
    /// Initial state.
    pub initial: MracState,
    /// Simulated time, s.
    pub t_end_s: f64,
    /// RK4 step, s.
    pub dt_s: f64,
}

impl Default for LyapunovCheckParams {
    /// Reference model ζ = 1, ω = 20 rad/s (a_m = 40, b_m = 400), Q = I, β = 1, and an adjustable
    /// system started far from it (the impedance loop at k_e = 700 N/m, m_d = 2 kg, b_d = 52.4:
    /// a_p = 26.2, b_p = 350) with e(0) = 10 N, w_p(0) = 5; 5 s at 0.1 ms.
    fn default() -> Self {
        Self {
            a_m: 40.0,
            b_m: 400.0,
            q: [[1.0, 0.0], [0.0, 1.0]],
            beta0: 1.0,
            beta1: 1.0,
            beta2: 1.0,
            initial: MracState {
                e: 10.0,
                e_dot: 0.0,
                e_m: 10.0,
                e_m_dot: 0.0,
                a_p: 26.2,
                b_p: 350.0,
                w_p: 5.0,
            },
            t_end_s: 5.0,
            dt_s: 1e-4,
        }
    }
}

impl LyapunovCheckParams {
    /// Checks the model, Q, the β weights (> 0), the run settings and the initial state.
    pub fn validate(&self) -> Result<(), ParamError> {
        solve_lyapunov(self.a_m, self.b_m, &self.q)?;
        positive("beta0", self.beta0)?;
        positive("beta1", self.beta1)?;
        positive("beta2", self.beta2)?;
        positive("t_end_s", self.t_end_s)?;
        positive("dt_s", self.dt_s)?;
        let s = &self.initial;
        for (name, v) in [
            ("initial.e", s.e),
            ("initial.e_dot", s.e_dot),
            ("initial.e_m", s.e_m),
            ("initial.e_m_dot", s.e_m_dot),
            ("initial.a_p", s.a_p),
            ("initial.b_p", s.b_p),
            ("initial.w_p", s.w_p),
        ] {
            finite(name, v)?;
        }
        Ok(())
    }
}

/// The error system with the unmodified adaptive law (eq. (34) form).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MracErrorSystem {
    /// Reference-model damping a_m.
    pub a_m: f64,
    /// Reference-model stiffness b_m.
    pub b_m: f64,
    /// Solution P of the Lyapunov equation.
    pub p: Mat2,
    /// β0, β1, β2.
    pub beta: [f64; 3],
}

impl MracErrorSystem {
    /// χ = p2 (e_m - e) + p3 (ė_m - ė) (Section III-C).
    pub fn chi(&self, s: &MracState) -> f64 {
        self.p[0][1] * (s.e_m - s.e) + self.p[1][1] * (s.e_m_dot - s.e_dot)
    }

    /// Time derivative of the state: eqs. (29), (31) and ȧ_p = -χė/β1, ḃ_p = -χe/β0, ẇ_p = χ/β2.
    pub fn derivative(&self, s: &MracState) -> MracState {
        let chi = self.chi(s);
        MracState {
            e: s.e_dot,
            // eq. (29): ë = -a_p ė - b_p e + w_p.
            e_dot: -s.a_p * s.e_dot - s.b_p * s.e + s.w_p,
            e_m: s.e_m_dot,
            // eq. (31).
            e_m_dot: -self.a_m * s.e_m_dot - self.b_m * s.e_m,
            a_p: -chi * s.e_dot / self.beta[1],
            b_p: -chi * s.e / self.beta[0],
            w_p: chi / self.beta[2],
        }
    }

    /// V of eq. (37): ½ E_eᵀPE_e + ½β0 (b_p - b_m)² + ½β1 (a_p - a_m)² + ½β2 w_p².
    pub fn v(&self, s: &MracState) -> f64 {
        let x0 = s.e_m - s.e;
        let x1 = s.e_m_dot - s.e_dot;
        let p = &self.p;
        let quad = p[0][0] * x0 * x0 + 2.0 * p[0][1] * x0 * x1 + p[1][1] * x1 * x1;
        let db = s.b_p - self.b_m;
        let da = s.a_p - self.a_m;
        0.5 * quad
            + 0.5 * self.beta[0] * db * db
            + 0.5 * self.beta[1] * da * da
            + 0.5 * self.beta[2] * s.w_p * s.w_p
    }

    /// One classical RK4 step of length `h`.
    pub fn rk4_step(&self, s: &MracState, h: f64) -> MracState {
        let k1 = self.derivative(s);
        let k2 = self.derivative(&s.axpy(0.5 * h, &k1));
        let k3 = self.derivative(&s.axpy(0.5 * h, &k2));
        let k4 = self.derivative(&s.axpy(h, &k3));
        MracState {
            e: s.e + h / 6.0 * (k1.e + 2.0 * k2.e + 2.0 * k3.e + k4.e),
            e_dot: s.e_dot + h / 6.0 * (k1.e_dot + 2.0 * k2.e_dot + 2.0 * k3.e_dot + k4.e_dot),
            e_m: s.e_m + h / 6.0 * (k1.e_m + 2.0 * k2.e_m + 2.0 * k3.e_m + k4.e_m),
            e_m_dot: s.e_m_dot
                + h / 6.0 * (k1.e_m_dot + 2.0 * k2.e_m_dot + 2.0 * k3.e_m_dot + k4.e_m_dot),
            a_p: s.a_p + h / 6.0 * (k1.a_p + 2.0 * k2.a_p + 2.0 * k3.a_p + k4.a_p),
            b_p: s.b_p + h / 6.0 * (k1.b_p + 2.0 * k2.b_p + 2.0 * k3.b_p + k4.b_p),
            w_p: s.w_p + h / 6.0 * (k1.w_p + 2.0 * k2.w_p + 2.0 * k3.w_p + k4.w_p),
        }
    }

    /// ½ E_eᵀQE_e, the rate at which V must fall.
    pub fn dissipation(&self, q: &Mat2, s: &MracState) -> f64 {
        let x0 = s.e_m - s.e;
        let x1 = s.e_m_dot - s.e_dot;
        0.5 * (q[0][0] * x0 * x0 + (q[0][1] + q[1][0]) * x0 * x1 + q[1][1] * x1 * x1)
    }
}

/// Result of a Lyapunov check run (what summary.json reports under "lyapunov").
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LyapunovReport {
    /// Solution P.
    pub p: Mat2,
    /// Largest |entry| of A_mᵀP + PA_m + Q.
    pub residual: f64,
    /// V at t = 0.
    pub v0: f64,
    /// V at the end of the run.
    pub v_end: f64,
    /// Largest one-step increase V_{k+1} - V_k (≤ 0 when V never rises).
    pub max_delta_v: f64,
    /// ∫ ½ E_eᵀQE_e dt by the trapezoidal rule (should equal v0 - v_end).
    pub dissipated: f64,
    /// Number of RK4 steps.
    pub steps: u64,
    /// Final state.
    pub final_state: MracState,
}

impl LyapunovReport {
    /// Whether V never rose by more than `rel_tol · V(0)` in one step.
    pub fn non_increasing(&self, rel_tol: f64) -> bool {
        self.max_delta_v <= rel_tol * self.v0
    }
}

/// Solves for P, simulates the MRAC error system with the unmodified law by RK4, and tracks V.
pub fn lyapunov_check(params: &LyapunovCheckParams) -> Result<LyapunovReport, ParamError> {
    params.validate()?;
    let p = solve_lyapunov(params.a_m, params.b_m, &params.q)?;
    let r = lyapunov_residual(params.a_m, params.b_m, &p, &params.q);
    let residual = libm::fmax(
        libm::fmax(libm::fabs(r[0][0]), libm::fabs(r[0][1])),
        libm::fmax(libm::fabs(r[1][0]), libm::fabs(r[1][1])),
    );
    let sys = MracErrorSystem {
        a_m: params.a_m,
        b_m: params.b_m,
        p,
        beta: [params.beta0, params.beta1, params.beta2],
    };
    let steps = libm::ceil(params.t_end_s / params.dt_s) as u64;
    let h = params.t_end_s / steps as f64;
    let mut s = params.initial;
    let v0 = sys.v(&s);
    let mut v = v0;
    let mut max_delta_v = f64::NEG_INFINITY;
    let mut dissipated = 0.0;
    let mut w = sys.dissipation(&params.q, &s);
    for _ in 0..steps {
        let next = sys.rk4_step(&s, h);
        let v_next = sys.v(&next);
        let w_next = sys.dissipation(&params.q, &next);
        dissipated += 0.5 * h * (w + w_next);
        max_delta_v = libm::fmax(max_delta_v, v_next - v);
        s = next;
        v = v_next;
        w = w_next;
    }
    Ok(LyapunovReport {
        p,
        residual,
        v0,
        v_end: v,
        max_delta_v,
        dissipated,
        steps,
        final_state: s,
    })
}
