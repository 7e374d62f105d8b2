//! `accelcal plan --design N|auto`: a plan designed for its uncertainty and head time
//! (`accelcal_core::design`), compared with the paper's plan, the 24-position tumble and the six
//! positions, and, with `--montecarlo`, checked by simulation.

use std::path::Path;

use accelcal_core::campaign::Campaign;
use accelcal_core::design::search::{design, design_auto, AutoTarget, Designed, Head};
use accelcal_core::design::{head_time_s, predict, Part, Prediction, Prior, Stated};
use accelcal_core::error::bad;
use accelcal_core::output::{write_atomic, write_json};
use accelcal_core::sim::plan::RATE_KEY;
use accelcal_core::sim::{Plan, PlanHeader};
use accelcal_core::uncertainty::montecarlo::{self, Scenario, Settings};
use accelcal_core::uncertainty::ARCSEC;
use anyhow::Context;
use indicatif::{ProgressBar, ProgressStyle};
use serde::Serialize;

use super::{Gravity, Source};
use crate::settings::campaign::{Design, DesignSize, UnitType, DESIGN_RATE_HZ};

/// Orientations each Monte Carlo unit is judged at.
const MC_ORIENTATIONS: usize = 10;

/// A plan of the comparison with its prediction.
struct Row {
    name: &'static str,
    positions: Vec<(f64, f64)>,
    samples: usize,
    prediction: Prediction,
}

/// One plan of the comparison.
#[derive(Serialize)]
struct Compared {
    plan: String,
    positions: usize,
    samples_per_position: usize,
    head_time_s: f64,
    #[serde(rename = "U_m_s2")]
    u_m_s2: f64,
    #[serde(rename = "U_axes_m_s2")]
    u_axes_m_s2: [f64; 3],
    /// The coverage factor of `U_m_s2`.
    k: f64,
    criteria: Criteria,
    #[serde(skip_serializing_if = "Option::is_none")]
    montecarlo: Option<MonteCarlo>,
}

/// The D-, A- and worst-case criteria of a plan.
#[derive(Serialize)]
struct Criteria {
    #[serde(rename = "D_codes")]
    d_codes: f64,
    #[serde(rename = "A_codes")]
    a_codes: f64,
    #[serde(rename = "worst_U_m_s2")]
    worst_u_m_s2: f64,
}

/// A plan checked by simulation.
#[derive(Serialize)]
struct MonteCarlo {
    units: usize,
    /// The mean over the units of their budgets' U (worst axis), m/s².
    #[serde(rename = "stated_U_m_s2")]
    stated_u_m_s2: f64,
    /// The worst axis of the RMS over the units of each axis' U, m/s²: the budgets' expectation,
    /// comparable with the prediction.
    #[serde(rename = "rms_stated_U_m_s2")]
    rms_stated_u_m_s2: f64,
    /// The share of axis values within the budget's U.
    coverage: f64,
    /// The RMS of the calibrated acceleration's error at orientations none of the plans chose.
    rms_error_m_s2: f64,
}

/// The JSON document of `plan --design`.
#[derive(Serialize)]
struct DesignJson<'a> {
    /// `auto` or the number asked for.
    design: String,
    positions: usize,
    samples_per_position: usize,
    dwell_s: f64,
    rate_hz: f64,
    move_s: f64,
    head_time_s: f64,
    #[serde(rename = "U_m_s2")]
    u_m_s2: f64,
    #[serde(rename = "U_axes_m_s2")]
    u_axes_m_s2: [f64; 3],
    /// The coverage factor of `U_m_s2` and its effective degrees of freedom.
    k: f64,
    nu_eff: Option<f64>,
    #[serde(rename = "target_U_m_s2", skip_serializing_if = "Option::is_none")]
    target_u_m_s2: Option<f64>,
    criteria: Criteria,
    contributors: &'a [Part],
    not_included: &'a [&'static str],
    /// How GMDH ranks the paper's models on the plan: `alternate` or `leave-one-out`.
    selection: accelcal_core::design::order::Selection,
    travel_deg: f64,
    unit_type: &'a str,
    head: Head,
    head_angle_u_arcsec: f64,
    #[serde(rename = "g_u_m_s2")]
    g_u_m_s2: f64,
    /// The chamber the plan is run in (absent: one pass, model 4).
    #[serde(skip_serializing_if = "Option::is_none")]
    chamber: Option<ChamberJson>,
    angles: Vec<Angles>,
    compared: Vec<Compared>,
}

