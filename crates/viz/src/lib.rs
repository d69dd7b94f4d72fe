//! The figures of a scene's runs, like the paper's Figs. 2–4: force against reference, position against
//! reference position (controllers overlaid), a zoom on the force around each scene event, Fig. 7's swap of
//! the environment, and the Bode plot of the loop analysis. Drawn with `pneuflex-plot`.
//!
//! On a plant with an on/off valve the measured signals are drawn as their PWM-period mean (the metrics'
//! `moving_average`) over a light band of the raw signal, the references on top.

use std::path::{Path, PathBuf};

use plotters::prelude::*;
use pneuflex_plot::{Band, BodeLine, Line, PALETTE, Plot, ensure_font, render};
pub use pneuflex_plot::{Format, PlotError};
use pneuflex_scene::analysis::metrics::moving_average;
use pneuflex_scene::schema::{EventSpec, WindowKind};
use pneuflex_scene::{RunResult, Scene, WindowMetrics};

/// A run's measured signal `y` (already in display units): on an on/off valve (`average` = samples per
/// PWM period) its PWM-period mean as the line over a light band of the raw signal; on a continuous
/// valve the raw signal as the line.
fn measured<'a>(
    plot: &mut Plot<'a>,
    label: String,
    t: &'a [f64],
    y: Vec<f64>,
    color: RGBColor,
    average: Option<(usize, f64)>,
) {
    match average {
        Some((n, period_s)) => {
            let mean = moving_average(&y, n);
            plot.lines.push(Line {
                label: format!("{label} ({} ms PWM-period mean)", fmt_ms(period_s)),
                t,
                y: mean,
                color,
                dashed: false,
                width: 2,
            });
            plot.bands.push(Band {
                label: format!("{label}, raw (range over a PWM period)"),
                t,
                y,
                color,
                period_s,
            });
        }
        None => plot.lines.push(Line {
            label,
            t,
            y,
            color,
            dashed: false,
            width: 2,
        }),
    }
}

fn fmt_ms(period_s: f64) -> String {
    let ms = period_s * 1e3;
    if (ms - ms.round()).abs() < 1e-9 {
        format!("{}", ms.round())
    } else {
        format!("{ms:.1}")
    }
}

/// Samples per PWM period and the period, s, for a run's trace (None: a continuous valve, nothing to
/// average — the same rule as the event metrics).
fn averaging(period_s: Option<f64>, t: &[f64]) -> Option<(usize, f64)> {
    let p = period_s?;
    let n = t.len();
    if n < 2 {
        return None;
    }
    let dt = (t[n - 1] - t[0]) / (n - 1) as f64;
    (p > 1.5 * dt).then(|| ((p / dt).round() as usize, p))
}

/// The force of every run (mean over the raw band on an on/off valve) with the reference on top.
fn force_plot<'a>(
    title: String,
    t_range: (f64, f64),
    events: Vec<f64>,
    ok: &[&'a RunResult],
    period_s: Option<f64>,
) -> Plot<'a> {
    let mut plot = Plot::new(title, "contact force f_e [N]", t_range, events);
    for (i, r) in ok.iter().enumerate() {
        let t = r.trace.t();
        measured(
            &mut plot,
            format!("f_e, {}", r.name),
            t,
            r.trace.f_e().to_vec(),
            PALETTE[i % PALETTE.len()],
            averaging(period_s, t),
        );
    }
    plot.lines.push(Line {
        label: "reference f_ref".into(),
        t: ok[0].trace.t(),
        y: ok[0].trace.f_ref().to_vec(),
        color: BLACK,
        dashed: true,
        width: 2,
    });
    plot
}

/// The metrics window of a run that measures its response to the event at `te`: the event window starting
/// at the event, else the first event window starting inside `[te, t_max]`.
fn event_window(r: &RunResult, te: f64, t_max: f64) -> Option<&WindowMetrics> {
    let events = || {
        r.windows
            .iter()
            .filter(|w| w.kind == WindowKind::Event && w.event.is_some())
    };
    events()
        .find(|w| (w.t0_s - te).abs() <= 1e-6)
        .or_else(|| events().find(|w| w.t0_s >= te - 1e-6 && w.t0_s <= t_max))
}

/// Marks each run's settling time after the event at `te` (or says why it did not settle).
fn mark_settling(plot: &mut Plot, ok: &[&RunResult], te: f64) {
    for (i, r) in ok.iter().enumerate() {
        let color = PALETTE[i % PALETTE.len()];
        let Some(w) = event_window(r, te, plot.t_range.1) else {
            continue;
        };
        let Some(ev) = &w.event else { continue };
        let text = match (ev.settling_time_s, &ev.not_settled) {
            (Some(ts), _) if ev.settled => {
                plot.marks.push((w.t0_s + ts, color));
                format!(
                    "{}: settled {ts:.3} s after {} s (band ±{:.2} N, window '{}')",
                    r.name, w.t0_s, ev.settling_band_n, w.name
                )
            }
            (_, Some(why)) => format!("{}: not settled: {why} (window '{}')", r.name, w.name),
            _ => format!("{}: not settled (window '{}')", r.name, w.name),
        };
        plot.notes.push((text, color));
        // A fragile settling time gets its range on a line of its own (docs/scenes.md).
        plot.notes
            .extend(ev.fragility().map(|f| (format!("  {f}"), color)));
    }
}

