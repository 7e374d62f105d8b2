//! The certificate as a PDF, without a browser: [`accelcal_core::certificate::Certificate`] laid
//! out on A4 pages by krilla (ARCHITECTURE says why krilla). DejaVu Sans is subset and embedded,
//! and every glyph carries its text, so `pdftotext` reads every value back. Each page ends with
//! the footer and "Page i of n"; a draft carries "DRAFT — awaiting approval" at the top of every
//! page. A table row is never split, a table's head is repeated on the page it continues on, and
//! each cell wraps within its column. The document's canonical JSON is attached to the file
//! (`accelcal-certificate.json`), so that the PDF can be checked against what was approved.
//! Nothing is computed here: the layout only measures text.

use anyhow::anyhow;
use krilla::color::rgb;
use krilla::embed::{AssociationKind, EmbeddedFile, MimeType};
use krilla::geom::{PathBuilder, Point, Rect};
use krilla::metadata::Metadata;
use krilla::num::NormalizedF32;
use krilla::page::PageSettings;
use krilla::paint::{Fill, Stroke};
use krilla::text::{Font, TextDirection};
use krilla::Document;
use skrifa::instance::{LocationRef, Size};
use skrifa::{FontRef, MetadataProvider};

use accelcal_core::certificate::approval::Seal;
use accelcal_core::certificate::{Block, Certificate, Chart, Column, Release, Span, Style, Superseded};

/// A4, points.
const PAGE_W: f32 = 595.28;
const PAGE_H: f32 = 841.89;
const LEFT: f32 = 28.0;
const RIGHT: f32 = PAGE_W - 28.0;
const TOP: f32 = 36.0;
/// The lowest baseline of the body; the footer sits below.
const BOTTOM: f32 = PAGE_H - 40.0;
const BODY: f32 = 8.0;
const SMALL: f32 = 6.8;
const CELL: f32 = 6.8;
const LEAD: f32 = 1.25;
const PAD: f32 = 2.2;

/// The attached document's name.
pub const ATTACHMENT: &str = "accelcal-certificate.json";

#[derive(Clone, Copy, PartialEq)]
enum Face {
    Regular,
    Bold,
}

/// The two faces and their metrics.
struct Fonts {
    regular: Font,
    bold: Font,
    regular_ref: FontRef<'static>,
    bold_ref: FontRef<'static>,
}

impl Fonts {
    fn load() -> anyhow::Result<Fonts> {
        let (r, b) = (dejavu::sans::regular(), dejavu::sans::bold());
        Ok(Fonts {
            regular: Font::new(r.into(), 0).ok_or_else(|| anyhow!("DejaVu Sans does not load"))?,
            bold: Font::new(b.into(), 0).ok_or_else(|| anyhow!("DejaVu Sans Bold does not load"))?,
            regular_ref: FontRef::new(r).map_err(|e| anyhow!("DejaVu Sans: {e}"))?,
            bold_ref: FontRef::new(b).map_err(|e| anyhow!("DejaVu Sans Bold: {e}"))?,
        })
    }

    /// The width of `text` at `size`, points.
    fn width(&self, text: &str, face: Face, size: f32) -> f32 {
        let f = if face == Face::Bold { &self.bold_ref } else { &self.regular_ref };
        let map = f.charmap();
        let metrics = f.glyph_metrics(Size::new(size), LocationRef::default());
        text.chars().map(|c| map.map(c).and_then(|g| metrics.advance_width(g)).unwrap_or(size * 0.6)).sum()
    }
}

/// Something drawn on a page.
enum Op {
    Text { x: f32, y: f32, size: f32, face: Face, color: (u8, u8, u8), text: String },
    Line { x0: f32, y0: f32, x1: f32, y1: f32, width: f32, color: (u8, u8, u8) },
    Rect { x: f32, y: f32, w: f32, h: f32, color: (u8, u8, u8) },
    Poly { points: Vec<(f32, f32)>, color: (u8, u8, u8) },
}

