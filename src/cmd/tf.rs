//! `pneuflex tf <file>`: the linearised transfer function of eqs. (16)-(17) of an actuator sheet (or of
//! the sheet a scene names), at mid-stroke holding no external load.

use std::fmt::Write as _;
use std::path::Path;

use anyhow::Context as _;
use pneuflex_pneumatics::load_actuator_sheet;

/// Computes K_n, omega_n, xi_n and the denominator of eq. (16) for the actuator in `path`; returns a
/// table, or one JSON object (SI units) when `json` is set. `--margin-db` and `--bode` belong to `--loop`:
/// given without it they are refused rather than silently ignored.
pub fn tf(
    path: &Path,
    json: bool,
    margin_db: Option<f64>,
    bode: Option<&Path>,
) -> anyhow::Result<String> {
    if let Some(b) = bode {
        anyhow::bail!(
            "--bode {}: the Bode plot is of the loop; add --loop (with a scene file)",
            b.display()
        );
    }
    if margin_db.is_some() {
        anyhow::bail!("--margin-db: applies to the loop analysis; add --loop (with a scene file)");
    }
    // Errors name the file, the line and the key (also the scene key or sheet key naming a missing file).
    let sheet = load_actuator_sheet(path)?;
    let sheet_path = sheet.path.clone();
    let model = sheet.model();
    let (op, tf) = model
        .transfer_function_mid_stroke()
        .with_context(|| format!("{}: no operating point at mid-stroke", sheet_path.display()))?;
    let lin = model.linearise(&op);
    let [a3, a2, a1, a0] = tf.den;
    // Eqs. (16)-(17) are the paper's model: the effects beyond it (docs/pneumatics.md) are not in them.
    let mut ignored = sheet.effects.given();
    if matches!(
        sheet.mechanics.friction,
        pneuflex_pneumatics::Friction::LuGre { .. }
    ) {
        ignored.push("mechanics.friction = \"lugre\"".into());
    }
    if json {
        let v = serde_json::json!({
            "actuator": sheet_path.display().to_string(),
            "k_n": tf.k_n,
            "omega_n": tf.omega_n,
            "xi_n": tf.xi_n,
            "num": tf.num,
            "den": tf.den,
            "a3": a3, "a2": a2, "a1": a1, "a0": a0,
            "operating_point": {
                "x": op.x, "u": op.u, "p_a": op.p_a, "p_b": op.p_b, "temperature": op.temperature_k,
            },
            "k_pa": lin.k_pa, "k_pb": lin.k_pb, "k_ca": lin.k_ca, "k_cb": lin.k_cb,
        });
        let mut v = v;
        if !ignored.is_empty() {
            v["effects_not_linearised"] = serde_json::json!(ignored);
        }
        return Ok(serde_json::to_string_pretty(&v)?);
    }
    let mut s = String::new();
    writeln!(
        s,
        "transfer function Y(s)/P_L(s), eqs. (16)-(17): {}",
        sheet_path.display()
    )?;
    writeln!(
        s,
        "operating point: x = {:.4} m (mid-stroke), u0 = {:+.4}, p_a = {:.0} Pa abs, p_b = {:.0} Pa abs, T = {:.2} K",
        op.x, op.u, op.p_a, op.p_b, op.temperature_k
    )?;
    let rows: [(&str, f64, &str); 12] = [
        ("K_n", tf.k_n, "m/(Pa s)"),
        ("omega_n", tf.omega_n, "rad/s"),
        ("f_n", tf.omega_n / (2.0 * std::f64::consts::PI), "Hz"),
        ("xi_n", tf.xi_n, "1"),
        ("a3 (s^3)", a3, "kg m^3"),
        ("a2 (s^2)", a2, "kg m^3/s"),
        ("a1 (s^1) = beta_n", a1, "kg m^3/s^2"),
        ("a0 (s^0)", a0, "kg m^3/s^3"),
        ("b0 (numerator)", tf.num, "m^5/s"),
        ("K_ca", lin.k_ca, "kg/(s Pa)"),
        ("K_cb", lin.k_cb, "kg/(s Pa)"),
        ("K_pa", lin.k_pa, "kg/s"),
    ];
    writeln!(s, "{:<20} {:>14}  unit", "quantity", "value")?;
    for (name, v, unit) in rows {
        writeln!(s, "{name:<20} {v:>14.6e}  {unit}")?;
    }
    if !ignored.is_empty() {
        writeln!(
            s,
            "not linearised (the paper's model only): {}",
            ignored.join(", ")
        )?;
    }
    Ok(s)
}