/// `--chamber` as the design took it.
#[derive(Serialize)]
struct ChamberJson {
    setpoints_c: Vec<f64>,
    soak_s: f64,
    passes: usize,
    /// `f(t)` at the worst end of the calibrated range: the factor on the noise, quantisation and
    /// head-angle variances.
    variance_factor: f64,
}

#[derive(Serialize)]
struct Angles {
    alpha_deg: f64,
    beta_deg: f64,
}

fn criteria(p: &Prediction) -> Criteria {
    Criteria { d_codes: p.d_codes, a_codes: p.a_codes, worst_u_m_s2: p.worst_m_s2 }
}

/// What the design works at: the rate, Hz, and g, each with where it came from (`--rate-hz`,
/// `--g` or the command line's gravity first; else the `--like` campaign's header; else the
/// defaults), and the words of the one line that says so.
struct Node {
    rate_hz: f64,
    gravity: Gravity,
    words: String,
}

/// [`Node`] of a design: `--like`'s header read for what the command line does not give.
fn node(d: &Design) -> anyhow::Result<Node> {
    let like = match &d.unit {
        UnitType::Like(path) => {
            let header = accelcal_core::campaign::header(path)
                .with_context(|| format!("--like {}", path.display()))?;
            Some((path, header))
        }
        UnitType::Noise(_) => None,
    };
    let like_rate = match &like {
        Some((path, header)) => match header.iter().find(|(k, _)| k == RATE_KEY) {
            Some((_, v)) => {
                Some(v.parse::<f64>().ok().filter(|r| r.is_finite() && *r > 0.0).ok_or_else(|| {
                    bad(format!(
                        "--like {}: `# {RATE_KEY}: {v}` is not a positive rate in Hz",
                        path.display()
                    ))
                })?)
            }
            None => None,
        },
        None => None,
    };
    let (rate_hz, rate_words) = match (d.rate_hz, like_rate, &like) {
        (Some(r), _, _) => (r, "--rate-hz".to_string()),
        (None, Some(r), Some((path, _))) => (r, format!("--like {}'s `# {RATE_KEY}:`", path.display())),
        (None, _, Some((path, _))) => (
            DESIGN_RATE_HZ,
            format!(
                "the default: --like {} states no `# {RATE_KEY}:` and --rate-hz was not given",
                path.display()
            ),
        ),
        (None, _, None) => (DESIGN_RATE_HZ, "the default: --rate-hz was not given".to_string()),
    };
    // A gravity the command line states wins; the default `--g` gives way to the campaign's.
    let from_like = match (&d.gravity.source, &like) {
        (Source::Default, Some((path, header))) => super::header_g(path, header)?,
        _ => None,
    };
    let gravity = from_like.unwrap_or_else(|| d.gravity.clone());
    let g_words = match (&gravity.source, &like) {
        (Source::Campaign(_), Some((path, _))) => format!("--like {}: {}", path.display(), gravity.words()),
        (Source::Default, Some((path, _))) => {
            format!("the default --g: --like {} states no `# g_m_s2:`", path.display())
        }
        _ => gravity.words(),
    };
    let noise_words = match &like {
        Some((path, _)) => format!("--like {}'s scatter within its dwells", path.display()),
        None => "--noise".to_string(),
    };
    let (u_g, _) = gravity.standard_u();
    let words = format!(
        "rate {rate_hz} Hz ({rate_words}); g = {} m/s², u(g) = {u_g:.2e} m/s² ({g_words}); noise per sample from {noise_words}",
        gravity.g
    );
    Ok(Node { rate_hz, gravity, words })
}

/// The unit type: from `--like` or the nominal triad.
fn prior(unit: &UnitType, g: f64) -> anyhow::Result<Prior> {
    Ok(match unit {
        UnitType::Like(path) => {
            let c = Campaign::read(path).with_context(|| format!("--like {}", path.display()))?;
            Prior::from_campaign(&c, g, &path.display().to_string())
                .with_context(|| format!("--like {}", path.display()))?
        }
        UnitType::Noise(noise) => Prior::nominal(*noise, g)?,
    })
}

