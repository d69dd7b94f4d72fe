//! A heatmap: one cell per grid point, its value as a colour, a colour bar, marked cells.

use std::path::Path;

use plotters::prelude::*;

use crate::{FAMILY, PlotError, ensure_font};

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
    /// (no value: the run diverged or failed), a non-finite value grey with ∞ (an infinite settling time).
    pub cells: &'a [Option<f64>],
    /// Cells whose run is flagged (did not settle in some window), in the order of `cells` (empty: none):
    /// a † after the value, and `flag_note` under the map when any is flagged.
    pub flagged: &'a [bool],
    /// What the dagger means.
    pub flag_note: &'a str,
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

/// Draws a heatmap as a PNG, or an SVG for a path ending in `.svg` (900 × 700 px, plus room for many columns
/// and for the legend lines).
pub fn write_heatmap(path: &Path, map: &Heatmap<'_>) -> Result<(), PlotError> {
    ensure_font()?;
    let (nx, ny) = (map.x_ticks.len(), map.y_ticks.len());
    if nx == 0 || ny == 0 || map.cells.len() != nx * ny {
        return Err(PlotError::Empty);
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
    // A legend line for every cell state the map shows, under it.
    let mut notes = Vec::new();
    if map.cells.iter().any(|c| c.is_none()) {
        notes.push("grey ×: no value (the run diverged or failed)");
    }
    if map.cells.iter().any(|c| c.is_some_and(|v| !v.is_finite())) {
        notes.push("grey ∞: not settled (an infinite settling time)");
    }
    if map.flagged.contains(&true) {
        notes.push(map.flag_note);
    }
    if map.marked.contains(&true) {
        notes.push(map.mark_note);
    }
    let room = 18 * notes.len() as u32;
    let width = 900.max(160 + 60 * nx as u32);
    let height = 700.max(160 + 32 * ny as u32) + room;
    let frame = Frame {
        map,
        nx,
        ny,
        lo,
        hi,
        width,
        height,
        notes,
        room,
        colour: &colour,
    };
    // SVG or PDF for a path ending in .svg or .pdf (`sweep --format`), PNG otherwise.
    crate::figure::write(path, (width, height), &frame)
}

/// What [`draw`] draws: the map and what [`write_heatmap`] worked out for it.
struct Frame<'a, 'm> {
    map: &'a Heatmap<'m>,
    nx: usize,
    ny: usize,
    lo: f64,
    hi: f64,
    width: u32,
    height: u32,
    notes: Vec<&'a str>,
    room: u32,
    colour: &'a dyn Fn(f64) -> RGBColor,
}

impl crate::figure::Figure for Frame<'_, '_> {
    fn draw<DB: DrawingBackend>(
        &self,
        root: DrawingArea<DB, plotters::coord::Shift>,
        _raster: bool,
    ) -> Result<(), String>
    where
        DB::ErrorType: 'static,
    {
        draw(root, self)
    }
}

fn draw<DB: DrawingBackend>(
    root: DrawingArea<DB, plotters::coord::Shift>,
    f: &Frame<'_, '_>,
) -> Result<(), String> {
    use plotters::coord::ranged1d::SegmentValue;
    let Frame {
        map,
        nx,
        ny,
        lo,
        hi,
        width,
        height,
        ref notes,
        room,
        colour,
    } = *f;
    root.fill(&WHITE).map_err(|e| e.to_string())?;
    let (main, bar) = root.split_horizontally(width - 150);
    let mut chart = ChartBuilder::on(&main)
        .caption(map.title, (FAMILY, 20))
        .margin(14)
        .margin_bottom(14 + room)
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
            let star = match (
                map.marked.get(y * nx + x) == Some(&true),
                map.flagged.get(y * nx + x) == Some(&true),
            ) {
                (true, true) => "*†",
                (true, false) => "*",
                (false, true) => "†",
                (false, false) => "",
            };
            let text = match v {
                None => "×".to_string(),
                Some(v) if !v.is_finite() => "∞".to_string() + star,
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
        .margin_bottom(74 + room)
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
    for (k, note) in notes.iter().rev().enumerate() {
        root.draw(&Text::new(
            *note,
            (14, height as i32 - 22 - 18 * k as i32),
            (FAMILY, 13).into_font(),
        ))
        .map_err(|e| e.to_string())?;
    }
    root.present().map_err(|e| e.to_string())
}
