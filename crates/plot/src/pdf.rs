//! PDF figures: the figure's SVG converted by svg2pdf (typst's converter; vectors stay vectors), with the
//! embedded DejaVu Sans as the only font, so the text is the PNG's and the SVG's on any machine.

use std::path::Path;

/// Writes the SVG document `svg` as a one-page PDF at `path`.
#[cfg(feature = "pdf")]
pub(crate) fn write(path: &Path, svg: &str) -> Result<(), String> {
    use svg2pdf::usvg;
    let mut options = usvg::Options::default();
    let fonts = options.fontdb_mut();
    fonts.load_font_data(crate::FONT.to_vec());
    // plotters writes font-family="sans-serif": the embedded face is that family.
    fonts.set_sans_serif_family("DejaVu Sans");
    let tree = usvg::Tree::from_str(svg, &options).map_err(|e| format!("the figure's SVG: {e}"))?;
    let pdf = svg2pdf::to_pdf(
        &tree,
        svg2pdf::ConversionOptions::default(),
        svg2pdf::PageOptions::default(),
    )
    .map_err(|e| format!("converting to PDF: {e}"))?;
    std::fs::write(path, pdf).map_err(|e| e.to_string())
}

/// Without the `pdf` feature there is no converter: the error says how to get one.
#[cfg(not(feature = "pdf"))]
pub(crate) fn write(_path: &Path, _svg: &str) -> Result<(), String> {
    Err(
        "this build has no PDF writer (pneuflex-plot's `pdf` feature, on in the pneuflex command): \
         write SVG and convert it, or rebuild with the feature"
            .into(),
    )
}
