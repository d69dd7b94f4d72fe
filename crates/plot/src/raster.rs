//! Pixels: a reused pixel buffer per drawing thread for PNG figures, and our own PNG encoder.

use std::path::Path;

thread_local! {
    /// This thread's pixel buffer for PNG figures ([`with_pixels`]).
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

/// Runs `draw` on this thread's RGB buffer for an image of `size` px. The figures of a command are drawn on
/// a few threads, each reusing its pixel buffer: a fresh 2.5 MB buffer costs its page faults again (a third
/// of drawing's kernel time). Every figure paints every pixel (its white background first), so what the
/// buffer held does not matter.
pub(crate) fn with_pixels(
    size: (u32, u32),
    draw: impl FnOnce(&mut [u8]) -> Result<(), String>,
) -> Result<(), String> {
    Pixels::with(size.0 as usize * size.1 as usize * 3, draw)
        .unwrap_or_else(|e| Err(format!("no memory for the pixels: {e}")))
}

/// Writes an RGB image as PNG with one filter for every row (`Up`: a plot is long runs of one colour, the
/// same from row to row) and zlib level 1 (flate2's zlib-rs backend). Against plotters' own encoder (five filters
/// tried on every row, then fdeflate) the pixels are the same and the files about half the size (paper-fig3:
/// 553 -> 338 KB; scripts/time_run.py, docs/performance.md).
pub(crate) fn write_png(path: &Path, rgb: &[u8], (w, h): (u32, u32)) -> Result<(), String> {
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ensure_font;
    use crate::series::{Line, Plot, draw_plot, render};
    use plotters::prelude::*;

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
        // A PWM-like raw band under its (here: a 25-sample) mean.
        let mean: Vec<f64> = (0..raw.len())
            .map(|i| {
                let w = &raw[i.saturating_sub(12)..(i + 13).min(raw.len())];
                w.iter().sum::<f64>() / w.len() as f64
            })
            .collect();
        plot.lines.push(Line {
            label: "f_e (mean)".into(),
            t: &t,
            y: mean,
            color: RGBColor(31, 119, 180),
            dashed: false,
            width: 2,
        });
        plot.bands.push(crate::series::Band {
            label: "f_e, raw".into(),
            t: &t,
            y: raw,
            color: RGBColor(31, 119, 180),
            period_s: 0.025,
        });
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
        let dir = std::env::temp_dir().join(format!("pneuflex-plot-png-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let ours = dir.join("ours.png");
        let theirs = dir.join("theirs.png");
        render(&ours, &plot).unwrap();
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
