//! The documentation against the binary: every `$ accelcal` example of `README.md` and of the
//! guide (`docs/src/**/*.md`, an mdBook) prints what its page shows, the demo's tables and a
//! diagnosis report are the guide's (and `insta` snapshots under `tests/snapshots/`), and the
//! command reference (`docs/src/reference/commands.md`) is what the binary's help prints.

#[path = "../xtask/src/commands_md.rs"]
mod commands_md;
use crate::common;

use std::path::{Path, PathBuf};
use std::process::Command;

use common::ok;

/// The repository root.
fn root() -> &'static Path {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/.."))
}

/// `path` as the repository names it (`docs/src/diagnosis.md`).
fn shown(path: &Path) -> String {
    path.strip_prefix(root()).unwrap_or(path).display().to_string()
}

/// The pages whose examples are run: `README.md`, then every markdown file under `docs/src`,
/// in path order. Fails when a directory of the guide cannot be listed.
fn pages() -> Vec<PathBuf> {
    let mut found = Vec::new();
    let mut todo = vec![root().join("docs/src")];
    while let Some(dir) = todo.pop() {
        let entries = std::fs::read_dir(&dir).unwrap_or_else(|e| panic!("cannot list {}: {e}", shown(&dir)));
        for e in entries {
            let path = e.unwrap_or_else(|e| panic!("cannot list {}: {e}", shown(&dir))).path();
            if path.is_dir() {
                todo.push(path);
            } else if path.extension().is_some_and(|x| x == "md") {
                found.push(path);
            }
        }
    }
    found.sort();
    assert!(found.len() >= 20, "the guide has {} pages: {found:?}", found.len());
    std::iter::once(root().join("README.md")).chain(found).collect()
}

/// A page's text; fails, naming the file, when it cannot be read (or is not UTF-8).
fn doc(path: &Path) -> String {
    std::fs::read_to_string(path).unwrap_or_else(|e| panic!("cannot read {}: {e}", shown(path)))
}

/// The one page that holds the line `line` (a heading or a line of an example), and its text.
fn page_with(line: &str) -> (PathBuf, String) {
    let mut hits: Vec<(PathBuf, String)> = pages()
        .into_iter()
        .map(|p| {
            let text = doc(&p);
            (p, text)
        })
        .filter(|(_, t)| t.lines().any(|l| l == line))
        .collect();
    let names: Vec<String> = hits.iter().map(|(p, _)| shown(p)).collect();
    assert_eq!(hits.len(), 1, "the line `{line}` must be on one page of the docs, it is on {names:?}");
    hits.pop().unwrap()
}

/// The lines of the first fenced block after the line `after` (a heading or a line inside a
/// block), wherever in the docs it is, up to its closing fence, each ending in a newline.
fn doc_block(after: &str) -> String {
    let (page, text) = page_with(after);
    let mut lines = text.lines().skip_while(|l| *l != after);
    lines.next();
    let inside_a_block = !after.starts_with('#');
    if !inside_a_block {
        lines.find(|l| l.starts_with("```")).expect("a fenced block after the heading");
    }
    let block: String = lines.take_while(|l| !l.starts_with("```")).map(|l| format!("{l}\n")).collect();
    assert!(!block.is_empty(), "{}: empty block after `{after}`", shown(&page));
    block
}

/// A session of the docs: the `$ accelcal ...` lines of the block that holds `last` (the last
/// command, whose output the block shows after it), run in order in a fresh directory; returns
/// (the page's output of the last command, the binary's).
fn doc_session(last: &str) -> (String, String) {
    let (page, text) = page_with(last);
    let lines: Vec<&str> = text.lines().collect();
    let at = lines.iter().position(|l| *l == last).unwrap();
    let start = lines[..at].iter().rposition(|l| l.starts_with("```")).unwrap() + 1;
    let d = tempfile::tempdir().unwrap();
    let mut stdout = String::new();
    for cmd in &lines[start..=at] {
        let Some(cmd) = cmd.strip_prefix("$ accelcal ") else { continue };
        let args: Vec<&str> = cmd.split_whitespace().collect();
        let out =
            Command::new(env!("CARGO_BIN_EXE_accelcal")).args(&args).current_dir(d.path()).output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{}: {cmd}: {err}", shown(&page));
        stdout = String::from_utf8(out.stdout).unwrap();
    }
    (doc_block(last), stdout)
}

/// `accelcal demo --out DIR` with DIR a temporary directory, its stdout with DIR written as the
/// guide writes it (`accelcal-demo`, the default).
fn demo_stdout() -> String {
    let d = tempfile::tempdir().unwrap();
    let out_dir = d.path().join("accelcal-demo");
    let out = ok(&["demo", "--out", out_dir.to_str().unwrap()]);
    let dir = d.path().to_str().unwrap();
    assert!(out.contains(dir), "the output names the directory: {out}");
    out.replace(&format!("{dir}/"), "")
}

#[test]
fn demo_tables_are_the_guide_s() {
    let out = demo_stdout();
    // Table 1 for the three channels, the coefficient table, Table 2.
    for want in [
        "channel x: regularity",
        "channel y: regularity",
        "channel z: regularity",
        "Model 4 coefficients",
        "Table 2.",
    ] {
        assert_eq!(out.matches(want).count(), 1, "{want}: {out}");
    }
    insta::assert_snapshot!("demo_stdout", out);
    // The guide shows the same run, digit for digit (docs/src/method/demo.md).
    assert_eq!(doc_block("# What the demo prints"), out, "the guide's demo output is stale");
}

