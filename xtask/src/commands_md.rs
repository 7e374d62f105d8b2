//! The guide's command reference, `docs/src/reference/commands.md`: every command's help as the
//! `accelcal` binary prints it, one section per command (nested subcommands included). One
//! definition for both its users: `cargo xtask docs` writes the file from the built binary, and
//! `tests/docs.rs` (which includes this file) fails when the file is not what the binary under
//! test prints. Plain `std`, so that both crates can compile it.

/// The reference's path from the repository root.
pub const PATH: &str = "docs/src/reference/commands.md";

/// What the page says before the first command.
const HEADER: &str = "# Commands

Every command's options, as `accelcal help` and `accelcal COMMAND --help` print them. This page is
generated: `cargo xtask docs` writes it from the built binary, and `tests/docs.rs` fails when it
is not what the binary prints. How the commands are used: the chapters of this guide.
";

/// The reference's text. `help(args)` runs `accelcal ARGS` and returns its stdout. The commands
/// are read off the help texts themselves: `accelcal help`'s `Commands:` list, then each
/// command's `--help` and its own `Commands:` list, if any (`db` -> `db verify`).
pub fn commands_md<E>(help: &mut dyn FnMut(&[&str]) -> Result<String, E>) -> Result<String, E> {
    let mut out = String::from(HEADER);
    let top = help(&["help"])?;
    section(&mut out, &[], &top);
    for cmd in listed(&top) {
        walk(&[cmd], help, &mut out)?;
    }
    Ok(out)
}

/// The section of the command `path` and those of its subcommands, depth first.
fn walk<E>(
    path: &[String],
    help: &mut dyn FnMut(&[&str]) -> Result<String, E>,
    out: &mut String,
) -> Result<(), E> {
    let mut args: Vec<&str> = path.iter().map(String::as_str).collect();
    args.push("--help");
    let text = help(&args)?;
    section(out, path, &text);
    for sub in listed(&text) {
        let mut p = path.to_vec();
        p.push(sub);
        walk(&p, help, out)?;
    }
    Ok(())
}

/// `## accelcal PATH` and the help text in a fenced block.
fn section(out: &mut String, path: &[String], help: &str) {
    let name = std::iter::once("accelcal").chain(path.iter().map(String::as_str)).collect::<Vec<_>>();
    out.push_str(&format!("\n## {}\n\n```text\n{}\n```\n", name.join(" "), help.trim_end()));
}

/// The subcommands a help text lists under `Commands:` (`help` left out): the first word of each
/// entry line (indented two spaces; a wrapped description is indented further).
fn listed(help: &str) -> Vec<String> {
    help.lines()
        .skip_while(|l| *l != "Commands:")
        .skip(1)
        .take_while(|l| !l.trim().is_empty())
        .filter(|l| l.starts_with("  ") && !l[2..].starts_with(' '))
        .filter_map(|l| l.split_whitespace().next())
        .filter(|c| *c != "help")
        .map(str::to_string)
        .collect()
}
