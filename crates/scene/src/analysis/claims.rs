//! The paper's claims as a table the tool produces: for each `[[claims]]` of a scene, the two runs' values
//! of the metric and whether the claim holds (summary.json `claims`, printed by `run`).

use serde::Serialize;

use crate::run::result::{RunResult, WindowMetrics};
use crate::schema::{ClaimSpec, Scene};

/// One claim checked on a scene's results.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ClaimResult {
    /// The claim in words.
    pub statement: String,
    /// Window and metric it is read on.
    pub window: String,
    /// The metric (lower is better).
    pub metric: String,
    /// The run claimed better, and its value (None: missing, diverged or not settled).
    pub better: String,
    /// Its value.
    pub better_value: Option<f64>,
    /// The run compared with.
    pub than: String,
    /// Its value.
    pub than_value: Option<f64>,
    /// Whether the claim holds on these results.
    pub holds: bool,
    /// Why it does not hold, when it does not.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub why_not: Option<String>,
    /// On settling times: the verdict flips when the settling band is drawn 5 % narrower or wider
    /// (`EventResponse::settling_time_range_s`), with both runs' ranges. Such a verdict is not one to lean on.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub fragile: Option<String>,
    /// On a claim won by an adaptive run that has frozen runs ([`crate::schema::FrozenSpec`]): whether
    /// the adaptation, the values it reached or its projection bound earned the win.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub adaptation: Option<AdaptationVerdict>,
}

/// What earned an adaptive run's win, told by the same controller with its parameters frozen.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct AdaptationVerdict {
    /// The verdict.
    pub earned_by: EarnedBy,
    /// The verdict in words, with the shares of the lead.
    pub why: String,
    /// Each frozen run of the adaptive one, on the claim's metric.
    pub frozen: Vec<FrozenClaim>,
}

/// The verdict of [`AdaptationVerdict`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum EarnedBy {
    /// The controller held at the projection bounds wins too, keeping most of the lead.
    ProjectionBound,
    /// The controller held at the run's mean g, p, d wins too, keeping most of the lead.
    ParameterValues,
    /// No frozen run keeps most of the lead: the adaptation itself earns it.
    Adaptation,
    /// The claim does not hold: nothing to attribute.
    NoWin,
}

impl EarnedBy {
    /// The verdict in a table's words.
    pub fn words(self) -> &'static str {
        match self {
            EarnedBy::ProjectionBound => "projection bound",
            EarnedBy::ParameterValues => "parameter values",
            EarnedBy::Adaptation => "adaptation",
            EarnedBy::NoWin => "no win",
        }
    }
}

/// A frozen run on the metric of a claim its source makes.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct FrozenClaim {
    /// The frozen run.
    pub run: String,
    /// `means` or `bounds`.
    pub at: &'static str,
    /// Its value of the metric.
    pub value: Option<f64>,
    /// Whether it beats the claim's `than` run by the claim's margin.
    pub wins: bool,
    /// Its lead over `than` as a fraction of the adaptive run's lead (1: the same; None: no lead).
    pub share_of_lead: Option<f64>,
}

/// Share of the adaptive run's lead a frozen run must keep for the win to be put down to its values, not
/// to the adaptation: half.
pub const FROZEN_SHARE: f64 = 0.5;

/// The metrics a claim (and a comparison) can name.
pub const METRICS: [&str; 8] = [
    "rms_force_error_n",
    "phase_lag_deg",
    "steady_state_error_n",
    "peak_force_n",
    "jump_n",
    "recovery_overshoot_n",
    "recovery_overshoot_pct",
    "settling_time_s",
];

/// The value of `metric` in a window (settling time None when not settled; None when the window's kind
/// does not have it).
pub fn value(w: &WindowMetrics, metric: &str) -> Option<f64> {
    let e = w.event.as_ref();
    match metric {
        "rms_force_error_n" => Some(w.rms_force_error_n),
        "phase_lag_deg" => w.phase_lag_deg,
        "steady_state_error_n" => w.steady_state_error_n.map(f64::abs),
        "peak_force_n" => e.map(|e| e.peak_force_n),
        "jump_n" => e.map(|e| e.jump_n),
        "recovery_overshoot_n" => e.map(|e| e.recovery_overshoot_n),
        "recovery_overshoot_pct" => e.map(|e| e.recovery_overshoot_pct),
        "settling_time_s" => e.and_then(|e| e.settling_time_s),
        _ => None,
    }
}

fn lookup<'a>(results: &'a [RunResult], run: &str, window: &str) -> Option<&'a WindowMetrics> {
    results.iter().find(|r| r.name == run)?.window(window)
}

