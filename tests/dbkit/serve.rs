//! `accelcal serve`: the read-only web view, over HTTP and in headless Chromium (`--dump-dom`):
//! the pages load, their tables hold the database's numbers (those `fleet --json` gives), a chart
//! is drawn, a hostile serial is shown as text, a stored certificate's script does not run, and
//! nothing but GET is answered. Each scenario takes the database's spec (a SQLite file or a
//! PostgreSQL URL): `tests/db.rs` and `tests/db_pg.rs` run them on both engines.

use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::process::{Child, Command, Stdio};

use accelcal_db::Db;

use super::fleet::{head_knocked_out, hostile_unit, line_of_units, HOSTILE_SERIAL};
use super::{accelcal, DAY, T0};

/// A running `accelcal serve`, stopped when dropped.
struct Server {
    child: Child,
    base: String,
}

impl Server {
    /// Sends `signal` and waits (at most 15 s) for the exit: its code and what it wrote on stderr.
    fn stop(mut self, signal: i32) -> (Option<i32>, String) {
        // SAFETY: kill(2) on the child this test started, still unreaped.
        assert_eq!(unsafe { libc::kill(self.child.id() as i32, signal) }, 0);
        let deadline = std::time::Instant::now() + std::time::Duration::from_secs(15);
        let status = loop {
            if let Some(s) = self.child.try_wait().unwrap() {
                break s;
            }
            assert!(
                std::time::Instant::now() < deadline,
                "serve did not stop within 15 s of signal {signal}"
            );
            std::thread::sleep(std::time::Duration::from_millis(50));
        };
        let mut err = String::new();
        self.child.stderr.take().unwrap().read_to_string(&mut err).unwrap();
        (status.code(), err)
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// Starts `accelcal serve --db SPEC --bind 127.0.0.1:0` and reads its address off its first line.
fn serve(spec: &str) -> Server {
    serve_with(spec, &[])
}

/// `serve` with `extra` options (`--bind 127.0.0.1:0` unless they bind), run by `bash -c
/// 'ulimit -n 1024; exec accelcal serve …'`: the common limit of open files. Its address is
/// always reached through 127.0.0.1.
fn serve_with(spec: &str, extra: &[&str]) -> Server {
    let mut child = Command::new("bash")
        .args(["-c", "ulimit -n 1024 && exec \"$0\" \"$@\"", env!("CARGO_BIN_EXE_accelcal")])
        .args(["serve", "--db", spec])
        .args(if extra.contains(&"--bind") { &[][..] } else { &["--bind", "127.0.0.1:0"][..] })
        .args(extra)
        .env_remove("ACCELCAL_DB")
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut line = String::new();
    BufReader::new(child.stdout.take().unwrap()).read_line(&mut line).unwrap();
    let Some(at) = line.find("http://") else {
        let mut err = String::new();
        let _ = child.stderr.take().unwrap().read_to_string(&mut err);
        panic!("no address in `{line}`: {err}");
    };
    let base = line[at..].split_whitespace().next().unwrap().trim_end_matches('/').to_string();
    let port = base.rsplit(':').next().unwrap();
    let base = format!("http://127.0.0.1:{port}");
    assert!(line.starts_with("serving ") && line.contains("read-only"), "{line}");
    Server { child, base }
}

/// One HTTP/1.1 request: (status, headers, body).
fn request(base: &str, method: &str, path: &str) -> (u16, String, String) {
    request_with(base, method, path, "")
}

/// One HTTP/1.1 request with `headers` (each ending in CRLF): (status, headers, body).
fn request_with(base: &str, method: &str, path: &str, headers: &str) -> (u16, String, String) {
    let host = base.trim_start_matches("http://");
    let mut s = TcpStream::connect(host).unwrap();
    s.set_read_timeout(Some(std::time::Duration::from_secs(30))).unwrap();
    write!(
        s,
        "{method} {path} HTTP/1.1\r\nHost: {host}\r\nConnection: close\r\nContent-Length: 0\r\n{headers}\r\n"
    )
    .unwrap();
    let mut raw = Vec::new();
    s.read_to_end(&mut raw).unwrap();
    let raw = String::from_utf8_lossy(&raw).into_owned();
    let (head, body) = raw.split_once("\r\n\r\n").unwrap();
    let status = head.split_whitespace().nth(1).unwrap().parse().unwrap();
    // A chunked body: join the chunks.
    let body = if head.to_ascii_lowercase().contains("transfer-encoding: chunked") {
        let mut out = String::new();
        let mut rest = body;
        while let Some((size, after)) = rest.split_once("\r\n") {
            let n = usize::from_str_radix(size.trim(), 16).unwrap();
            if n == 0 {
                break;
            }
            out.push_str(&after[..n]);
            rest = &after[n + 2..];
        }
        out
    } else {
        body.to_string()
    };
    (status, head.to_string(), body)
}

/// The DOM headless Chromium builds of `url`, after its scripts (if any were allowed) ran.
fn dom(url: &str) -> String {
    let profile = tempfile::tempdir().unwrap();
    let out = Command::new("chromium")
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--disable-quic",
            "--no-first-run",
            "--disable-background-networking",
            "--disable-component-update",
            "--disable-sync",
        ])
        .arg(format!("--user-data-dir={}", profile.path().display()))
        .args(["--dump-dom", url])
        .output()
        .expect("chromium is installed (bash scripts/setup-chromium.sh)");
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    String::from_utf8(out.stdout).unwrap()
}

