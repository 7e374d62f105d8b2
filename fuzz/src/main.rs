//! `accelcal-fuzz`: runs the mutation fuzzer on the record parser, the record slots and the frame
//! decoder for a bounded time and prints executions per second; on a failure, saves the input and
//! exits 1.
//!
//! `accelcal-fuzz [--seconds N] [--target record|slots|frame|all] [--seed S] [--out DIR]`
//! (the seconds are shared between the targets; a failing input is written to DIR, default
//! `target/fuzz-failures`).

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;

use accelcal_fuzz::{frame::FrameTarget, record::RecordTarget, run, slots::SlotsTarget, Target};

struct Settings {
    seconds: f64,
    targets: Vec<Box<dyn Target>>,
    seed: u64,
    out: PathBuf,
}

fn parse_args() -> Result<Settings, String> {
    let mut s =
        Settings { seconds: 10.0, targets: Vec::new(), seed: 1, out: PathBuf::from("target/fuzz-failures") };
    let mut which = "all".to_string();
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        let mut value = || args.next().ok_or_else(|| format!("{a} needs a value"));
        match a.as_str() {
            "--seconds" => s.seconds = value()?.parse().map_err(|e| format!("--seconds: {e}"))?,
            "--seed" => s.seed = value()?.parse().map_err(|e| format!("--seed: {e}"))?,
            "--target" => which = value()?,
            "--out" => s.out = value()?.into(),
            _ => return Err(format!("unknown argument `{a}`")),
        }
    }
    if !(s.seconds > 0.0 && s.seconds.is_finite()) {
        return Err("--seconds must be a positive number".into());
    }
    match which.as_str() {
        "record" => s.targets.push(Box::new(RecordTarget::default())),
        "slots" => s.targets.push(Box::new(SlotsTarget::default())),
        "frame" => s.targets.push(Box::new(FrameTarget::default())),
        "all" => {
            s.targets.push(Box::new(RecordTarget::default()));
            s.targets.push(Box::new(SlotsTarget::default()));
            s.targets.push(Box::new(FrameTarget::default()));
        }
        t => return Err(format!("unknown target `{t}` (record, slots, frame or all)")),
    }
    Ok(s)
}

fn main() -> ExitCode {
    let mut s = match parse_args() {
        Ok(s) => s,
        Err(e) => {
            eprintln!("error: {e}\nusage: accelcal-fuzz [--seconds N] [--target record|slots|frame|all] [--seed S] [--out DIR]");
            return ExitCode::from(2);
        }
    };
    let per_target = Duration::from_secs_f64(s.seconds / s.targets.len() as f64);
    for t in &mut s.targets {
        match run(t.as_mut(), s.seed, per_target) {
            Ok(r) => {
                let secs = r.elapsed.as_secs_f64();
                println!(
                    "fuzz {}: {} execs in {secs:.1} s = {:.0} execs/s (seed {}); {}",
                    t.name(),
                    r.execs,
                    r.execs as f64 / secs,
                    s.seed,
                    t.summary()
                );
            }
            Err(f) => {
                let path = s.out.join(format!("{}-seed{}.bin", t.name(), s.seed));
                let saved = std::fs::create_dir_all(&s.out).and_then(|_| std::fs::write(&path, &f.input));
                let hex: String = f.input.iter().take(512).map(|b| format!("{b:02x}")).collect();
                eprintln!("fuzz {}: FAILED: {}\ninput ({} bytes): {hex}", t.name(), f.message, f.input.len());
                match saved {
                    Ok(()) => eprintln!("input saved to {}", path.display()),
                    Err(e) => eprintln!("cannot save the input to {}: {e}", path.display()),
                }
                return ExitCode::FAILURE;
            }
        }
    }
    ExitCode::SUCCESS
}
