//! A time-series figure: lines (measured signals, references), light bands of a raw signal under its mean,
//! events, a shaded interval, marks and notes, drawn on any plotters backend.

use plotters::element::{DashedPathElement, Drawable, PointCollection};
use plotters::prelude::*;
use plotters_backend::{BackendCoord, DrawingErrorKind};

use crate::FAMILY;
use crate::decimate::{decimate, envelope};

/// One line of a plot.
pub struct Line<'a> {
    pub label: String,
    pub t: &'a [f64],
    pub y: Vec<f64>,
    pub color: RGBColor,
    pub dashed: bool,
    pub width: u32,
}

/// A light band: the raw signal's per-column min/max envelope, under the line of its period mean.
pub struct Band<'a> {
    pub label: String,
    pub t: &'a [f64],
    pub y: Vec<f64>,
    pub color: RGBColor,
    /// The PWM period, s: each column's band spans the raw signal's range over the period around it (a
    /// column shorter than the period holds only part of a ripple and the band would be hatched).
    pub period_s: f64,
}

/// [`envelope`] widened to the min/max over the columns within half a period either side of each.
fn period_envelope(
    env: &[(f64, f64, f64)],
    t0: f64,
    t1: f64,
    columns: usize,
    period_s: f64,
) -> Vec<(f64, f64, f64)> {
    let col_s = (t1 - t0) / columns.max(1) as f64;
    let k = if col_s > 0.0 {
        (0.5 * period_s / col_s).round() as usize
    } else {
        0
    };
    if k == 0 {
        return env.to_vec();
    }
    (0..env.len())
        .map(|j| {
            let near = &env[j.saturating_sub(k)..(j + k + 1).min(env.len())];
            let lo = near.iter().map(|e| e.1).fold(f64::INFINITY, f64::min);
            let hi = near.iter().map(|e| e.2).fold(f64::NEG_INFINITY, f64::max);
            (env[j].0, lo, hi)
        })
        .collect()
}

/// A time-series figure: what is drawn, in order.
pub struct Plot<'a> {
    pub title: String,
    /// A line under the title (the scene's description); empty for none.
    pub subtitle: String,
    pub y_label: String,
    pub t_range: (f64, f64),
    pub bands: Vec<Band<'a>>,
    /// Drawn in order: the measured signals first, the references last (on top).
    pub lines: Vec<Line<'a>>,
    pub events: Vec<f64>,
    /// A shaded time interval with a label (the environment swap of Fig. 7).
    pub shade: Option<(f64, f64, String)>,
    /// Vertical dotted lines in a run's colour (the settling time of each run after an event).
    pub marks: Vec<(f64, RGBColor)>,
    /// Lines of text in the upper left corner, in a run's colour.
    pub notes: Vec<(String, RGBColor)>,
}

impl<'a> Plot<'a> {
    /// An empty figure of `title`, its y axis `y_label`, over `t_range`, with dashed lines at `events`.
    pub fn new(title: String, y_label: &str, t_range: (f64, f64), events: Vec<f64>) -> Self {
        Plot {
            title,
            subtitle: String::new(),
            y_label: y_label.into(),
            t_range,
            bands: Vec::new(),
            lines: Vec::new(),
            events,
            shade: None,
            marks: Vec::new(),
            notes: Vec::new(),
        }
    }
}

/// The light shade of a run's colour for its raw band.
pub fn band_color(c: RGBColor) -> RGBAColor {
    c.mix(0.22)
}

