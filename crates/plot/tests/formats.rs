//! Every kind of figure in every format: a time series, a heatmap, a Bode plot, a stacked overlay and a
//! convergence plot, each written as .png, .svg and .pdf by its file's extension. Each file is what its
//! extension says, at the figure's size, and the PDF carries the embedded font (its text is the SVG's).

use std::path::{Path, PathBuf};

use pneuflex_plot::{
    BodeLine, Format, Heatmap, Line, Panel, Plot, Series, ensure_font, render, write_bode,
    write_convergence, write_heatmap, write_overlay,
};

/// Width and height of a PNG, from its IHDR chunk.
fn png_size(bytes: &[u8]) -> (u32, u32) {
    assert!(bytes.starts_with(b"\x89PNG\r\n\x1a\n"), "not a PNG");
    let be = |b: &[u8]| u32::from_be_bytes([b[0], b[1], b[2], b[3]]);
    (be(&bytes[16..20]), be(&bytes[20..24]))
}

/// `width="W" height="H"` of an SVG's root element.
fn svg_size(text: &str) -> (u32, u32) {
    assert!(text.starts_with("<svg"), "not an SVG");
    let attr = |name: &str| -> u32 {
        let at = text.find(&format!("{name}=\"")).unwrap() + name.len() + 2;
        text[at..].split('"').next().unwrap().parse().unwrap()
    };
    (attr("width"), attr("height"))
}

/// The first page's MediaBox of a PDF, rounded to points.
fn pdf_size(bytes: &[u8]) -> (u32, u32) {
    assert!(bytes.starts_with(b"%PDF-"), "not a PDF");
    let text = String::from_utf8_lossy(bytes);
    let at = text.find("/MediaBox [").expect("a MediaBox") + "/MediaBox [".len();
    let v: Vec<f64> = text[at..]
        .split(']')
        .next()
        .unwrap()
        .split_whitespace()
        .map(|x| x.parse().unwrap())
        .collect();
    ((v[2] - v[0]).round() as u32, (v[3] - v[1]).round() as u32)
}

/// Writes one figure as PNG, SVG and PDF with `write`, and checks each file against `size`.
fn every_format(dir: &Path, name: &str, size: (u32, u32), write: impl Fn(&Path)) {
    for format in [Format::Png, Format::Svg, Format::Pdf] {
        let path: PathBuf = dir.join(format!("{name}.{}", format.ext()));
        assert_eq!(Format::of(&path), format);
        write(&path);
        let bytes = std::fs::read(&path).unwrap();
        let got = match format {
            Format::Png => png_size(&bytes),
            Format::Svg => svg_size(&String::from_utf8(bytes.clone()).unwrap()),
            Format::Pdf => {
                // The text is drawn with the embedded face, carried in the file (a subset of it).
                assert!(
                    String::from_utf8_lossy(&bytes).contains("DejaVuSans"),
                    "{name}.pdf names no DejaVu Sans font"
                );
                pdf_size(&bytes)
            }
        };
        assert_eq!(got, size, "{}", path.display());
    }
}

#[test]
fn every_figure_kind_is_written_in_every_format() {
    ensure_font().unwrap();
    let dir = tempfile::tempdir().unwrap();
    let t: Vec<f64> = (0..=2000).map(|k| k as f64 * 1e-3).collect();
    let y: Vec<f64> = t.iter().map(|x| (6.0 * x).sin()).collect();

    every_format(dir.path(), "series", (1200, 700), |p| {
        let mut plot = Plot::new("a sine".into(), "y [1]", (0.0, 2.0), vec![1.0]);
        plot.subtitle = "under the title: the scene's description".into();
        plot.lines.push(Line {
            label: "sin".into(),
            t: &t,
            y: y.clone(),
            color: pneuflex_plot::PALETTE[0],
            dashed: false,
            width: 2,
        });
        render(p, &plot).unwrap();
    });

    let ticks = ["1".to_string(), "2".to_string()];
    every_format(dir.path(), "heatmap", (900, 700), |p| {
        write_heatmap(
            p,
            &Heatmap {
                title: "a map",
                x_label: "a [1]",
                x_ticks: &ticks,
                y_label: "b [1]",
                y_ticks: &ticks,
                cells: &[Some(1.0), Some(2.0), Some(3.0), Some(4.0)],
                marked: &[],
                mark_note: "",
                flagged: &[],
                flag_note: "",
                value_label: "v [1]",
                diverging: false,
            },
        )
        .unwrap();
    });

    // A first-order loop 10 / (s/(2 pi) + 1)... in Hz, dB, degrees: enough points to draw.
    let points: Vec<(f64, f64, f64)> = (0..200)
        .map(|k| {
            let f = 0.1 * 10f64.powf(k as f64 / 50.0);
            let mag = 10.0 / (1.0 + f * f).sqrt();
            (f, 20.0 * mag.log10(), -f.atan().to_degrees() - 2.0 * f)
        })
        .collect();
    every_format(dir.path(), "bode", (1200, 900), |p| {
        let line = BodeLine {
            label: "loop".into(),
            points: &points,
            gain_crossover: Some((9.95, 60.0)),
            phase_crossover: None,
        };
        write_bode(p, "a loop", &[line]).unwrap();
    });

    every_format(dir.path(), "overlay", (1200, 2 * 260), |p| {
        let panel = |title: &str| Panel {
            title: title.into(),
            y_desc: "y [1]".into(),
            series: vec![Series {
                label: "measured".into(),
                t: &t,
                y: &y,
            }],
            include_zero: false,
        };
        write_overlay(p, &[panel("p_a"), panel("residual")]).unwrap();
    });

    let candidates: Vec<(f64, f64)> = (1..=30)
        .map(|i| (i as f64, 1.0 + 30.0 / i as f64))
        .collect();
    let best: Vec<(f64, f64)> = candidates.clone();
    every_format(dir.path(), "convergence", (1000, 600), |p| {
        write_convergence(p, "a search", "J", &candidates, &best).unwrap();
    });
}
