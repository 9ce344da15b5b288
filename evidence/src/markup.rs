//! What every page and plot of this crate writes its text with: the font, XML escaping and
//! the HTML table cells of the reports.
//! Kept outside the `report` feature so the sweep report, which needs no rasteriser, can
//! use it too.

use std::fmt::Write;

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

/// A table cell of text.
pub fn cell(out: &mut String, content: &str) {
    let _ = write!(out, "<td>{}</td>", esc(content));
}

/// A table cell of a number (right-aligned by the pages' `td.num`).
pub fn num(out: &mut String, content: &str) {
    let _ = write!(out, r#"<td class="num">{}</td>"#, esc(content));
}

/// A table's header row.
pub fn header(out: &mut String, names: &[&str]) {
    out.push_str("<tr>");
    for n in names {
        let _ = write!(out, "<th>{}</th>", esc(n));
    }
    out.push_str("</tr>");
}