/// Writes the figures of a scene's runs into `dir`; returns the files written.
///
/// `force.<ext>`: f_e of every run with f_ref on top; `position.<ext>`: x (solid) and x_r (dashed, on top)
/// of every run, mm; `event-<i>.<ext>`: the force from 0.5 s before to 2.5 s after event i (longer when a
/// run settles later), each run's settling time marked (dotted, in its colour) or why it did not settle;
/// for a swap of the environment instead `fig7-swap-<i>.<ext>` (paper Fig. 7): 1 s before to 4 s after the
/// carriage move (longer when a run settles later), the move shaded, the settling times marked.
/// On an on/off valve the measured f_e and x are drawn as their PWM-period mean over a light band of the raw
/// signal (its per-pixel-column min/max); on a continuous valve raw. Every series is reduced to its
/// per-pixel-column first/min/max/last before drawing. Diverged runs are left out.
pub fn write_figures(
    dir: &Path,
    scene: &Scene,
    results: &[RunResult],
    format: Format,
) -> Result<Vec<PathBuf>, PlotError> {
    ensure_font()?;
    let ok: Vec<&RunResult> = results
        .iter()
        .filter(|r| r.diverged.is_none() && !r.trace.is_empty())
        .collect();
    if ok.is_empty() {
        return Err(PlotError::Empty);
    }
    // The valve's PWM period as the plant that ran reports it (every run of a scene has the same plant).
    let period_s = results.iter().find_map(|r| r.pwm_period_s);
    let events: Vec<f64> = scene.events.iter().map(|e| e.t_s()).collect();
    let t_end = ok
        .iter()
        .map(|r| *r.trace.t().last().unwrap_or(&0.0))
        .fold(0.0, f64::max);
    // Every figure is a job that builds its plot (period means, unit conversions) and draws it into its own
    // file; the jobs run in parallel (building the plots first, on one thread, was 1.2 ms of fig7's outputs).
    type Build<'b> = Box<dyn Fn() -> Plot<'b> + Send + Sync + 'b>;
    let mut jobs: Vec<(PathBuf, Build<'_>)> = Vec::new();
    let (ok, events) = (&ok, &events);
    jobs.push((
        dir.join(format!("force.{}", format.ext())),
        Box::new(move || {
            force_plot(
                format!("{}: contact force", scene.name),
                (0.0, t_end),
                events.clone(),
                ok,
                period_s,
            )
        }),
    ));
    jobs.push((
        dir.join(format!("position.{}", format.ext())),
        Box::new(move || position_plot(scene, ok, t_end, events.clone(), period_s)),
    ));
    // The latest settling time of any run after an event at `te` (at least `te + 2.5` s).
    let settle_end = |te: f64| {
        ok.iter()
            .filter_map(|r| event_window(r, te, t_end))
            .filter_map(|w| Some(w.t0_s + w.event.as_ref()?.settling_time_s?))
            .fold(te + 2.5, f64::max)
    };
    for (i, ev) in scene.events.iter().enumerate() {
        // A swap has its Fig. 7 figure below, with the settling times on it: not two views of one window.
        if let EventSpec::SwapEnvironment { .. } = ev {
            continue;
        }
        let te = ev.t_s();
        // Long enough to show every run's settling time, within the trace.
        let t_range = ((te - 0.5).max(0.0), (settle_end(te) + 0.3).min(t_end));
        if t_range.1 <= t_range.0 {
            continue;
        }
        jobs.push((
            dir.join(format!("event-{i}.{}", format.ext())),
            Box::new(move || {
                let mut zoom = force_plot(
                    format!(
                        "{}: force around event {} at t = {te} s ({})",
                        scene.name,
                        i,
                        event_label(ev)
                    ),
                    t_range,
                    vec![te],
                    ok,
                    period_s,
                );
                mark_settling(&mut zoom, ok, te);
                zoom
            }),
        ));
    }
    // Paper Fig. 7: the force response of every controller around each environment swap, the carriage
    // move shaded, each run's settling time marked (as on an event figure).
    for (i, ev) in scene.events.iter().enumerate() {
        if let EventSpec::SwapEnvironment {
            t_s,
            to,
            duration_s,
        } = ev
        {
            let t_range = (
                (t_s - 1.0).max(0.0),
                (t_s + duration_s + 4.0)
                    .max(settle_end(*t_s) + 0.3)
                    .min(t_end),
            );
            if t_range.1 <= t_range.0 {
                continue;
            }
            jobs.push((
                dir.join(format!("fig7-swap-{i}.{}", format.ext())),
                Box::new(move || {
                    let mut fig7 = force_plot(
                        format!(
                            "{}: force response to the environment change (swap to {to} at {t_s} s)",
                            scene.name
                        ),
                        t_range,
                        vec![*t_s, t_s + duration_s],
                        ok,
                        period_s,
                    );
                    fig7.shade = Some((*t_s, t_s + duration_s, format!(" carriage swaps to {to}")));
                    mark_settling(&mut fig7, ok, *t_s);
                    fig7
                }),
            ));
        }
    }
    use rayon::prelude::*;
    jobs.par_iter()
        .map(|(p, build)| {
            // Every figure says which experiment it shows: the scene's description under its title.
            let mut plot = build();
            plot.subtitle = scene.description.clone();
            render(p, &plot).map(|()| p.clone())
        })
        .collect()
}

/// The flange position of every run against its reference position (both in mm).
fn position_plot<'a>(
    scene: &Scene,
    ok: &[&'a RunResult],
    t_end: f64,
    events: Vec<f64>,
    period_s: Option<f64>,
) -> Plot<'a> {
    let mut position = Plot::new(
        format!(
            "{}: flange position x against reference position x_r",
            scene.name
        ),
        "position [mm]",
        (0.0, t_end),
        events,
    );
    let mm = |v: &[f64]| v.iter().map(|x| x * 1e3).collect::<Vec<_>>();
    for (i, r) in ok.iter().enumerate() {
        let t = r.trace.t();
        measured(
            &mut position,
            format!("x, {}", r.name),
            t,
            mm(r.trace.x()),
            PALETTE[i % PALETTE.len()],
            averaging(period_s, t),
        );
    }
    // x_r follows the measured force through the controller and ripples with it: drawn as its PWM-period
    // mean too, so the reference stays readable on top of the positions.
    for (i, r) in ok.iter().enumerate() {
        let t = r.trace.t();
        let x_r = mm(r.trace.x_r());
        let (y, label) = match averaging(period_s, t) {
            Some((n, p)) => (
                moving_average(&x_r, n),
                format!("x_r, {} ({} ms PWM-period mean)", r.name, fmt_ms(p)),
            ),
            None => (x_r, format!("x_r, {}", r.name)),
        };
        position.lines.push(Line {
            label,
            t,
            y,
            color: darker(PALETTE[i % PALETTE.len()]),
            dashed: true,
            width: 2,
        });
    }
    position
}

