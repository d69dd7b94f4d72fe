//! A convergence plot: every candidate's objective and the best so far against the evaluations.

use std::path::Path;

use plotters::prelude::*;

use crate::{FAMILY, PALETTE, PlotError, ensure_font};

/// A convergence plot of a search: every candidate's objective (dots) and the best so far (a line) against
/// the number of evaluations; a log scale when the values span more than a decade.
pub fn write_convergence(
    path: &Path,
    title: &str,
    y_label: &str,
    candidates: &[(f64, f64)],
    best: &[(f64, f64)],
) -> Result<(), PlotError> {
    ensure_font()?;
    let finite: Vec<f64> = candidates
        .iter()
        .chain(best)
        .map(|p| p.1)
        .filter(|v| v.is_finite() && *v > 0.0)
        .collect();
    if finite.is_empty() {
        return Err(PlotError::Empty);
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
    let figure = Convergence {
        caption,
        y_label,
        candidates,
        best,
        lo,
        hi,
        n,
    };
    crate::figure::write(path, (1000, 600), &figure)
}

/// A convergence plot's content: the caption, the points, the value range and the last evaluation.
struct Convergence<'a> {
    caption: String,
    y_label: &'a str,
    candidates: &'a [(f64, f64)],
    best: &'a [(f64, f64)],
    lo: f64,
    hi: f64,
    n: f64,
}

impl crate::figure::Figure for Convergence<'_> {
    fn draw<DB: DrawingBackend>(
        &self,
        root: DrawingArea<DB, plotters::coord::Shift>,
        _raster: bool,
    ) -> Result<(), String>
    where
        DB::ErrorType: 'static,
    {
        let Convergence {
            ref caption,
            y_label,
            candidates,
            best,
            lo,
            hi,
            n,
        } = *self;
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
                crate::figure::draw_legend(&mut chart, SeriesLabelPosition::UpperRight, 0.85, 14)?;
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
    }
}
