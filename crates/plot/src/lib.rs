//! Plotting on the bottom floor: what every pneuflex figure is drawn with, and nothing of the scene. Time
//! series with bands and marks ([`series`]), heatmaps ([`heatmap`]), Bode plots ([`bode`]), stacked
//! overlays ([`overlay`]), convergence plots ([`convergence`]); PNG (plotters' bitmap backend, our own
//! encoder), SVG or PDF (from the SVG), each by the file's extension, with an embedded DejaVu Sans font so
//! the output does not depend on system fonts.
//! Every series is reduced to its per-pixel-column first/min/max/last before drawing ([`decimate`]), so the
//! picture is the same and the cost does not grow with the length of the trace.

pub mod bode;
pub mod convergence;
pub mod decimate;
mod figure;
pub mod heatmap;
pub mod overlay;
mod pdf;
mod raster;
pub mod series;

use std::path::PathBuf;
use std::sync::OnceLock;

use plotters::prelude::RGBColor;
use plotters::style::{FontStyle, register_font};

pub use bode::{BodeLine, write_bode};
pub use convergence::write_convergence;
pub use decimate::{column_index, decimate, envelope};
pub use heatmap::{Heatmap, write_heatmap};
pub use overlay::{Panel, Series, write_overlay};
/// The colour type of lines and marks.
pub use plotters::style::RGBColor as Color;
pub use series::{Band, Line, Plot, render};

/// DejaVu Sans (fonts-dejavu-core; free license in assets/DejaVuSans-LICENSE.txt).
static FONT: &[u8] = include_bytes!("../assets/DejaVuSans.ttf");
/// The font family name the figures use.
pub const FAMILY: &str = "sans-serif";

/// Errors while drawing figures.
#[derive(Debug, thiserror::Error)]
pub enum PlotError {
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
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Format {
    /// Raster image, 1200×700 px.
    #[default]
    Png,
    /// Vector image.
    Svg,
    /// Vector document (one page), converted from the SVG.
    Pdf,
}

impl Format {
    /// The file extension.
    pub fn ext(self) -> &'static str {
        match self {
            Format::Png => "png",
            Format::Svg => "svg",
            Format::Pdf => "pdf",
        }
    }

    /// The format a figure path's extension names: `.svg`, `.pdf`, otherwise PNG.
    pub fn of(path: &std::path::Path) -> Self {
        match path.extension().and_then(|e| e.to_str()) {
            Some(e) if e.eq_ignore_ascii_case("svg") => Format::Svg,
            Some(e) if e.eq_ignore_ascii_case("pdf") => Format::Pdf,
            _ => Format::Png,
        }
    }
}

/// Registers the embedded font (once); every figure calls it first.
pub fn ensure_font() -> Result<(), PlotError> {
    static DONE: OnceLock<bool> = OnceLock::new();
    if *DONE.get_or_init(|| register_font(FAMILY, FontStyle::Normal, FONT).is_ok()) {
        Ok(())
    } else {
        Err(PlotError::Font)
    }
}

/// Colours of the runs, in order (colour-blind friendly: blue, vermillion, green, purple, ...).
pub const PALETTE: [RGBColor; 6] = [
    RGBColor(0, 114, 178),
    RGBColor(213, 94, 0),
    RGBColor(0, 158, 115),
    RGBColor(204, 121, 167),
    RGBColor(230, 159, 0),
    RGBColor(86, 180, 233),
];

/// The names of [`PALETTE`]'s colours, for a key written in words.
pub const PALETTE_NAMES: [&str; 6] = [
    "blue",
    "vermillion",
    "green",
    "purple",
    "orange",
    "sky blue",
];