/// Fills the database with the fleet fixture's line of units and a unit whose serial is a
/// script; gives that unit's run.
fn line_db(spec: &str) -> String {
    let mut db = Db::open(spec).unwrap();
    line_of_units(&mut db);
    hostile_unit(&mut db, T0 + 10 * DAY).to_string()
}

const JANUARY: &str = "since=2026-01-01&until=2026-01-31";

/// The pages hold the numbers `fleet --json` gives, in Chromium's DOM.
pub fn the_pages_hold_the_database_s_numbers(spec: &str) {
    let d = tempfile::tempdir().unwrap();
    line_db(spec);
    let json = d.path().join("f.json");
    let (code, _, err) = accelcal(&[
        "fleet",
        "--db",
        spec,
        "--since",
        "2026-01-01",
        "--until",
        "2026-01-31",
        "--json",
        json.to_str().unwrap(),
    ]);
    assert_eq!(code, Some(0), "{err}");
    let f: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let c = &f["counts"];
    let server = serve(spec);

    let fleet = dom(&format!("{}/fleet?{JANUARY}", server.base));
    let counts = format!(
        "{} runs of {} units: {} pass, {} rejected, {} unfinished, {} voided",
        c["runs"], c["units"], c["passed"], c["rejected"], c["unfinished"], c["voided"]
    );
    assert!(fleet.contains(&counts), "{counts} not in {fleet}");
    let yields = format!(
        "first-pass yield {}/{} ({:.1} %)",
        c["first_pass_units"],
        c["units_finished"],
        100.0 * c["first_pass_units"].as_f64().unwrap() / c["units_finished"].as_f64().unwrap()
    );
    assert!(fleet.contains(&yields), "{yields} not in the page");
    // Every run of the period is a row, and every population with its Cpk.
    for r in f["runs"].as_array().unwrap() {
        assert!(fleet.contains(r["device_id"].as_str().unwrap()), "{r}");
    }
    let bias = f["populations"].as_array().unwrap().iter().find(|p| p["name"] == "as-left bias x").unwrap();
    let row = format!(
        "<td>as-left bias x</td><td>mg</td><td class=\"num\">{}</td><td class=\"num\">{:+.4}</td>",
        bias["n"],
        bias["mean"].as_f64().unwrap()
    );
    assert!(fleet.contains(&row), "{row} not in the page");
    assert!(fleet.contains(&format!("{:.2}", bias["cpk"].as_f64().unwrap())));
    // The CSV download is `fleet --csv`'s rows.
    let (status, head, csv) = request(&server.base, "GET", &format!("/fleet.csv?{JANUARY}"));
    assert_eq!(status, 200, "{head}");
    assert!(head.to_ascii_lowercase().contains("content-type: text/csv"), "{head}");
    assert_eq!(csv.lines().count(), 1 + f["runs"].as_array().unwrap().len(), "{csv}");

    // A chart is drawn: SVG with its points, and the head's row on the overview.
    let charts = dom(&format!("{}/charts?{JANUARY}", server.base));
    assert!(charts.contains("<svg") && charts.contains("<circle"), "no chart drawn");
    assert!(charts.contains("station st-1, K0 x"), "no chart of st-1's K0 x");
    // Issue 60: a head with too few units says so under its signature.
    assert!(charts.contains("not enough units to flag a change: 0 of the 5"), "{charts}");
    let overview = dom(&format!("{}/", server.base));
    assert!(overview.contains("HEAD-1") && overview.contains("DKD-17-001") && overview.contains("overdue"));
    // A unit's page: its runs and its drift between calibrations.
    let unit = dom(&format!("{}/unit/SN-B1", server.base));
    assert!(unit.contains("rejected: selection beyond model 4"), "{unit}");
    assert!(unit.contains("<a href=\"/certificate/") && unit.contains(" awaiting approval</a>"), "{unit}");
}

/// The tick labels of each chart (`<svg>`) of a page: its y axis's (plotters anchors them at
/// their end) and its x axis's (at their middle), the rotated axis description left out.
fn tick_labels(page: &str) -> Vec<[Vec<String>; 2]> {
    let mut charts = Vec::new();
    for svg in page.split("<svg").skip(1) {
        let svg = &svg[..svg.find("</svg>").unwrap_or(svg.len())];
        let mut axes: [Vec<String>; 2] = Default::default();
        for text in svg.split("<text").skip(1) {
            let (tag, rest) = text.split_once('>').unwrap();
            let label = rest[..rest.find("</text>").unwrap()].trim().to_string();
            if tag.contains("transform=") {
                continue;
            }
            if tag.contains("text-anchor=\"end\"") {
                axes[0].push(label);
            } else if tag.contains("text-anchor=\"middle\"") {
                axes[1].push(label);
            }
        }
        charts.push(axes);
    }
    charts
}

/// Whether `labels` are all different.
fn distinct(labels: &[String]) -> bool {
    let mut l = labels.to_vec();
    l.sort();
    l.dedup();
    l.len() == labels.len()
}

