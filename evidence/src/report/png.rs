//! PNG copies of the report's SVG plots, for viewers that do not show SVG (chat, issue
//! trackers, slides). Rasterised with resvg; text is drawn with the DejaVu fonts embedded
//! in this binary and no system font, so every machine draws the same pixels.

use resvg::{tiny_skia, usvg};

/// Pixels per SVG unit: the plots are laid out at 1600 units wide, so 1:1 keeps text of
/// 13-24 px readable at a normal zoom.
pub const SCALE: f32 = 1.0;

/// The options every plot is parsed with: DejaVu Sans (regular and bold) as the only
/// fonts, and as the generic `sans-serif` family.
fn options() -> usvg::Options<'static> {
    let mut opt = usvg::Options { font_family: super::svg::FONT.to_string(), ..usvg::Options::default() };
    let db = opt.fontdb_mut();
    db.load_font_data(dejavu::sans::regular().to_vec());
    db.load_font_data(dejavu::sans::bold().to_vec());
    db.set_sans_serif_family(super::svg::FONT);
    opt
}

/// Rasterises `svg` on a white background and encodes it as PNG.
///
/// # Errors
/// When the SVG cannot be parsed or the image cannot be allocated or encoded (the message
/// says which).
pub fn render(svg: &str) -> Result<Vec<u8>, String> {
    let tree = usvg::Tree::from_str(svg, &options()).map_err(|e| format!("the SVG cannot be parsed: {e}"))?;
    let size = tree.size().to_int_size().scale_by(SCALE).ok_or("the SVG has no size")?;
    let mut pixmap = tiny_skia::Pixmap::new(size.width(), size.height())
        .ok_or_else(|| format!("cannot allocate a {}x{} image", size.width(), size.height()))?;
    pixmap.fill(tiny_skia::Color::WHITE);
    resvg::render(&tree, tiny_skia::Transform::from_scale(SCALE, SCALE), &mut pixmap.as_mut());
    pixmap.encode_png().map_err(|e| format!("PNG encoding failed: {e}"))
}
