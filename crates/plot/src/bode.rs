//! A Bode plot: the gain and the phase of open loops against frequency, with the 0 dB and -180 deg lines.

use std::path::Path;

use plotters::prelude::*;

use crate::{FAMILY, PlotError, ensure_font};

/// One loop's frequency response: its legend label and (Hz, dB, degrees) points, frequency ascending.
pub type BodeLine<'a> = (String, &'a [(f64, f64, f64)]);

/// Draws the gain (top) and phase (bottom) of `lines` into a PNG at `path` (1200 x 900); lines of fewer
/// than two points are left out, and nothing to draw is [`PlotError::Empty`].
/// A Bode plot of inner-loop analyses (`pneuflex_scene::analysis::loop_margins`): |L| in dB above, arg L in degrees
/// below, one line per run and stiffness, against frequency on a log axis; the 0 dB and −180° lines dashed.
pub fn write_bode(path: &Path, lines: &[BodeLine<'_>]) -> Result<(), PlotError> {
    ensure_font()?;
    let lines: Vec<&BodeLine<'_>> = lines.iter().filter(|(_, b)| b.len() > 1).collect();
    if lines.is_empty() {
        return Err(PlotError::Empty);
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
    draw().map_err(|message| PlotError::Draw {
        path: path.to_path_buf(),
        message,
    })
}