const BLACK: (u8, u8, u8) = (17, 17, 17);
const GREY: (u8, u8, u8) = (68, 68, 68);
const RULE: (u8, u8, u8) = (190, 190, 190);
const SHADE: (u8, u8, u8) = (236, 236, 236);
const GREEN: (u8, u8, u8) = (0, 102, 0);
const RED: (u8, u8, u8) = (187, 0, 0);
const SERIES: [(u8, u8, u8); 3] = [(31, 119, 180), (214, 39, 40), (44, 160, 44)];

fn look(style: Style) -> (Face, (u8, u8, u8)) {
    match style {
        Style::Plain => (Face::Regular, BLACK),
        Style::Strong => (Face::Bold, BLACK),
        Style::Pass => (Face::Regular, GREEN),
        Style::Fail => (Face::Bold, RED),
    }
}

/// A line of wrapped text: its pieces, each with its style and width.
type Line = Vec<(String, Style, f32)>;

/// The pages being laid out.
struct Layout<'f> {
    fonts: &'f Fonts,
    pages: Vec<Vec<Op>>,
    y: f32,
}

impl<'f> Layout<'f> {
    fn new(fonts: &'f Fonts) -> Self {
        Layout { fonts, pages: vec![Vec::new()], y: TOP }
    }

    fn ops(&mut self) -> &mut Vec<Op> {
        self.pages.last_mut().expect("a page")
    }

    fn new_page(&mut self) {
        self.pages.push(Vec::new());
        self.y = TOP;
    }

    /// Starts a new page unless `h` points fit below.
    fn room(&mut self, h: f32) {
        if self.y + h > BOTTOM && self.y > TOP {
            self.new_page();
        }
    }

    /// Wraps styled text into lines of at most `width` points.
    fn wrap(&self, spans: &[Span], size: f32, width: f32) -> Vec<Line> {
        let mut lines: Vec<Line> = vec![Vec::new()];
        let mut used = 0.0;
        for s in spans {
            let (face, _) = look(s.style);
            let space = self.fonts.width(" ", face, size);
            for (i, word) in s.text.split(' ').enumerate() {
                // A space between words of one span; a span's own leading space is kept too.
                let gap = if i > 0 || s.text.starts_with(' ') && !word.is_empty() { space } else { 0.0 };
                let mut w = self.fonts.width(word, face, size);
                if used > 0.0 && used + gap + w > width {
                    lines.push(Vec::new());
                    used = 0.0;
                } else if gap > 0.0 && used > 0.0 {
                    push(lines.last_mut().expect("a line"), " ", s.style, space);
                    used += space;
                }
                // A word longer than the line is cut where it must be.
                let mut rest = word.to_string();
                while w > width && rest.chars().count() > 1 {
                    let mut cut = String::new();
                    for c in rest.chars() {
                        let mut t = cut.clone();
                        t.push(c);
                        if self.fonts.width(&t, face, size) > width - used && !cut.is_empty() {
                            break;
                        }
                        cut = t;
                    }
                    let cw = self.fonts.width(&cut, face, size);
                    push(lines.last_mut().expect("a line"), &cut, s.style, cw);
                    lines.push(Vec::new());
                    used = 0.0;
                    rest = rest[cut.len()..].to_string();
                    w = self.fonts.width(&rest, face, size);
                }
                if !rest.is_empty() {
                    push(lines.last_mut().expect("a line"), &rest, s.style, w);
                    used += w;
                }
            }
        }
        lines
    }

    /// Draws wrapped lines from `x`, aligned right within `width` when `right`.
    fn draw_lines(&mut self, lines: &[Line], x: f32, top: f32, width: f32, size: f32, right: bool) {
        for (n, line) in lines.iter().enumerate() {
            let total: f32 = line.iter().map(|p| p.2).sum();
            let mut at = if right { x + width - total } else { x };
            let base = top + size + n as f32 * size * LEAD;
            for (text, style, w) in line {
                let (face, color) = look(*style);
                if !text.trim().is_empty() {
                    self.ops().push(Op::Text { x: at, y: base, size, face, color, text: text.clone() });
                }
                at += w;
            }
        }
    }