/// Whether `s` is a day written YYYY-MM-DD.
fn is_date(s: &str) -> bool {
    let b = s.as_bytes();
    b.len() == 10
        && b.iter().enumerate().all(|(i, c)| if i == 4 || i == 7 { *c == b'-' } else { c.is_ascii_digit() })
}

/// Issue 59, the morning view in Chromium: the overview opens with what needs attention (the
/// overdue head HEAD-1 planted by the fixture, linked to its row; over January also the unit found
/// out of tolerance and the certificates awaiting approval); the search box finds a unit by its
/// certificate number; the charts' tick labels differ on every axis and the control charts' time
/// axes say dates.
pub fn the_morning_view_needs_attention_finds_and_ticks(spec: &str) {
    let mut db = Db::open(spec).unwrap();
    let line = line_of_units(&mut db);
    head_knocked_out(&mut db);
    let number = db.number_in_force(line.b[1]).unwrap().unwrap();
    drop(db);
    let server = serve(spec);

    let overview = dom(&format!("{}/", server.base));
    let panel = &overview[overview.find("<section id=\"attention\">").expect("no attention panel")..];
    let panel = &panel[..panel.find("</section>").unwrap()];
    assert!(
        panel.contains(
            "<strong>asset overdue</strong>: <a href=\"/#asset-HEAD-1\">head HEAD-1: certificate DKD-17-001 was due 2026-01-20</a>"
        ),
        "{panel}"
    );
    assert!(!panel.contains("HEAD-2"), "HEAD-2 is due in 2099: {panel}");
    assert!(overview.contains("<tr id=\"asset-HEAD-1\">"), "the entry's link goes nowhere");
    assert!(overview.find("id=\"attention\"") < overview.find("id=\"today\""), "the panel is not first");
    let january = dom(&format!("{}/?{JANUARY}", server.base));
    let panel = &january[january.find("<section id=\"attention\">").unwrap()..];
    let panel = &panel[..panel.find("</section>").unwrap()];
    assert!(panel.contains(&format!("<a href=\"/run/{}\">SN-C1 (", line.c)), "{panel}");
    assert!(panel.contains(" as found (run ") && panel.contains("tell its users"), "{panel}");
    assert!(
        panel.contains(&format!("<a href=\"/certificate/{number}\">{number} of SN-B1 (run {})", line.b[1])),
        "{panel}"
    );
    // HEAD-2's units run from T0 on, a head knocked out from the 56th: charts out of control
    // and a change point.
    assert!(
        panel.contains("chart out of control</strong>: <a href=\"/charts?since=2026-01-01&amp;until=2026-01-31&amp;head_asset=HEAD-2\">head HEAD-2, "),
        "{panel}"
    );
    assert!(panel.contains("head change point</strong>: <a href=\"/charts?since=2026-01-01&amp;until=2026-01-31&amp;head_asset=HEAD-2\">head HEAD-2: "), "{panel}");

    // The search box is on every page; a certificate's number finds its unit, at the run's row.
    assert!(overview.contains("<form id=\"search\" action=\"/search\" method=\"get\">"), "{overview}");
    let found = dom(&format!("{}/search?q={number}", server.base));
    assert!(found.contains("<title>SN-B1 · accelcal</title>") && found.contains("<h1>SN-B1</h1>"), "{found}");
    assert!(found.contains(&format!("<p id=\"device\">device id {}</p>", super::DEVICE_2)), "{found}");
    assert!(found.contains(&format!("<tr id=\"run-{}\">", line.b[1])), "{found}");

    // Every chart's tick labels differ on each axis; the control charts' x axes say dates.
    let charts = dom(&format!("{}/charts?{JANUARY}", server.base));
    let labels = tick_labels(&charts);
    assert!(labels.len() > 5, "{} charts", labels.len());
    for [y, x] in &labels {
        assert!(y.len() >= 2 && distinct(y), "y: {y:?}");
        assert!(!x.is_empty() && distinct(x), "x: {x:?}");
    }
    let dated = labels.iter().filter(|[_, x]| x.iter().filter(|l| is_date(l)).count() >= 2).count();
    assert!(dated >= 2, "no time axis with dates: {labels:?}");
    assert!(labels.iter().all(|[y, _]| y.iter().all(|l| l.parse::<f64>().is_ok())), "{labels:?}");
}

/// A serial that is a script is shown as text, and a stored certificate's script does not run.
pub fn a_hostile_serial_is_text_and_a_stored_script_does_not_run(spec: &str) {
    let run = line_db(spec);
    let server = serve(spec);
    let fleet = dom(&format!("{}/fleet?{JANUARY}", server.base));
    assert!(
        fleet.contains("&lt;script&gt;document.write('PWNED')&lt;/script&gt;"),
        "the serial is not shown as text"
    );
    assert!(!fleet.contains("<script"), "a script element in the fleet page");
    assert!(!fleet.contains("PWNED</"), "the serial's script ran");
    // Its unit page, through the link the table gives (the serial percent-encoded).
    let link = fleet.split("href=\"/unit/").find(|s| s.starts_with("%3Cscript")).unwrap();
    let path = &link[..link.find('"').unwrap()];
    let unit = dom(&format!("{}/unit/{path}", server.base));
    assert!(unit.contains("&lt;script&gt;document.write"), "{unit}");
    assert!(!unit.contains("<script"), "{unit}");
    // The stored certificate is served as issued, script and all, but no script may run.
    let (status, head, body) = request(&server.base, "GET", &format!("/run/{run}/certificate"));
    assert_eq!(status, 200);
    assert!(body.contains(HOSTILE_SERIAL));
    assert!(head.to_ascii_lowercase().contains("content-security-policy: default-src 'none'"), "{head}");
    let cert = dom(&format!("{}/run/{run}/certificate", server.base));
    assert_eq!(cert.matches("PWNED").count(), 1, "the certificate's script ran: {cert}");
}

