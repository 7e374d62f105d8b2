//! Ctrl-C and a head that is not turned: acquire ends with 130 and leaves a campaign that
//! resumes; a manual head that never moves is refused; a resumed campaign keeps its samples,
//! rate and g.

use super::*;

/// Issue 24: Ctrl-C ends `acquire` with 130 wherever it lands (the serial port's wait, a write, a
/// position being written). Before the fix about one delay in three ended with exit 1
/// "Interrupted system call" (the port's `ppoll` cut by the signal).
#[test]
fn ctrl_c_always_ends_acquire_with_130() {
    let _one = one_bench();
    let dir = tempfile::tempdir().unwrap();
    let (truth, _) = unit(dir.path(), "u", 8, 10);
    let em = Emulator::start(&truth, &[]);
    for (i, delay_ms) in [300u64, 700, 1100, 1500, 1900, 2300, 2700, 3100].into_iter().enumerate() {
        let c = dir.path().join(format!("c{i}.csv"));
        let mut child = spawn(&acquire_args(&em, "six", "300", &c, &[]));
        // The campaign file exists once the handler is installed and the node answered.
        let t0 = Instant::now();
        while !c.exists() {
            assert!(t0.elapsed() < Duration::from_secs(30), "no campaign file");
            std::thread::sleep(Duration::from_millis(10));
        }
        std::thread::sleep(Duration::from_millis(delay_ms));
        let (code, err) = stop_acquire(&mut child);
        assert_eq!(code, Some(130), "Ctrl-C after {delay_ms} ms: {err}");
        assert!(err.trim_end().ends_with("continue with --resume"), "{err}");
    }
}

/// An `acquire --head manual` run driven through its prompts: stderr read as it comes (prompts
/// end without a newline), answers written to stdin.
struct Operator {
    child: Child,
    stdin: std::process::ChildStdin,
    said: std::sync::mpsc::Receiver<String>,
    /// Everything the command wrote to stderr so far.
    err: String,
}

impl Operator {
    fn start(args: &[&str]) -> Operator {
        let mut child = Command::new(env!("CARGO_BIN_EXE_accelcal"))
            .args(args)
            .stdin(Stdio::piped())
            .stderr(Stdio::piped())
            .stdout(Stdio::null())
            .spawn()
            .unwrap();
        let stdin = child.stdin.take().unwrap();
        let mut stderr = child.stderr.take().unwrap();
        let (tx, said) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            let mut buf = [0u8; 4096];
            while let Ok(n @ 1..) = std::io::Read::read(&mut stderr, &mut buf) {
                if tx.send(String::from_utf8_lossy(&buf[..n]).into_owned()).is_err() {
                    break;
                }
            }
        });
        Operator { child, stdin, said, err: String::new() }
    }

    /// Waits until stderr holds `text` `count` times.
    fn wait_for(&mut self, text: &str, count: usize) {
        let t0 = Instant::now();
        while self.err.matches(text).count() < count {
            assert!(t0.elapsed() < Duration::from_secs(60), "waiting for `{text}` x{count}: {}", self.err);
            if let Ok(s) = self.said.recv_timeout(Duration::from_millis(100)) {
                self.err.push_str(&s);
            }
        }
    }

    fn answer(&mut self, line: &str) {
        use std::io::Write;
        writeln!(self.stdin, "{line}").unwrap();
        self.stdin.flush().unwrap();
    }

    /// Waits for the exit; its code and all of stderr.
    fn finish(mut self) -> (Option<i32>, String) {
        let st = self.child.wait().unwrap();
        while let Ok(s) = self.said.recv_timeout(Duration::from_millis(500)) {
            self.err.push_str(&s);
        }
        (st.code(), self.err)
    }
}