    fn paragraph(&mut self, spans: &[Span], size: f32) {
        let lines = self.wrap(spans, size, RIGHT - LEFT);
        for line in lines {
            self.room(size * LEAD);
            let top = self.y;
            self.draw_lines(std::slice::from_ref(&line), LEFT, top, RIGHT - LEFT, size, false);
            self.y += size * LEAD;
        }
        self.y += 3.0;
    }

    fn heading(&mut self, text: &str, size: f32) {
        let lines = self.wrap(&[Span::styled(text, Style::Strong)], size, RIGHT - LEFT);
        let h = lines.len() as f32 * size * LEAD + 3.0;
        // A heading keeps with at least a few lines of what follows.
        self.room(h + 40.0);
        self.y += 4.0;
        let top = self.y;
        self.draw_lines(&lines, LEFT, top, RIGHT - LEFT, size, false);
        self.y += h;
        let y = self.y - 1.5;
        self.ops().push(Op::Line { x0: LEFT, y0: y, x1: RIGHT, y1: y, width: 0.6, color: GREY });
        self.y += 2.0;
    }

    /// A table; `head_shaded` columns are drawn as a header row.
    fn table(&mut self, columns: &[Column], rows: &[Vec<Span>], label_column: bool) {
        let total: f32 = columns.iter().map(|c| c.width as f32).sum::<f32>().max(f32::MIN_POSITIVE);
        let widths: Vec<f32> = columns.iter().map(|c| c.width as f32 / total * (RIGHT - LEFT)).collect();
        let head: Vec<Vec<Line>> = columns
            .iter()
            .zip(&widths)
            .map(|(c, w)| self.wrap(&[Span::styled(c.head.clone(), Style::Strong)], CELL, w - 2.0 * PAD))
            .collect();
        let show_head = columns.iter().any(|c| !c.head.is_empty());
        let height = |cells: &[Vec<Line>]| {
            cells.iter().map(|l| l.len()).max().unwrap_or(1) as f32 * CELL * LEAD + 2.0 * PAD
        };
        let head_h = height(&head);
        let bodies: Vec<Vec<Vec<Line>>> = rows
            .iter()
            .map(|r| {
                r.iter()
                    .zip(&widths)
                    .map(|(s, w)| self.wrap(std::slice::from_ref(s), CELL, w - 2.0 * PAD))
                    .collect()
            })
            .collect();
        let mut first = true;
        for (r, cells) in bodies.iter().enumerate() {
            let h = height(cells);
            let need = if first && show_head { head_h + h } else { h };
            if self.y + need > BOTTOM {
                self.new_page();
                first = true;
            }
            if first && show_head {
                self.row(&head, &widths, columns, head_h, true, false);
            }
            first = false;
            self.row(cells, &widths, columns, h, false, label_column);
            let _ = r;
        }
        self.y += 4.0;
    }

    fn row(
        &mut self,
        cells: &[Vec<Line>],
        widths: &[f32],
        columns: &[Column],
        h: f32,
        head: bool,
        label: bool,
    ) {
        let mut x = LEFT;
        let top = self.y;
        for (i, (lines, w)) in cells.iter().zip(widths).enumerate() {
            if head || (label && i == 0) {
                self.ops().push(Op::Rect { x, y: top, w: *w, h, color: SHADE });
            }
            let right = columns.get(i).is_some_and(|c| c.numeric);
            self.draw_lines(lines, x + PAD, top + PAD, w - 2.0 * PAD, CELL, right);
            x += w;
        }
        // The cell borders.
        let mut x = LEFT;
        for w in widths {
            self.ops().push(Op::Line { x0: x, y0: top, x1: x, y1: top + h, width: 0.4, color: RULE });
            x += w;
        }
        self.ops().push(Op::Line { x0: RIGHT, y0: top, x1: RIGHT, y1: top + h, width: 0.4, color: RULE });
        self.ops().push(Op::Line { x0: LEFT, y0: top, x1: RIGHT, y1: top, width: 0.4, color: RULE });
        self.ops().push(Op::Line { x0: LEFT, y0: top + h, x1: RIGHT, y1: top + h, width: 0.4, color: RULE });
        self.y += h;
    }

