//! Reducing a series to what the pixel columns of a plot can show.

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
