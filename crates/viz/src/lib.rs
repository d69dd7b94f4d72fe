//! Figures of pneuflex runs, like the paper's Figs. 2–4: force against reference, position against reference
//! position (controllers overlaid), and a zoom on the force around each scene event. PNG (plotters' bitmap
//! backend) or SVG, with an embedded DejaVu Sans font so the output does not depend on system fonts.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use plotters::element::DashedPathElement;
use plotters::prelude::*;
use plotters::style::{FontStyle, register_font};
use pneuflex_scene::schema::EventSpec;
use pneuflex_scene::{RunResult, Scene};

/// DejaVu Sans (fonts-dejavu-core; free license in assets/DejaVuSans-LICENSE.txt).
static FONT: &[u8] = include_bytes!("../assets/DejaVuSans.ttf");
/// The font family name the figures use.
const FAMILY: &str = "sans-serif";

/// Errors while drawing figures.
#[derive(Debug, thiserror::Error)]
pub enum VizError {
    /// The embedded font could not be registered.
    #[error("cannot register the embedded font")]
    Font,
    /// Drawing or encoding a figure failed.
    #[error("{}: cannot draw figure: {message}", path.display())]
    Draw {
        /// The figure file.
        path: PathBuf,
        /// The backend's message.
        message: String,
    },
    /// Nothing to draw.
    #[error("no successful run to draw")]
    Empty,
}

/// Output format of a figure.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    /// Raster image, 1200×700 px.
    Png,
    /// Vector image.
    Svg,
}

impl Format {
    fn ext(self) -> &'static str {
        match self {
            Format::Png => "png",
            Format::Svg => "svg",
        }
    }
}

fn ensure_font() -> Result<(), VizError> {
    static DONE: OnceLock<bool> = OnceLock::new();
    if *DONE.get_or_init(|| register_font(FAMILY, FontStyle::Normal, FONT).is_ok()) {
        Ok(())
    } else {
        Err(VizError::Font)
    }
}

/// Colours of the runs, in order (colour-blind friendly: blue, vermillion, green, purple, ...).
const PALETTE: [RGBColor; 6] = [
    RGBColor(0, 114, 178),
    RGBColor(213, 94, 0),
    RGBColor(0, 158, 115),
    RGBColor(204, 121, 167),
    RGBColor(230, 159, 0),
    RGBColor(86, 180, 233),
];

/// One line of a plot.
struct Line<'a> {
    label: String,
    t: &'a [f64],
    y: Vec<f64>,
    color: RGBColor,
    dashed: bool,
    width: u32,
}

struct Plot<'a> {
    title: String,
    y_label: String,
    t_range: (f64, f64),
    lines: Vec<Line<'a>>,
    events: Vec<f64>,
    /// A shaded time interval with a label (the environment swap of Fig. 7).
    band: Option<(f64, f64, String)>,
}

