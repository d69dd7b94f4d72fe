//! The controller around the inner PID, linearised for the loop analysis: the impedance filter (eq. 22)
//! from the force error to x_f, and for an adaptive run the correction Δx_f = g + p e + d ẋ (eq. 36) with
//! g adapting by eq. (35) and p, d held where the adaptation takes them. About a settled contact the
//! force error is e = f_r − f_e = −δf_e, and eq. (35) is
//!     ġ = −μ1 χ ∓ σ1 g,  ṗ = −μ2 χ e − σ2 p,  ḋ = −μ3 χ ẋ − σ3 d,  χ = −(λp e ∓ λd ẋ):
//! g's forcing is linear in (e, ẋ), p's and d's are products of two signals that vanish at the operating
//! point, so to first order g is a state of the loop and p, d are constants. Which constants: a limit cycle
//! feeds p on e² and d on ẋ² (ṗ = μ2 λp e², ḋ = −μ3 λd ẋ² with the λd sign carried through from ė), so an
//! oscillating loop drives them to their projection bounds (docs/control.md "Projection") — where the
//! adaptive run's loop is at its stiffest. Without a bound there is no value they stop at, and the method
//! says it cannot predict.

use pneuflex_control::{AdaptiveParams, LambdaDSign, Sigma1Sign, VelocitySource, ZohStep};
use serde::Serialize;

use crate::plants::Linearisable;
use crate::schema::{ControllerKind, FrozenAt, RunSpec};

/// The values the analysis holds p and d at, and where they come from.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct HeldGains {
    /// p, m/N.
    pub p_m_per_n: f64,
    /// d, s.
    pub d_s: f64,
    /// Whether g adapts in the analysed loop (the adaptive run) or is held (a frozen run, impedance).
    pub g_adapts: bool,
    /// Where the values come from, in words.
    pub source: String,
}

/// The linearised outer controller of one run (see the module's comment).
#[derive(Clone, Debug)]
pub struct OuterLaw {
    /// The impedance filter's exact one-tick step (eq. 22).
    filter: ZohStep,
    /// p, m/N and d, s, held.
    p: f64,
    d: f64,
    /// g's one-tick step g ← decay g + gain (from_e e + from_v ẋ), SI; None when g is held.
    g: Option<[f64; 4]>,
    /// ẋ in eq. (36) is the impedance filter's velocity rather than the measured one.
    v_from_filter: bool,
    /// What the analysis holds p, d at.
    pub held: HeldGains,
}

/// The output rows of a plant at its current state: δẋ = c_v · δs and δf_e = c_f · δs (central
/// differences of its `sense`), for the controller's velocity and force signals.
#[derive(Clone, Debug)]
pub struct Outputs {
    pub c_v: Vec<f64>,
    pub c_f: Vec<f64>,
}

impl Outputs {
    /// The rows at `p`'s current state (the state is put back).
    pub fn of<P: Linearisable + ?Sized>(p: &mut P) -> Self {
        let s0 = p.state_vector();
        let scales = p.perturbation_scales();
        let mut c_v = vec![0.0; s0.len()];
        let mut c_f = vec![0.0; s0.len()];
        for j in 0..s0.len() {
            let h = scales[j];
            let (mut a, mut b) = (s0.clone(), s0.clone());
            a[j] += h;
            b[j] -= h;
            p.set_state_vector(&a);
            let sa = p.sense();
            p.set_state_vector(&b);
            let sb = p.sense();
            c_v[j] = (sa.x_dot - sb.x_dot) / (2.0 * h);
            c_f[j] = (sa.f_e - sb.f_e) / (2.0 * h);
        }
        p.set_state_vector(&s0);
        Self { c_v, c_f }
    }

    /// Whether the force does not depend on the state (no contact): the outer loop is open and leaves the
    /// inner loop's stability alone.
    pub fn no_contact(&self) -> bool {
        self.c_f.iter().all(|v| *v == 0.0)
    }
}