/// No control character of a stored certificate reaches the page (issue 55): a customer's name
/// holding ESC, an OSC title, BEL and NUL is served as the visible text `\u{1b}`, `\u{7}`,
/// `\u{0}`; the page's own line feeds stay.
pub fn a_stored_certificate_s_controls_are_shown_escaped(spec: &str) {
    let mut db = Db::open(spec).unwrap();
    let s = super::start(accelcal_db::RunId::new(), super::DEVICE, "SN-C", "st-1", T0);
    db.begin_run(&s, None).unwrap();
    db.store_certificate(s.run_id, "<html>\n<p>customer ACME\u{1b}]0;owned\u{7} Ltd\u{0}</p>\n</html>")
        .unwrap();
    db.finish_run(s.run_id, accelcal_db::Outcome::Pass, "verified").unwrap();
    drop(db);
    let server = serve(spec);
    let (status, _, body) = request(&server.base, "GET", &format!("/run/{}/certificate", s.run_id));
    assert_eq!(status, 200, "{body}");
    assert!(body.contains("<p>customer ACME\\u{1b}]0;owned\\u{7} Ltd\\u{0}</p>\n"), "{body:?}");
    assert!(!body.chars().any(|c| c.is_control() && !matches!(c, '\n' | '\t' | '\r')), "{body:?}");
}

/// Only GET is answered; a bad filter, an unknown unit or page say why; a SQLite database is the
/// same bytes afterwards.
pub fn only_get_is_answered_and_bad_requests_say_why(spec: &str) {
    line_db(spec);
    let server = serve(spec);
    for path in ["/", "/fleet", "/charts", "/unit/SN-A1"] {
        let (status, _, body) = request(&server.base, "GET", path);
        assert_eq!(status, 200, "{path}: {body}");
        for method in ["POST", "PUT", "DELETE", "PATCH"] {
            let (status, _, _) = request(&server.base, method, path);
            assert_eq!(status, 405, "{method} {path}");
        }
    }
    let (status, _, body) = request(&server.base, "GET", "/fleet?since=2026-13-01");
    assert_eq!(status, 400);
    assert!(body.contains("since: `2026-13-01` is not a date YYYY-MM-DD"), "{body}");
    let (status, _, body) = request(&server.base, "GET", "/fleet?since=2026-02-01&until=2026-01-01");
    assert_eq!(status, 400);
    assert!(body.contains("the period is empty"), "{body}");
    let (status, _, body) = request(&server.base, "GET", "/unit/NOBODY");
    assert_eq!(status, 404);
    assert!(body.contains("no unit `NOBODY` in the database"), "{body}");
    let (status, _, _) = request(&server.base, "GET", "/run/not-a-uuid/certificate");
    assert_eq!(status, 400);
    let (status, _, _) = request(&server.base, "GET", "/admin");
    assert_eq!(status, 404);
    drop(server);
    if std::path::Path::new(spec).is_file() {
        // The database file is the same bytes after all of it: nothing was written.
        let before = std::fs::read(spec).unwrap();
        let server = serve(spec);
        let _ = request(&server.base, "GET", &format!("/fleet?{JANUARY}"));
        drop(server);
        assert_eq!(std::fs::read(spec).unwrap(), before);
    }
    // A database that is not there is refused before listening.
    let d = tempfile::tempdir().unwrap();
    let (code, _, err) = accelcal(&["serve", "--db", d.path().join("none.sqlite").to_str().unwrap()]);
    assert_eq!(code, Some(2), "{err}");
}