    /// A line chart: axes with ticks, one line per series, a legend.
    fn chart(&mut self, c: &Chart) {
        let (w, h) = (380.0f32, 190.0f32);
        self.room(h + 12.0);
        let (x0, y0) = (LEFT + 46.0, self.y + 26.0);
        let (pw, ph) = (w - 56.0, h - 58.0);
        let (title, ty0) = (c.title.clone(), self.y + 9.0);
        self.ops().push(Op::Text {
            x: LEFT,
            y: ty0,
            size: BODY,
            face: Face::Bold,
            color: BLACK,
            text: title,
        });
        let xs = c.series.iter().flat_map(|s| s.points.iter().map(|p| p.0));
        let ys = c.series.iter().flat_map(|s| s.points.iter().map(|p| p.1));
        let (xa, xb) = bounds(xs);
        let (ya, yb) = bounds(ys);
        let (xa, xb) = (xa - 0.5, xb + 0.5);
        let ty = ticks(ya, yb);
        let (ya, yb) = (ty.first().copied().unwrap_or(ya).min(ya), ty.last().copied().unwrap_or(yb).max(yb));
        let px = |x: f64| x0 + ((x - xa) / (xb - xa)) as f32 * pw;
        let py = |y: f64| y0 + ph - ((y - ya) / (yb - ya)) as f32 * ph;
        for t in &ty {
            let y = py(*t);
            self.ops().push(Op::Line { x0, y0: y, x1: x0 + pw, y1: y, width: 0.3, color: SHADE });
            let label = tick_label(*t, &ty);
            let lw = self.fonts.width(&label, Face::Regular, SMALL);
            self.ops().push(Op::Text {
                x: x0 - 3.0 - lw,
                y: y + 2.3,
                size: SMALL,
                face: Face::Regular,
                color: GREY,
                text: label,
            });
        }
        for t in ticks(xa, xb).into_iter().filter(|t| t.fract() == 0.0 && *t >= xa && *t <= xb) {
            let x = px(t);
            self.ops().push(Op::Line {
                x0: x,
                y0: y0 + ph,
                x1: x,
                y1: y0 + ph + 2.5,
                width: 0.4,
                color: GREY,
            });
            let label = format!("{t:.0}");
            let lw = self.fonts.width(&label, Face::Regular, SMALL);
            self.ops().push(Op::Text {
                x: x - lw / 2.0,
                y: y0 + ph + 9.5,
                size: SMALL,
                face: Face::Regular,
                color: GREY,
                text: label,
            });
        }
        self.ops().push(Op::Line { x0, y0, x1: x0, y1: y0 + ph, width: 0.6, color: GREY });
        self.ops().push(Op::Line { x0, y0: y0 + ph, x1: x0 + pw, y1: y0 + ph, width: 0.6, color: GREY });
        let xl = c.x_label.clone();
        let xw = self.fonts.width(&xl, Face::Regular, SMALL);
        self.ops().push(Op::Text {
            x: x0 + pw / 2.0 - xw / 2.0,
            y: y0 + ph + 19.0,
            size: SMALL,
            face: Face::Regular,
            color: BLACK,
            text: xl,
        });
        self.ops().push(Op::Text {
            x: LEFT,
            y: y0 - 8.0,
            size: SMALL,
            face: Face::Regular,
            color: BLACK,
            text: c.y_label.clone(),
        });
        let mut lx = x0 + pw - 10.0;
        for (i, s) in c.series.iter().enumerate().rev() {
            let color = SERIES[i % SERIES.len()];
            let points: Vec<(f32, f32)> = s.points.iter().map(|&(x, y)| (px(x), py(y))).collect();
            self.ops().push(Op::Poly { points, color });
            let lw = self.fonts.width(&s.name, Face::Regular, SMALL);
            lx -= lw + 18.0;
            self.ops().push(Op::Line {
                x0: lx,
                y0: y0 - 10.0,
                x1: lx + 10.0,
                y1: y0 - 10.0,
                width: 1.2,
                color,
            });
            self.ops().push(Op::Text {
                x: lx + 13.0,
                y: y0 - 8.0,
                size: SMALL,
                face: Face::Regular,
                color: BLACK,
                text: s.name.clone(),
            });
        }
        self.y += h + 6.0;
    }
}

