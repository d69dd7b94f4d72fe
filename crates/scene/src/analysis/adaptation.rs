//! What the adaptive law did in a run: the Lyapunov check of its error system (Section III-D) and the
//! parameters it pinned at a projection bound.

use pneuflex_control as control;

use crate::run::result::{LyapunovSummary, RunResult};
use crate::run::trace::Trace;
use crate::schema::{FrozenAt, FrozenValues, RunSpec, Scene};

/// The Lyapunov check (Section III-D) for an adaptive run: the control crate's reference model and Q,
/// started from the run's impedance loop at the scene's initial stiffness (eq. (28) with p = d = g = 0)
/// and the initial force error e(0) = f_r(0).
pub fn lyapunov_summary(scene: &Scene, run: &RunSpec) -> Option<LyapunovSummary> {
    let mut params = control::LyapunovCheckParams::default();
    let imp = &run.impedance;
    let k_e = scene.environment.stiffness_n_per_m;
    let a_p0 = imp.b_d_ns_per_m / imp.m_d_kg; // eq. (28), d = 0
    let b_p0 = (imp.k_d_n_per_m + k_e) / imp.m_d_kg; // eq. (28), p = 0
    let e0 = scene.setpoints().ok()?.at(0.0).f_ref;
    // eq. (28) with g = 0, x_e measured from x_d (eq. (27)'s x_e - x_d; eq. (28) drops x_d).
    let x_rel = scene.environment.x_e_m - scene.reference.x_d_m;
    let w_p0 =
        imp.k_d_n_per_m * k_e / imp.m_d_kg * (if k_e > 0.0 { e0 / k_e } else { 0.0 } + x_rel);
    params.initial = control::MracState {
        e: e0,
        e_dot: 0.0,
        e_m: e0,
        e_m_dot: 0.0,
        a_p: a_p0,
        b_p: b_p0,
        w_p: w_p0,
    };
    let r = control::lyapunov_check(&params).ok()?;
    Some(LyapunovSummary {
        a_m: params.a_m,
        b_m: params.b_m,
        a_p0,
        b_p0,
        p: r.p,
        residual: r.residual,
        v0: r.v0,
        v_end: r.v_end,
        max_delta_v: r.max_delta_v,
        non_increasing: r.non_increasing(1e-9),
    })
}

/// Warnings for adaptive parameters that sat at their projection bound for most of the run: then the bound,
/// not the adaptive law, set them (issue: a silently pinned parameter).
pub fn pinned_parameters(run: &RunSpec, tr: &Trace) -> Vec<String> {
    let Some(a) = run.adaptive.filter(|_| run.frozen.is_none()) else {
        return Vec::new();
    };
    let mut out = Vec::new();
    for (name, key, bound) in [
        ("p", "p_max_m_per_n", a.p_max_m_per_n),
        ("d", "d_max_s", a.d_max_s),
    ] {
        let Some(col) = tr.column(name).filter(|c| !c.is_empty()) else {
            continue;
        };
        if !(bound.is_finite() && bound > 0.0) {
            continue;
        }
        let at = col
            .iter()
            .filter(|v| (v.abs() - bound).abs() <= 1e-9 * bound)
            .count();
        let frac = at as f64 / col.len() as f64;
        if frac > 0.5 {
            out.push(format!(
                "run `{}`: the adaptive {name} sat at its projection bound {key} = {bound} for {:.0} % of the \
                 run: the bound, not the adaptive law, set it (widen the bound or retune; docs/control.md)",
                run.name,
                100.0 * frac
            ));
        }
    }
    out
}

/// The values frozen run `run` holds, from its source's result: the means of g, p, d over the source's
/// trace, or (at = "bounds") p and d at the source's projection bounds with g at its mean. The error says
/// why there is nothing to hold (the source diverged, was stopped or has no g, p, d columns).
pub fn frozen_values(run: &RunSpec, source: &RunResult) -> Result<FrozenValues, String> {
    let (Some(f), Some(a)) = (&run.frozen, run.adaptive) else {
        return Err(format!("run `{}` is not a frozen adaptive run", run.name));
    };
    if let Some(why) = source.diverged.as_ref().or(source.interrupted.as_ref()) {
        return Err(format!(
            "not run: its source `{}` did not finish ({why})",
            source.name
        ));
    }
    let mean = |name: &str| -> Result<f64, String> {
        let col = source
            .trace
            .column(name)
            .filter(|c| !c.is_empty())
            .ok_or_else(|| format!("not run: the trace of `{}` has no {name}", source.name))?;
        Ok(col.iter().sum::<f64>() / col.len() as f64)
    };
    let g_m = mean("g")?;
    Ok(match f.at {
        FrozenAt::Means => FrozenValues {
            g_m,
            p_m_per_n: mean("p")?,
            d_s: mean("d")?,
        },
        // The sign of the d box follows λd's (AdaptiveLaw::update): d <= 0 from ė, d >= 0 as printed.
        FrozenAt::Bounds => FrozenValues {
            g_m,
            p_m_per_n: a.p_max_m_per_n,
            d_s: match a.lambda_d_sign {
                control::LambdaDSign::FromEdot => -a.d_max_s,
                control::LambdaDSign::AsPrinted => a.d_max_s,
            },
        },
    })
}