/// Issue 24: `acquire --head manual` with Enter pressed and the head never moved refuses the
/// second position (its reading did not move as the plan says), lets the operator retry, and
/// stops naming the position when the operator declines; resumed with the head turned, the
/// campaign completes and fits to a record a node accepts.
#[test]
fn a_manual_head_that_is_not_turned_is_refused() {
    let _one = one_bench();
    let dir = tempfile::tempdir().unwrap();
    let (truth, _) = unit(dir.path(), "u", 9, 10);
    let em = Emulator::start(&truth, &[]);
    let c = dir.path().join("manual.csv");
    let args = |extra: &[&'static str]| {
        let mut a: Vec<String> = ["acquire", "--port", &em.port, "--head", "manual", "--plan", "six"]
            .iter()
            .map(|s| s.to_string())
            .collect();
        a.extend(["--samples", "100", "--g", "9.81", "-o", s(&c)].map(String::from));
        a.extend(extra.iter().map(|s| s.to_string()));
        a
    };
    let prompt = |k: usize| format!("position {k} of 6: set the head to");
    let refused = "position 2 refused: the head did not move as the plan says: its mean codes moved";
    let a = args(&[]);
    let mut op = Operator::start(&a.iter().map(String::as_str).collect::<Vec<_>>());
    // The emulated head stands at position 1 (alpha 0, beta 0) and is never moved.
    op.wait_for(&prompt(1), 1);
    op.answer("");
    op.wait_for(&prompt(2), 1);
    op.answer("");
    op.wait_for(refused, 1);
    op.wait_for("Retry it? [Y/n]", 1);
    op.answer("");
    op.wait_for(&prompt(2), 2);
    op.answer("");
    op.wait_for(refused, 2);
    op.answer("n");
    let (code, err) = op.finish();
    assert_eq!(code, Some(2), "{err}");
    // (The prompts end without a newline: the error follows the last one on its line.)
    let last = &err[err.rfind("error: ").unwrap()..].trim_end();
    assert!(
        last.starts_with(
            "error: position 2 of 6 (alpha 180 deg, beta 0 deg) refused: the head did not move as the plan says: \
             its mean codes moved"
        ),
        "{last}"
    );
    assert!(last.ends_with("the campaign keeps the 1 positions before it: retry with --resume"), "{last}");
    assert_eq!(dwells(&c).len(), 1);

    // Resumed, with the head turned before each Enter: accepted.
    let addr = em.head.strip_prefix("sim:").unwrap();
    let mut head = accelcal_line::head::LineHead::connect(addr, Duration::from_secs(60)).unwrap();
    let a = args(&["--resume"]);
    let mut op = Operator::start(&a.iter().map(String::as_str).collect::<Vec<_>>());
    for (k, &(al, be)) in accelcal_core::sim::Plan::six().positions.iter().enumerate().skip(1) {
        op.wait_for(&prompt(k + 1), 1);
        head.move_to(al, be).unwrap();
        op.answer("");
    }
    let (code, err) = op.finish();
    assert_eq!(code, Some(0), "{err}");
    assert!(!err.contains("refused"), "{err}");
    assert_eq!(dwells(&c).len(), 6);
    let rec = dir.path().join("r.rec");
    ok(&["fit", s(&c), "--record", s(&rec), "--device-id", "51454d552d422d4c34373545"]);
    assert!(ok(&["record", "show", s(&rec)]).contains("node: accepts it"));

    // Ctrl-C while the command waits for Enter stops it at once, with 130.
    std::fs::remove_file(&c).unwrap();
    let a = args(&[]);
    let mut op = Operator::start(&a.iter().map(String::as_str).collect::<Vec<_>>());
    op.wait_for(&prompt(1), 1);
    let code = interrupt(&mut op.child, Duration::from_secs(5));
    let (_, err) = op.finish();
    assert_eq!(code, Some(130), "{err}");
    assert!(err.trim_end().ends_with("holds 0 of 6 positions; continue with --resume"), "{err}");
}

/// Issue 24: `--resume` takes samples, rate and g from the campaign, refuses an option that
/// contradicts them, and sets the node back to the campaign's rate when it streams at another
/// (as after a reset): the resumed rows are 1/rate apart, as the header says.
#[test]
fn resume_keeps_the_campaign_s_samples_rate_and_g() {
    let _one = one_bench();
    let dir = tempfile::tempdir().unwrap();
    let (truth, _) = unit(dir.path(), "u", 10, 10);
    let em = Emulator::start(&truth, &[]);
    let c = dir.path().join("c.csv");
    let mut child = spawn(&acquire_args(&em, "six", "200", &c, &["--rate-hz", "500"]));
    wait_positions(&c, 200, 2);
    let (code, err) = stop_acquire(&mut child);
    assert_eq!(code, Some(130), "{err}");
    let kept = dwells(&c).iter().filter(|d| d.2 == 200).count();
    assert!(std::fs::read_to_string(&c).unwrap().contains("# rate_hz: 500\n"));
    // The node back at another rate, as after a reset.
    let mut node = Session::open(&em.port, 921_600, Duration::from_secs(5)).unwrap();
    assert_eq!(node.set_rate(1000).unwrap().rate_hz, 1000);
    drop(node);
    let resume = |extra: &[&'static str]| {
        let mut a =
            vec!["acquire", "--port", &em.port, "--head", &em.head, "--plan", "six", "-o", s(&c), "--resume"];
        a.extend_from_slice(extra);
        a
    };
    let d = s(&c);
    for (extra, want) in [
        (&["--samples", "300"][..], format!("--samples 300 contradicts {d}'s `# samples: 200`")),
        (&["--rate-hz", "1000"][..], format!("--rate-hz 1000 contradicts {d}'s `# rate_hz: 500`")),
        (&["--g", "9.8"][..], format!("--g 9.8 contradicts {d}'s `# g_m_s2: 9.81`")),
    ] {
        let e = common::bad(&resume(extra));
        assert!(e.contains(&want), "{extra:?}: {e}");
    }
    let out = succeed(&resume(&["--samples", "200", "--g", "9.81"]));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("note: the node streams at 1000 Hz, the campaign's rate is 500 Hz"), "{err}");
    assert!(err.contains(&format!("resume: {kept} complete positions kept")), "{err}");
    let d = dwells(&c);
    assert_eq!(d.len(), 6);
    assert!(d.iter().all(|x| x.2 == 200), "{d:?}");
    // Every dwell's rows are 1/500 s apart (lost sets leave larger steps), and t_s never decreases.
    let text = std::fs::read_to_string(&c).unwrap();
    let rows: Vec<Vec<f64>> = text
        .lines()
        .filter(|l| !l.starts_with('#'))
        .skip(1)
        .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
        .collect();
    for (i, w) in rows.windows(2).enumerate() {
        let dt = w[1][0] - w[0][0];
        assert!(dt >= 0.0, "row {i}: t_s decreases: {w:?}");
        if w[0][1..3] == w[1][1..3] {
            assert!(dt > 0.0019, "row {i}: {dt} s apart at 500 Hz");
        }
    }
    let steps =
        rows.windows(2).filter(|w| w[0][1..3] == w[1][1..3] && (w[1][0] - w[0][0] - 0.002).abs() < 1e-6);
    assert!(steps.count() > 6 * 150, "most rows 0.002 s apart");
}