fn push(line: &mut Line, text: &str, style: Style, w: f32) {
    match line.last_mut() {
        Some(last) if last.1 == style => {
            last.0.push_str(text);
            last.2 += w;
        }
        _ => line.push((text.to_string(), style, w)),
    }
}

/// The smallest and largest finite value, widened when equal.
fn bounds(v: impl Iterator<Item = f64>) -> (f64, f64) {
    let (a, b) = v
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| (a.min(v), b.max(v)));
    if !a.is_finite() {
        return (0.0, 1.0);
    }
    if a == b {
        (a - 0.5 * a.abs().max(1e-9), b + 0.5 * b.abs().max(1e-9))
    } else {
        (a, b)
    }
}

/// About five round tick values covering `a..b`.
fn ticks(a: f64, b: f64) -> Vec<f64> {
    let raw = (b - a) / 5.0;
    let mag = 10f64.powf(raw.log10().floor());
    let step = [1.0, 2.0, 2.5, 5.0, 10.0].iter().map(|m| m * mag).find(|s| *s >= raw).unwrap_or(10.0 * mag);
    let mut t = (a / step).floor() * step;
    let mut out = Vec::new();
    while t <= b + step * 1e-9 && out.len() < 50 {
        out.push(if t.abs() < step * 1e-9 { 0.0 } else { t });
        t += step;
    }
    if out.last().is_some_and(|l| *l < b) {
        out.push(t);
    }
    out
}

/// A tick's label with the decimals its step needs.
fn tick_label(t: f64, all: &[f64]) -> String {
    let step = if all.len() > 1 { (all[1] - all[0]).abs() } else { 1.0 };
    let d = (-step.log10().floor()).max(0.0) as usize + 1;
    format!("{t:.d$}")
}

