//! Developer tasks for accelcal (`cargo xtask <task>`). Every task prints the commands it runs.
//!
//! Tasks: `test-firmware` (build both node firmwares, run the QEMU tests), `bench` (hot-path
//! instruction count on the emulated Cortex-M4F, firmware footprint).

mod firmware;

fn main() {
    let task = std::env::args().nth(1).unwrap_or_default();
    let result = match task.as_str() {
        "test-firmware" => firmware::test(),
        "bench" => firmware::bench(),
        _ => {
            eprintln!("usage: cargo xtask <test-firmware|bench>");
            std::process::exit(2);
        }
    };
    if let Err(e) = result {
        eprintln!("xtask {task}: {e:#}");
        std::process::exit(1);
    }
}
