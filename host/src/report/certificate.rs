//! The certificate's HTML page: [`accelcal_core::certificate::Certificate`] through the
//! `certificate/page.html` template (escaped by `serve::escape::Html`, as `serve`'s pages), its
//! charts as inline SVG. A4 pages, every one ending with the number and "Page i of n" (CSS page
//! margin boxes), and a draft marked on every page. Nothing is computed here.

use askama::Template;

use accelcal_core::certificate::{Block, Certificate, Column, Paragraph, Release, Span, Style};

use crate::report::plot::lines_svg;

/// A block as the template shows it: a chart already drawn.
enum View<'a> {
    Paragraph(&'a Paragraph),
    Table(TableView<'a>),
    Chart(String),
}

/// A table and the sum of its columns' widths.
struct TableView<'a> {
    columns: &'a [Column],
    rows: &'a [Vec<Span>],
    total_width: f64,
}

struct SectionView<'a> {
    heading: Option<&'a str>,
    blocks: Vec<View<'a>>,
}

#[derive(Template)]
#[template(path = "certificate/page.html")]
struct Page<'a> {
    doc: &'a Certificate,
    sections: Vec<SectionView<'a>>,
    authorised_by: String,
    mark: Option<String>,
    mark_css: Option<String>,
    footer_css: String,
    json: String,
}

/// The certificate as one self-contained HTML page.
pub fn html(doc: &Certificate, release: &Release) -> anyhow::Result<String> {
    let mut sections = Vec::new();
    for s in &doc.sections {
        let mut blocks = Vec::new();
        for b in &s.blocks {
            blocks.push(match b {
                Block::Paragraph(p) => View::Paragraph(p),
                Block::Table(t) => View::Table(TableView {
                    columns: &t.columns,
                    rows: &t.rows,
                    total_width: t.columns.iter().map(|c| c.width).sum::<f64>().max(f64::MIN_POSITIVE),
                }),
                Block::Chart(c) => {
                    let series: Vec<(String, Vec<(f64, f64)>)> =
                        c.series.iter().map(|s| (s.name.clone(), s.points.clone())).collect();
                    View::Chart(lines_svg(&c.title, &c.x_label, &c.y_label, &series, (640, 330))?)
                }
            });
        }
        sections.push(SectionView { heading: s.heading.as_deref(), blocks });
    }
    let mark = release.mark();
    let page = Page {
        doc,
        sections,
        authorised_by: release.authorised_by(),
        mark_css: mark.as_deref().map(css_text),
        mark,
        footer_css: css_text(&doc.footer),
        json: script_json(doc),
    };
    Ok(page.render()?)
}

/// The document's canonical JSON as a `<script>` element may hold it: `<`, `>` and `&` (so no
/// `</script>` ends it) and every hidden character written as JSON `\u` escapes, which read back
/// as the same document.
fn script_json(doc: &Certificate) -> String {
    let mut out = String::new();
    for c in doc.canonical_json().chars() {
        if matches!(c, '<' | '>' | '&') || crate::serve::escape::hidden(c) {
            let mut buf = [0u16; 2];
            for unit in c.encode_utf16(&mut buf) {
                out.push_str(&format!("\\u{unit:04x}"));
            }
        } else {
            out.push(c);
        }
    }
    out
}

/// The document a certificate page carries, `None` for a page written before pages carried
/// one (accelcal before issue 57): [`Certificate::of_page`], the element
/// `accelcal_core::certificate::PAGE_SCRIPT_OPEN` opens, which `certificate/page.html` writes.
pub fn document_of(html: &str) -> Option<Result<Certificate, accelcal_core::certificate::DocumentError>> {
    Certificate::of_page(html)
}

/// Text as a CSS string's content inside the page's `<style>`: quotes and backslashes escaped,
/// `<` and `>` as CSS escapes (a `</style>` in a serial number must not end the element), `&` as
/// a CSS escape too (the template writes it as it is), control characters left out.
fn css_text(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars().filter(|c| !crate::serve::escape::hidden(*c)) {
        match c {
            '"' | '\\' => {
                out.push('\\');
                out.push(c);
            }
            '<' => out.push_str("\\3C "),
            '>' => out.push_str("\\3E "),
            '&' => out.push_str("\\26 "),
            c => out.push(c),
        }
    }
    out
}

#[cfg(test)]
pub(crate) mod tests {
    use super::{css_text, document_of, html, Release};
    use accelcal_core::certificate::{Certificate, Facts, Quantity, Span, FORMAT};

    pub(crate) fn doc(serial: &str) -> Certificate {
        Certificate {
            format: FORMAT,
            number: Some("2026-000001".into()),
            title: "Calibration certificate No. 2026-000001".into(),
            subtitle: format!("Accelerometer triad {serial}"),
            footer: format!("Calibration certificate No. 2026-000001 — accelerometer triad {serial}"),
            laboratory: None,
            verdict: vec![Span::plain("VERIFIED")],
            identification: Vec::new(),
            sections: Vec::new(),
            facts: Facts {
                serial: serial.into(),
                device_id: "00".into(),
                firmware: None,
                record_crc: "0".into(),
                campaign_sha256: "0".into(),
                customer: None,
                received: None,
                place: None,
                calibrated: None,
                issued: "2026-12-07T00:00:00Z".into(),
                operator: None,
                method: "lsq".into(),
                software: "0".into(),
                gravity: Quantity { value: 9.81, u: None, k: None, unit: "m/s²".into() },
                temperature: None,
                temperature_source: None,
                u_axis: None,
                coefficients: Vec::new(),
                parameters: Vec::new(),
                decision: None,
                decision_rule: String::new(),
                equipment: Vec::new(),
                recalibration_due: None,
                anchor: None,
                replaces: None,
            },
        }
    }

    /// A page carries its document, and a serial that would end the script element, or hide
    /// itself, reads back as it was.
    #[test]
    fn a_page_carries_its_document() {
        let d = doc("U-1</script><b>\u{200b}&");
        let page = html(&d, &Release::Draft).unwrap();
        assert!(!page.contains("</script><b>"), "{page}");
        assert!(!page.contains('\u{200b}'));
        let back = document_of(&page).unwrap().unwrap();
        assert_eq!(back, d);
        assert_eq!(back.sha256(), d.sha256());
        assert!(page.contains("DRAFT — awaiting approval"));
        assert!(document_of("<html></html>").is_none());
    }

    #[test]
    fn text_in_a_css_string_cannot_end_it() {
        assert_eq!(css_text(r#"U-42"; } body { x"#), r#"U-42\"; } body { x"#);
        assert_eq!(css_text("a\\b\nc"), "a\\\\bc");
        assert_eq!(css_text("</style><b>"), "\\3C /style\\3E \\3C b\\3E ");
    }
}