/// A darker shade of a run's colour, for its reference line drawn over its measured signal.
fn darker(c: RGBColor) -> RGBColor {
    let f = |v: u8| (f64::from(v) * 0.55) as u8;
    RGBColor(f(c.0), f(c.1), f(c.2))
}

fn event_label(ev: &EventSpec) -> String {
    match ev {
        EventSpec::Stiffness {
            stiffness_n_per_m,
            material,
            ..
        } => match material {
            Some(m) => format!("k_e({m}) -> {stiffness_n_per_m} N/m"),
            None => format!("k_e -> {stiffness_n_per_m} N/m"),
        },
        EventSpec::SwapEnvironment { to, duration_s, .. } => {
            format!("swap to {to} over {duration_s} s")
        }
        EventSpec::Alpha { alpha_deg, .. } => format!("alpha -> {alpha_deg} deg"),
    }
}

/// The Bode plot of the scene's loop analyses (`pneuflex tf SCENE --loop --bode FILE`): every distinct open
/// inner loop at every stiffness the scene meets, runs with the same loop on one line, titled with the scene.
/// The response is drawn up to half the Nyquist frequency of the control tick: above it a sampled loop's
/// phase bends towards z = -1, which a reader takes for plant behaviour.
pub fn write_bode(
    path: &Path,
    scene: &Scene,
    analyses: &[pneuflex_scene::analysis::loop_margins::LoopAnalysis],
) -> Result<(), PlotError> {
    let f_max = 0.25 / scene.dt_s;
    // (runs, kp, margins): loops whose responses are the same, bit for bit, share a line.
    let mut loops: Vec<(
        Vec<&str>,
        f64,
        &pneuflex_scene::analysis::loop_margins::Margins,
    )> = Vec::new();
    for a in analyses {
        for m in &a.margins {
            match loops
                .iter_mut()
                .find(|(_, kp, l)| *kp == a.kp_per_m && l.bode == m.bode)
            {
                Some((runs, _, _)) => runs.push(&a.run),
                None => loops.push((vec![&a.run], a.kp_per_m, m)),
            }
        }
    }
    let lines: Vec<BodeLine<'_>> = loops
        .iter()
        .map(|(runs, kp, m)| {
            let end = m.bode.partition_point(|p| p.0 <= f_max);
            BodeLine {
                label: format!(
                    "{} (kp {kp} /m), k_e {} N/m",
                    runs.join(", "),
                    m.stiffness_n_per_m
                ),
                points: &m.bode[..end],
                gain_crossover: m.crossover_hz.zip(m.phase_margin_deg),
                phase_crossover: m.phase_crossover_hz.zip(m.gain_margin_db),
            }
        })
        .collect();
    let title = if scene.description.is_empty() {
        format!(
            "{}: open inner position loop, broken at the valve command",
            scene.name
        )
    } else {
        format!("{}: {}", scene.name, scene.description)
    };
    pneuflex_plot::write_bode(path, &title, &lines)
}
