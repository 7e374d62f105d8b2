//! The libraries' source files, for the tests that read them (`exit`'s registry of error types,
//! `words`' check that the core spells no flag, `out`'s that the binary prints only through it).

use std::path::PathBuf;

/// Every `.rs` file below `src/` of each crate in `crates` (`core`, `line`, `db`), with its text.
pub fn library_sources(crates: &[&str]) -> Vec<(PathBuf, String)> {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let mut stack: Vec<PathBuf> = crates.iter().map(|c| root.join("..").join(c).join("src")).collect();
    let mut out = Vec::new();
    while let Some(d) = stack.pop() {
        for entry in std::fs::read_dir(&d).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                stack.push(path);
            } else if path.extension().is_some_and(|x| x == "rs") {
                let text = std::fs::read_to_string(&path).unwrap();
                out.push((path, text));
            }
        }
    }
    out
}

/// The lines of code of a source file, numbered from 1 and trimmed at the start: before its unit
/// tests (which sit at the end, after `#[cfg(test)]`), comment lines left out.
pub fn code_lines(text: &str) -> impl Iterator<Item = (usize, &str)> {
    let code = text.split("#[cfg(test)]").next().unwrap_or_default();
    code.lines().enumerate().map(|(i, l)| (i + 1, l.trim_start())).filter(|(_, t)| !t.starts_with("//"))
}
