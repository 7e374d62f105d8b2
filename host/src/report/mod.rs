//! What users read and look at: plots (rendered in memory, written atomically) and number
//! formatting for tables. The JSON documents of each command live beside the command in `cmd`.

pub mod certificate;
pub mod dcc;
pub mod diagnose_plot;
pub mod gravity_plot;
pub mod pdf;
pub mod plot;

pub use accelcal_core::certificate::round::sig;
