//! `accelcal simulate`: write a simulated campaign and its truth.

use anyhow::Context;
use serde_json::json;

use crate::cli::SimulateArgs;
use accelcal_core::campaign::CodeRange;
use accelcal_core::error::bad;
use accelcal_core::output::{write_atomic_with, write_json};
use accelcal_core::sim::{self, Plan, SimConfig};

/// Soak at each chamber setpoint when --soak-s is not given, s.
pub(crate) const SOAK_DEFAULT_S: f64 = 900.0;
/// Chamber-to-sensor lag when --thermal-lag-s is not given, s (`emulate`'s default).
const THERMAL_LAG_DEFAULT_S: f64 = 30.0;

/// The thermal plan of `--chamber`, `--soak-s` and `--thermal-lag-s` (settings refuses the last two
/// without the first).
fn thermal_plan(a: &SimulateArgs) -> anyhow::Result<Option<sim::ThermalPlan>> {
    if a.chamber.is_empty() {
        return Ok(None);
    }
    if let Some(t) = a.chamber.iter().find(|t| !(t.is_finite() && (-60.0..=150.0).contains(*t))) {
        return Err(bad(format!("--chamber: each setpoint must be a temperature in -60..=150 °C, got {t}")));
    }
    let soak_s = a.soak_s.unwrap_or(SOAK_DEFAULT_S);
    let tau_s = a.thermal_lag_s.unwrap_or(THERMAL_LAG_DEFAULT_S);
    for (name, v) in [("--soak-s", soak_s), ("--thermal-lag-s", tau_s)] {
        if !(v.is_finite() && v >= 0.0) {
            return Err(bad(format!("{name} must be a number of seconds >= 0, got {v}")));
        }
    }
    Ok(Some(sim::ThermalPlan { chamber_c: a.chamber.clone(), soak_s, tau_s }))
}

/// Builds the simulator settings from the command line.
pub fn config(a: &SimulateArgs, g: f64) -> anyhow::Result<SimConfig> {
    let plan = Plan::from_spec(&a.plan, a.seed).map_err(|e| bad(format!("--plan {e}")))?;
    let effects = a
        .effects
        .iter()
        .map(|s| sim::effects::parse(s).map_err(|e| bad(format!("--effect {e}"))))
        .collect::<anyhow::Result<Vec<_>>>()?;
    let thermal = thermal_plan(a)?;
    if a.temp_profile.is_some() && thermal.is_some() {
        return Err(bad("--temp-profile and --chamber both set the temperature: give one"));
    }
    if a.temp_profile.is_none() && thermal.is_none() {
        if let Some(e) = effects.iter().find(|e| e.needs_temperature()) {
            return Err(bad(format!(
                "--effect {} needs a temperature: --temp-profile BASE:AMP:CYCLES or --chamber T1,T2,…",
                e.name()
            )));
        }
    }
    for (name, v) in [
        ("--noise", a.noise),
        ("--bias-sd", a.bias_sd),
        ("--scale-sd", a.scale_sd),
        ("--misalign-sd", a.misalign_sd),
    ] {
        if !(v.is_finite() && v >= 0.0) {
            return Err(bad(format!("{name} must be a finite number >= 0, got {v}")));
        }
    }
    if a.samples == 0
        || !(a.rate_hz.is_finite() && a.rate_hz > 0.0)
        || !(a.move_s.is_finite() && a.move_s >= 0.0)
    {
        return Err(bad("--samples must be >= 1, --rate-hz > 0 and --move-s >= 0"));
    }
    Ok(SimConfig {
        seed: a.seed,
        plan,
        layout: a.layout.clone(),
        g,
        samples: a.samples,
        rate_hz: a.rate_hz,
        move_s: a.move_s,
        noise: a.noise,
        bias_sd: a.bias_sd,
        scale_sd: a.scale_sd,
        misalign_sd: a.misalign_sd,
        effects,
        quantize: !a.ideal_adc,
        temp: a.temp_profile,
        thermal,
    })
}

/// Runs `accelcal simulate`.
pub fn run(a: &SimulateArgs, g: &super::Gravity) -> anyhow::Result<()> {
    let cfg = config(a, g.g)?;
    let (mut campaign, mut truth) = sim::simulate(&cfg);
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
    write_atomic_with(&a.out, |w| campaign.write(w).context("writing CSV"))?;
    let truth_path = a.truth.clone().unwrap_or_else(|| a.out.with_extension("truth.json"));
    write_json(&truth_path, &truth)?;
    println!(
        "wrote {} ({} rows, {} positions) and {}",
        a.out.display(),
        campaign.len(),
        cfg.plan.positions.len(),
        truth_path.display()
    );
    println!("{:<8} {:>10} {:>10} {:>10} {:>10}", "channel", "bias", "k_x", "k_y", "k_z");
    for c in &truth.channels {
        println!("{:<8} {:>10.1} {:>10.3} {:>10.3} {:>10.3}", c.name, c.bias, c.k[0], c.k[1], c.k[2]);
    }
    if let Some(j) = &a.json {
        write_json(
            j,
            &json!({"campaign": a.out, "truth": truth_path, "rows": campaign.len(), "positions": cfg.plan.positions.len(), "channels": truth.channels.iter().map(|c| &c.name).collect::<Vec<_>>()}),
        )?;
    }
    Ok(())
}