/// Checks one claim against a scene's results: it holds when the better run's value is lower by at least
/// the claim's margin.
pub fn check(c: &ClaimSpec, results: &[RunResult]) -> ClaimResult {
    let get = |run: &str| lookup(results, run, &c.window).and_then(|w| value(w, &c.metric));
    let (b, t) = (get(&c.better), get(&c.than));
    let settling = c.metric == "settling_time_s";
    let why_not = verdict(c, b, t);
    // A settling-time verdict is checked again with both runs' settling times at the probed bands.
    let range = |run: &str| {
        lookup(results, run, &c.window)
            .and_then(|w| w.event.as_ref())
            .map(|e| e.settling_time_range_s)
    };
    let fragile = match (settling, range(&c.better), range(&c.than)) {
        (true, Some(rb), Some(rt))
            if (0..2).any(|k| verdict(c, rb[k], rt[k]).is_none() != why_not.is_none()) =>
        {
            let show = |r: [Option<f64>; 2]| {
                let s =
                    |v: Option<f64>| v.map_or("not settled".to_string(), |v| format!("{v:.3} s"));
                format!("{}–{}", s(r[0]), s(r[1]))
            };
            Some(format!(
                "the verdict flips with the settling band {:.0} % narrower or wider ({} {}, {} {})",
                100.0 * crate::analysis::metrics::SETTLING_BAND_PROBE,
                c.better,
                show(rb),
                c.than,
                show(rt)
            ))
        }
        _ => None,
    };
    ClaimResult {
        statement: c.statement.clone(),
        window: c.window.clone(),
        metric: c.metric.clone(),
        better: c.better.clone(),
        better_value: b,
        than: c.than.clone(),
        than_value: t,
        holds: why_not.is_none(),
        why_not,
        fragile,
        adaptation: None,
    }
}

/// The adaptation verdict of claim `c` (checked: `checked`) when its better run is an adapting run with
/// frozen runs among the results, and the claim is not against one of them.
pub fn adaptation_verdict(
    scene: &Scene,
    c: &ClaimSpec,
    checked: &ClaimResult,
    results: &[RunResult],
) -> Option<AdaptationVerdict> {
    let frozen: Vec<_> = scene
        .runs
        .iter()
        .filter_map(|r| Some((r, r.frozen.as_ref()?)))
        .filter(|(r, f)| f.run == c.better && results.iter().any(|x| x.name == r.name))
        .collect();
    if frozen.is_empty() || frozen.iter().any(|(r, _)| r.name == c.than) {
        return None;
    }
    let get = |run: &str| lookup(results, run, &c.window).and_then(|w| value(w, &c.metric));
    let t = checked.than_value;
    let lead = match (checked.better_value, t) {
        (Some(b), Some(t)) => Some(t - b),
        _ => None,
    };
    let rows: Vec<FrozenClaim> = frozen
        .iter()
        .map(|(r, f)| {
            let v = get(&r.name);
            let wins = verdict(c, v, t).is_none();
            // Not settling is an infinite time: a frozen run that settles keeps the whole lead.
            let share = match (v, t, lead) {
                (Some(v), Some(t), Some(lead)) if lead > 0.0 => Some((t - v) / lead),
                (Some(_), None, _) => Some(1.0),
                _ => None,
            };
            FrozenClaim {
                run: r.name.clone(),
                at: f.at.name(),
                value: v,
                wins,
                share_of_lead: share,
            }
        })
        .collect();
    let pct = |s: Option<f64>| s.map_or("no".to_string(), |s| format!("{:.0} %", 100.0 * s));
    // The bounds first: when the controller held at its bounds keeps the lead, the bound suffices
    // whatever the means do; then the means.
    let keeps = |f: &&FrozenClaim| f.wins && f.share_of_lead.is_some_and(|s| s >= FROZEN_SHARE);
    let bounds = crate::schema::FrozenAt::Bounds.name();
    let kept =
        (rows.iter().filter(keeps).find(|f| f.at == bounds)).or_else(|| rows.iter().find(keeps));
    let (earned_by, why) = if !checked.holds {
        // A frozen run that wins where the adaptive one does not: the adaptation costs the win.
        let costs = match rows.iter().find(|f| f.wins) {
            Some(f) => format!(
                "; `{}` (held at the {}) would win it with {}: the adaptation costs this win",
                f.run,
                f.at,
                f.value.map_or("-".into(), |v| format!("{v:.4}"))
            ),
            None => String::new(),
        };
        (
            EarnedBy::NoWin,
            format!(
                "the claim does not hold: `{}` has no win to attribute{costs}",
                c.better
            ),
        )
    } else if let Some(f) = kept {
        let by = if f.at == crate::schema::FrozenAt::Bounds.name() {
            EarnedBy::ProjectionBound
        } else {
            EarnedBy::ParameterValues
        };
        (
            by,
            format!(
                "`{}` (held at the {}) also beats `{}` and keeps {} of the lead: {} earn the win, not the adaptation",
                f.run,
                f.at,
                c.than,
                pct(f.share_of_lead),
                if by == EarnedBy::ProjectionBound {
                    "the projection bounds"
                } else {
                    "the values the law reached"
                }
            ),
        )
    } else {
        let shares: Vec<String> = rows
            .iter()
            .map(|f| format!("`{}` keeps {}", f.run, pct(f.share_of_lead)))
            .collect();
        (
            EarnedBy::Adaptation,
            format!(
                "no frozen run keeps {:.0} % of the lead ({}): the adaptation earns the win",
                100.0 * FROZEN_SHARE,
                shares.join(", ")
            ),
        )
    };
    Some(AdaptationVerdict {
        earned_by,
        why,
        frozen: rows,
    })
}

