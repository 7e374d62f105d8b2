//! `accelcal simulate`: write a simulated campaign and its truth.

use anyhow::Context;
use serde_json::json;

use crate::settings::campaign::Simulate;
use accelcal_core::campaign::CodeRange;
use accelcal_core::output::{write_atomic_with, write_json};
use accelcal_core::sim;

/// Runs `accelcal simulate`.
pub fn run(a: &Simulate) -> anyhow::Result<()> {
    let cfg = &a.config;
    let (mut campaign, mut truth) = sim::simulate(cfg);
    if a.codes == CodeRange::Signed16 {
        // The simulated ADC is unsigned16; its codes less mid-scale are the signed counts of a
        // digital MEMS, its rails 0 and 65535 their rails -32768 and 32767.
        let mid = CodeRange::Unsigned16.rails().0 - CodeRange::Signed16.rails().0;
        for v in campaign.channels.iter_mut().flat_map(|c| c.codes.iter_mut()) {
            *v -= mid;
        }
        for t in &mut truth.channels {
            t.bias -= mid;
        }
        campaign.codes = CodeRange::Signed16;
    }
    campaign.serial = a.serial.clone();
    campaign.g_source = Some(a.g_source.clone());
    write_atomic_with(&a.out, |w| campaign.write(w).context("writing CSV"))?;
    let truth_path = &a.truth;
    write_json(truth_path, &truth)?;
    outln!(
        "wrote {} ({} rows, {} positions) and {}",
        a.out.display(),
        campaign.len(),
        cfg.plan.positions.len(),
        truth_path.display()
    )?;
    outln!("{:<8} {:>10} {:>10} {:>10} {:>10}", "channel", "bias", "k_x", "k_y", "k_z")?;
    for c in &truth.channels {
        outln!("{:<8} {:>10.1} {:>10.3} {:>10.3} {:>10.3}", c.name, c.bias, c.k[0], c.k[1], c.k[2])?;
    }
    if let Some(j) = &a.json {
        write_json(
            j,
            &json!({"campaign": a.out, "truth": truth_path, "rows": campaign.len(), "positions": cfg.plan.positions.len(), "channels": truth.channels.iter().map(|c| &c.name).collect::<Vec<_>>()}),
        )?;
    }
    Ok(())
}