/// A report with a known effect (the guide's diagnosis example: seed 42, settling).
const DIAGNOSE_EXAMPLE: &str = "$ accelcal diagnose c.csv --json d.json";

#[test]
fn diagnosis_report_is_the_guide_s() {
    let (shown, out) = doc_session(DIAGNOSE_EXAMPLE);
    assert!(out.contains("\n  -> settling\n"), "{out}");
    assert!(out.contains("effect settling on x,y,z"), "{out}");
    insta::assert_snapshot!("diagnose_settling_stdout", out);
    assert_eq!(shown, out, "the guide's diagnosis example is stale");
}

/// Examples whose inputs the docs do not make: files edited by hand, described in the text around
/// them, and the database `tests/db.rs` builds (`history`'s example). A command naming one of
/// them is not run.
const HAND_MADE: &[&str] = &["three-sat.csv", "half.csv", "cal.sqlite"];

/// Copies the directory `from` into `to`.
fn copy_dir(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for e in std::fs::read_dir(from).unwrap().flatten() {
        if e.path().is_dir() {
            copy_dir(&e.path(), &to.join(e.file_name()));
        } else {
            std::fs::copy(e.path(), to.join(e.file_name())).unwrap();
        }
    }
}

/// Runs the `$ accelcal` examples of one page in order, in a fresh directory that holds the
/// repository's test data at the docs' paths (an example may use the files an earlier one of the
/// same page wrote), and checks that each prints what the page shows. Returns how many ran.
fn check_page(page: &Path) -> usize {
    let d = tempfile::tempdir().unwrap();
    copy_dir(&root().join("tests/data"), &d.path().join("tests/data"));
    let text = doc(page);
    let lines: Vec<&str> = text.lines().collect();
    let mut checked = 0;
    for (i, line) in lines.iter().enumerate() {
        let Some(cmd) = line.strip_prefix("$ accelcal ") else { continue };
        if HAND_MADE.iter().any(|f| cmd.contains(f)) {
            continue;
        }
        let at = format!("{} line {}: {line}", shown(page), i + 1);
        // Through the shell, as a reader would type it (some examples pipe into `head`), with
        // this build's `accelcal` first on the PATH.
        let bin_dir = Path::new(env!("CARGO_BIN_EXE_accelcal")).parent().unwrap();
        let path = format!("{}:{}", bin_dir.display(), std::env::var("PATH").unwrap_or_default());
        let out = Command::new("bash")
            .arg("-c")
            .arg(format!("accelcal {cmd}"))
            .env("PATH", path)
            .current_dir(d.path())
            .output()
            .unwrap();
        let got = format!("{}{}", String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
        // What the page shows: the lines up to the next command or the end of the block; a line
        // `...` elides the middle of the output.
        let shown: Vec<&str> = lines[i + 1..]
            .iter()
            .take_while(|l| !l.starts_with("$ ") && !l.starts_with("```"))
            .copied()
            .collect();
        let got: Vec<&str> = got.lines().collect();
        match shown.iter().position(|l| l.trim() == "...") {
            None if shown.is_empty() => assert!(out.status.success(), "{at}: {got:?}"),
            None => assert_eq!(shown, got, "{at}"),
            Some(k) => {
                let tail = &shown[k + 1..];
                assert_eq!(shown[..k], got[..k.min(got.len())], "{at}");
                assert!(got.len() >= tail.len(), "{at}: {got:?}");
                assert_eq!(tail, &got[got.len() - tail.len()..], "{at}");
            }
        }
        checked += 1;
    }
    checked
}

#[test]
fn every_example_prints_what_its_page_shows() {
    let mut checked = Vec::new();
    for page in pages() {
        let n = check_page(&page);
        if n > 0 {
            checked.push((shown(&page), n));
        }
    }
    let total: usize = checked.iter().map(|c| c.1).sum();
    eprintln!("examples checked per page: {checked:?}");
    // The 34 the README held before the guide took them, the `bmi.csv` that `select`'s page makes
    // again, and the README's demo excerpt.
    assert!(total >= 36, "{total} examples checked: {checked:?}");
    assert!(checked.iter().any(|c| c.0 == "README.md"), "no example of the README checked: {checked:?}");
}

#[test]
fn the_command_reference_is_what_the_binary_prints() {
    let want =
        commands_md::commands_md(&mut |args: &[&str]| Ok::<_, std::convert::Infallible>(ok(args))).unwrap();
    let path = root().join(commands_md::PATH);
    let have = doc(&path);
    if have != want {
        let first = have
            .lines()
            .zip(want.lines())
            .position(|(a, b)| a != b)
            .unwrap_or(have.lines().count().min(want.lines().count()));
        panic!(
            "{} is not what the binary's help prints (first difference at line {}: `{}` against `{}`): run `cargo xtask docs`",
            commands_md::PATH,
            first + 1,
            have.lines().nth(first).unwrap_or("<end>"),
            want.lines().nth(first).unwrap_or("<end>"),
        );
    }
}