fn draw_plot<DB: DrawingBackend>(
    root: DrawingArea<DB, plotters::coord::Shift>,
    plot: &Plot,
) -> Result<(), String>
where
    DB::ErrorType: 'static,
{
    root.fill(&WHITE).map_err(|e| e.to_string())?;
    let (t0, t1) = plot.t_range;
    let mut lo = f64::INFINITY;
    let mut hi = f64::NEG_INFINITY;
    for l in &plot.lines {
        for (t, y) in l.t.iter().zip(&l.y) {
            if *t >= t0 && *t <= t1 && y.is_finite() {
                lo = lo.min(*y);
                hi = hi.max(*y);
            }
        }
    }
    if !lo.is_finite() {
        lo = 0.0;
        hi = 1.0;
    }
    let pad = ((hi - lo) * 0.08).max(1e-9 + 1e-3 * hi.abs().max(lo.abs()));
    let (lo, hi) = (lo - pad, hi + pad);
    let mut chart = ChartBuilder::on(&root)
        .caption(&plot.title, (FAMILY, 26))
        .margin(16)
        .x_label_area_size(50)
        .y_label_area_size(80)
        .build_cartesian_2d(t0..t1, lo..hi)
        .map_err(|e| e.to_string())?;
    chart
        .configure_mesh()
        .x_desc("time t [s]")
        .y_desc(plot.y_label.as_str())
        .label_style((FAMILY, 16))
        .axis_desc_style((FAMILY, 18))
        .light_line_style(RGBColor(235, 235, 235))
        .draw()
        .map_err(|e| e.to_string())?;
    if let Some((b0, b1, label)) = &plot.band {
        let (b0, b1) = (b0.max(t0), b1.min(t1));
        if b1 > b0 {
            chart
                .draw_series(std::iter::once(Rectangle::new(
                    [(b0, lo), (b1, hi)],
                    RGBColor(255, 235, 200).filled(),
                )))
                .map_err(|e| e.to_string())?;
            chart
                .draw_series(std::iter::once(Text::new(
                    label.clone(),
                    (b0, hi - 0.04 * (hi - lo)),
                    (FAMILY, 16).into_font().color(&RGBColor(140, 80, 0)),
                )))
                .map_err(|e| e.to_string())?;
        }
    }
    for &te in &plot.events {
        if te >= t0 && te <= t1 {
            chart
                .draw_series(DashedLineSeries::new(
                    vec![(te, lo), (te, hi)],
                    6,
                    6,
                    RGBColor(120, 120, 120).stroke_width(1),
                ))
                .map_err(|e| e.to_string())?;
        }
    }
    for l in &plot.lines {
        let pts: Vec<(f64, f64)> =
            l.t.iter()
                .zip(&l.y)
                .filter(|(t, y)| **t >= t0 && **t <= t1 && y.is_finite())
                .map(|(t, y)| (*t, *y))
                .collect();
        let style = l.color.stroke_width(l.width);
        let color = l.color;
        let width = l.width;
        if l.dashed {
            chart
                .draw_series(DashedLineSeries::new(pts, 10, 6, style))
                .map_err(|e| e.to_string())?
                .label(l.label.as_str())
                .legend(move |(x, y)| {
                    DashedPathElement::new(
                        vec![(x, y), (x + 12, y), (x + 24, y)],
                        6,
                        4,
                        color.stroke_width(width),
                    )
                });
        } else {
            // Segment by segment: plotters joins a thick polyline with miters, and a sharp reversal (the PWM
            // ripple, a contact impact) then draws a spike far outside the data.
            chart
                .draw_series(
                    pts.windows(2)
                        .map(|w| PathElement::new(vec![w[0], w[1]], style)),
                )
                .map_err(|e| e.to_string())?
                .label(l.label.as_str())
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 24, y)], color.stroke_width(width))
                });
        }
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font((FAMILY, 16))
        .draw()
        .map_err(|e| e.to_string())?;
    root.present().map_err(|e| e.to_string())?;
    Ok(())
}

fn render(path: &Path, format: Format, plot: &Plot) -> Result<(), VizError> {
    let size = (1200, 700);
    let r = match format {
        Format::Png => draw_plot(BitMapBackend::new(path, size).into_drawing_area(), plot),
        Format::Svg => draw_plot(SVGBackend::new(path, size).into_drawing_area(), plot),
    };
    r.map_err(|message| VizError::Draw {
        path: path.to_path_buf(),
        message,
    })
}

fn force_lines<'a>(ok: &[&'a RunResult]) -> Vec<Line<'a>> {
    let mut lines = vec![Line {
        label: "reference f_ref".into(),
        t: ok[0].trace.t(),
        y: ok[0].trace.f_ref().to_vec(),
        color: BLACK,
        dashed: true,
        width: 2,
    }];
    for (i, r) in ok.iter().enumerate() {
        lines.push(Line {
            label: format!("f_e, {}", r.name),
            t: r.trace.t(),
            y: r.trace.f_e().to_vec(),
            color: PALETTE[i % PALETTE.len()],
            dashed: false,
            width: 2,
        });
    }
    lines
}

