//! A Bode plot: the gain and the phase of open loops against frequency, with the 0 dB and -180 deg lines and
//! each loop's margins marked where they are read.

use std::path::Path;

use plotters::coord::Shift;
use plotters::prelude::*;

use crate::{FAMILY, PALETTE, PlotError, ensure_font};

/// One loop's frequency response and the margins read off it.
#[derive(Clone, Debug, PartialEq)]
pub struct BodeLine<'a> {
    /// Legend label.
    pub label: String,
    /// (Hz, dB, degrees) points, frequency ascending.
    pub points: &'a [(f64, f64, f64)],
    /// The gain crossover (|L| = 0 dB), Hz, and the phase margin there, degrees.
    pub gain_crossover: Option<(f64, f64)>,
    /// The phase crossover (arg L = -180°), Hz, and the gain margin there, dB.
    pub phase_crossover: Option<(f64, f64)>,
}

/// Draws the gain (top) and phase (bottom) of `lines` under `title` into `path` (1200 x 900; SVG or PDF when
/// the path ends in `.svg` or `.pdf`, PNG otherwise). At each gain crossover a dot on 0 dB and, below, the phase margin as
/// a bar up from -180°; at each phase crossover a dot on -180° and, above, the gain margin as a bar up to
/// 0 dB; the legend gives the numbers. The axes span the data: no floor. Lines of fewer than two points are
/// left out, and nothing to draw is [`PlotError::Empty`].
pub fn write_bode(path: &Path, title: &str, lines: &[BodeLine<'_>]) -> Result<(), PlotError> {
    ensure_font()?;
    let lines: Vec<&BodeLine<'_>> = lines.iter().filter(|l| l.points.len() > 1).collect();
    if lines.is_empty() {
        return Err(PlotError::Empty);
    }
    crate::figure::write(path, (1200, 900), &Bode { title, lines })
}

/// A Bode figure's content.
struct Bode<'a, 'b> {
    title: &'a str,
    lines: Vec<&'a BodeLine<'b>>,
}

impl crate::figure::Figure for Bode<'_, '_> {
    fn draw<DB: DrawingBackend>(
        &self,
        root: DrawingArea<DB, Shift>,
        _raster: bool,
    ) -> Result<(), String>
    where
        DB::ErrorType: 'static,
    {
        draw(root, self.title, &self.lines)
    }
}

/// The range of a column of every line's points, with a little room.
fn span(lines: &[&BodeLine<'_>], col: fn(&(f64, f64, f64)) -> f64) -> (f64, f64) {
    let (lo, hi) = lines
        .iter()
        .flat_map(|l| l.points.iter())
        .map(col)
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), v| {
            (l.min(v), h.max(v))
        });
    let pad = 0.05 * (hi - lo).max(1.0);
    (lo - pad, hi + pad)
}

fn draw<DB: DrawingBackend>(
    root: DrawingArea<DB, Shift>,
    title: &str,
    lines: &[&BodeLine<'_>],
) -> Result<(), String> {
    let e = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
    root.fill(&WHITE).map_err(e)?;
    let root = root.titled(title, (FAMILY, 20)).map_err(e)?;
    let (top, bottom) = root.split_vertically(430);
    let f_lo = lines
        .iter()
        .map(|l| l.points[0].0)
        .fold(f64::INFINITY, f64::min);
    let f_hi = (lines.iter())
        .map(|l| l.points[l.points.len() - 1].0)
        .fold(0.0_f64, f64::max);
    // The 0 dB and -180° lines are always in view.
    let (g_lo, g_hi) = span(lines, |p| p.1);
    let (p_lo, p_hi) = span(lines, |p| p.2);
    let panels = [
        (
            "open loop L: gain",
            "|L| [dB]",
            g_lo.min(-5.0),
            g_hi.max(5.0),
            0.0,
        ),
        (
            "phase",
            "arg L [deg]",
            p_lo.min(-190.0),
            p_hi.max(-170.0),
            -180.0,
        ),
    ];
    for (k, (area, (caption, y_desc, lo, hi, reference))) in
        [&top, &bottom].into_iter().zip(panels).enumerate()
    {
        let gain = k == 0;
        let mut chart = ChartBuilder::on(area)
            .caption(caption, (FAMILY, 18))
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(70)
            .build_cartesian_2d((f_lo..f_hi).log_scale(), lo..hi)
            .map_err(e)?;
        chart
            .configure_mesh()
            .x_desc("frequency [Hz]")
            .y_desc(y_desc)
            .label_style((FAMILY, 15))
            .draw()
            .map_err(e)?;
        chart
            .draw_series(DashedLineSeries::new(
                vec![(f_lo, reference), (f_hi, reference)],
                6,
                4,
                BLACK.stroke_width(1),
            ))
            .map_err(e)?;
        for (i, l) in lines.iter().enumerate() {
            let c = PALETTE[i % PALETTE.len()];
            let label = if gain {
                let f = |v: Option<(f64, f64)>, unit: &str, what: &str| {
                    v.map_or(format!("no {what}"), |(hz, m)| {
                        format!("{what} {m:.1} {unit} at {hz:.2} Hz")
                    })
                };
                format!(
                    "{}: {}, {}",
                    l.label,
                    f(l.phase_crossover, "dB", "GM"),
                    f(l.gain_crossover, "deg", "PM")
                )
            } else {
                l.label.clone()
            };
            chart
                .draw_series(LineSeries::new(
                    l.points.iter().map(|p| (p.0, if gain { p.1 } else { p.2 })),
                    c.stroke_width(2),
                ))
                .map_err(e)?
                .label(label)
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 24, y)], c.stroke_width(2))
                });
            // Where each margin is read: the crossover on this panel's reference line, and the other
            // crossover's margin as a bar from the curve to the reference.
            let (dot, bar) = if gain {
                (
                    l.gain_crossover,
                    l.phase_crossover.map(|(hz, gm)| (hz, -gm, 0.0)),
                )
            } else {
                (
                    l.phase_crossover,
                    l.gain_crossover.map(|(hz, pm)| (hz, -180.0, -180.0 + pm)),
                )
            };
            if let Some((hz, _)) = dot {
                chart
                    .draw_series(std::iter::once(Circle::new((hz, reference), 5, c.filled())))
                    .map_err(e)?;
            }
            if let Some((hz, a, b)) = bar {
                chart
                    .draw_series(std::iter::once(PathElement::new(
                        vec![(hz, a.clamp(lo, hi)), (hz, b.clamp(lo, hi))],
                        c.stroke_width(4),
                    )))
                    .map_err(e)?;
            }
        }
        crate::figure::draw_legend(&mut chart, SeriesLabelPosition::LowerLeft, 0.9, 14)?;
    }
    root.present().map_err(e)
}
