//! The certificate as a reader prints it: headless Chromium's PDF of the HTML page, and the PDF
//! accelcal writes itself; each page's text by poppler's `pdftotext`, and the checks every
//! printed page must pass.

use std::path::Path;
use std::process::Command;

/// Prints `html` to PDF with headless Chromium (as a reader prints the certificate) and gives
/// each page's text (poppler's `pdftotext -layout`).
fn pdf_page_texts(html: &Path, pdf: &Path) -> Vec<String> {
    let out = Command::new("chromium")
        .args(["--headless", "--no-sandbox", "--disable-gpu", "--no-pdf-header-footer"])
        .arg(format!("--print-to-pdf={}", pdf.display()))
        .arg(html)
        .output()
        .expect("chromium is installed (bash scripts/setup-chromium.sh)");
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    pdf_texts(pdf)
}

/// Each page's text of a PDF (poppler's `pdftotext -layout`).
pub fn pdf_texts(pdf: &Path) -> Vec<String> {
    let text = Command::new("pdftotext")
        .args(["-layout", "-enc", "UTF-8"])
        .arg(pdf)
        .arg("-")
        .output()
        .expect("pdftotext is installed (bash scripts/setup-chromium.sh)");
    assert!(text.status.success(), "{}", String::from_utf8_lossy(&text.stderr));
    // pdftotext ends each page with a form feed.
    let all = String::from_utf8(text.stdout).unwrap();
    let mut pages: Vec<String> = all.split('\u{c}').map(str::to_string).collect();
    if pages.last().is_some_and(|p| p.trim().is_empty()) {
        pages.pop();
    }
    pages
}

/// The certificate as printed: every page says "Page i of n" and names the certificate (its
/// number, or that it is a draft) and the unit, no page carries the tool's command-line wording
/// (an `--option`), and each of `sections` is on some page. Gives the pages' text.
pub fn printed_certificate(html: &Path, pdf: &Path, named: &str, sections: &[&str]) -> Vec<String> {
    page_checks(pdf_page_texts(html, pdf), named, sections)
}

/// The certificate's own PDF (`report --pdf`, the station's `certificate.pdf`), checked as
/// [`printed_certificate`] checks a printed page.
pub fn certificate_pdf(pdf: &Path, named: &str, sections: &[&str]) -> Vec<String> {
    page_checks(pdf_texts(pdf), named, sections)
}

fn page_checks(pages: Vec<String>, named: &str, sections: &[&str]) -> Vec<String> {
    let n = pages.len();
    assert!((1..=4).contains(&n), "{n} pages");
    for (i, t) in pages.iter().enumerate() {
        assert!(t.contains(&format!("Page {} of {n}", i + 1)), "page {}: {t}", i + 1);
        assert!(t.contains(named), "page {} does not name {named}: {t}", i + 1);
        let flag = t.find(" --").filter(|&at| t[at + 3..].starts_with(|c: char| c.is_ascii_lowercase()));
        assert!(flag.is_none(), "command-line wording on page {}: {t}", i + 1);
    }
    for want in sections {
        assert!(pages.iter().any(|p| p.contains(want)), "no page has {want}: {pages:?}");
    }
    pages
}
