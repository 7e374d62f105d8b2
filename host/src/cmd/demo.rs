//! `accelcal demo`: the main job on built-in simulated data.

use accelcal_shared::terms::MODEL_4;
use anyhow::Context;
use indicatif::{ProgressBar, ProgressStyle};

use accelcal_core::calibrate::{fit_all, gate, record, record_bytes, record_crc_hex, Method};
use accelcal_core::campaign::identity::{content_sha256, Identity};
use accelcal_line::node::session::device_id_hex;

use crate::settings::campaign::Demo;
use accelcal_core::gmdh::Split;
use accelcal_core::output::{write_atomic, write_atomic_with, write_json};
use accelcal_core::sim::{self, SimConfig};

/// Runs `accelcal demo`.
pub fn run(a: &Demo) -> anyhow::Result<()> {
    let out = &a.out;
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let steps = ProgressBar::new(5);
    steps.set_style(ProgressStyle::with_template("[{pos}/{len}] {msg}").expect("valid template"));
    let g = accelcal_shared::G_STANDARD;

    steps.set_message("simulating an MS9002-class triad on the dividing head (62 positions x 400 samples)");
    let cfg = SimConfig { seed: a.seed, ..SimConfig::default() };
    let (campaign, truth) = sim::simulate(&cfg);
    let campaign_path = out.join("campaign.csv");
    write_atomic_with(&campaign_path, |w| campaign.write(w).context("writing CSV"))?;
    write_json(&out.join("truth.json"), &truth)?;
    steps.inc(1);

    steps.set_message("GMDH over the paper's 11 models (regularity criterion, alternate split)");
    let settings = accelcal_core::gmdh::Settings::paper();
    let sel = super::select::compute(&campaign, g, &[], &settings)?;
    write_json(
        &out.join("select.json"),
        &super::select::to_json(&sel, &settings, &Split::Alternate.to_string(), None),
    )?;
    let crit_plots = super::select::plots(out, &sel, &settings)?;
    steps.inc(1);

    steps.set_message("fitting model 4 by LSQ and by test turns; writing the calibration record");
    let lsq = fit_all(&campaign, g, Method::Lsq, MODEL_4)?;
    let tt = fit_all(&campaign, g, Method::TestTurns, MODEL_4)?;
    // For the QEMU node (`accelcal hil`), the only node a demo has; checked by the node's gate
    // like every record the tool writes.
    let rec_path = out.join("calibration.rec");
    let rec = record(&lsq, accelcal_shared::contract::QEMU_DEVICE_ID, 0, g, None)?;
    gate(&rec_path, &rec)?;
    let rec_bytes = record_bytes(&rec)?;
    let sha256 = content_sha256(&campaign_path)?;
    let unit = |record_crc| Identity {
        device_id: Some(device_id_hex(&accelcal_shared::contract::QEMU_DEVICE_ID)),
        serial: None,
        g_m_s2: g,
        g_source: None,
        campaign_sha256: sha256.clone(),
        record_crc,
    };
    let t_ref = accelcal_core::positions::T_REF_DEFAULT_C;
    let lsq_json =
        super::fit::to_json(Method::Lsq, &lsq, t_ref, unit(Some(record_crc_hex(&rec_bytes))), None);
    write_json(&out.join("fit-lsq.json"), &lsq_json)?;
    write_json(
        &out.join("fit-test-turns.json"),
        &super::fit::to_json(Method::TestTurns, &tt, t_ref, unit(None), None),
    )?;
    write_atomic(&rec_path, &rec_bytes)?;
    steps.inc(1);

    steps.set_message("comparing the methods on held-out positions");
    let cmp = accelcal_core::compare::compute(&campaign, None, g)?;
    write_json(&out.join("compare.json"), &cmp)?;
    let err_plots = super::compare::plots(out, &cmp)?;
    steps.inc(1);
    steps.finish_and_clear();

    outln!(
        "accelcal demo: simulated triad (seed {}), {} rows at {} positions -> {}\n",
        a.seed,
        campaign.len(),
        cfg.plan.positions.len(),
        campaign_path.display()
    )?;
    outln!("Table 1. Model structure selection (combinatorial GMDH)\n")?;
    super::select::print_tables(&sel, &settings)?;
    outln!("Model 4 coefficients by LSQ against the simulator's truth")?;
    outln!(
        "  {:<8} {:>12} {:>12} {:>10} {:>10} {:>10} {:>10}",
        "channel",
        "u0 fit",
        "u0 true",
        "k_own fit",
        "k_own true",
        "cross fit",
        "cross true"
    )?;
    for ((name, f), t) in lsq.iter().zip(&truth.channels) {
        let own = t.axis;
        let cross = |k: &[f64]| (0..3).filter(|&j| j != own).map(|j| k[j].abs()).fold(0.0, f64::max);
        outln!(
            "  {:<8} {:>12.2} {:>12.2} {:>10.3} {:>10.3} {:>10.3} {:>10.3}",
            name,
            f.coefficients[0],
            t.bias,
            f.coefficients[1 + own],
            t.k[own],
            cross(&f.coefficients[1..4]),
            cross(&t.k)
        )?;
    }
    outln!("\nTable 2. Errors of the calibrated acceleration, LSQ against test turns\n")?;
    super::compare::print_table(&cmp)?;
    outln!("\nwrote in {}: campaign.csv truth.json select.json fit-lsq.json fit-test-turns.json compare.json calibration.rec ({} bytes)", out.display(), rec.len())?;
    for p in crit_plots.iter().chain(&err_plots) {
        outln!("plot: {}", p.display())?;
    }
    Ok(())
}
