//! An adapter for any other positioner (`exec:COMMAND`): a program this command starts speaks the
//! head protocol of [`super::protocol`] on its standard input and output, and [`LineHead`] drives
//! it as it drives the emulated head. What the adapter writes to its standard error reaches the
//! operator line by line, escaped and prefixed with `head adapter:`.
//!
//! The adapter runs in a process group of its own, so the operator's Ctrl-C reaches this command
//! alone: the command sends `STOP` and waits for the head to stand still, rather than the adapter
//! dying mid-move with the axes running. It ends when its standard input closes (it is killed
//! after [`super::link::EXEC_GRACE`] if it does not).

use std::io::{BufRead, BufReader, Read, Write};
use std::os::unix::process::CommandExt;
use std::process::{Command, Stdio};
use std::time::Duration;

use super::line_head::LineHead;
use super::link::Link;
use super::HeadError;
use accelcal_core::text::escape_peer;

/// The adapter's program and arguments, split as a POSIX shell would (quotes and backslashes; no
/// variables, globs or pipes: no shell runs).
pub fn words(command: &str) -> Result<Vec<String>, String> {
    match shlex::split(command) {
        Some(w) if !w.is_empty() && !w[0].is_empty() => Ok(w),
        Some(_) => Err("exec: needs a command, e.g. `exec:python3 adapter.py HOST:PORT`".into()),
        None => Err(format!(
            "exec:{}: unbalanced quotes or a trailing backslash",
            escape_peer(command.as_bytes())
        )),
    }
}

/// Starts the adapter `command` and greets it; its replies must come within `timeout`. Its
/// standard error goes to `operator`, line by line.
pub fn start(
    command: &str,
    timeout: Duration,
    operator: Box<dyn Write + Send>,
) -> Result<LineHead, HeadError> {
    let spec = format!("exec:{command}");
    let words = words(command).map_err(|message| HeadError::Protocol { addr: spec.clone(), message })?;
    let mut child = Command::new(&words[0])
        .args(&words[1..])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .process_group(0)
        .spawn()
        .map_err(|cause| HeadError::Io { addr: format!("{spec} (starting `{}`)", words[0]), cause })?;
    let forwarder =
        child.stderr.take().map(|err| std::thread::spawn(move || forward(BufReader::new(err), operator)));
    LineHead::greet(spec.clone(), Link::child(&spec, child, forwarder, timeout)?)
}

/// Copies the adapter's diagnostics to the operator, each line escaped (an adapter cannot send
/// escape sequences to the terminal) and cut at 1024 bytes.
fn forward(mut from: impl BufRead, mut to: Box<dyn Write + Send>) {
    let mut line = Vec::new();
    loop {
        line.clear();
        match from.by_ref().take(1024).read_until(b'\n', &mut line) {
            Ok(0) | Err(_) => return,
            Ok(_) => {
                let shown = format!("head adapter: {}\n", escape_peer(line.trim_ascii_end()));
                if to.write_all(shown.as_bytes()).and_then(|()| to.flush()).is_err() {
                    return;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_command_is_split_as_a_shell_would_without_one() {
        assert_eq!(words("python3 a.py 'h:1' \"x y\"").unwrap(), ["python3", "a.py", "h:1", "x y"]);
        assert!(words("").is_err() && words("  ").is_err() && words("''").is_err());
        assert!(words("python3 'open").unwrap_err().contains("unbalanced quotes"));
    }

    /// An adapter in a few lines of shell: it greets, homes, moves, and says something on its
    /// standard error with an escape sequence that reaches the operator escaped.
    #[test]
    fn an_adapter_is_driven_over_its_pipes_and_its_diagnostics_are_escaped() {
        use crate::head::{Positioner, Target};
        let script = r#"
            printf 'starting \033[2J\n' >&2
            while read -r req a b; do
              case "$req" in
                HELLO) echo "HELLO 2 shell head";;
                HOME) echo "OK 0 0";;
                MOVE) echo "OK $a $b";;
                WHERE) echo "AT 1 2 STILL";;
                *) echo "ERR no $req here";;
              esac
            done"#;
        let (tx, rx) = std::sync::mpsc::channel::<Vec<u8>>();
        struct Chan(std::sync::mpsc::Sender<Vec<u8>>);
        impl Write for Chan {
            fn write(&mut self, b: &[u8]) -> std::io::Result<usize> {
                let _ = self.0.send(b.to_vec());
                Ok(b.len())
            }
            fn flush(&mut self) -> std::io::Result<()> {
                Ok(())
            }
        }
        let command = format!("sh -c '{}'", script.replace('\'', r"'\''"));
        let mut head = start(&command, Duration::from_secs(5), Box::new(Chan(tx))).unwrap();
        assert_eq!(head.ident(), "shell head");
        head.home().unwrap();
        let t = Target { k: 0, n: 1, angles: (30.0, -60.0).into(), expected_m_s2: [0.0; 3] };
        let at = head.set(&t).unwrap();
        assert_eq!((at.alpha_deg, at.beta_deg), (30.0, -60.0));
        let e = head.chamber(20.0).unwrap_err().to_string();
        assert!(e.ends_with("refused: no CHAMBER here"), "{e}");
        drop(head);
        // Dropping the head waited for the adapter's last words.
        let said: Vec<u8> = rx.try_recv().unwrap();
        assert_eq!(String::from_utf8(said).unwrap(), "head adapter: starting \\x1b[2J\n");
    }

    #[test]
    fn a_missing_adapter_is_named() {
        let e = start("/nonexistent/adapter --x", Duration::from_secs(1), Box::new(std::io::sink()))
            .err()
            .unwrap()
            .to_string();
        assert!(
            e.starts_with("head exec:/nonexistent/adapter --x (starting `/nonexistent/adapter`):"),
            "{e}"
        );
    }
}