/// `pneuflex tf <scene> --loop`: each run's inner-loop margins at every stiffness the scene meets, the
/// largest kp with `margin_db` of gain margin, and (on a pneumatic plant) the limit-cycle onset predicted by
/// describing functions of the valve and the friction (docs/scenes.md, "Inner-loop margins").
pub fn loop_margins(
    path: &Path,
    margin_db: f64,
    json: bool,
    bode: Option<&Path>,
) -> anyhow::Result<String> {
    use pneuflex_scene::analysis::loop_margins::{analyse, stiffnesses};
    use pneuflex_scene::analysis::run_onset::{RunOnset, run_onset};
    anyhow::ensure!(
        margin_db.is_finite() && (0.0..=60.0).contains(&margin_db),
        "--margin-db: a gain margin in [0, 60] dB, got {margin_db}"
    );
    if pneuflex_pneumatics::ActuatorSheet::load(path).is_ok() {
        anyhow::bail!(
            "{}: an actuator sheet; --loop analyses a scene's loop: give a scene file (scenes/*.toml), or drop \
             --loop for the sheet's transfer function",
            path.display()
        );
    }
    let text = pneuflex_files::read_text(path, pneuflex_files::InputKind::Scene)?;
    if pneuflex_scene::mechanism::MechanismScene::is_mechanism(&text) {
        return mechanism_loops(path, json, bode);
    }
    let scene = pneuflex_scene::Scene::load(path)?;
    // Never write over a file pneuflex did not make: the plot goes beside and is renamed in only if the
    // name is free.
    if let Some(b) = bode {
        pneuflex_files::output::check_file_destination(b)
            .map_err(|e| anyhow::anyhow!("--bode: {e}"))?;
    }
    let mut analyses = Vec::new();
    let mut out = Vec::new();
    let mut s = String::new();
    let f = |x: Option<f64>, p: usize| x.map_or("-".to_string(), |v| format!("{v:.p$}"));
    for i in 0..scene.runs.len() {
        let run = &scene.runs[i];
        // Each run's own onset at each stiffness: the whole loop, the adaptive law's p and d where an
        // oscillation drives them (docs/scenes.md "The whole loop's onset").
        let mut onsets = Vec::new();
        for k in stiffnesses(&scene) {
            onsets.push(run_onset(&scene, i, k)?);
        }
        let onset_text = |o: &Option<RunOnset>| -> String {
            let Some(o) = o else { return String::new() };
            if let Some(why) = &o.not_predicted {
                return format!("; limit cycle: not predicted ({why})");
            }
            let Some(k) = o.kp_per_m else {
                return "; limit cycle: none within 1000x of the run's kp".into();
            };
            let amp = o
                .amplitude_m
                .map_or(String::new(), |a| format!(", {:.1} mm", a * 1e3));
            format!(
                "; limit cycle predicted from kp = {k:.2} /m at {} Hz ({}{amp})",
                f(o.frequency_hz, 1),
                o.method
            )
        };
        let held_text = onsets
            .iter()
            .flatten()
            .find_map(|o| {
                o.held
                    .as_ref()
                    .filter(|h| h.g_adapts || h.p_m_per_n != 0.0 || h.d_s != 0.0)
            })
            .map(|h| {
                format!(
                    "  onset with the adaptive law in the loop: p = {} m/N, d = {} s ({})",
                    h.p_m_per_n, h.d_s, h.source
                )
            });
        if let Some(fr) = &run.frozen {
            writeln!(
                s,
                "run `{}`: the controller of `{}` with g, p, d held at its {}",
                run.name,
                fr.run,
                fr.at.name(),
            )?;
            if let Some(h) = &held_text {
                writeln!(s, "{h}")?;
            }
            for o in onsets.iter().flatten() {
                writeln!(
                    s,
                    "  k_e = {:>8} N/m{}",
                    o.stiffness_n_per_m,
                    onset_text(&Some(o.clone()))
                )?;
            }
            out.push(
                serde_json::json!({"run": run.name, "frozen": fr, "limit_cycle_onsets": onsets}),
            );
            continue;
        }
        let a = analyse(&scene, i, margin_db)?;
        writeln!(
            s,
            "run `{}` (kp = {} /m): inner position loop, broken at the valve command; valve: {}",
            a.run, a.kp_per_m, a.valve_model
        )?;
        if a.valve_model.contains("averaged") {
            writeln!(
                s,
                "  (an on/off valve: these margins are of its PWM-period average, which does not see the duty \
                 held over the period; the onset below comes from the sampled-data model of the PWM, \
                 docs/scenes.md \"The PWM valve's onset\")"
            )?;
        }
        if let Some(h) = &held_text {
            writeln!(s, "{h}")?;
        }
        for m in &a.margins {
            let onset = onsets
                .iter()
                .flatten()
                .find(|o| o.stiffness_n_per_m == m.stiffness_n_per_m)
                .cloned();
            writeln!(
                s,
                "  k_e = {:>8} N/m: crossover {} Hz, phase margin {} deg; phase crossover {} Hz, gain margin {} dB; kp for {margin_db} dB: {} /m{}",
                m.stiffness_n_per_m,
                f(m.crossover_hz, 2),
                f(m.phase_margin_deg, 1),
                f(m.phase_crossover_hz, 2),
                f(m.gain_margin_db, 1),
                f(m.kp_max_per_m, 2),
                onset_text(&onset)
            )?;
            let o = &m.outer;
            writeln!(
                s,
                "  {:>14}  outer force loop (impedance filter, inner loop, environment): crossover {} Hz, phase margin {} deg; phase crossover {} Hz, gain margin {} dB",
                "",
                f(o.crossover_hz, 2),
                f(o.phase_margin_deg, 1),
                f(o.phase_crossover_hz, 2),
                f(o.gain_margin_db, 1),
            )?;
        }
        out.push(serde_json::json!({"analysis": a, "limit_cycle_onsets": onsets}));
        analyses.push(a);
    }
    if let Some(b) = bode {
        // The partial file keeps the format's extension (SVG for `.svg`, PDF for `.pdf`, PNG otherwise).
        let ext = pneuflex_viz::Format::of(b).ext();
        let tmp = b.with_extension(format!("partial-{}.{ext}", std::process::id()));
        let drawn = pneuflex_viz::write_bode(&tmp, &scene, &analyses);
        if let Err(e) = drawn {
            let _ = std::fs::remove_file(&tmp);
            return Err(e.into());
        }
        // A hard link, not a rename: it fails rather than replace a file that appeared meanwhile.
        let linked = std::fs::hard_link(&tmp, b);
        let _ = std::fs::remove_file(&tmp);
        linked.with_context(|| format!("--bode {}", b.display()))?;
        writeln!(s, "Bode plot: {}", b.display())?;
    }
    if json {
        return Ok(serde_json::to_string_pretty(&out)?);
    }
    Ok(s)
}

