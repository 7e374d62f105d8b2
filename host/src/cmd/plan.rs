//! `accelcal plan`: a position plan's head angles and what each axis of the block should read
//! there, under the dividing-head convention of the campaigns (`shared::kinematics`):
//! `ax = −g·cosβ·sinα`, `ay = −g·sinβ`, `az = −g·cosα·cosβ`.

use accelcal_core::output::write_json;
use accelcal_core::sim::Plan;
use serde::Serialize;

use crate::settings::campaign::PlanSettings;

/// One position of the JSON document.
#[derive(Serialize)]
struct PositionJson {
    alpha_deg: f64,
    beta_deg: f64,
    /// Apparent acceleration along x, y, z, m/s².
    accel_ms2: [f64; 3],
}

/// The positions of a plan with their apparent acceleration.
fn positions(plan: &Plan, g: f64) -> Vec<PositionJson> {
    plan.positions
        .iter()
        .map(|&(alpha_deg, beta_deg)| PositionJson {
            alpha_deg,
            beta_deg,
            // `+ 0.0` turns the −0 of an exact zero into 0.
            accel_ms2: accelcal_shared::gravity(alpha_deg, beta_deg, g).map(|v| v + 0.0),
        })
        .collect()
}

/// Runs `accelcal plan`.
pub fn run(p: &PlanSettings) -> anyhow::Result<()> {
    let a = match p {
        PlanSettings::Design(d) => return super::design::run(d),
        PlanSettings::Show(a) => a,
    };
    let g = a.gravity.g;
    let rows = positions(&a.plan, g);
    outln!(
        "plan `{}`: {} positions; what a triad's axes should read, g = {} m/s² \
         (ax = -g cos(beta) sin(alpha), ay = -g sin(beta), az = -g cos(alpha) cos(beta))",
        a.spec,
        rows.len(),
        g
    )?;
    outln!(
        "  {:>4} {:>10} {:>10} {:>10} {:>10} {:>10} {:>7} {:>7} {:>7}",
        "#",
        "alpha_deg",
        "beta_deg",
        "ax m/s²",
        "ay m/s²",
        "az m/s²",
        "ax g",
        "ay g",
        "az g"
    )?;
    for (i, r) in rows.iter().enumerate() {
        let [x, y, z] = r.accel_ms2;
        outln!(
            "  {:>4} {:>10.2} {:>10.2} {:>10.4} {:>10.4} {:>10.4} {:>7.3} {:>7.3} {:>7.3}",
            i + 1,
            r.alpha_deg,
            r.beta_deg,
            x,
            y,
            z,
            x / g,
            y / g,
            z / g
        )?;
    }
    if let Some(j) = &a.json {
        write_json(j, &serde_json::json!({ "plan": a.spec, "g": g, "positions": rows }))?;
    }
    Ok(())
}