/// The y axis of a plot: the data's range, padded. A spike that the bulk of the data does not reach (beyond
/// the 0.5 %–99.5 % quantiles by more than their span: an impact of a few ticks on a signal of seconds) would
/// set the scale and flatten the rest, so the axis stops just past the bulk there and a note gives the
/// clipped extreme, its value and time.
pub(crate) fn y_range(plot: &Plot) -> (f64, f64, Vec<String>) {
    let (t0, t1) = plot.t_range;
    let series = plot
        .bands
        .iter()
        .map(|b| (b.t, &b.y))
        .chain(plot.lines.iter().map(|l| (l.t, &l.y)));
    let mut values = Vec::new();
    // The extremes and their times.
    let (mut lo, mut hi) = ((f64::INFINITY, 0.0), (f64::NEG_INFINITY, 0.0));
    for (t, y) in series {
        for (t, y) in t.iter().zip(y) {
            if *t >= t0 && *t <= t1 && y.is_finite() {
                values.push(*y);
                if *y < lo.0 {
                    lo = (*y, *t);
                }
                if *y > hi.0 {
                    hi = (*y, *t);
                }
            }
        }
    }
    if values.is_empty() {
        return (-0.08, 1.08, Vec::new());
    }
    let (mut a, mut b) = (lo.0, hi.0);
    let mut notes = Vec::new();
    // The axis's unit, from a label that ends in `[unit]`.
    let unit = (plot.y_label.rsplit_once('['))
        .and_then(|(_, u)| u.strip_suffix(']'))
        .map_or(String::new(), |u| format!(" {u}"));
    if values.len() >= 200 {
        let n = values.len();
        let q =
            |values: &mut Vec<f64>, k: usize| *values.select_nth_unstable_by(k, f64::total_cmp).1;
        let (q_lo, q_hi) = (q(&mut values, n / 200), q(&mut values, n - 1 - n / 200));
        let span = q_hi - q_lo;
        if span > 0.0 {
            if hi.0 > q_hi + span {
                b = q_hi + 0.25 * span;
                notes.push(format!(
                    "clipped: peak {}{unit} at t = {:.3} s",
                    short(hi.0),
                    hi.1
                ));
            }
            if lo.0 < q_lo - span {
                a = q_lo - 0.25 * span;
                notes.push(format!(
                    "clipped: low {}{unit} at t = {:.3} s",
                    short(lo.0),
                    lo.1
                ));
            }
        }
    }
    let pad = ((b - a) * 0.08).max(1e-9 + 1e-3 * b.abs().max(a.abs()));
    (a - pad, b + pad, notes)
}

/// A value in four significant digits.
fn short(v: f64) -> String {
    let a = v.abs();
    if a != 0.0 && !(1e-2..1e5).contains(&a) {
        format!("{v:.3e}")
    } else {
        format!(
            "{:.*}",
            (3 - a.max(1.0).log10().floor() as i32).max(0) as usize,
            v
        )
    }
}

/// Draws `plot` into `path` (1200 x 700), in the format of its extension (PNG, SVG or PDF).
pub fn render(path: &std::path::Path, plot: &Plot) -> Result<(), crate::PlotError> {
    crate::figure::write(path, (1200, 700), plot)
}

/// `raster`: the backend is a pixel buffer (thick lines as side-by-side pixel lines, [`Stroke`]), not SVG.
impl crate::figure::Figure for Plot<'_> {
    fn draw<DB: DrawingBackend>(
        &self,
        root: DrawingArea<DB, plotters::coord::Shift>,
        raster: bool,
    ) -> Result<(), String>
    where
        DB::ErrorType: 'static,
    {
        draw_plot(root, self, raster)
    }
}

