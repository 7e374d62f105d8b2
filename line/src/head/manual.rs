//! `--head manual`: an operator turns the head by hand. Each position is shown ("position k of
//! N", the angles and what the unit should then read), and the operator confirms with Enter.

use std::io::{BufRead, Write};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{mpsc, Arc};
use std::time::Duration;

use accelcal_core::error::bad;

use super::{Angles, Positioner, Target};

/// The operator at a manual head. Standard input is read by a thread, so that a Ctrl-C at a
/// prompt stops the command at once (a read of a terminal is restarted after the signal, and
/// would wait for Enter).
pub struct ManualHead {
    /// The operator's lines; `None` once standard input is closed.
    lines: mpsc::Receiver<Option<String>>,
    stop: Arc<AtomicBool>,
    /// Where the prompts go (the terminal's stderr).
    prompt: Box<dyn Write + Send>,
    /// The angles last confirmed.
    at: Angles,
}

impl ManualHead {
    /// An operator answering on standard input, prompted on `prompt`.
    pub fn new(stop: Arc<AtomicBool>, prompt: Box<dyn Write + Send>) -> ManualHead {
        let (tx, lines) = mpsc::channel();
        std::thread::spawn(move || loop {
            let mut line = String::new();
            let got = match std::io::stdin().lock().read_line(&mut line) {
                Ok(0) | Err(_) => None,
                Ok(_) => Some(line),
            };
            let end = got.is_none();
            if tx.send(got).is_err() || end {
                break;
            }
        });
        ManualHead { lines, stop, prompt, at: Angles { alpha_deg: 0.0, beta_deg: 0.0 } }
    }

    fn ask(&mut self, text: &str) -> anyhow::Result<()> {
        self.prompt.write_all(text.as_bytes())?;
        self.prompt.flush()?;
        Ok(())
    }

    /// The operator's next line; `None` when a stop was requested meanwhile.
    fn read_line(&mut self) -> anyhow::Result<Option<String>> {
        loop {
            if self.stop.load(Ordering::Relaxed) {
                return Ok(None);
            }
            match self.lines.recv_timeout(Duration::from_millis(100)) {
                Ok(Some(line)) => return Ok(Some(line)),
                Err(mpsc::RecvTimeoutError::Timeout) => {}
                Ok(None) | Err(mpsc::RecvTimeoutError::Disconnected) => return Err(bad(
                    "standard input closed while waiting for the operator (--head manual needs a terminal)",
                )),
            }
        }
    }
}

impl Positioner for ManualHead {
    fn describe(&self) -> String {
        "manual".into()
    }

    fn set(&mut self, t: &Target) -> anyhow::Result<Angles> {
        let e = t.expected_m_s2;
        self.ask(&format!(
            "position {} of {}: set the head to alpha {} deg, beta {} deg; the unit should then read \
             ax {:+.3}, ay {:+.3}, az {:+.3} m/s². Press Enter when it stands there. ",
            t.k + 1,
            t.n,
            t.angles.alpha_deg,
            t.angles.beta_deg,
            e[0],
            e[1],
            e[2]
        ))?;
        self.read_line()?;
        // The operator's word is the read-back.
        self.at = t.angles;
        Ok(self.at)
    }

    fn read_back(&mut self) -> anyhow::Result<Angles> {
        Ok(self.at)
    }

    fn retry(&mut self, k: usize, why: &str) -> anyhow::Result<bool> {
        let stop = if why.ends_with(['?', '.']) { "" } else { "." };
        self.ask(&format!("position {} refused: {why}{stop} Retry it? [Y/n] ", k + 1))?;
        // Stopped: "retry", and the caller sees its stop flag.
        Ok(self.read_line()?.is_none_or(|l| !l.trim().eq_ignore_ascii_case("n")))
    }

    fn chamber(&mut self, setpoint_c: f64) -> anyhow::Result<()> {
        self.ask(&format!(
            "set the thermal chamber to {setpoint_c} °C; press Enter when it is set (the soak time starts then). "
        ))?;
        self.read_line().map(|_| ())
    }
}