/// Whether `better` beats `than` (lower is better) by at least `margin_pct` % of the larger magnitude: the
/// one rule every claim of every scene kind is judged by.
pub fn beats(better: f64, than: f64, margin_pct: f64) -> bool {
    better < than && than - better >= 0.01 * margin_pct * better.abs().max(than.abs())
}

/// Why the claim does not hold for the better run's value `b` and the other's `t` (None: it holds).
fn verdict(c: &ClaimSpec, b: Option<f64>, t: Option<f64>) -> Option<String> {
    let settling = c.metric == "settling_time_s";
    match (b, t) {
        (Some(b), Some(t)) if beats(b, t, c.margin_pct) => None,
        (Some(b), Some(t)) if b < t => Some(format!(
            "too close to call: {} {b:.4} is below {} {t:.4} by {:.2} %, less than the {} % margin",
            c.better,
            c.than,
            100.0 * (t - b) / b.abs().max(t.abs()),
            c.margin_pct
        )),
        (Some(b), Some(t)) => Some(format!(
            "{} {b:.4} is not below {} {t:.4}",
            c.better, c.than
        )),
        // Not settling is an infinite settling time: a settled run beats one that did not settle.
        (Some(_), None) if settling => None,
        (None, _) if settling => Some(format!("{} did not settle", c.better)),
        _ => Some("a value is missing (a run diverged or did not reach the window)".into()),
    }
}

/// Every claim of the scene checked against its results.
pub fn check_all(scene: &Scene, results: &[RunResult]) -> Vec<ClaimResult> {
    scene
        .claims
        .iter()
        .map(|c| {
            let mut r = check(c, results);
            r.adaptation = adaptation_verdict(scene, c, &r, results);
            r
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::analysis::metrics::{Steady, event_response};
    use crate::schema::{ControllerKind, WindowKind};

    /// A run whose only window, `change`, is the event response of f_e = 10 + e(t) on a 10 N reference.
    fn run(name: &str, e: impl Fn(f64) -> f64) -> RunResult {
        let t: Vec<f64> = (0..=4000).map(|k| k as f64 * 1e-3).collect();
        let f_ref = vec![10.0; t.len()];
        let f_e: Vec<f64> = t.iter().map(|&ti| 10.0 + e(ti)).collect();
        RunResult {
            name: name.into(),
            controller: ControllerKind::Impedance,
            trace: crate::run::trace::Trace::with_capacity(0, Vec::new()),
            windows: vec![WindowMetrics {
                name: "change".into(),
                kind: WindowKind::Event,
                t0_s: 0.0,
                t1_s: 4.0,
                rms_force_error_n: 0.0,
                frequency_hz: None,
                phase_lag_deg: None,
                amplitude_ratio: None,
                steady_state_error_n: None,
                event: event_response(&t, &f_ref, &f_e, Steady::Constant, None),
            }],
            lyapunov: None,
            diverged: None,
            interrupted: None,
            warnings: Vec::new(),
            pwm_period_s: None,
        }
    }

    fn claim(better: &str, than: &str) -> ClaimSpec {
        ClaimSpec {
            statement: format!("{better} settles faster"),
            window: "change".into(),
            metric: "settling_time_s".into(),
            better: better.into(),
            than: than.into(),
            margin_pct: 2.0,
        }
    }

    #[test]
    fn a_settling_verdict_that_flips_with_the_band_is_called_fragile() {
        // `edge`: a damped oscillation whose 5th extremum (w t = 5π - atan(a/w), 1.551 s) is 2 % above the
        // 0.2 N band, so it settles just after it with the nominal band, and ~0.1 s after the 4th (1.237 s)
        // with a 5 % wider one. `smooth`: 5 e^{-2.2 t}, which reaches the band at ln(25)/2.2 = 1.463 s (the
        // wider one at 1.441 s), between the two.
        let (a, w) = (2.0_f64, 10.0_f64);
        let shape = move |t: f64| (-a * t).exp() * (w * t).cos();
        let t5 = (5.0 * std::f64::consts::PI - (a / w).atan()) / w;
        let amp = 1.02 * 0.2 / shape(t5).abs();
        let results = [
            run("edge", move |t| amp * shape(t)),
            run("smooth", |t| 5.0 * (-2.2 * t).exp()),
        ];
        let c = check(&claim("edge", "smooth"), &results);
        assert!(!c.holds, "{c:?}");
        let why = c.fragile.expect("the verdict flips with the wider band");
        assert!(why.contains("edge") && why.contains("smooth"), "{why}");
        // The smooth run against a slower smooth one: the same verdict at every band, nothing to flag.
        let results = [
            run("smooth", |t| 5.0 * (-2.2 * t).exp()),
            run("slow", |t| 5.0 * (-1.1 * t).exp()),
        ];
        let c = check(&claim("smooth", "slow"), &results);
        assert!(c.holds && c.fragile.is_none(), "{c:?}");
    }
}