pub(crate) fn draw_plot<DB: DrawingBackend>(
    root: DrawingArea<DB, plotters::coord::Shift>,
    plot: &Plot,
    raster: bool,
) -> Result<(), String>
where
    DB::ErrorType: 'static,
{
    root.fill(&WHITE).map_err(|e| e.to_string())?;
    let (t0, t1) = plot.t_range;
    let (lo, hi, clipped) = y_range(plot);
    let notes: Vec<(String, RGBColor)> = (plot.notes.iter().cloned())
        .chain(clipped.into_iter().map(|n| (n, BLACK)))
        .collect();
    let e = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
    let body = root.titled(&plot.title, (FAMILY, 26)).map_err(e)?;
    let body = if plot.subtitle.is_empty() {
        body
    } else {
        body.titled(
            &plot.subtitle,
            (FAMILY, 15).into_font().color(&RGBColor(90, 90, 90)),
        )
        .map_err(e)?
    };
    let mut chart = ChartBuilder::on(&body)
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
    let (px, py) = chart.plotting_area().get_pixel_range();
    // One column per pixel of the plotting area: every series is reduced to what the pixels can show.
    let columns = (px.end - px.start).max(1) as usize;
    if let Some((b0, b1, label)) = &plot.shade {
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
                    (b0, lo + 0.04 * (hi - lo)),
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
    draw_bands_and_lines(&mut chart, plot, (t0, t1), columns, raster)?;
    for &(tm, color) in &plot.marks {
        if tm >= t0 && tm <= t1 {
            chart
                .draw_series(DashedLineSeries::new(
                    vec![(tm, lo), (tm, hi)],
                    3,
                    4,
                    color.stroke_width(2),
                ))
                .map_err(|e| e.to_string())?;
        }
    }
    draw_notes(&root, &notes, (px.start, py.start))?;
    crate::figure::draw_legend(&mut chart, SeriesLabelPosition::UpperRight, 0.85, 16)?;
    root.present().map_err(|e| e.to_string())?;
    Ok(())
}

/// Each band (a period's envelope, filled) and each line (decimated to `columns`), with their legend
/// entries, in the plot's order.
fn draw_bands_and_lines<DB: DrawingBackend>(
    chart: &mut ChartContext<
        '_,
        DB,
        Cartesian2d<plotters::coord::types::RangedCoordf64, plotters::coord::types::RangedCoordf64>,
    >,
    plot: &Plot,
    (t0, t1): (f64, f64),
    columns: usize,
    raster: bool,
) -> Result<(), String>
where
    DB::ErrorType: 'static,
{
    for b in &plot.bands {
        let env = period_envelope(
            &envelope(b.t, &b.y, t0, t1, columns),
            t0,
            t1,
            columns,
            b.period_s,
        );
        let mut outline: Vec<(f64, f64)> = env.iter().map(|&(t, _, hi)| (t, hi)).collect();
        outline.extend(env.iter().rev().map(|&(t, lo, _)| (t, lo)));
        let fill = band_color(b.color);
        chart
            .draw_series(std::iter::once(Polygon::new(outline, fill.filled())))
            .map_err(|e| e.to_string())?
            .label(b.label.as_str())
            .legend(move |(x, y)| Rectangle::new([(x, y - 6), (x + 24, y + 6)], fill.filled()));
    }
    for l in &plot.lines {
        let pts = decimate(l.t, &l.y, t0, t1, columns);
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
            chart
                .draw_series(std::iter::once(Stroke {
                    points: pts,
                    color,
                    width,
                    raster,
                }))
                .map_err(|e| e.to_string())?
                .label(l.label.as_str())
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 24, y)], color.stroke_width(width))
                });
        }
    }
    Ok(())
}

/// The notes in a framed box at the top left of the plotting area (`origin`, pixels).
fn draw_notes<DB: DrawingBackend>(
    root: &DrawingArea<DB, plotters::coord::Shift>,
    notes: &[(String, RGBColor)],
    origin: (i32, i32),
) -> Result<(), String>
where
    DB::ErrorType: 'static,
{
    if notes.is_empty() {
        return Ok(());
    }
    let font = (FAMILY, 16).into_font();
    let measure: TextStyle = font.clone().into();
    let line_h = 22;
    let w = notes
        .iter()
        .map(|(s, _)| {
            root.estimate_text_size(s, &measure)
                .map(|(w, _)| w as i32)
                .unwrap_or(0)
        })
        .max()
        .unwrap_or(0);
    let (x0, y0) = (origin.0 + 10, origin.1 + 10);
    let h = line_h * notes.len() as i32 + 8;
    root.draw(&Rectangle::new(
        [(x0, y0), (x0 + w + 16, y0 + h)],
        WHITE.mix(0.85).filled(),
    ))
    .map_err(|e| e.to_string())?;
    root.draw(&Rectangle::new([(x0, y0), (x0 + w + 16, y0 + h)], BLACK))
        .map_err(|e| e.to_string())?;
    for (k, (s, c)) in notes.iter().enumerate() {
        root.draw(&Text::new(
            s.clone(),
            (x0 + 8, y0 + 6 + line_h * k as i32),
            font.clone().color(c),
        ))
        .map_err(|e| e.to_string())?;
    }
    Ok(())
}

