//! What every page and plot of this crate writes its text with: the font and XML escaping.
//! Kept outside the `report` feature so the sweep report, which needs no rasteriser, can
//! use it too.

/// Font of every text element.
pub const FONT: &str = "DejaVu Sans";

/// XML (and HTML) text and attribute escape.
pub fn esc(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&#39;"),
            c => out.push(c),
        }
    }
    out
}