/// Writes a plan file: the design's words as comments, then its dwell's header lines
/// (`# samples:`, `# rate_hz:`, which the station takes), then the positions.
fn write_plan(path: &Path, d: &Designed, header: &str, dwell: &PlanHeader) -> anyhow::Result<()> {
    let mut s = String::new();
    for line in header.lines() {
        s.push_str("# ");
        s.push_str(line);
        s.push('\n');
    }
    s.push_str(&dwell.lines());
    s.push_str("alpha_deg,beta_deg\n");
    for (al, be) in &d.positions {
        s.push_str(&format!("{al},{be}\n"));
    }
    write_atomic(path, s.as_bytes())
}

/// Runs `accelcal plan --design`.
pub fn run(d: &Design) -> anyhow::Result<()> {
    let size = d.size;
    let node = node(d)?;
    let gravity = &node.gravity;
    let g = gravity.g;
    let out = d.out.as_path();
    let prior = prior(&d.unit, g)?;
    let (u_g, _) = gravity.standard_u();
    let angle_u = d.head_angle_u_arcsec;
    let chamber = d.chamber.clone();
    let stated = Stated { head_angle_rad: angle_u * ARCSEC, g_m_s2: u_g, chamber: chamber.clone() };
    let (move_s, rate_hz) = (d.move_s, node.rate_hz);
    // A plan's head time: one pass, or in a chamber every pass and its soak.
    let time_of = |positions: usize, samples: usize| {
        let one = head_time_s(positions, samples, rate_hz, move_s);
        chamber.as_ref().map_or(one, |c| c.head_time_s(one))
    };
    let samples = d.samples as usize;
    let head = d.head;
    let paper = predict(&Plan::head().positions, samples, &prior, &stated, g)?;
    let (designed, target) = match size {
        DesignSize::Positions(n) => (design(n, samples, &prior, &stated, g, &head, d.seed)?, None),
        DesignSize::Auto => {
            let target = d.target_u.unwrap_or(paper.worst_m_s2);
            let t = AutoTarget { u_m_s2: target, rate_hz, move_s };
            let n = accelcal_core::design::search::AUTO_DWELLS_S.len() as u64;
            let pb = bar(n, "dwells tried");
            let r = design_auto(&t, &prior, &stated, g, &head, d.seed, &|_| pb.inc(1));
            pb.finish_and_clear();
            (r?, Some(target))
        }
    };
    let p = &designed.prediction;
    let n = designed.positions.len();
    let time = time_of(n, designed.samples);
    let dwell = designed.samples as f64 / rate_hz;
    let selection = match designed.selection {
        accelcal_core::design::order::Selection::Alternate => "the alternate split (select's default): both its parts identify model 10, the largest of the paper's models a head plan identifies",
        accelcal_core::design::order::Selection::LeaveOneOut => "leave-one-out only (select --criterion loo; on the station, --criterion loo or its key criterion = \"loo\"): no order of these positions lets both parts of the alternate split identify model 10",
    };
    let in_chamber = chamber.as_ref().map(|c| {
        let (lo, hi) = c.range_c();
        let list: Vec<String> = c.setpoints_c.iter().map(|t| t.to_string()).collect();
        (
            format!(
                "run at each chamber setpoint (acquire --chamber={}): {} passes, {} s of soak each",
                list.join(","),
                c.passes(),
                c.soak_s
            ),
            format!(
                "the linear thermal model at the worst temperature of {lo}..{hi} °C (variance factor {:.3})",
                c.factor()
            ),
        )
    });
    let header = format!(
        "designed by accelcal plan --design {}: {n} positions x {} sample sets ({dwell} s at {rate_hz} Hz), head time {time:.0} s with {move_s} s per move{}\npredicted U = {:.4e} m/s^2 (k = {:.2}, worst axis and orientation at 1 g{}); unit type: {}; head angle u {angle_u} arcsec\nGMDH: {selection}",
        size_word(size),
        designed.samples,
        in_chamber.as_ref().map_or(String::new(), |(run, _)| format!("\n{run}")),
        p.worst_m_s2,
        p.k,
        in_chamber.as_ref().map_or(String::new(), |(_, model)| format!(", {model}")),
        prior.source
    );
    let dwell_header = PlanHeader { samples: Some(designed.samples), rate_hz: Some(rate_hz) };
    write_plan(out, &designed, &header, &dwell_header)?;

    outln!(
        "plan design: {n} positions x {} sample sets ({dwell} s at {rate_hz} Hz), head time {time:.0} s with {move_s} s per move and settling",
        designed.samples
    )?;
    if let Some((run, model)) = &in_chamber {
        outln!("  {run}; U of {model}")?;
    }
    outln!("  unit type: {}", prior.source)?;
    outln!("  at {}", node.words)?;
    outln!(
        "  head: α every {}°, β every {}° within ±{}° ({} positions); angle u {angle_u}″ per angle and position; u(g) = {:.2e} m/s²",
        head.alpha_step_deg,
        head.beta_step_deg,
        head.beta_max_deg,
        head.reachable()?.len(),
        stated.g_m_s2
    )?;
    if let Some(t) = target {
        let whence = if d.target_u.is_some() { "--target-U" } else { "the paper's plan's, at --samples" };
        outln!(
            "  target U = {t:.4e} m/s² ({whence}); the least head time among the dwells tried reaches it"
        )?;
    }
    outln!("  GMDH ranks the paper's models on it by {selection}")?;
    outln!("  order: {:.0}° of travel from α = β = 0 (the larger stage per move)", designed.travel_deg)?;
    outln!("  written: {}", out.display())?;

    let reference = |name: &'static str, plan: Plan| -> anyhow::Result<Row> {
        let prediction = predict(&plan.positions, samples, &prior, &stated, g)?;
        Ok(Row { name, positions: plan.positions, samples, prediction })
    };
    let rows = [
        Row { name: "head (paper)", positions: Plan::head().positions, samples, prediction: paper },
        reference("tumble24", Plan::tumble24())?,
        reference("six", Plan::six())?,
        Row {
            name: "designed",
            positions: designed.positions.clone(),
            samples: designed.samples,
            prediction: designed.prediction.clone(),
        },
    ];
    let mut compared: Vec<Compared> = rows
        .iter()
        .map(|r| Compared {
            plan: r.name.to_string(),
            positions: r.positions.len(),
            samples_per_position: r.samples,
            head_time_s: time_of(r.positions.len(), r.samples),
            u_m_s2: r.prediction.worst_m_s2,
            u_axes_m_s2: r.prediction.expanded_m_s2,
            k: r.prediction.k,
            criteria: criteria(&r.prediction),
            montecarlo: None,
        })
        .collect();
    if let Some(units) = d.montecarlo {
        let noise = prior.noise_codes.into_iter().fold(0.0, f64::max);
        let scenario = Scenario {
            name: "plan".into(),
            noise_codes: noise,
            head_angle_arcsec: angle_u,
            head_orthogonality_arcsec: 0.0,
            g_u_m_s2: stated.g_m_s2,
            temperature: None,
            quadratic_codes: 0.0,
            range: (0.93, 0.97),
        };
        let pb = bar(units as u64 * rows.len() as u64, "simulated units");
        for (r, c) in rows.iter().zip(compared.iter_mut()) {
            let set = Settings {
                units: units as usize,
                plan: Plan { positions: r.positions.clone() },
                samples: r.samples,
                orientations: MC_ORIENTATIONS,
                seed: d.seed,
            };
            let o = montecarlo::run(&scenario, &set, &|_| pb.inc(1)).map_err(anyhow::Error::msg)?;
            c.montecarlo = Some(MonteCarlo {
                units: o.units,
                stated_u_m_s2: o.mean_u_m_s2,
                rms_stated_u_m_s2: o.rms_u_m_s2,
                coverage: o.coverage,
                rms_error_m_s2: o.rms_error_m_s2,
            });
        }
        pb.finish_and_clear();
    }
    print_table(&compared, d.montecarlo.is_some(), noise_words(&prior))?;
    let parts: Vec<String> = p.parts.iter().map(|x| format!("{} {:.3e}", x.name, x.u_m_s2)).collect();
    outln!("the designed plan's contributors (standard uncertainty, m/s²): {}", parts.join(", "))?;
    outln!("not predicted (add them from the fit's budget): {}", p.not_included.join("; "))?;
    if let Some(j) = &d.json {
        let doc = DesignJson {
            design: size_word(size),
            positions: n,
            samples_per_position: designed.samples,
            dwell_s: dwell,
            rate_hz,
            move_s,
            head_time_s: time,
            u_m_s2: p.worst_m_s2,
            u_axes_m_s2: p.expanded_m_s2,
            k: p.k,
            nu_eff: p.nu_eff,
            target_u_m_s2: target,
            criteria: criteria(p),
            contributors: &p.parts,
            not_included: &p.not_included,
            selection: designed.selection,
            travel_deg: designed.travel_deg,
            unit_type: &prior.source,
            head,
            head_angle_u_arcsec: angle_u,
            g_u_m_s2: stated.g_m_s2,
            chamber: chamber.as_ref().map(|c| ChamberJson {
                setpoints_c: c.setpoints_c.clone(),
                soak_s: c.soak_s,
                passes: c.passes(),
                variance_factor: c.factor(),
            }),
            angles: designed
                .positions
                .iter()
                .map(|&(alpha_deg, beta_deg)| Angles { alpha_deg, beta_deg })
                .collect(),
            compared,
        };
        write_json(j, &doc)?;
    }
    Ok(())
}

