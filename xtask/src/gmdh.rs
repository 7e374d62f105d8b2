//! The GMDH benchmark: `accelcal select` against the PyPI `gmdh` package on the same data
//! (`bench/gmdh_compare.py`), in a virtual environment under `target/` with `numpy<2` and
//! `gmdh==1.0.3` installed from PyPI.

use std::path::Path;

use crate::run;

/// Builds the release binary, prepares the Python environment and runs the comparison.
pub fn bench(root: &Path) -> anyhow::Result<()> {
    run(root, "cargo", &["build", "--release", "-p", "accelcal", "--locked"])?;
    let venv = root.join("target/bench-venv");
    let python = venv.join("bin/python");
    if !python.exists() {
        run(root, "python3", &["-m", "venv", venv.to_str().expect("utf-8 path")])?;
    }
    let py = python.to_str().expect("utf-8 path");
    run(root, py, &["-m", "pip", "install", "--quiet", "numpy<2", "gmdh==1.0.3"])?;
    let bin = root.join("target/release/accelcal");
    let work = root.join("target/bench-gmdh");
    run(
        root,
        py,
        &[
            "bench/gmdh_compare.py",
            bin.to_str().expect("utf-8 path"),
            work.to_str().expect("utf-8 path"),
            "--threads",
            "2",
        ],
    )
}