/// The certificate as a PDF, with its signed decision attached when it has one.
pub fn pdf(doc: &Certificate, release: &Release, seal: Option<&Seal>) -> anyhow::Result<Vec<u8>> {
    let fonts = Fonts::load()?;
    let mut l = Layout::new(&fonts);
    // The top: title and subtitle left, the laboratory right.
    let lab_w = 200.0;
    if let Some(lab) = &doc.laboratory {
        let mut spans = vec![Span::styled(lab.name.clone(), Style::Strong)];
        if let Some(a) = &lab.address {
            spans.push(Span::plain(format!(" {a}")));
        }
        let lines = l.wrap(&spans, BODY, lab_w);
        l.draw_lines(&lines, RIGHT - lab_w, TOP, lab_w, BODY, true);
    }
    let title = l.wrap(&[Span::styled(doc.title.clone(), Style::Strong)], 13.0, RIGHT - LEFT - lab_w - 10.0);
    l.draw_lines(&title, LEFT, TOP, RIGHT - LEFT - lab_w, 13.0, false);
    l.y += title.len() as f32 * 13.0 * LEAD + 2.0;
    l.paragraph(&[Span::plain(doc.subtitle.clone())], BODY + 1.0);
    l.paragraph(&doc.verdict, BODY + 1.5);
    // The identification table.
    let columns = [
        Column { head: String::new(), numeric: false, width: 24.0 },
        Column { head: String::new(), numeric: false, width: 76.0 },
    ];
    let mut rows: Vec<Vec<Span>> = doc
        .identification
        .iter()
        .map(|f| vec![Span::styled(f.label.clone(), Style::Strong), Span::plain(f.text.clone())])
        .collect();
    rows.push(vec![Span::styled("Authorised by", Style::Strong), Span::plain(release.authorised_by())]);
    l.table(&columns, &rows, true);
    for s in &doc.sections {
        if let Some(h) = &s.heading {
            l.heading(h, 9.0);
        }
        for b in &s.blocks {
            match b {
                Block::Paragraph(p) => l.paragraph(&p.spans, if p.small { SMALL } else { BODY }),
                Block::Table(t) => l.table(&t.columns, &t.rows, false),
                Block::Chart(c) => l.chart(c),
            }
        }
    }
    // Every page's footer and mark, now that the pages are counted.
    let n = l.pages.len();
    for (i, ops) in l.pages.iter_mut().enumerate() {
        let page = format!("Page {} of {n}", i + 1);
        let pw = fonts.width(&page, Face::Regular, SMALL);
        let y = PAGE_H - 22.0;
        ops.push(Op::Line { x0: LEFT, y0: y - 9.0, x1: RIGHT, y1: y - 9.0, width: 0.4, color: RULE });
        ops.push(Op::Text {
            x: LEFT,
            y,
            size: SMALL,
            face: Face::Regular,
            color: GREY,
            text: doc.footer.clone(),
        });
        ops.push(Op::Text { x: RIGHT - pw, y, size: SMALL, face: Face::Regular, color: GREY, text: page });
        if let Some(mark) = release.mark() {
            // A long rejection reason is set smaller, never past the margins.
            let full = fonts.width(&mark, Face::Bold, 10.0);
            let size = if full > RIGHT - LEFT { 10.0 * (RIGHT - LEFT) / full } else { 10.0 };
            let mw = fonts.width(&mark, Face::Bold, size);
            ops.push(Op::Text {
                x: (PAGE_W - mw) / 2.0,
                y: 20.0,
                size,
                face: Face::Bold,
                color: RED,
                text: mark,
            });
        }
    }
    emit(&fonts, &l.pages, doc, seal, release.superseded())
}

fn paint(c: (u8, u8, u8)) -> krilla::paint::Paint {
    rgb::Color::new(c.0, c.1, c.2).into()
}