/// The pages as a reader sees them, in headless Chromium's screenshots (the README's pictures
/// are copies of these, from `target/tmp/serve-screenshots/`): the line of units and the 70
/// units of a head knocked out of true.
pub fn the_pages_render_to_screenshots(spec: &str) {
    let mut db = Db::open(spec).unwrap();
    line_of_units(&mut db);
    head_knocked_out(&mut db);
    drop(db);
    let server = serve(spec);
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("serve-screenshots");
    std::fs::create_dir_all(&dir).unwrap();
    for (name, path, height) in [
        ("overview", "/".to_string(), 1000),
        ("fleet", format!("/fleet?{JANUARY}"), 1500),
        ("charts", format!("/charts?{JANUARY}&head_asset=HEAD-2"), 1400),
        ("unit", "/unit/SN-B1".to_string(), 800),
    ] {
        let png = dir.join(format!("{name}.png"));
        let _ = std::fs::remove_file(&png);
        let profile = tempfile::tempdir().unwrap();
        let out = Command::new("chromium")
            .args(["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run"])
            .args(["--disable-background-networking", "--disable-component-update", "--disable-sync"])
            .arg(format!("--user-data-dir={}", profile.path().display()))
            .arg(format!("--window-size=1280,{height}"))
            .arg(format!("--screenshot={}", png.display()))
            .arg(format!("{}{path}", server.base))
            .output()
            .expect("chromium is installed (bash scripts/setup-chromium.sh)");
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        let bytes = std::fs::read(&png).unwrap();
        assert!(bytes.starts_with(b"\x89PNG") && bytes.len() > 20_000, "{name}: {} bytes", bytes.len());
        // What the screenshot shows, read from the same page's DOM: its numbers and a chart.
        let page = dom(&format!("{}{path}", server.base));
        let holds = match name {
            "overview" => vec!["<strong>asset overdue</strong>", "DKD-17-001", "<td class=\"num\">"],
            "fleet" => {
                vec!["<table id=\"populations\">", "<td>as-left bias x</td><td>mg</td>", "first-pass yield "]
            }
            "charts" => vec!["head HEAD-2: 70 units", "<svg", "<rect", "<circle", "violations (about "],
            _ => vec!["<h1>SN-B1</h1>", "rejected: selection beyond model 4", "awaiting approval</a>"],
        };
        for h in holds {
            assert!(page.contains(h), "{name}: no {h} in {page}");
        }
        if name == "charts" {
            assert!(tick_labels(&page).iter().all(|[y, x]| distinct(y) && distinct(x)), "{name}");
        }
    }
}

/// Issue 59: the search box over plain HTTP. A serial, a certificate number, a run id or its first
/// 8 hex digits answer 303 to the unit's page (at the run's row); a beginning of several run ids
/// lists them; a miss is 404 in words. A unit is titled by its serial, else by its device id;
/// a certificate is found by its number, a run by its id.
pub fn search_finds_a_unit_and_says_what_it_missed(spec: &str) {
    let mut db = Db::open(spec).unwrap();
    let line = line_of_units(&mut db);
    let number = db.number_in_force(line.a).unwrap().unwrap();
    // Two runs whose ids begin alike, of a unit without a serial.
    let twins = ["abcdef01-0000-4000-8000-000000000001", "abcdef01-0000-4000-8000-000000000002"];
    let bare = "0a0b0c0d0e0f101112131415";
    for (i, id) in twins.iter().enumerate() {
        let s = super::start(accelcal_db::RunId::parse(id).unwrap(), bare, "", "st-1", T0 + i as i64 * DAY);
        db.begin_run(&s, None).unwrap();
    }
    // A serial written like a certificate number.
    let s = super::start(accelcal_db::RunId::new(), "1f1e1d1c1b1a191817161514", "2027-000001", "st-2", T0);
    db.begin_run(&s, None).unwrap();
    drop(db);
    let server = serve(spec);
    let location = |q: &str| {
        let (status, head, body) = request(&server.base, "GET", &format!("/search?q={q}"));
        assert_eq!(status, 303, "{q}: {head}{body}");
        let at = head.to_ascii_lowercase().find("\r\nlocation: ").unwrap() + 12;
        head[at..].lines().next().unwrap().to_string()
    };
    let a_row = format!("/unit/{}#run-{}", super::DEVICE, line.a);
    assert_eq!(location("SN-A1"), "/unit/SN-A1");
    assert_eq!(location("%20SN-A1%20"), "/unit/SN-A1");
    assert_eq!(location(&number), a_row);
    assert_eq!(location(&line.a.to_string()), a_row);
    assert_eq!(location(&line.a.to_string()[..8]), a_row);
    assert_eq!(location(super::DEVICE), format!("/unit/{}", super::DEVICE));
    assert_eq!(location("2027-000001"), "/unit/2027-000001");
    let (status, head, _) = request(&server.base, "GET", &format!("/run/{}", line.a));
    assert_eq!(status, 303, "{head}");
    assert!(head.contains(&a_row), "{head}");
    // A beginning of two run ids: both listed, each a link to its row.
    let (status, _, body) = request(&server.base, "GET", "/search?q=abcdef01");
    assert_eq!(status, 200, "{body}");
    assert!(body.contains("abcdef01 begins several run ids: which one?"), "{body}");
    for id in twins {
        assert!(
            body.contains(&format!("<a href=\"/unit/{bare}#run-{id}\">run {id}: unit - ({bare})")),
            "{body}"
        );
    }
    // Misses, in words.
    for (q, words) in [
        ("NOBODY", "nothing found for `NOBODY`: it is no serial, device id, certificate number or run id"),
        ("2026-999999", "no certificate is numbered 2026-999999 in the database, and no unit has the serial"),
        ("ffffffff", "nothing found for `ffffffff`"),
        (
            "ffffffff-0000-4000-8000-000000000000",
            "no run ffffffff-0000-4000-8000-000000000000 in the database",
        ),
    ] {
        let (status, _, body) = request(&server.base, "GET", &format!("/search?q={q}"));
        assert_eq!(status, 404, "{q}: {body}");
        assert!(body.contains(words), "{q}: {body}");
    }
    let (status, _, body) = request(&server.base, "GET", "/search?q=");
    assert_eq!(status, 400, "{body}");
    // Titles: the serial, the device id below; a unit without a serial is titled by its device id.
    let (_, _, body) = request(&server.base, "GET", "/unit/SN-A1");
    assert!(body.contains("<title>SN-A1 · accelcal</title>") && body.contains("<h1>SN-A1</h1>"), "{body}");
    assert!(body.contains(&format!("<p id=\"device\">device id {}</p>", super::DEVICE)), "{body}");
    assert!(
        body.contains(&format!("<a href=\"/certificate/{number}\">{number} awaiting approval</a>")),
        "{body}"
    );
    let (_, _, body) = request(&server.base, "GET", &format!("/unit/{bare}"));
    assert!(body.contains(&format!("<h1>{bare}</h1>")) && body.contains("no serial number"), "{body}");
    // A certificate by its number; run ids and certificate numbers link in the fleet's table.
    let (status, _, body) = request(&server.base, "GET", &format!("/certificate/{number}"));
    assert_eq!(status, 200, "{body}");
    assert!(body.contains("certificate of SN-A1"), "{body}");
    assert_eq!(request(&server.base, "GET", "/certificate/2026-999999").0, 404);
    assert_eq!(request(&server.base, "GET", "/certificate/not-one").0, 400);
    let (_, _, fleet) = request(&server.base, "GET", &format!("/fleet?{JANUARY}"));
    assert!(
        fleet.contains(&format!(
            "<a href=\"/run/{}\" title=\"{}\">{}</a>",
            line.a,
            line.a,
            &line.a.to_string()[..8]
        )),
        "{fleet}"
    );
    assert!(fleet.contains(&format!("<a href=\"/certificate/{number}\">{number}</a>")), "{fleet}");
}