impl OuterLaw {
    /// The outer controller of `run` for the analysis at control period `dt`: Err says why the values the
    /// adaptation reaches cannot be known (no projection bound, or a frozen run held at the means of a
    /// trace the analysis does not have).
    pub fn of_run(run: &RunSpec, dt: f64) -> Result<Self, String> {
        let imp = &run.impedance;
        let filter = ZohStep::new(imp.m_d_kg, imp.b_d_ns_per_m, imp.k_d_n_per_m, dt);
        let base = |p: f64, d: f64, g, v_from_filter, held| Self {
            filter,
            p,
            d,
            g,
            v_from_filter,
            held,
        };
        let a = match (run.controller, run.adaptive) {
            (ControllerKind::Adaptive, Some(a)) => a,
            _ => {
                return Ok(base(
                    0.0,
                    0.0,
                    None,
                    false,
                    HeldGains {
                        p_m_per_n: 0.0,
                        d_s: 0.0,
                        g_adapts: false,
                        source: "impedance controller (no adaptive law)".into(),
                    },
                ));
            }
        };
        let v_from_filter = a.velocity_source == VelocitySource::ImpedanceFilter;
        let (p, d) = bounds(&a)?;
        if let Some(f) = &run.frozen {
            return match f.at {
                FrozenAt::Bounds => Ok(base(
                    p,
                    d,
                    None,
                    v_from_filter,
                    HeldGains {
                        p_m_per_n: p,
                        d_s: d,
                        g_adapts: false,
                        source: format!("held at `{}`'s projection bounds", f.run),
                    },
                )),
                FrozenAt::Means => Err(format!(
                    "p and d are held at the means of `{}`'s trace, which only a run of the scene gives",
                    f.run
                )),
            };
        }
        Ok(base(
            p,
            d,
            Some(g_step(&a, dt)),
            v_from_filter,
            HeldGains {
                p_m_per_n: p,
                d_s: d,
                g_adapts: true,
                source: "p and d at their projection bounds, where an oscillation drives them; g adapting"
                    .into(),
            },
        ))
    }

    /// The number of states the outer controller adds: x_f, v_f, g.
    pub const STATES: usize = 3;

    /// One tick of the outer controller from the state [x_f, v_f, g] (`z`) and the plant's deviation
    /// `s`: returns (x_r, the next [x_f, v_f, g]) as the controller computes them (filter step, then the
    /// law's update, then eq. 25).
    pub fn tick(&self, z: &[f64], s: &[f64], out: &Outputs) -> (f64, [f64; 3]) {
        let dot = |c: &[f64]| c.iter().zip(s).map(|(a, b)| a * b).sum::<f64>();
        let e = -dot(&out.c_f);
        let ZohStep { phi, gamma } = self.filter;
        let x_f = phi[0][0] * z[0] + phi[0][1] * z[1] + gamma[0] * e;
        let v_f = phi[1][0] * z[0] + phi[1][1] * z[1] + gamma[1] * e;
        let v = if self.v_from_filter {
            v_f
        } else {
            dot(&out.c_v)
        };
        let g = self.g.map_or(0.0, |[decay, gain, ae, av]| {
            decay * z[2] + gain * (ae * e + av * v)
        });
        (x_f + g + self.p * e + self.d * v, [x_f, v_f, g])
    }
}

/// p and d at their projection bounds (SI), d on the side λd's sign drives it (as `frozen_values`).
fn bounds(a: &AdaptiveParams) -> Result<(f64, f64), String> {
    if !a.p_max_m_per_n.is_finite() {
        return Err(
            "p has no projection bound (p_max_m_per_n): an oscillation raises it (ṗ = μ2 λp e²) with no value \
             it stops at"
                .into(),
        );
    }
    if !a.d_max_s.is_finite() {
        return Err(
            "d has no projection bound (d_max_s): an oscillation drives it (ḋ = ∓μ3 λd ẋ²) with no value it \
             stops at"
                .into(),
        );
    }
    let d = match a.lambda_d_sign {
        LambdaDSign::FromEdot => -a.d_max_s,
        LambdaDSign::AsPrinted => a.d_max_s,
    };
    Ok((a.p_max_m_per_n, d))
}

/// g's exact one-tick step in SI (eq. 35 in the law's units, `AdaptiveLaw::update`):
/// ĝ' = −r ĝ + μ1 (λp e/F ∓ λd ẋ/X), g = X ĝ, so g ← e^{−r dt} g + (1 − e^{−r dt})/r · μ1 (λp X/F e ∓ λd ẋ).
fn g_step(a: &AdaptiveParams, dt: f64) -> [f64; 4] {
    let r = match a.sigma1_sign {
        Sigma1Sign::Leakage => a.sigma1,
        Sigma1Sign::AsPrinted => -a.sigma1,
    };
    let decay = (-r * dt).exp();
    let gain = if r == 0.0 {
        dt
    } else {
        -(-r * dt).exp_m1() / r
    };
    let from_e = a.mu1 * a.lambda_p * a.position_unit_m / a.force_unit_n;
    let from_v = match a.lambda_d_sign {
        LambdaDSign::FromEdot => -a.mu1 * a.lambda_d,
        LambdaDSign::AsPrinted => a.mu1 * a.lambda_d,
    };
    [decay, gain, from_e, from_v]
}