/// Writes the laid-out pages.
fn emit(
    fonts: &Fonts,
    pages: &[Vec<Op>],
    doc: &Certificate,
    seal: Option<&Seal>,
    superseded: Option<&Superseded>,
) -> anyhow::Result<Vec<u8>> {
    let mut d = Document::new();
    d.set_metadata(
        Metadata::new()
            .title(doc.title.clone())
            .creator(format!("accelcal {}", env!("CARGO_PKG_VERSION")))
            .language("en".into()),
    );
    for ops in pages {
        let settings = PageSettings::from_wh(PAGE_W, PAGE_H).ok_or_else(|| anyhow!("the A4 page size"))?;
        let mut page = d.start_page_with(settings);
        let mut s = page.surface();
        for op in ops {
            match op {
                Op::Text { x, y, size, face, color, text } => {
                    s.set_fill(Some(Fill {
                        paint: paint(*color),
                        opacity: NormalizedF32::ONE,
                        rule: Default::default(),
                    }));
                    let font = if *face == Face::Bold { fonts.bold.clone() } else { fonts.regular.clone() };
                    s.draw_text(Point::from_xy(*x, *y), font, *size, text, false, TextDirection::Auto);
                }
                Op::Line { x0, y0, x1, y1, width, color } => {
                    let mut pb = PathBuilder::new();
                    pb.move_to(*x0, *y0);
                    pb.line_to(*x1, *y1);
                    if let Some(path) = pb.finish() {
                        s.set_fill(None);
                        s.set_stroke(Some(Stroke {
                            paint: paint(*color),
                            width: *width,
                            ..Default::default()
                        }));
                        s.draw_path(&path);
                        s.set_stroke(None);
                    }
                }
                Op::Rect { x, y, w, h, color } => {
                    if let Some(r) = Rect::from_xywh(*x, *y, *w, *h) {
                        let mut pb = PathBuilder::new();
                        pb.push_rect(r);
                        if let Some(path) = pb.finish() {
                            s.set_stroke(None);
                            s.set_fill(Some(Fill {
                                paint: paint(*color),
                                opacity: NormalizedF32::ONE,
                                rule: Default::default(),
                            }));
                            s.draw_path(&path);
                        }
                    }
                }
                Op::Poly { points, color } => {
                    let mut pb = PathBuilder::new();
                    for (i, (x, y)) in points.iter().enumerate() {
                        if i == 0 {
                            pb.move_to(*x, *y);
                        } else {
                            pb.line_to(*x, *y);
                        }
                    }
                    if let Some(path) = pb.finish() {
                        s.set_fill(None);
                        s.set_stroke(Some(Stroke { paint: paint(*color), width: 1.0, ..Default::default() }));
                        s.draw_path(&path);
                        s.set_stroke(None);
                    }
                }
            }
        }
        s.finish();
        page.finish();
    }
    d.embed_file(EmbeddedFile {
        path: ATTACHMENT.into(),
        mime_type: MimeType::new("application/json"),
        description: Some("the certificate document (canonical JSON) this PDF was rendered from".into()),
        association_kind: AssociationKind::Source,
        data: doc.canonical_json().into_bytes().into(),
        modification_date: None,
        compress: Some(true),
        location: None,
    })
    .ok_or_else(|| anyhow!("the certificate document could not be attached"))?;
    if let Some(seal) = seal {
        d.embed_file(EmbeddedFile {
            path: Seal::ATTACHMENT.into(),
            mime_type: MimeType::new("application/json"),
            description: Some(
                "the signed decision on this certificate (accelcal certificate verify checks it)".into(),
            ),
            association_kind: AssociationKind::Supplement,
            data: serde_json::to_string(seal)?.into_bytes().into(),
            modification_date: None,
            compress: Some(true),
            location: None,
        })
        .ok_or_else(|| anyhow!("the signed decision could not be attached"))?;
    }
    if let Some(by) = superseded {
        d.embed_file(EmbeddedFile {
            path: Superseded::ATTACHMENT.into(),
            mime_type: MimeType::new("application/json"),
            description: Some("the amendment that replaced this certificate".into()),
            association_kind: AssociationKind::Supplement,
            data: serde_json::to_string(by)?.into_bytes().into(),
            modification_date: None,
            compress: Some(true),
            location: None,
        })
        .ok_or_else(|| anyhow!("the amendment's note could not be attached"))?;
    }
    d.finish().map_err(|e| anyhow!("the PDF could not be written: {e:?}"))
}

/// The largest attachment read back (a certificate document is some tens of kB).
const MAX_ATTACHMENT: usize = 16 << 20;

