//! `accelcal-fuzz`: a coverage-free mutation fuzzer for the parsers of untrusted bytes in
//! `accelcal-shared`: the calibration record parser, the record slots (slot image parser, the
//! choice of the slot in force, the write plan) and the link's frame decoder. It runs on the
//! pinned stable toolchain (cargo-fuzz and bolero's libFuzzer engine need nightly).
//!
//! Each execution takes a valid seed (records or frames built with the crate's own encoders),
//! applies one to eight random mutations ([`mutate`]) and the target's structure-aware fix-ups,
//! and checks the target's properties. There is no coverage feedback: inputs that reach new code
//! are not kept, so deep paths are reached only as often as random mutation of a seed reaches them.
//! Runs are reproducible from the seed of the random generator.

pub mod frame;
pub mod mutate;
pub mod record;
pub mod rng;
pub mod slots;

use std::panic::{catch_unwind, AssertUnwindSafe};
use std::time::{Duration, Instant};

use rng::Rng;

/// A parser under test: its seeds, its structure-aware fix-ups and its properties.
pub trait Target {
    /// Short name (`record`, `slots`, `frame`).
    fn name(&self) -> &'static str;
    /// Valid inputs the mutations start from.
    fn seeds(&self) -> Vec<Vec<u8>>;
    /// Format-aware changes applied after the generic mutations (e.g. recomputing a CRC).
    fn fix_up(&self, rng: &mut Rng, data: &mut Vec<u8>);
    /// Runs the parser on `input` and checks its properties; `Err` names the broken one.
    fn check(&mut self, input: &[u8], rng: &mut Rng) -> Result<(), String>;
    /// Tally of outcomes so far, one line.
    fn summary(&self) -> String;
}

/// What a run did.
#[derive(Debug)]
pub struct Report {
    /// Inputs executed.
    pub execs: u64,
    /// Wall time spent.
    pub elapsed: Duration,
}

/// An input that broke a property or made the parser panic.
#[derive(Debug)]
pub struct Failure {
    /// The input.
    pub input: Vec<u8>,
    /// Which property failed, or the panic message.
    pub message: String,
}

/// Runs `target` for `duration` from the random seed `seed` (at least one execution per seed
/// input).
pub fn run(target: &mut dyn Target, seed: u64, duration: Duration) -> Result<Report, Failure> {
    let seeds = target.seeds();
    let mut rng = Rng::new(seed);
    let t0 = Instant::now();
    let mut execs = 0u64;
    // The seeds themselves first, then mutants; the clock is read every 64 executions.
    loop {
        let input = if (execs as usize) < seeds.len() {
            seeds[execs as usize].clone()
        } else {
            let mut d = seeds[rng.below(seeds.len())].clone();
            let other = &seeds[rng.below(seeds.len())];
            mutate::mutate(&mut rng, &mut d, other);
            target.fix_up(&mut rng, &mut d);
            d
        };
        let result = catch_unwind(AssertUnwindSafe(|| target.check(&input, &mut rng)));
        execs += 1;
        let message = match result {
            Ok(Ok(())) => None,
            Ok(Err(m)) => Some(m),
            Err(p) => Some(format!(
                "panic: {}",
                p.downcast_ref::<String>()
                    .map(String::as_str)
                    .or(p.downcast_ref::<&str>().copied())
                    .unwrap_or("?")
            )),
        };
        if let Some(message) = message {
            return Err(Failure { input, message });
        }
        if execs.is_multiple_of(64) && execs as usize >= seeds.len() && t0.elapsed() >= duration {
            return Ok(Report { execs, elapsed: t0.elapsed() });
        }
    }
}
