//! Figures of pneuflex runs, like the paper's Figs. 2–4: force against reference, position against reference
//! position (controllers overlaid), and a zoom on the force around each scene event. PNG (plotters' bitmap
//! backend) or SVG, with an embedded DejaVu Sans font so the output does not depend on system fonts.
//!
//! On a plant with an on/off valve the measured signals are drawn as their PWM-period mean (the metrics'
//! `moving_average`) over a light band of the raw signal, the references on top; every series is reduced to
//! its per-pixel-column first/min/max/last before drawing ([`decimate`]), so the picture is the same and the
//! cost does not grow with the length of the trace.

pub mod overlay;

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use plotters::element::{DashedPathElement, Drawable, PointCollection};
use plotters::prelude::*;
use plotters::style::{FontStyle, register_font};
use plotters_backend::{BackendCoord, DrawingErrorKind};
use pneuflex_scene::analysis::metrics::moving_average;
use pneuflex_scene::schema::{EventSpec, WindowKind};
use pneuflex_scene::{RunResult, Scene, WindowMetrics};

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

/// Reduces a series to what the pixel columns of a plot can show: for each of the `columns` pixel columns
/// spanning `[t0, t1]` ([`column_index`]), the first, lowest, highest and last finite sample in it, in time
/// order (fewer when they coincide). A polyline through them covers what the full series' polyline covers in every column — its
/// whole vertical extent and its joins to the neighbouring columns — so a figure looks the same while the
/// cost of drawing it no longer grows with the length of the trace. Samples outside `[t0, t1]` and
/// non-finite values are left out; `t` must be ascending.
pub fn decimate(t: &[f64], y: &[f64], t0: f64, t1: f64, columns: usize) -> Vec<(f64, f64)> {
    let mut out = Vec::with_capacity(4 * columns.min(t.len()));
    for_each_column(t, y, t0, t1, columns, |c| {
        let mut idx = [c.first, c.min, c.max, c.last];
        idx.sort_unstable();
        let mut prev = usize::MAX;
        for i in idx {
            if i != prev {
                out.push((t[i], y[i]));
                prev = i;
            }
        }
    });
    out
}

/// The envelope of a series per pixel column of `[t0, t1]` (as [`decimate`] splits it): for every column
/// holding samples, (the middle of its samples' times, their minimum, their maximum).
pub fn envelope(t: &[f64], y: &[f64], t0: f64, t1: f64, columns: usize) -> Vec<(f64, f64, f64)> {
    let mut out = Vec::with_capacity(columns.min(t.len()));
    for_each_column(t, y, t0, t1, columns, |c| {
        out.push((0.5 * (t[c.first] + t[c.last]), y[c.min], y[c.max]));
    });
    out
}

/// The pixel column that time `t` falls in, of `columns` pixel columns spanning `[t0, t1]`, as plotters maps
/// a coordinate to a pixel (t0 on the first column's left edge, t1 on the last one's).
pub fn column_index(t: f64, t0: f64, t1: f64, columns: usize) -> usize {
    let last = columns.max(1) - 1;
    if t1 > t0 {
        // The cast truncates towards zero and saturates (negative and NaN to 0): floor(max(x, 0)) without
        // libm's floor, which baseline x86-64 calls as a function (2.5 % of drawing the figures).
        ((((t - t0) / (t1 - t0)) * last as f64 + 1e-3) as usize).min(last)
    } else {
        0
    }
}

/// Indices of one column's first, lowest, highest and last sample.
#[derive(Clone, Copy)]
struct Column {
    first: usize,
    min: usize,
    max: usize,
    last: usize,
}

fn for_each_column(
    t: &[f64],
    y: &[f64],
    t0: f64,
    t1: f64,
    columns: usize,
    mut f: impl FnMut(Column),
) {
    let mut cur: Option<(usize, Column)> = None;
    for (i, (&ti, &yi)) in t.iter().zip(y).enumerate() {
        if !(ti >= t0 && ti <= t1 && yi.is_finite()) {
            continue;
        }
        let col = column_index(ti, t0, t1, columns);
        match &mut cur {
            Some((c, acc)) if *c == col => {
                if yi < y[acc.min] {
                    acc.min = i;
                }
                if yi > y[acc.max] {
                    acc.max = i;
                }
                acc.last = i;
            }
            _ => {
                if let Some((_, acc)) = cur.take() {
                    f(acc);
                }
                cur = Some((
                    col,
                    Column {
                        first: i,
                        min: i,
                        max: i,
                        last: i,
                    },
                ));
            }
        }
    }
    if let Some((_, acc)) = cur {
        f(acc);
    }
}