/// The files attached to a PDF (its name tree `/EmbeddedFiles`), by name. The bytes are
/// untrusted: a PDF that does not read, or whose name tree is not as the specification has it,
/// is an error, never a panic.
pub fn attachments(pdf: &[u8]) -> anyhow::Result<Vec<(String, Vec<u8>)>> {
    use lopdf::{Document as Pdf, Object};
    let doc = Pdf::load_mem(pdf).map_err(|e| anyhow!("not a PDF that reads: {e}"))?;
    let deref = |o: &'_ Object| -> anyhow::Result<Object> {
        Ok(doc.dereference(o).map_err(|e| anyhow!("a broken reference: {e}"))?.1.clone())
    };
    let catalog = doc.catalog().map_err(|e| anyhow!("no document catalog: {e}"))?;
    let Ok(names) = catalog.get(b"Names") else { return Ok(Vec::new()) };
    let names = deref(names)?;
    let Ok(files) = names.as_dict().map_err(|e| anyhow!("{e}"))?.get(b"EmbeddedFiles") else {
        return Ok(Vec::new());
    };
    let mut out = Vec::new();
    // A name tree: a node has /Names [name spec name spec …] or /Kids [node …].
    let mut nodes = vec![deref(files)?];
    let mut seen = 0usize;
    while let Some(node) = nodes.pop() {
        seen += 1;
        if seen > 10_000 {
            anyhow::bail!("the attachments' name tree does not end");
        }
        let node = node.as_dict().map_err(|e| anyhow!("an attachments' node: {e}"))?.clone();
        if let Ok(kids) = node.get(b"Kids") {
            for k in deref(kids)?.as_array().map_err(|e| anyhow!("{e}"))? {
                nodes.push(deref(k)?);
            }
        }
        let Ok(list) = node.get(b"Names") else { continue };
        let list = deref(list)?;
        let list = list.as_array().map_err(|e| anyhow!("{e}"))?;
        for pair in list.chunks(2) {
            let [name, spec] = pair else { anyhow::bail!("an attachments' list of odd length") };
            let name =
                String::from_utf8_lossy(deref(name)?.as_str().map_err(|e| anyhow!("{e}"))?).into_owned();
            let spec = deref(spec)?;
            let spec = spec.as_dict().map_err(|e| anyhow!("attachment {name:?}: {e}"))?;
            let ef = deref(spec.get(b"EF").map_err(|e| anyhow!("attachment {name:?}: {e}"))?)?;
            let f = ef.as_dict().map_err(|e| anyhow!("{e}"))?.get(b"F").map_err(|e| anyhow!("{e}"))?;
            let stream = deref(f)?;
            let stream = stream.as_stream().map_err(|e| anyhow!("attachment {name:?}: {e}"))?;
            let bytes = match stream.decompressed_content_with_limit(MAX_ATTACHMENT) {
                Ok(b) => b,
                // A stream without a filter is its content.
                Err(_) if stream.dict.get(b"Filter").is_err() => stream.content.clone(),
                Err(e) => anyhow::bail!("attachment {name:?} does not decompress: {e}"),
            };
            out.push((name, bytes));
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::{attachments, pdf, tick_label, ticks, ATTACHMENT};
    use accelcal_core::certificate::{Certificate, Release};

    /// A PDF carries its document, read back the same, and the same document with the same
    /// release renders to the same bytes (what `certificate verify` compares).
    #[test]
    fn a_pdf_carries_its_document_and_renders_the_same_twice() {
        let doc = crate::report::certificate::tests::doc("U-7 <&>");
        let a = pdf(&doc, &Release::Draft, None).unwrap();
        let b = pdf(&doc, &Release::Draft, None).unwrap();
        assert_eq!(a, b, "two renderings of one document differ");
        let files = attachments(&a).unwrap();
        assert_eq!(files.len(), 1);
        assert_eq!(files[0].0, ATTACHMENT);
        let back = Certificate::parse(std::str::from_utf8(&files[0].1).unwrap()).unwrap();
        assert_eq!(back, doc);
        // Bytes that are not a PDF, or a PDF cut short, are an error, not a panic.
        assert!(attachments(b"%PDF-1.7 nothing").is_err());
        assert!(
            attachments(&a[..a.len() / 2]).is_err() || attachments(&a[..a.len() / 2]).unwrap().is_empty()
        );
    }

    #[test]
    fn ticks_are_round_and_cover_the_range() {
        assert_eq!(ticks(0.0, 10.0), vec![0.0, 2.0, 4.0, 6.0, 8.0, 10.0]);
        let t = ticks(-0.0031, 0.0042);
        assert!(t[0] <= -0.0031 && *t.last().unwrap() >= 0.0042, "{t:?}");
        assert_eq!(tick_label(0.002, &t), "0.0020");
    }
}