/// `serve` keeps its reading connections in a pool of at most `CONNECTIONS` (4): after 24 page
/// loads, 8 of them at once, the server holds between 1 and 4 connections, and one that served
/// the first page is still among them (a connection per request would hold none between pages).
/// `pids` lists the database's other sessions (PostgreSQL's backends but the caller's own).
pub fn connections_are_pooled_and_bounded(spec: &str, pids: impl Fn() -> Vec<i32>) {
    let mut db = Db::open(spec).unwrap();
    line_of_units(&mut db);
    drop(db);
    let server = serve(spec);
    assert_eq!(request(&server.base, "GET", "/unit/SN-A1").0, 200);
    let first = pids();
    assert!((1..=4).contains(&first.len()), "{first:?}");
    for _ in 0..3 {
        let loads: Vec<_> = (0..8)
            .map(|_| {
                let base = server.base.clone();
                std::thread::spawn(move || request(&base, "GET", "/unit/SN-A1").0)
            })
            .collect();
        for l in loads {
            assert_eq!(l.join().unwrap(), 200);
        }
    }
    let after = pids();
    assert!((1..=4).contains(&after.len()), "{after:?}");
    assert!(first.iter().any(|p| after.contains(p)), "{first:?} then {after:?}");
}

/// The body of `serve`'s page `path` on the database `spec`.
pub fn page(spec: &str, path: &str) -> String {
    let server = serve(spec);
    let (status, _, body) = request(&server.base, "GET", path);
    assert_eq!(status, 200, "{path}: {body}");
    body
}

/// Issue 55: 1,100 idle connections (never a byte sent) do not stop a `GET /` from answering
/// within a second under `ulimit -n 1024`: the connections are capped (256 by default) and a new
/// one takes the place of the oldest idle one, so the server's `accept` never runs out of
/// descriptors; the idle ones are closed by the header timeout.
pub fn idle_connections_do_not_stop_a_page(spec: &str) {
    line_db(spec);
    // This test holds the 1,100 connections: its own limit must allow them.
    let mut lim = libc::rlimit { rlim_cur: 0, rlim_max: 0 };
    // SAFETY: getrlimit/setrlimit read and write the struct they are given.
    unsafe {
        assert_eq!(libc::getrlimit(libc::RLIMIT_NOFILE, &mut lim), 0);
        if lim.rlim_cur < 4096 {
            lim.rlim_cur = lim.rlim_max.min(4096);
            assert_eq!(libc::setrlimit(libc::RLIMIT_NOFILE, &lim), 0);
        }
    }
    assert!(lim.rlim_cur >= 1_200, "the test needs 1,200 open files, the hard limit is {}", lim.rlim_max);
    let server = serve_with(spec, &["--header-timeout-s", "5"]);
    let host = server.base.trim_start_matches("http://").to_string();
    let idle: Vec<TcpStream> = (0..1_100).map(|_| TcpStream::connect(&host).unwrap()).collect();
    let t = std::time::Instant::now();
    let mut s = TcpStream::connect(&host).unwrap();
    s.set_read_timeout(Some(std::time::Duration::from_secs(1))).unwrap();
    write!(s, "GET / HTTP/1.1\r\nHost: {host}\r\nConnection: close\r\n\r\n").unwrap();
    let mut head = [0u8; 15];
    s.read_exact(&mut head).expect("an answer within a second");
    assert!(t.elapsed() < std::time::Duration::from_secs(1), "{:?}", t.elapsed());
    assert_eq!(&head, b"HTTP/1.1 200 OK", "{}", String::from_utf8_lossy(&head));
    // Most of the idle connections were closed to make room: a read finds their end at once.
    let closed = idle
        .iter()
        .take(100)
        .filter(|c| {
            c.set_read_timeout(Some(std::time::Duration::from_millis(200))).unwrap();
            matches!((&**c).read(&mut [0u8; 8]), Ok(0))
        })
        .count();
    assert_eq!(closed, 100, "the oldest idle connections are closed");
    drop(idle);
    let (code, err) = server.stop(libc::SIGINT);
    assert_eq!(code, Some(0), "{err}");
}

