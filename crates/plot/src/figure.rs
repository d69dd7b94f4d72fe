//! Where a figure goes: one function picks the backend for the file's format, so every kind of figure is
//! written in every format. PNG through this thread's reused pixel buffer and our encoder ([`crate::raster`]),
//! SVG through plotters, PDF from that SVG ([`crate::pdf`]).

use std::path::Path;

use plotters::coord::Shift;
use plotters::prelude::*;

use crate::{Format, PlotError, pdf, raster};

/// A figure that can be drawn onto any plotters backend.
pub(crate) trait Figure {
    /// Draws the whole figure onto `root` (which it fills first). `raster`: the backend is pixels (PNG), for
    /// the figures that draw dense bands differently on pixels and on vectors.
    fn draw<DB: DrawingBackend>(
        &self,
        root: DrawingArea<DB, Shift>,
        raster: bool,
    ) -> Result<(), String>
    where
        DB::ErrorType: 'static;
}

/// Writes `figure` at `size` (px; points for PDF) into `path`, in the format its extension names.
pub(crate) fn write(path: &Path, size: (u32, u32), figure: &impl Figure) -> Result<(), PlotError> {
    let drawn = match Format::of(path) {
        Format::Png => raster::with_pixels(size, |rgb| {
            figure
                .draw(
                    BitMapBackend::with_buffer(rgb, size).into_drawing_area(),
                    true,
                )
                .and_then(|()| raster::write_png(path, rgb, size))
        }),
        Format::Svg => figure.draw(SVGBackend::new(path, size).into_drawing_area(), false),
        Format::Pdf => {
            let mut svg = String::new();
            figure
                .draw(
                    SVGBackend::with_string(&mut svg, size).into_drawing_area(),
                    false,
                )
                .and_then(|()| pdf::write(path, &svg))
        }
    };
    drawn.map_err(|message| PlotError::Draw {
        path: path.to_path_buf(),
        message,
    })
}

/// The legend of a chart's labelled series: a framed, nearly opaque box (`opacity`) at `position`, its text
/// `size` points.
pub(crate) fn draw_legend<'a, DB: DrawingBackend + 'a, CT: plotters::coord::CoordTranslate>(
    chart: &mut ChartContext<'a, DB, CT>,
    position: SeriesLabelPosition,
    opacity: f64,
    size: u32,
) -> Result<(), String> {
    chart
        .configure_series_labels()
        .position(position)
        .background_style(WHITE.mix(opacity))
        .border_style(BLACK)
        .label_font((crate::FAMILY, size))
        .draw()
        .map_err(|e| e.to_string())
}
