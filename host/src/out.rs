//! The binary's writes to standard output and standard error, which never panic (`println!` and
//! `eprintln!` do when the stream fails: a full disk, a closed descriptor).
//!
//! - [`outln!`] and [`out!`] write to standard output and return an `anyhow::Result` with the
//!   context "writing to standard output": a command's output that cannot be written fails the
//!   command (`?`), with the environment's exit code (1).
//! - [`errln!`] and [`err!`] write the diagnostics (progress, warnings, notes, prompts) to standard
//!   error and return nothing: a failed write is remembered ([`stderr_failed`]) and `main` ends
//!   with exit code 1 after the command has finished. A diagnostic that cannot be written never
//!   stops a command half-way: a run begun in the database (`fit --db`, `station`) goes on to
//!   store its pieces, instead of being left begun with none because a progress line could not be
//!   written.

use std::io::Write;
use std::sync::Mutex;

/// The first failed write to standard error, if any.
static STDERR_FAILURE: Mutex<Option<String>> = Mutex::new(None);

/// Writes `args` to standard output (flushed when it ends a line, as `println!` does).
pub fn stdout(args: std::fmt::Arguments) -> anyhow::Result<()> {
    use anyhow::Context;
    let mut o = std::io::stdout().lock();
    o.write_fmt(args).context("writing to standard output")
}

/// Writes `args` to standard error; a failure is remembered, not returned.
pub fn stderr(args: std::fmt::Arguments) {
    if let Err(e) = std::io::stderr().lock().write_fmt(args) {
        let mut first = STDERR_FAILURE.lock().unwrap_or_else(|p| p.into_inner());
        first.get_or_insert_with(|| e.to_string());
    }
}

/// The first failed write to standard error, as its error's words.
pub fn stderr_failed() -> Option<String> {
    STDERR_FAILURE.lock().unwrap_or_else(|p| p.into_inner()).clone()
}

/// `println!` to standard output, returning `anyhow::Result<()>`.
macro_rules! outln {
    () => {
        $crate::out::stdout(format_args!("\n"))
    };
    ($($arg:tt)*) => {
        $crate::out::stdout(format_args!("{}\n", format_args!($($arg)*)))
    };
}

/// `print!` to standard output, returning `anyhow::Result<()>`.
macro_rules! out {
    ($($arg:tt)*) => {
        $crate::out::stdout(format_args!($($arg)*))
    };
}

/// `eprintln!` that does not panic: see [`stderr`].
macro_rules! errln {
    () => {
        $crate::out::stderr(format_args!("\n"))
    };
    ($($arg:tt)*) => {
        $crate::out::stderr(format_args!("{}\n", format_args!($($arg)*)))
    };
}

/// `eprint!` that does not panic: see [`stderr`].
macro_rules! err {
    ($($arg:tt)*) => {
        $crate::out::stderr(format_args!($($arg)*))
    };
}

/// `n` of `noun` in words, the noun's plural with an `s` unless `n` is 1: `1 run`, `3 units`.
pub fn count(n: impl std::fmt::Display, noun: &str) -> String {
    match n.to_string() {
        one if one == "1" => format!("1 {noun}"),
        n => format!("{n} {noun}s"),
    }
}

#[cfg(test)]
mod tests {
    /// No code of the binary (outside `serve`, whose output is its own) writes with the std macros
    /// that panic on a failed write.
    #[test]
    fn the_binary_prints_only_through_this_module() {
        let mut found = Vec::new();
        for (path, text) in crate::sources::library_sources(&["host"]) {
            if path.components().any(|c| c.as_os_str() == "serve") {
                continue;
            }
            for (n, t) in crate::sources::code_lines(&text) {
                for m in ["println!(", "print!(", "eprintln!(", "eprint!("] {
                    let hit = t
                        .match_indices(m)
                        .any(|(at, _)| !t[..at].ends_with(|c: char| c.is_alphanumeric() || c == '_'));
                    if hit {
                        found.push(format!("{}:{n}: {t}", path.display()));
                    }
                }
            }
        }
        assert!(found.is_empty(), "write with crate::out's macros:\n{}", found.join("\n"));
    }

    #[test]
    fn one_is_singular() {
        assert_eq!(super::count(1usize, "run"), "1 run");
        assert_eq!(super::count(0i64, "unit"), "0 units");
        assert_eq!(super::count(3u32, "unit"), "3 units");
    }
}