/// Writes the figures of a scene's runs into `dir`; returns the files written.
///
/// `force.<ext>`: f_e of every run against f_ref; `position.<ext>`: x (solid) and x_r (dashed) of every
/// run, mm; `event-<i>.<ext>`: the force from 0.5 s before to 2.5 s after event i. Diverged runs are left out.
pub fn write_figures(
    dir: &Path,
    scene: &Scene,
    results: &[RunResult],
    format: Format,
) -> Result<Vec<PathBuf>, VizError> {
    ensure_font()?;
    let ok: Vec<&RunResult> = results
        .iter()
        .filter(|r| r.diverged.is_none() && !r.trace.is_empty())
        .collect();
    if ok.is_empty() {
        return Err(VizError::Empty);
    }
    let events: Vec<f64> = scene.events.iter().map(|e| e.t_s()).collect();
    let t_end = ok
        .iter()
        .map(|r| *r.trace.t().last().unwrap_or(&0.0))
        .fold(0.0, f64::max);
    let mut written = Vec::new();

    let force = Plot {
        title: format!("{}: contact force", scene.name),
        y_label: "force [N]".into(),
        t_range: (0.0, t_end),
        lines: force_lines(&ok),
        events: events.clone(),
        band: None,
    };
    let p = dir.join(format!("force.{}", format.ext()));
    render(&p, format, &force)?;
    written.push(p);

    let mut lines = Vec::new();
    for (i, r) in ok.iter().enumerate() {
        let c = PALETTE[i % PALETTE.len()];
        let mm = |v: &[f64]| v.iter().map(|x| x * 1e3).collect::<Vec<_>>();
        lines.push(Line {
            label: format!("x, {}", r.name),
            t: r.trace.t(),
            y: mm(r.trace.x()),
            color: c,
            dashed: false,
            width: 2,
        });
        lines.push(Line {
            label: format!("x_r, {}", r.name),
            t: r.trace.t(),
            y: mm(r.trace.x_r()),
            color: c,
            dashed: true,
            width: 1,
        });
    }
    let position = Plot {
        title: format!("{}: flange position against reference position", scene.name),
        y_label: "position [mm]".into(),
        t_range: (0.0, t_end),
        lines,
        events: events.clone(),
        band: None,
    };
    let p = dir.join(format!("position.{}", format.ext()));
    render(&p, format, &position)?;
    written.push(p);

    for (i, ev) in scene.events.iter().enumerate() {
        let te = ev.t_s();
        let zoom = Plot {
            title: format!(
                "{}: force around event {} at t = {te} s ({})",
                scene.name,
                i,
                event_label(ev)
            ),
            y_label: "force [N]".into(),
            t_range: ((te - 0.5).max(0.0), (te + 2.5).min(t_end)),
            lines: force_lines(&ok),
            events: vec![te],
            band: None,
        };
        if zoom.t_range.1 > zoom.t_range.0 {
            let p = dir.join(format!("event-{i}.{}", format.ext()));
            render(&p, format, &zoom)?;
            written.push(p);
        }
    }
    // Paper Fig. 7: the force response of every controller around each environment swap, the carriage
    // move shaded.
    for (i, ev) in scene.events.iter().enumerate() {
        if let EventSpec::SwapEnvironment {
            t_s,
            to,
            duration_s,
        } = ev
        {
            let fig7 = Plot {
                title: format!(
                    "{}: force response to the environment change (swap to {to} at {t_s} s)",
                    scene.name
                ),
                y_label: "contact force f_e [N]".into(),
                t_range: ((t_s - 1.0).max(0.0), (t_s + duration_s + 4.0).min(t_end)),
                lines: force_lines(&ok),
                events: vec![*t_s, t_s + duration_s],
                band: Some((*t_s, t_s + duration_s, format!(" carriage swaps to {to}"))),
            };
            if fig7.t_range.1 > fig7.t_range.0 {
                let p = dir.join(format!("fig7-swap-{i}.{}", format.ext()));
                render(&p, format, &fig7)?;
                written.push(p);
            }
        }
    }
    Ok(written)
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