/// Ctrl-C (SIGINT) and SIGTERM stop the server with exit code 0 and no panic, with a page served
/// and a keep-alive connection open at the time (issue 55: the synchronous PostgreSQL client
/// panicked "Cannot start a runtime from within a runtime" as the pool closed).
pub fn a_signal_stops_the_server_cleanly(spec: &str) {
    line_db(spec);
    for signal in [libc::SIGINT, libc::SIGTERM] {
        let server = serve(spec);
        for path in ["/", "/unit/SN-A1", &format!("/fleet?{JANUARY}")] {
            assert_eq!(request(&server.base, "GET", path).0, 200, "{path}");
        }
        let host = server.base.trim_start_matches("http://").to_string();
        let mut open = TcpStream::connect(&host).unwrap();
        write!(open, "GET /unit/SN-A1 HTTP/1.1\r\nHost: {host}\r\n\r\n").unwrap();
        std::thread::sleep(std::time::Duration::from_millis(300));
        let (code, err) = server.stop(signal);
        assert_eq!(code, Some(0), "signal {signal}: {err}");
        assert!(!err.contains("panicked"), "signal {signal}: {err}");
    }
}

/// A bind beyond loopback needs `--users`; with it, every request needs the password (401
/// without it or with a wrong one, with `WWW-Authenticate: Basic realm="accelcal"`), 200 with it.
pub fn a_bind_beyond_loopback_needs_a_password(spec: &str) {
    line_db(spec);
    for bind in ["0.0.0.0:0", "[::]:0", "192.0.2.7:0"] {
        let (code, out, err) = accelcal(&["serve", "--db", spec, "--bind", bind]);
        assert_eq!(code, Some(2), "{bind}: {out}{err}");
        assert!(err.starts_with("error: --bind ") && err.contains("--users FILE"), "{err}");
        assert_eq!(err.lines().count(), 1, "{err}");
    }
    let d = tempfile::tempdir().unwrap();
    let (users, pw) = (d.path().join("users"), d.path().join("pw"));
    let (users_s, pw_s) = (users.to_str().unwrap(), pw.to_str().unwrap());
    // A password file that is not there, or whose first line is empty, is said plainly.
    let (code, _, err) = accelcal(&["serve-user", "add", "anna", "--file", users_s, "--password-file", pw_s]);
    assert_eq!(code, Some(1), "{err}");
    assert!(err.starts_with("error: reading the password file ") && err.contains("pw"), "{err}");
    std::fs::write(&pw, "\nsecond line\n").unwrap();
    let (code, _, err) = accelcal(&["serve-user", "add", "anna", "--file", users_s, "--password-file", pw_s]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("its first line is empty"), "{err}");
    // Names that are not plain text are refused before anything is read.
    for name in ["a:b", "a\u{1b}[2J", "a\u{200b}b", ""] {
        let (code, _, err) =
            accelcal(&["serve-user", "add", name, "--file", users_s, "--password-file", pw_s]);
        assert_eq!(code, Some(2), "{name:?}: {err}");
        assert_eq!(err.lines().count(), 1, "{err}");
    }
    assert!(!users.exists());
    std::fs::write(&pw, "correct horse\n").unwrap();
    let (code, out, err) =
        accelcal(&["serve-user", "add", "anna", "--file", users_s, "--password-file", pw_s]);
    assert_eq!(code, Some(0), "{err}");
    assert!(out.contains("anna added (1 users)"), "{out}");
    let text = std::fs::read_to_string(&users).unwrap();
    assert!(text.starts_with("anna:$argon2id$v=19$m=19456,t=2,p=1$") && text.lines().count() == 1, "{text}");
    use std::os::unix::fs::PermissionsExt;
    assert_eq!(std::fs::metadata(&users).unwrap().permissions().mode() & 0o777, 0o600);
    let server = serve_with(spec, &["--bind", "0.0.0.0:0", "--users", users_s]);
    use base64::Engine as _;
    let basic =
        |u: &str| format!("Authorization: Basic {}\r\n", base64::engine::general_purpose::STANDARD.encode(u));
    for (headers, want) in [
        (String::new(), 401),
        (basic("anna:wrong horse"), 401),
        (basic("bob:correct horse"), 401),
        (basic("anna:correct horse"), 200),
    ] {
        for path in ["/", "/unit/SN-A1", "/nothing-here"] {
            let (status, head, _) = request_with(&server.base, "GET", path, &headers);
            let want = if want == 200 && path == "/nothing-here" { 404 } else { want };
            assert_eq!(status, want, "{path} {headers}: {head}");
            if want == 401 {
                assert!(head.contains("www-authenticate: Basic realm=\"accelcal\""), "{head}");
            }
        }
    }
    // A second user, and a new password for the first: the old one no longer opens the view.
    std::fs::write(&pw, "battery staple\n").unwrap();
    let (code, out, err) =
        accelcal(&["serve-user", "add", "anna", "--file", users_s, "--password-file", pw_s]);
    assert_eq!(code, Some(0), "{err}");
    assert!(out.contains("anna password changed (1 users)"), "{out}");
    drop(server);
    let server = serve_with(spec, &["--bind", "0.0.0.0:0", "--users", users_s]);
    assert_eq!(request_with(&server.base, "GET", "/", &basic("anna:correct horse")).0, 401);
    assert_eq!(request_with(&server.base, "GET", "/", &basic("anna:battery staple")).0, 200);
    // A users file that is not one is refused at the start, naming its line.
    std::fs::write(&users, "anna:not a hash\n").unwrap();
    let (code, _, err) = accelcal(&["serve", "--db", spec, "--bind", "127.0.0.1:0", "--users", users_s]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("users:1: the hash of anna"), "{err}");
}

