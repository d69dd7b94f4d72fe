//! Overlays of measured and simulated signals, one panel per signal stacked vertically (the validation
//! figure of `pneuflex identify`). Every series is decimated per pixel column ([`super::decimate`]).

use std::path::Path;

use plotters::prelude::*;

use crate::{FAMILY, PALETTE, PALETTE_NAMES, PlotError, decimate, ensure_font};

/// One line: its label, times (s) and values; non-finite values are gaps.
#[derive(Clone, Debug)]
pub struct Series<'a> {
    /// Legend text.
    pub label: String,
    /// Times, s, ascending.
    pub t: &'a [f64],
    /// Values.
    pub y: &'a [f64],
}

/// One panel: a title, the y-axis description and its lines (the first in the palette's first colour, ...).
#[derive(Clone, Debug)]
pub struct Panel<'a> {
    /// Title above the panel.
    pub title: String,
    /// Y-axis description with unit.
    pub y_desc: String,
    /// The lines.
    pub series: Vec<Series<'a>>,
    /// Whether the y axis reaches 0 (a residual: its offset from zero is what is read).
    pub include_zero: bool,
}

/// Writes `panels` stacked vertically into `path` (1200 px wide, 260 px per panel; PNG, or SVG or PDF by the
/// extension). The lines'
/// labels go in each panel's title with their colours, not in a legend box over the data.
pub fn write_overlay(path: &Path, panels: &[Panel<'_>]) -> Result<(), PlotError> {
    ensure_font()?;
    if panels.is_empty() || panels.iter().all(|p| p.series.is_empty()) {
        return Err(PlotError::Empty);
    }
    let height = 260 * panels.len() as u32;
    crate::figure::write(path, (1200, height), &Overlay(panels))
}

/// The stacked panels as a figure.
struct Overlay<'a, 'b>(&'a [Panel<'b>]);

impl crate::figure::Figure for Overlay<'_, '_> {
    fn draw<DB: DrawingBackend>(
        &self,
        root: DrawingArea<DB, plotters::coord::Shift>,
        _raster: bool,
    ) -> Result<(), String>
    where
        DB::ErrorType: 'static,
    {
        let panels = self.0;
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        let areas = root.split_evenly((panels.len(), 1));
        for (area, panel) in areas.iter().zip(panels) {
            let finite = |v: &&f64| v.is_finite();
            let (t0, t1) = panel
                .series
                .iter()
                .flat_map(|s| s.t.iter().filter(finite))
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
                    (a.min(v), b.max(v))
                });
            let (y0, y1) = panel
                .series
                .iter()
                .flat_map(|s| s.y.iter().filter(finite))
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
                    (a.min(v), b.max(v))
                });
            if !(t0.is_finite() && t1 > t0 && y0.is_finite() && y1.is_finite()) {
                continue;
            }
            let (y0, y1) = if panel.include_zero {
                (y0.min(0.0), y1.max(0.0))
            } else {
                (y0, y1)
            };
            // At least 1 % of the values' size: a flat line gets an axis, not one repeated label.
            let pad = ((y1 - y0) * 0.05)
                .max(0.01 * y1.abs().max(y0.abs()))
                .max(1e-12);
            let key: Vec<String> = (panel.series.iter().enumerate())
                .map(|(i, s)| format!("{}: {}", s.label, PALETTE_NAMES[i % PALETTE.len()]))
                .collect();
            let caption = format!("{} ({})", panel.title, key.join(", "));
            let mut chart = ChartBuilder::on(area)
                .caption(caption, (FAMILY, 18))
                .margin(10)
                .x_label_area_size(35)
                .y_label_area_size(80)
                .build_cartesian_2d(t0..t1, (y0 - pad)..(y1 + pad))
                .map_err(|e| e.to_string())?;
            chart
                .configure_mesh()
                .x_desc("t [s]")
                .y_desc(panel.y_desc.as_str())
                .label_style((FAMILY, 14))
                .draw()
                .map_err(|e| e.to_string())?;
            for (i, s) in panel.series.iter().enumerate() {
                let color = PALETTE[i % PALETTE.len()];
                // A gap (non-finite values) breaks the line: each finite stretch is drawn on its own.
                let mut k = 0;
                while k < s.y.len() {
                    let start = k + s.y[k..].iter().take_while(|v| !v.is_finite()).count();
                    let end = start + s.y[start..].iter().take_while(|v| v.is_finite()).count();
                    k = end.max(start + 1);
                    if end <= start {
                        continue;
                    }
                    let pts = decimate(&s.t[start..end], &s.y[start..end], t0, t1, 1200);
                    chart
                        .draw_series(LineSeries::new(pts, color.stroke_width(2)))
                        .map_err(|e| e.to_string())?;
                }
            }
        }
        root.present().map_err(|e| e.to_string())
    }
}
