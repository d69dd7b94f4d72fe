//! Per-pixel-column decimation: the envelope of a long series is kept, and the drawn picture does not change.

use plotters::prelude::*;
use pneuflex_plot::{column_index, decimate, envelope};

/// 100,000 samples of a sine with a fast ripple and a few spikes (what a PWM force trace looks like).
fn long_series() -> (Vec<f64>, Vec<f64>) {
    let n = 100_000;
    let t: Vec<f64> = (0..n).map(|i| i as f64 * 1e-3).collect();
    let y = t
        .iter()
        .enumerate()
        .map(|(i, &t)| {
            let spike = if i % 7919 == 0 { 8.0 } else { 0.0 };
            10.0 + 2.0 * (2.0 * std::f64::consts::PI * t).sin()
                + 1.3 * (2.0 * std::f64::consts::PI * 40.0 * t).sin().signum()
                + 0.1 * (i as f64 * 0.37).sin()
                + spike
        })
        .collect();
    (t, y)
}

/// Per column: (min, max, index of first, index of last) of the samples of `t, y` in it.
fn columns_of(
    t: &[f64],
    y: &[f64],
    t0: f64,
    t1: f64,
    columns: usize,
) -> Vec<Option<(f64, f64, f64, f64)>> {
    let mut out: Vec<Option<(f64, f64, f64, f64)>> = vec![None; columns];
    for (&ti, &yi) in t.iter().zip(y) {
        if ti < t0 || ti > t1 || !yi.is_finite() {
            continue;
        }
        let c = &mut out[column_index(ti, t0, t1, columns)];
        *c = Some(match *c {
            None => (yi, yi, ti, ti),
            Some((lo, hi, first, _)) => (lo.min(yi), hi.max(yi), first, ti),
        });
    }
    out
}

#[test]
fn decimation_keeps_every_columns_envelope_with_at_most_four_points() {
    let (t, y) = long_series();
    for &(t0, t1, columns) in &[(0.0, 99.999, 1088), (12.3, 15.0, 1088), (0.0, 99.999, 97)] {
        let d = decimate(&t, &y, t0, t1, columns);
        let (dt, dy): (Vec<f64>, Vec<f64>) = d.iter().copied().unzip();
        let raw = columns_of(&t, &y, t0, t1, columns);
        let dec = columns_of(&dt, &dy, t0, t1, columns);
        // Per column, at most 4 points, and its min, max, first and last sample are the raw series'.
        let mut per_column = vec![0usize; columns];
        for &ti in &dt {
            per_column[column_index(ti, t0, t1, columns)] += 1;
        }
        assert!(per_column.iter().all(|&k| k <= 4), "{per_column:?}");
        assert_eq!(raw, dec, "window {t0}..{t1}, {columns} columns");
        assert!(d.len() <= 4 * columns);
        // Time order kept.
        assert!(dt.windows(2).all(|w| w[0] < w[1]));
        // The envelope the raw band is drawn from is the same per column.
        let env = envelope(&t, &y, t0, t1, columns);
        let raw_env: Vec<(f64, f64)> = raw.iter().flatten().map(|c| (c.0, c.1)).collect();
        let env_mm: Vec<(f64, f64)> = env.iter().map(|e| (e.1, e.2)).collect();
        assert_eq!(raw_env, env_mm);
    }
}

/// Draws `pts` segment by segment (as the figures draw a solid line) into a 1200×700 RGB buffer.
fn draw_segments(pts: &[(f64, f64)], t_range: (f64, f64), width: u32) -> (Vec<u8>, usize) {
    let mut buf = vec![0u8; 1200 * 700 * 3];
    let columns;
    {
        let root = BitMapBackend::with_buffer(&mut buf, (1200, 700)).into_drawing_area();
        root.fill(&WHITE).unwrap();
        let mut chart = ChartBuilder::on(&root)
            .margin(16)
            .x_label_area_size(50)
            .y_label_area_size(80)
            .build_cartesian_2d(t_range.0..t_range.1, 0.0..22.0)
            .unwrap();
        let (px, _) = chart.plotting_area().get_pixel_range();
        columns = (px.end - px.start) as usize;
        let style = BLUE.stroke_width(width);
        chart
            .draw_series(
                pts.windows(2)
                    .map(|w| PathElement::new(vec![w[0], w[1]], style)),
            )
            .unwrap();
        root.present().unwrap();
    }
    (buf, columns)
}

#[test]
fn a_decimated_line_draws_the_same_pixels_as_the_raw_one() {
    let (t, y) = long_series();
    for &(t0, t1) in &[(0.0, 99.999), (40.0, 43.0)] {
        for width in [1, 2] {
            let raw: Vec<(f64, f64)> = t
                .iter()
                .zip(&y)
                .filter(|(t, _)| **t >= t0 && **t <= t1)
                .map(|(t, y)| (*t, *y))
                .collect();
            let (raw_px, columns) = draw_segments(&raw, (t0, t1), width);
            let d = decimate(&t, &y, t0, t1, columns);
            let (dec_px, _) = draw_segments(&d, (t0, t1), width);
            let drawn = raw_px.chunks(3).filter(|p| *p != [255, 255, 255]).count();
            // A pixel drawn in one picture and not in the other: at most a rasterisation detail of the
            // thick line's caps (plotters fills each thick segment as a polygon), next to a drawn pixel
            // of the other picture.
            let white = |b: &[u8], x: i64, y: i64| {
                !(0..1200).contains(&x)
                    || !(0..700).contains(&y)
                    || b[3 * (y * 1200 + x) as usize..][..3] == [255, 255, 255]
            };
            let mut differ = 0;
            for yy in 0..700i64 {
                for xx in 0..1200i64 {
                    let (a, b) = (white(&raw_px, xx, yy), white(&dec_px, xx, yy));
                    if a != b {
                        differ += 1;
                        let other = if a { &raw_px } else { &dec_px };
                        let near = (-1..=1)
                            .flat_map(|dx| (-1..=1).map(move |dy| (dx, dy)))
                            .any(|(dx, dy)| !white(other, xx + dx, yy + dy));
                        assert!(near, "{t0}..{t1}, width {width}: pixel ({xx}, {yy}) apart");
                    }
                }
            }
            assert!(
                differ * 100 <= drawn,
                "{t0}..{t1}, width {width}: {differ} of {drawn} drawn pixels differ ({} points for {})",
                d.len(),
                raw.len()
            );
            eprintln!(
                "{t0}..{t1}, width {width}: {differ} of {drawn} drawn pixels differ ({} points for {})",
                d.len(),
                raw.len()
            );
        }
    }
}