/// Dates beyond what the view can count are a 400 naming the field; control characters of the
/// URL are shown as `\u{…}` text, never written raw.
pub fn hostile_urls_are_answered_in_words(spec: &str) {
    line_db(spec);
    let server = serve(spec);
    for (path, field) in [
        ("/fleet?until=9999-12-31", "until: 9999-12-31 is too late"),
        ("/charts?since=2026-01-01&until=9999-12-31", "until: 9999-12-31 is too late"),
        ("/fleet.csv?until=9999-12-31", "until: 9999-12-31 is too late"),
        ("/fleet?since=9999-12-31", "since 9999-12-31 is after until"),
    ] {
        let (status, _, body) = request(&server.base, "GET", path);
        assert_eq!(status, 400, "{path}: {body}");
        assert!(body.contains(field), "{path}: {body}");
    }
    for (path, shown) in [("/unit/%00", "no unit `\\u{0}`"), ("/unit/%1b[2J", "no unit `\\u{1b}[2J`")] {
        let (status, _, body) = request(&server.base, "GET", path);
        assert_eq!(status, 404, "{path}: {body}");
        assert!(
            !body.chars().any(|c| c.is_control() && !matches!(c, '\n' | '\t' | '\r')),
            "{path}: {body:?}"
        );
        assert!(body.contains(shown), "{path}: {body}");
    }
}

/// A query that fails in the engine is 503 (the database's failure), not 404; a unit that is not
/// there stays 404. `break_it` renames the table `run` behind the server's back.
pub fn a_database_failure_is_503(spec: &str, break_it: impl FnOnce()) {
    line_db(spec);
    let server = serve(spec);
    assert_eq!(request(&server.base, "GET", "/unit/SN-A1").0, 200);
    let (status, _, body) = request(&server.base, "GET", "/unit/NOBODY");
    assert_eq!(status, 404, "{body}");
    break_it();
    let (status, _, body) = request(&server.base, "GET", "/unit/SN-A1");
    assert_eq!(status, 503, "{body}");
    assert!(body.contains("the database failed: "), "{body}");
    assert_eq!(request(&server.base, "GET", "/").0, 503);
}

/// A SQLite file removed while the server runs is 503 until a database is there again, then
/// its data is served (not the removed file's, which the pooled connections still held open).
pub fn a_database_file_replaced_is_read_anew(spec: &str) {
    line_db(spec);
    let server = serve(spec);
    assert_eq!(request(&server.base, "GET", "/unit/SN-A1").0, 200);
    assert_eq!(request(&server.base, "GET", "/unit/SN-NEW").0, 404);
    let path = std::path::Path::new(spec);
    for f in [spec.to_string(), format!("{spec}-wal"), format!("{spec}-shm")] {
        let _ = std::fs::remove_file(f);
    }
    let (status, _, body) = request(&server.base, "GET", "/unit/SN-A1");
    assert_eq!(status, 503, "{body}");
    assert!(body.contains("the database file is not there"), "{body}");
    assert_eq!(request(&server.base, "GET", "/").0, 503);
    // Another database, written beside it and moved into its place.
    let other = path.with_file_name("other.sqlite");
    let mut db = Db::open(other.to_str().unwrap()).unwrap();
    let s = super::start(accelcal_db::RunId::new(), super::DEVICE_2, "SN-NEW", "st-9", T0);
    super::calibrate(&mut db, &s, &super::coefs(0.0, 0), None);
    drop(db);
    std::fs::rename(&other, path).unwrap();
    let (status, _, body) = request(&server.base, "GET", "/unit/SN-NEW");
    assert_eq!(status, 200, "{body}");
    let (status, _, body) = request(&server.base, "GET", "/unit/SN-A1");
    assert_eq!(status, 404, "{body}");
}

/// Starts `serve` on `spec`, asks for each of `paths` and stops it: each one's status and body.
pub fn statuses(spec: &str, paths: &[&str]) -> Vec<(u16, String)> {
    let s = serve(spec);
    paths.iter().map(|p| request(&s.base, "GET", p)).map(|(code, _, body)| (code, body)).collect()
}
