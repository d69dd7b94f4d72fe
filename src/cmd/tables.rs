//! What `pneuflex run` prints after the runs: the metrics of every window of every run, and the scene's
//! claims with their verdicts.

use std::fmt::Write as _;

use pneuflex_scene::{RunResult, WindowKind};

/// The scene's claims: the statement, the two values and the verdict.
pub(super) fn claims(claims: &[pneuflex_scene::analysis::claims::ClaimResult]) -> String {
    let mut s = String::from("claims:\n");
    for c in claims {
        let v = |x: Option<f64>| x.map_or("-".to_string(), |x| format!("{x:.4}"));
        let fragile = c
            .fragile
            .as_ref()
            .map_or(String::new(), |f| format!("; fragile: {f}"));
        let _ = writeln!(
            s,
            "  {:<13} {} ({} {}: {} {}, {} {}{fragile})",
            if c.holds { "holds" } else { "DOES NOT HOLD" },
            c.statement,
            c.window,
            c.metric,
            c.better,
            v(c.better_value),
            c.than,
            v(c.than_value)
        );
        if let Some(a) = &c.adaptation {
            let _ = writeln!(
                s,
                "  {:<13} adaptation verdict, {}: {}",
                "",
                a.earned_by.words(),
                a.why
            );
        }
    }
    s
}

fn opt(v: Option<f64>, unit: &str, prec: usize) -> String {
    match v {
        Some(x) if x.is_finite() => format!("{x:.prec$} {unit}"),
        _ => "-".into(),
    }
}

/// A short text table: one line per run and window with the window's main metrics.
pub(super) fn metrics(results: &[RunResult]) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "{:<13} {:<18} {:>12}  details",
        "run", "window", "RMS error"
    );
    for r in results {
        if let Some(why) = &r.diverged {
            let _ = writeln!(s, "{:<13} DIVERGED: {why}", r.name);
            continue;
        }
        for w in &r.windows {
            let details = match w.kind {
                WindowKind::Sine => format!("phase lag {}", opt(w.phase_lag_deg, "deg", 2)),
                WindowKind::Step => {
                    format!("steady-state error {}", opt(w.steady_state_error_n, "N", 3))
                }
                WindowKind::Event => match &w.event {
                    Some(e) => format!(
                        "peak {}, jump {}, overshoot {} ({:.0} % of the jump), {}",
                        opt(Some(e.peak_force_n), "N", 2),
                        opt(Some(e.jump_n), "N", 2),
                        opt(Some(e.recovery_overshoot_n), "N", 3),
                        e.recovery_overshoot_pct,
                        match (e.settling_time_s, &e.not_settled) {
                            (Some(ts), _) => match e.fragility() {
                                Some(f) => format!("settled in {ts:.3} s ({f})"),
                                None => format!("settled in {ts:.3} s"),
                            },
                            (None, Some(why)) => format!("NOT SETTLED: {why}"),
                            (None, None) => "not settled".into(),
                        }
                    ),
                    None => "-".into(),
                },
            };
            let _ = writeln!(
                s,
                "{:<13} {:<18} {:>10.4} N  {details}",
                r.name, w.name, w.rms_force_error_n
            );
        }
    }
    s
}