/// A polyline `width` pixels wide, drawn segment by segment: not plotters' thick path, which joins segments
/// with miters, so that a sharp reversal (the PWM ripple, a contact impact) draws a spike far outside the
/// data. On a pixel buffer (`raster`) each segment is one-pixel lines side by side (offset across its main
/// direction): plotters' own thick segment, a filled polygon (a vector, an edge sort), cost a third of a
/// figure. In SVG each segment is a thick path of its own.
struct Stroke<C> {
    points: Vec<C>,
    color: RGBColor,
    width: u32,
    raster: bool,
}

impl<'a, C> PointCollection<'a, C> for &'a Stroke<C> {
    type Point = &'a C;
    type IntoIter = &'a [C];
    fn point_iter(self) -> &'a [C] {
        &self.points
    }
}

impl<C, DB: DrawingBackend> Drawable<DB> for Stroke<C> {
    fn draw<I: Iterator<Item = BackendCoord>>(
        &self,
        mut points: I,
        backend: &mut DB,
        _: (u32, u32),
    ) -> Result<(), DrawingErrorKind<DB::ErrorType>> {
        let style = self.color.stroke_width(1);
        let Some(mut from) = points.next() else {
            return Ok(());
        };
        if !self.raster {
            let thick = self.color.stroke_width(self.width);
            for to in points {
                backend.draw_path([from, to], &thick)?;
                from = to;
            }
            return Ok(());
        }
        // The offsets -w/2 ..= w/2 (integer division): what plotters' own thick line covers (a quadrilateral
        // w/2 either side of the path, its corners truncated to pixels), so the figures look as before.
        let r = (self.width / 2) as i32;
        for to in points {
            let across = if (to.0 - from.0).abs() >= (to.1 - from.1).abs() {
                (0, 1)
            } else {
                (1, 0)
            };
            for k in -r..=r {
                let d = (across.0 * k, across.1 * k);
                backend.draw_line(
                    (from.0 + d.0, from.1 + d.1),
                    (to.0 + d.0, to.1 + d.1),
                    &style,
                )?;
            }
            from = to;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The pixels (x, y) a drawing paints in black, at least half covered (plotters anti-aliases one-pixel
    /// sloped lines), on a white 200 x 200 buffer.
    fn painted(
        draw: impl FnOnce(&DrawingArea<BitMapBackend<'_>, plotters::coord::Shift>),
    ) -> Vec<(i32, i32)> {
        let mut rgb = vec![0u8; 200 * 200 * 3];
        {
            let root = BitMapBackend::with_buffer(&mut rgb, (200, 200)).into_drawing_area();
            root.fill(&WHITE).unwrap();
            draw(&root);
            root.present().unwrap();
        }
        (0..200 * 200)
            .filter(|i| rgb[3 * i] < 128)
            .map(|i| ((i % 200) as i32, (i / 200) as i32))
            .collect()
    }

    /// `Stroke` (our thick line) looks like plotters' own thick line: every pixel it paints is next to one
    /// of plotters'; on flat and steep segments (the traces' PWM ripple) it paints as many pixels within a
    /// quarter, and on any slope at least `width` pixels per pixel of length (plotters' own diagonals are
    /// wider than its flat lines); a sharp reversal stays within the line's width of the data, without a
    /// miter spike.
    #[test]
    fn a_stroke_looks_like_plotters_thick_line_without_its_spikes() {
        let segments: [[(i32, i32); 2]; 4] = [
            [(20, 100), (180, 104)],
            [(100, 20), (103, 180)],
            [(20, 20), (180, 180)],
            [(30, 170), (170, 60)],
        ];
        for seg in segments {
            let ours = painted(|root| {
                root.draw(&Stroke {
                    points: seg.to_vec(),
                    color: BLACK,
                    width: 2,
                    raster: true,
                })
                .unwrap();
            });
            let theirs = painted(|root| {
                root.draw(&PathElement::new(seg.to_vec(), BLACK.stroke_width(2)))
                    .unwrap();
            });
            let (dx, dy) = (seg[1].0 - seg[0].0, seg[1].1 - seg[0].1);
            let length = f64::from(dx * dx + dy * dy).sqrt();
            assert!(
                ours.len() as f64 >= 2.0 * length,
                "{seg:?}: {} pixels on a {length:.0}-pixel segment",
                ours.len()
            );
            if dx.abs() > 10 * dy.abs() || dy.abs() > 10 * dx.abs() {
                let ratio = ours.len() as f64 / theirs.len() as f64;
                assert!(
                    (0.75..=1.25).contains(&ratio),
                    "{seg:?}: {} pixels against {}",
                    ours.len(),
                    theirs.len()
                );
            }
            for &(x, y) in &ours {
                assert!(
                    theirs
                        .iter()
                        .any(|&(u, v)| (u - x).abs() <= 1 && (v - y).abs() <= 1),
                    "{seg:?}: ({x}, {y}) is not next to plotters' line"
                );
            }
        }
        // A reversal: up 100 px and straight back down within 4 px of x.
        let zigzag = vec![(50, 150), (52, 50), (54, 150), (150, 150)];
        let ours = painted(|root| {
            root.draw(&Stroke {
                points: zigzag.clone(),
                color: BLACK,
                width: 2,
                raster: true,
            })
            .unwrap();
        });
        let top = ours.iter().map(|p| p.1).min().unwrap();
        assert!(
            top >= 49,
            "the reversal reaches y = {top}, above the data's 50 by more than the width"
        );
    }
}

#[cfg(test)]
mod y_axis_tests {
    use super::*;

    fn plot_of<'a>(t: &'a [f64], y: Vec<f64>) -> Plot<'a> {
        let mut p = Plot::new("t".into(), "f [N]", (0.0, 10.0), Vec::new());
        p.lines.push(Line {
            label: "f".into(),
            t,
            y,
            color: BLACK,
            dashed: false,
            width: 1,
        });
        p
    }

    #[test]
    fn an_impact_spike_is_clipped_with_a_note_and_a_smooth_signal_is_not() {
        let t: Vec<f64> = (0..10_001).map(|k| k as f64 * 1e-3).collect();
        let sine: Vec<f64> = t.iter().map(|t| 20.0 + 5.0 * (6.0 * t).sin()).collect();
        let (lo, hi, notes) = y_range(&plot_of(&t, sine.clone()));
        assert!(notes.is_empty(), "{notes:?}");
        // The whole signal in view, padded by 8 % of its range.
        assert!(
            (lo - (15.0 - 0.8)).abs() < 1e-3 && (hi - (25.0 + 0.8)).abs() < 1e-3,
            "{lo} {hi}"
        );
        // 5 ms of a 2.5 kN impact at t = 4.0 s.
        let mut spiked = sine;
        for (k, v) in spiked.iter_mut().enumerate().skip(4000).take(5) {
            *v = if k == 4002 { 2500.0 } else { 1500.0 };
        }
        let (lo, hi, notes) = y_range(&plot_of(&t, spiked));
        assert!(
            hi < 40.0 && lo > 10.0,
            "the axis follows the bulk: {lo}..{hi}"
        );
        assert_eq!(notes, ["clipped: peak 2500 N at t = 4.002 s"]);
    }
}