/// `tf --loop` on a scene of several actuators: the loop at each actuator's valve command, measured by
/// injection with every controller closed (`pneuflex_scene::analysis::injection`), per run and per phase of
/// the scene's events.
fn mechanism_loops(path: &Path, json: bool, bode: Option<&Path>) -> anyhow::Result<String> {
    use pneuflex_scene::analysis::injection::{Injection, mechanism_loops};
    let scene = pneuflex_scene::mechanism::MechanismScene::load(path)?;
    if let Some(b) = bode {
        anyhow::bail!(
            "--bode {}: a scene with several actuators has measured loops, not drawn yet; --json gives each \
             loop's Bode points (Hz, dB, degrees)",
            b.display()
        );
    }
    let inj = Injection::default();
    let loops = mechanism_loops(&scene, &inj)?;
    if json {
        return Ok(serde_json::to_string_pretty(&loops)?);
    }
    let f = |x: Option<f64>, p: usize| x.map_or("-".to_string(), |v| format!("{v:.p$}"));
    let mut s = String::new();
    writeln!(
        s,
        "{}: the loop at each actuator's valve command with every controller closed, measured by injection (a \
         multisine of {} RMS on the command, {} frequencies from {:.2} to {} Hz over {} s after {} s; each force \
         reference held at its first value; docs/scenes.md \"Loops of several actuators\")",
        scene.name,
        inj.rms,
        loops.first().map_or(0, |l| l.measured.bode.len()),
        loops
            .first()
            .and_then(|l| l.measured.bode.first())
            .map_or(0.0, |b| b.0),
        inj.f_max_hz,
        inj.window_s,
        inj.settle_s
    )?;
    let mut run = "";
    for l in &loops {
        if l.run != run {
            run = &l.run;
            writeln!(s, "run `{run}`:")?;
        }
        let phase = l
            .after_events_at_s
            .map_or("from the start".to_string(), |t| {
                format!("after the events at {t} s")
            });
        let m = &l.measured;
        writeln!(
            s,
            "  {:<14} {:<24} crossover {} Hz, phase margin {} deg; phase crossover {} Hz, gain margin {} dB",
            l.actuator,
            phase,
            f(m.crossover_hz, 2),
            f(m.phase_margin_deg, 1),
            f(m.phase_crossover_hz, 2),
            f(m.gain_margin_db, 1)
        )?;
    }
    Ok(s)
}
