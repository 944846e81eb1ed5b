//! The report pages people look at: `report.html` next to every
//! evaluation's `report.md` ([`write_report_html`]) and `index.html` next to
//! a summary ([`index::write_index`]).
//!
//! Both are single files that open from disk: pictures are inline data URIs
//! (JPEG strips of small frames, the dataset preview), charts inline SVG,
//! the filters plain inline JavaScript, and nothing names an outside URL.
//! The page's script marks the document (`data-script="ok"` on `<html>`)
//! once it has run without an exception, and `window.onerror` adds a
//! `#script-error` element otherwise, so a headless browser's DOM says
//! whether the page works (`trainer/tests/it/eval_cli.rs`).

pub mod frames;
pub mod index;
mod page;
mod strips;
mod svg;

pub use frames::{FrameMark, FrameRecord};
pub use index::{write_index, IndexExtras};

use crate::error::EvalError;
use std::path::Path;
use std::time::Instant;

/// What writing a page cost.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PageStats {
    pub bytes: usize,
    pub seconds: f64,
    /// Frames drawn as thumbnails.
    pub thumbnails: usize,
}

/// Writes `dir/report.html` for `report`: its tables and plots, and, when
/// the report carries its frames ([`FrameRecord`], kept by `eval`, not in
/// report.json), every video as a strip of thumbnails with each run's
/// per-frame answers.
pub fn write_report_html(report: &super::Report, dir: &Path) -> Result<PageStats, EvalError> {
    let start = Instant::now();
    let (html, thumbnails) = page::report_page(report);
    grasp_support::atomic::write_atomic(&dir.join("report.html"), html.as_bytes())?;
    let stats = PageStats {
        bytes: html.len(),
        seconds: start.elapsed().as_secs_f64(),
        thumbnails,
    };
    tracing::info!(
        "report.html: {:.2} MB, {} thumbnails, written in {:.2} s",
        stats.bytes as f64 / 1e6,
        stats.thumbnails,
        stats.seconds
    );
    Ok(stats)
}

/// `text` with HTML's special characters escaped (for text and quoted
/// attribute values alike).
pub(crate) fn esc(text: &str) -> String {
    let mut s = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '&' => s.push_str("&amp;"),
            '<' => s.push_str("&lt;"),
            '>' => s.push_str("&gt;"),
            '"' => s.push_str("&quot;"),
            '\'' => s.push_str("&#39;"),
            c => s.push(c),
        }
    }
    s
}

/// Standard base64 (RFC 4648, padded).
pub(crate) fn base64(bytes: &[u8]) -> String {
    const ABC: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut s = String::with_capacity(bytes.len().div_ceil(3) * 4);
    for chunk in bytes.chunks(3) {
        let b = [
            chunk[0],
            chunk.get(1).copied().unwrap_or(0),
            chunk.get(2).copied().unwrap_or(0),
        ];
        let n = (u32::from(b[0]) << 16) | (u32::from(b[1]) << 8) | u32::from(b[2]);
        for (k, shift) in [18, 12, 6, 0].into_iter().enumerate() {
            if k <= chunk.len() {
                s.push(ABC[((n >> shift) & 63) as usize] as char);
            } else {
                s.push('=');
            }
        }
    }
    s
}

/// A `data:` URI of `bytes` of the given MIME type.
pub(crate) fn data_uri(mime: &str, bytes: &[u8]) -> String {
    format!("data:{mime};base64,{}", base64(bytes))
}

/// A fraction as a percentage with one decimal, "–" for none.
pub(crate) fn pct(v: Option<f64>) -> String {
    v.map(|v| format!("{:.1}", v * 100.0))
        .unwrap_or_else(|| "–".into())
}

/// Mean ± std of fractions, in %.
pub(crate) fn pct_ms(m: Option<&super::metrics::MeanStd>) -> String {
    m.map(|m| format!("{:.1} ± {:.1}", m.mean * 100.0, m.std * 100.0))
        .unwrap_or_else(|| "–".into())
}

/// The page's shared style sheet and the error catcher that must run
/// before any other script.
pub(crate) fn head(title: &str) -> String {
    format!(
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n\
         <meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n\
         <title>{}</title>\n<style>\n{}</style>\n<script>\n{}</script>\n</head>\n",
        esc(title),
        include_str!("assets/report.css"),
        include_str!("assets/onerror.js")
    )
}

/// The closing script: `body` (the page's own code) run inside a guard
/// that marks the document once it ran to the end.
pub(crate) fn tail(body: &str) -> String {
    format!(
        "<script>\n(function () {{\n{body}\ndocument.documentElement.setAttribute('data-script', 'ok');\n}})();\n</script>\n</body>\n</html>\n"
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base64_matches_the_rfc_vectors() {
        let cases = [
            ("", ""),
            ("f", "Zg=="),
            ("fo", "Zm8="),
            ("foo", "Zm9v"),
            ("foob", "Zm9vYg=="),
            ("fooba", "Zm9vYmE="),
            ("foobar", "Zm9vYmFy"),
        ];
        for (plain, coded) in cases {
            assert_eq!(base64(plain.as_bytes()), coded, "{plain}");
        }
        assert_eq!(base64(&[0xff, 0xfe, 0xfd]), "//79");
    }

    #[test]
    fn text_is_escaped_for_elements_and_attributes() {
        assert_eq!(
            esc("<a href=\"x\">Tom & Jerry's</a>"),
            "&lt;a href=&quot;x&quot;&gt;Tom &amp; Jerry&#39;s&lt;/a&gt;"
        );
    }
}