fn noise_words(p: &Prior) -> String {
    let [x, y, z] = p.noise_codes;
    format!("noise x {x:.1}, y {y:.1}, z {z:.1} codes per sample")
}

fn size_word(size: DesignSize) -> String {
    match size {
        DesignSize::Positions(n) => n.to_string(),
        DesignSize::Auto => "auto".into(),
    }
}

fn bar(len: u64, what: &str) -> ProgressBar {
    let pb = ProgressBar::new(len);
    pb.set_style(
        ProgressStyle::with_template(&format!(
            "{{bar:40}} {{pos}}/{{len}} {what}, {{elapsed}} elapsed, eta {{eta}}"
        ))
        .expect("valid template"),
    );
    pb
}

fn print_table(rows: &[Compared], mc: bool, noise: String) -> anyhow::Result<()> {
    outln!()?;
    outln!(
        "predicted expanded uncertainty of the calibrated acceleration at its worst orientation at 1 g (k = 2, or Student's t where the noise's degrees of freedom, the samples' within the dwells, are few); {noise}"
    )?;
    out!(
        "  {:<13} {:>9} {:>7} {:>11} {:>10} {:>10} {:>10} {:>5} {:>8} {:>8}",
        "plan",
        "positions",
        "samples",
        "head time s",
        "U_x m/s²",
        "U_y m/s²",
        "U_z m/s²",
        "k",
        "D codes",
        "A codes"
    )?;
    if mc {
        out!(" {:>11} {:>11} {:>8} {:>11}", "MC mean U", "MC RMS U", "coverage", "RMS error")?;
    }
    outln!()?;
    for r in rows {
        let [x, y, z] = r.u_axes_m_s2;
        out!(
            "  {:<13} {:>9} {:>7} {:>11.0} {:>10.3e} {:>10.3e} {:>10.3e} {:>5.2} {:>8.3} {:>8.3}",
            r.plan,
            r.positions,
            r.samples_per_position,
            r.head_time_s,
            x,
            y,
            z,
            r.k,
            r.criteria.d_codes,
            r.criteria.a_codes
        )?;
        if let Some(m) = &r.montecarlo {
            out!(
                " {:>11.3e} {:>11.3e} {:>7.1}% {:>11.3e}",
                m.stated_u_m_s2,
                m.rms_stated_u_m_s2,
                100.0 * m.coverage,
                m.rms_error_m_s2
            )?;
        }
        outln!()?;
    }
    if mc {
        let units = rows.first().and_then(|r| r.montecarlo.as_ref()).map_or(0, |m| m.units);
        outln!(
            "  MC: {units} simulated units per plan (the simulator's spread of units, the noise above, the head's angle errors drawn), each fitted with model 4 by least squares and judged at {MC_ORIENTATIONS} random orientations: the mean of the budgets' U (worst axis of each: a mean of maxima, above the expectation when the budget has few degrees of freedom), the RMS of each axis' U (worst axis; the prediction's like), the share of true errors within U (95 % when right), and their RMS, m/s²"
        )?;
    }
    Ok(())
}