/// One line of a plot.
struct Line<'a> {
    label: String,
    t: &'a [f64],
    y: Vec<f64>,
    color: RGBColor,
    dashed: bool,
    width: u32,
}

/// A light band: the raw signal's per-column min/max envelope, under the line of its period mean.
struct Band<'a> {
    label: String,
    t: &'a [f64],
    y: Vec<f64>,
    color: RGBColor,
    /// The PWM period, s: each column's band spans the raw signal's range over the period around it (a
    /// column shorter than the period holds only part of a ripple and the band would be hatched).
    period_s: f64,
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

struct Plot<'a> {
    title: String,
    y_label: String,
    t_range: (f64, f64),
    bands: Vec<Band<'a>>,
    /// Drawn in order: the measured signals first, the references last (on top).
    lines: Vec<Line<'a>>,
    events: Vec<f64>,
    /// A shaded time interval with a label (the environment swap of Fig. 7).
    shade: Option<(f64, f64, String)>,
    /// Vertical dotted lines in a run's colour (the settling time of each run after an event).
    marks: Vec<(f64, RGBColor)>,
    /// Lines of text in the upper left corner, in a run's colour.
    notes: Vec<(String, RGBColor)>,
}

impl<'a> Plot<'a> {
    fn new(title: String, y_label: &str, t_range: (f64, f64), events: Vec<f64>) -> Self {
        Plot {
            title,
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

    /// A run's measured signal `y` (already in display units): on an on/off valve (`average` = samples per
    /// PWM period) its PWM-period mean as the line over a light band of the raw signal; on a continuous
    /// valve the raw signal as the line.
    fn measured(
        &mut self,
        label: String,
        t: &'a [f64],
        y: Vec<f64>,
        color: RGBColor,
        average: Option<(usize, f64)>,
    ) {
        match average {
            Some((n, period_s)) => {
                let mean = moving_average(&y, n);
                self.lines.push(Line {
                    label: format!("{label} ({} ms PWM-period mean)", fmt_ms(period_s)),
                    t,
                    y: mean,
                    color,
                    dashed: false,
                    width: 2,
                });
                self.bands.push(Band {
                    label: format!("{label}, raw (range over a PWM period)"),
                    t,
                    y,
                    color,
                    period_s,
                });
            }
            None => self.lines.push(Line {
                label,
                t,
                y,
                color,
                dashed: false,
                width: 2,
            }),
        }
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

/// The light shade of a run's colour for its raw band.
fn band_color(c: RGBColor) -> RGBAColor {
    c.mix(0.22)
}

fn y_range(plot: &Plot) -> (f64, f64) {
    let (t0, t1) = plot.t_range;
    let mut lo = f64::INFINITY;
    let mut hi = f64::NEG_INFINITY;
    let series = plot
        .bands
        .iter()
        .map(|b| (b.t, &b.y))
        .chain(plot.lines.iter().map(|l| (l.t, &l.y)));
    for (t, y) in series {
        for (t, y) in t.iter().zip(y) {
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
    (lo - pad, hi + pad)
}

/// `raster`: the backend is a pixel buffer (thick lines as side-by-side pixel lines, [`Stroke`]), not SVG.
fn draw_plot<DB: DrawingBackend>(
    root: DrawingArea<DB, plotters::coord::Shift>,
    plot: &Plot,
    raster: bool,
) -> Result<(), String>
where
    DB::ErrorType: 'static,
{
    root.fill(&WHITE).map_err(|e| e.to_string())?;
    let (t0, t1) = plot.t_range;
    let (lo, hi) = y_range(plot);
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
    if !plot.notes.is_empty() {
        let font = (FAMILY, 16).into_font();
        let measure: TextStyle = font.clone().into();
        let line_h = 22;
        let w = plot
            .notes
            .iter()
            .map(|(s, _)| {
                root.estimate_text_size(s, &measure)
                    .map(|(w, _)| w as i32)
                    .unwrap_or(0)
            })
            .max()
            .unwrap_or(0);
        let (x0, y0) = (px.start + 10, py.start + 10);
        let h = line_h * plot.notes.len() as i32 + 8;
        root.draw(&Rectangle::new(
            [(x0, y0), (x0 + w + 16, y0 + h)],
            WHITE.mix(0.85).filled(),
        ))
        .map_err(|e| e.to_string())?;
        root.draw(&Rectangle::new([(x0, y0), (x0 + w + 16, y0 + h)], BLACK))
            .map_err(|e| e.to_string())?;
        for (k, (s, c)) in plot.notes.iter().enumerate() {
            root.draw(&Text::new(
                s.clone(),
                (x0 + 8, y0 + 6 + line_h * k as i32),
                font.clone().color(c),
            ))
            .map_err(|e| e.to_string())?;
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

thread_local! {
    /// This thread's pixel buffer for PNG figures ([`render`]).
    static PIXELS: std::cell::RefCell<Option<Pixels>> = const { std::cell::RefCell::new(None) };
}

/// A drawing thread's pixel buffer, kept for the thread's life and reused by its figures. Anonymous memory
/// whose first 2 MiB are aligned and advised as one huge page: the kernel then faults in one 2 MiB page
/// instead of 512 small ones. A fresh 2.5 MB buffer in 4 KiB pages was ~1.1 ms of page faults (615 of
/// them) on each thread's first figure here, 0.1–0.3 ms with the huge page (docs/performance.md). Where
/// transparent huge pages are off, the advice is ignored and the buffer is as before.
struct Pixels {
    map: memmap2::MmapMut,
    offset: usize,
    len: usize,
}

impl Pixels {
    const HUGE: usize = 2 << 20;

    fn new(len: usize) -> std::io::Result<Self> {
        let map = memmap2::MmapOptions::new()
            .len(len + Self::HUGE)
            .map_anon()?;
        let offset = (Self::HUGE - map.as_ptr() as usize % Self::HUGE) % Self::HUGE;
        #[cfg(target_os = "linux")]
        if len >= Self::HUGE {
            // Only an advice: a kernel without it leaves the small pages.
            let _ = map.advise_range(memmap2::Advice::HugePage, offset, Self::HUGE);
        }
        Ok(Self { map, offset, len })
    }

    /// This thread's buffer of `len` bytes, made on its first use (or when a larger one is needed).
    fn with<R>(len: usize, f: impl FnOnce(&mut [u8]) -> R) -> std::io::Result<R> {
        PIXELS.with_borrow_mut(|slot| {
            if slot.as_ref().is_none_or(|p| p.len < len) {
                *slot = Some(Self::new(len)?);
            }
            let p = slot.as_mut().expect("made above");
            Ok(f(&mut p.map[p.offset..p.offset + len]))
        })
    }
}

fn render(path: &Path, format: Format, plot: &Plot) -> Result<(), VizError> {
    let size = (1200, 700);
    let r = match format {
        // The figures of a command are drawn on a few threads, each reusing its pixel buffer: a fresh
        // 2.5 MB buffer costs its page faults again (a third of drawing's kernel time). Every pixel is
        // painted (the white background first), so what the buffer held does not matter.
        Format::Png => Pixels::with(size.0 as usize * size.1 as usize * 3, |rgb| {
            draw_plot(
                BitMapBackend::with_buffer(rgb, size).into_drawing_area(),
                plot,
                true,
            )
            .and_then(|()| write_png(path, rgb, size))
        })
        .unwrap_or_else(|e| Err(format!("no memory for the pixels: {e}"))),
        Format::Svg => draw_plot(SVGBackend::new(path, size).into_drawing_area(), plot, false),
    };
    r.map_err(|message| VizError::Draw {
        path: path.to_path_buf(),
        message,
    })
}

/// Writes an RGB image as PNG with one filter for every row (`Up`: a plot is long runs of one colour, the
/// same from row to row) and zlib level 1 (flate2's zlib-rs backend). Against plotters' own encoder (five filters
/// tried on every row, then fdeflate) the pixels are the same and the files about half the size (paper-fig3:
/// 553 -> 338 KB; scripts/time_run.py, docs/performance.md).
fn write_png(path: &Path, rgb: &[u8], (w, h): (u32, u32)) -> Result<(), String> {
    let file = std::fs::File::create(path).map_err(|e| e.to_string())?;
    let mut encoder = png::Encoder::new(std::io::BufWriter::new(file), w, h);
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    encoder.set_deflate_compression(png::DeflateCompression::Level(1));
    encoder.set_filter(png::Filter::Up);
    let mut writer = encoder.write_header().map_err(|e| e.to_string())?;
    writer.write_image_data(rgb).map_err(|e| e.to_string())?;
    writer.finish().map_err(|e| e.to_string())
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
        plot.measured(
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
) -> Result<Vec<PathBuf>, VizError> {
    ensure_font()?;
    let ok: Vec<&RunResult> = results
        .iter()
        .filter(|r| r.diverged.is_none() && !r.trace.is_empty())
        .collect();
    if ok.is_empty() {
        return Err(VizError::Empty);
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
        .map(|(p, build)| render(p, format, &build()).map(|()| p.clone()))
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
        position.measured(
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

/// One Bode line: its label and its points (Hz, |L| dB, arg L degrees).
type BodeLine<'a> = (String, &'a [(f64, f64, f64)]);

/// A Bode plot of inner-loop analyses (`pneuflex_scene::analysis::loop_margins`): |L| in dB above, arg L in degrees
/// below, one line per run and stiffness, against frequency on a log axis; the 0 dB and −180° lines dashed.
pub fn write_bode(
    path: &Path,
    analyses: &[pneuflex_scene::analysis::loop_margins::LoopAnalysis],
) -> Result<(), VizError> {
    ensure_font()?;
    let lines: Vec<BodeLine<'_>> = analyses
        .iter()
        .flat_map(|a| {
            a.margins.iter().map(move |m| {
                (
                    format!(
                        "{} (kp {} /m), k_e {} N/m",
                        a.run, a.kp_per_m, m.stiffness_n_per_m
                    ),
                    m.bode.as_slice(),
                )
            })
        })
        .filter(|(_, b)| b.len() > 1)
        .collect();
    if lines.is_empty() {
        return Err(VizError::Empty);
    }
    let draw = || -> Result<(), String> {
        let root = BitMapBackend::new(path, (1200, 900)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        let (top, bottom) = root.split_vertically(450);
        let f_lo = lines
            .iter()
            .map(|(_, b)| b[0].0)
            .fold(f64::INFINITY, f64::min);
        let f_hi = lines
            .iter()
            .map(|(_, b)| b[b.len() - 1].0)
            .fold(0.0_f64, f64::max);
        let (m_lo, m_hi) = lines
            .iter()
            .flat_map(|(_, b)| b.iter())
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), p| {
                (l.min(p.1), h.max(p.1))
            });
        let (p_lo, p_hi) = lines
            .iter()
            .flat_map(|(_, b)| b.iter())
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), p| {
                (l.min(p.2), h.max(p.2))
            });
        let colors = [BLUE, RED, GREEN, MAGENTA, CYAN, BLACK];
        for (area, title, y_desc, idx, lo, hi, reference) in [
            (
                &top,
                "open inner loop L: gain",
                "|L| [dB]",
                1,
                m_lo.max(-80.0),
                m_hi.min(80.0),
                0.0,
            ),
            (
                &bottom,
                "phase",
                "arg L [deg]",
                2,
                p_lo.max(-720.0),
                p_hi.min(180.0),
                -180.0,
            ),
        ] {
            let mut chart = ChartBuilder::on(area)
                .caption(title, (FAMILY, 22))
                .margin(12)
                .x_label_area_size(40)
                .y_label_area_size(70)
                .build_cartesian_2d((f_lo..f_hi).log_scale(), (lo - 5.0)..(hi + 5.0))
                .map_err(|e| e.to_string())?;
            chart
                .configure_mesh()
                .x_desc("frequency [Hz]")
                .y_desc(y_desc)
                .label_style((FAMILY, 15))
                .draw()
                .map_err(|e| e.to_string())?;
            chart
                .draw_series(DashedLineSeries::new(
                    vec![(f_lo, reference), (f_hi, reference)],
                    6,
                    4,
                    BLACK.stroke_width(1),
                ))
                .map_err(|e| e.to_string())?;
            for (k, (label, b)) in lines.iter().enumerate() {
                let c = colors[k % colors.len()];
                chart
                    .draw_series(LineSeries::new(
                        b.iter().map(|p| (p.0, if idx == 1 { p.1 } else { p.2 })),
                        c.stroke_width(2),
                    ))
                    .map_err(|e| e.to_string())?
                    .label(label.as_str())
                    .legend(move |(x, y)| {
                        PathElement::new(vec![(x, y), (x + 24, y)], c.stroke_width(2))
                    });
            }
            chart
                .configure_series_labels()
                .position(SeriesLabelPosition::LowerLeft)
                .background_style(WHITE.mix(0.85))
                .border_style(BLACK)
                .label_font((FAMILY, 14))
                .draw()
                .map_err(|e| e.to_string())?;
        }
        root.present().map_err(|e| e.to_string())
    };
    draw().map_err(|message| VizError::Draw {
        path: path.to_path_buf(),
        message,
    })
}

/// A heatmap: one cell per (x, y) grid point, its value as a colour, and a colour bar.
#[derive(Clone, Debug)]
pub struct Heatmap<'a> {
    /// Title above the map.
    pub title: &'a str,
    /// What the x axis sweeps (e.g. a key path).
    pub x_label: &'a str,
    /// Labels of the x values, left to right.
    pub x_ticks: &'a [String],
    /// What the y axis sweeps.
    pub y_label: &'a str,
    /// Labels of the y values, bottom to top.
    pub y_ticks: &'a [String],
    /// The cells, row by row from the bottom: `cells[y * nx + x]`; None is drawn grey with a cross
    /// (no value: the run diverged), a non-finite value grey with a circle (e.g. never settled).
    pub cells: &'a [Option<f64>],
    /// Cells whose number hangs on a threshold (a fragile settling time), in the order of `cells` (empty:
    /// none): an asterisk after the value, and `mark_note` under the map when any is marked.
    pub marked: &'a [bool],
    /// What the asterisk means.
    pub mark_note: &'a str,
    /// What the colour bar shows.
    pub value_label: &'a str,
    /// A diverging scale centred on zero (blue < 0 < red), for differences; else a sequential scale.
    pub diverging: bool,
}

/// A perceptually ordered sequential colour scale (a viridis-like ramp), f in [0, 1].
fn sequential(f: f64) -> RGBColor {
    const STOPS: [(f64, (f64, f64, f64)); 5] = [
        (0.0, (68.0, 1.0, 84.0)),
        (0.25, (59.0, 82.0, 139.0)),
        (0.5, (33.0, 145.0, 140.0)),
        (0.75, (94.0, 201.0, 98.0)),
        (1.0, (253.0, 231.0, 37.0)),
    ];
    ramp(&STOPS, f)
}

/// Blue – white – red, f in [0, 1] with 0.5 white.
fn diverging(f: f64) -> RGBColor {
    const STOPS: [(f64, (f64, f64, f64)); 3] = [
        (0.0, (33.0, 102.0, 172.0)),
        (0.5, (247.0, 247.0, 247.0)),
        (1.0, (178.0, 24.0, 43.0)),
    ];
    ramp(&STOPS, f)
}

fn ramp(stops: &[(f64, (f64, f64, f64))], f: f64) -> RGBColor {
    let f = if f.is_finite() {
        f.clamp(0.0, 1.0)
    } else {
        0.0
    };
    let k = stops
        .windows(2)
        .position(|w| f <= w[1].0)
        .unwrap_or(stops.len() - 2);
    let ((a, ca), (b, cb)) = (stops[k], stops[k + 1]);
    let t = if b > a { (f - a) / (b - a) } else { 0.0 };
    let mix = |x: f64, y: f64| (x + t * (y - x)).round().clamp(0.0, 255.0) as u8;
    RGBColor(mix(ca.0, cb.0), mix(ca.1, cb.1), mix(ca.2, cb.2))
}

/// Short text of a cell value.
fn cell_text(v: f64) -> String {
    let a = v.abs();
    if a != 0.0 && !(1e-2..1e4).contains(&a) {
        format!("{v:.1e}")
    } else if a >= 100.0 {
        format!("{v:.0}")
    } else if a >= 10.0 {
        format!("{v:.1}")
    } else {
        format!("{v:.2}")
    }
}

/// Draws a heatmap as a PNG (900 × 700 px, plus room for many columns).
pub fn write_heatmap(path: &Path, map: &Heatmap<'_>) -> Result<(), VizError> {
    use plotters::coord::ranged1d::SegmentValue;
    ensure_font()?;
    let (nx, ny) = (map.x_ticks.len(), map.y_ticks.len());
    if nx == 0 || ny == 0 || map.cells.len() != nx * ny {
        return Err(VizError::Empty);
    }
    let finite: Vec<f64> = map
        .cells
        .iter()
        .flatten()
        .copied()
        .filter(|v| v.is_finite())
        .collect();
    let (mut lo, mut hi) = finite
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &v| {
            (l.min(v), h.max(v))
        });
    if finite.is_empty() {
        (lo, hi) = (0.0, 1.0);
    }
    if map.diverging {
        let m = lo.abs().max(hi.abs()).max(1e-12);
        (lo, hi) = (-m, m);
    } else if hi <= lo {
        (lo, hi) = (lo - 0.5, hi + 0.5);
    }
    let colour = |v: f64| {
        let f = (v - lo) / (hi - lo);
        if map.diverging {
            diverging(f)
        } else {
            sequential(f)
        }
    };
    let width = 900.max(160 + 60 * nx as u32);
    let height = 700.max(160 + 32 * ny as u32);
    let draw = || -> Result<(), String> {
        let root = BitMapBackend::new(path, (width, height)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        let (main, bar) = root.split_horizontally(width - 150);
        let mut chart = ChartBuilder::on(&main)
            .caption(map.title, (FAMILY, 20))
            .margin(14)
            .x_label_area_size(60)
            .y_label_area_size(90)
            // Integer ranges are inclusive: 0..n - 1 is n segments.
            .build_cartesian_2d((0..nx - 1).into_segmented(), (0..ny - 1).into_segmented())
            .map_err(|e| e.to_string())?;
        let label = |ticks: &[String], v: &SegmentValue<usize>| match v {
            SegmentValue::CenterOf(i) => ticks.get(*i).cloned().unwrap_or_default(),
            _ => String::new(),
        };
        chart
            .configure_mesh()
            .disable_mesh()
            .x_desc(map.x_label)
            .y_desc(map.y_label)
            .x_labels(nx)
            .y_labels(ny)
            .x_label_formatter(&|v| label(map.x_ticks, v))
            .y_label_formatter(&|v| label(map.y_ticks, v))
            .label_style((FAMILY, 13))
            .axis_desc_style((FAMILY, 16))
            .draw()
            .map_err(|e| e.to_string())?;
        let grey = RGBColor(190, 190, 190);
        let show_text = nx * ny <= 200;
        for y in 0..ny {
            for x in 0..nx {
                let v = map.cells[y * nx + x];
                let fill = match v {
                    Some(v) if v.is_finite() => colour(v),
                    _ => grey,
                };
                let edge = |i: usize, n: usize| {
                    if i >= n {
                        SegmentValue::Last
                    } else {
                        SegmentValue::Exact(i)
                    }
                };
                let c0 = (edge(x, nx), edge(y, ny));
                let c1 = (edge(x + 1, nx), edge(y + 1, ny));
                chart
                    .draw_series(std::iter::once(Rectangle::new([c0, c1], fill.filled())))
                    .map_err(|e| e.to_string())?;
                let centre = (SegmentValue::CenterOf(x), SegmentValue::CenterOf(y));
                let star = if map.marked.get(y * nx + x) == Some(&true) {
                    "*"
                } else {
                    ""
                };
                let text = match v {
                    None => "×".to_string(),
                    Some(v) if !v.is_finite() => "∞".to_string(),
                    Some(v) if show_text => cell_text(v) + star,
                    Some(_) => star.to_string(),
                };
                if !text.is_empty() {
                    let (r, g, b) = (fill.0 as f64, fill.1 as f64, fill.2 as f64);
                    let ink = if 0.299 * r + 0.587 * g + 0.114 * b > 140.0 {
                        BLACK
                    } else {
                        WHITE
                    };
                    let style = TextStyle::from((FAMILY, 12).into_font()).color(&ink).pos(
                        plotters::style::text_anchor::Pos::new(
                            plotters::style::text_anchor::HPos::Center,
                            plotters::style::text_anchor::VPos::Center,
                        ),
                    );
                    chart
                        .draw_series(std::iter::once(Text::new(text, centre, style)))
                        .map_err(|e| e.to_string())?;
                }
            }
        }
        // The colour bar.
        let mut cb = ChartBuilder::on(&bar)
            .margin_top(60)
            .margin_bottom(74)
            .margin_right(10)
            .y_label_area_size(70)
            .build_cartesian_2d(0.0..1.0, lo..hi)
            .map_err(|e| e.to_string())?;
        cb.configure_mesh()
            .disable_mesh()
            .disable_x_axis()
            .y_desc(map.value_label)
            .label_style((FAMILY, 12))
            .axis_desc_style((FAMILY, 14))
            .draw()
            .map_err(|e| e.to_string())?;
        let steps = 100;
        cb.draw_series((0..steps).map(|k| {
            let a = lo + (hi - lo) * k as f64 / steps as f64;
            let b = lo + (hi - lo) * (k + 1) as f64 / steps as f64;
            Rectangle::new([(0.0, a), (1.0, b)], colour(0.5 * (a + b)).filled())
        }))
        .map_err(|e| e.to_string())?;
        if map.marked.contains(&true) {
            root.draw(&Text::new(
                map.mark_note,
                (14, height as i32 - 22),
                (FAMILY, 13).into_font(),
            ))
            .map_err(|e| e.to_string())?;
        }
        root.present().map_err(|e| e.to_string())
    };
    draw().map_err(|message| VizError::Draw {
        path: path.to_path_buf(),
        message,
    })
}

/// A convergence plot of a search: every candidate's objective (dots) and the best so far (a line) against
/// the number of evaluations; a log scale when the values span more than a decade.
pub fn write_convergence(
    path: &Path,
    title: &str,
    y_label: &str,
    candidates: &[(f64, f64)],
    best: &[(f64, f64)],
) -> Result<(), VizError> {
    ensure_font()?;
    let finite: Vec<f64> = candidates
        .iter()
        .chain(best)
        .map(|p| p.1)
        .filter(|v| v.is_finite() && *v > 0.0)
        .collect();
    if finite.is_empty() {
        return Err(VizError::Empty);
    }
    let lo = finite.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = finite.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let n = candidates
        .iter()
        .chain(best)
        .map(|p| p.0)
        .fold(1.0_f64, f64::max);
    let dropped = candidates.iter().filter(|p| !p.1.is_finite()).count();
    let caption = if dropped > 0 {
        format!("{title} ({dropped} candidate(s) with J = inf not drawn)")
    } else {
        title.to_string()
    };
    let draw = || -> Result<(), String> {
        let root = BitMapBackend::new(path, (1000, 600)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        let blue = PALETTE[0];
        let orange = PALETTE[1];
        macro_rules! body {
            ($chart:expr) => {{
                let mut chart = $chart;
                chart
                    .configure_mesh()
                    .x_desc("evaluations")
                    .y_desc(y_label)
                    .label_style((FAMILY, 14))
                    .draw()
                    .map_err(|e| e.to_string())?;
                chart
                    .draw_series(
                        candidates
                            .iter()
                            .filter(|p| p.1.is_finite() && p.1 > 0.0)
                            .map(|&p| Circle::new(p, 3, blue.mix(0.5).filled())),
                    )
                    .map_err(|e| e.to_string())?
                    .label("candidate (worst case over the environments)")
                    .legend(move |(x, y)| Circle::new((x + 12, y), 3, blue.filled()));
                chart
                    .draw_series(LineSeries::new(
                        best.iter()
                            .copied()
                            .filter(|p| p.1.is_finite() && p.1 > 0.0),
                        orange.stroke_width(3),
                    ))
                    .map_err(|e| e.to_string())?
                    .label("best so far")
                    .legend(move |(x, y)| {
                        PathElement::new(vec![(x, y), (x + 24, y)], orange.stroke_width(3))
                    });
                chart
                    .configure_series_labels()
                    .position(SeriesLabelPosition::UpperRight)
                    .background_style(WHITE.mix(0.85))
                    .border_style(BLACK)
                    .label_font((FAMILY, 14))
                    .draw()
                    .map_err(|e| e.to_string())?;
            }};
        }
        macro_rules! builder {
            () => {
                ChartBuilder::on(&root)
                    .caption(&caption, (FAMILY, 20))
                    .margin(14)
                    .x_label_area_size(45)
                    .y_label_area_size(80)
            };
        }
        if hi / lo > 10.0 {
            body!(
                builder!()
                    .build_cartesian_2d(0.0..n, (lo * 0.8..hi * 1.25).log_scale())
                    .map_err(|e| e.to_string())?
            );
        } else {
            let pad = 0.05 * (hi - lo).max(1e-12 * hi.abs().max(1.0));
            body!(
                builder!()
                    .build_cartesian_2d(0.0..n, (lo - pad)..(hi + pad))
                    .map_err(|e| e.to_string())?
            );
        }
        root.present().map_err(|e| e.to_string())
    };
    draw().map_err(|message| VizError::Draw {
        path: path.to_path_buf(),
        message,
    })
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

    fn pixels(path: &Path) -> (u32, u32, Vec<u8>) {
        let decoder =
            png::Decoder::new(std::io::BufReader::new(std::fs::File::open(path).unwrap()));
        let mut reader = decoder.read_info().unwrap();
        let mut buf = vec![0; reader.output_buffer_size().unwrap()];
        let info = reader.next_frame(&mut buf).unwrap();
        assert_eq!(info.color_type, png::ColorType::Rgb, "{}", path.display());
        buf.truncate(info.buffer_size());
        (info.width, info.height, buf)
    }

    /// `render` encodes the figure itself (write_png); a reader must see exactly the pixels plotters' own
    /// PNG writer gives for the same plot (a sine over a PWM-like band, a reference, an event, a shade).
    #[test]
    fn the_figure_encoder_changes_the_file_not_the_pixels() {
        ensure_font().unwrap();
        let t: Vec<f64> = (0..=4000).map(|k| k as f64 * 1e-3).collect();
        let raw: Vec<f64> = t
            .iter()
            .map(|&x| 10.0 + 2.0 * (std::f64::consts::TAU * x).sin() + (251.0 * x).sin())
            .collect();
        let mut plot = Plot::new("encoder".into(), "force [N]", (0.0, 4.0), vec![2.0]);
        plot.measured(
            "f_e".into(),
            &t,
            raw,
            RGBColor(31, 119, 180),
            Some((25, 0.025)),
        );
        plot.lines.push(Line {
            label: "f_ref".into(),
            t: &t,
            y: t.iter()
                .map(|&x| 10.0 + 2.0 * (std::f64::consts::TAU * x).sin())
                .collect(),
            color: BLACK,
            dashed: true,
            width: 1,
        });
        plot.shade = Some((2.5, 3.0, "swap".into()));
        let dir = std::env::temp_dir().join(format!("pneuflex-viz-png-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let ours = dir.join("ours.png");
        let theirs = dir.join("theirs.png");
        render(&ours, Format::Png, &plot).unwrap();
        draw_plot(
            BitMapBackend::new(&theirs, (1200, 700)).into_drawing_area(),
            &plot,
            true,
        )
        .unwrap();
        let (a, b) = (pixels(&ours), pixels(&theirs));
        assert_eq!((a.0, a.1), (1200, 700));
        assert_eq!((a.0, a.1), (b.0, b.1));
        let differ = a.2.iter().zip(&b.2).filter(|(x, y)| x != y).count();
        assert_eq!(differ, 0, "{differ} bytes of pixel data differ");
        // Something was drawn: more than the white background and the frame.
        assert!(a.2.iter().filter(|&&v| v != 255).count() > 10_000);
        std::fs::remove_dir_all(&dir).ok();
    }
}
