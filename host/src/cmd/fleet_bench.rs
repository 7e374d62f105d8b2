//! `accelcal bench-fleet`: the fleet's commands and pages on a line-sized database (issue 31
//! item 5). A database without runs is first filled with a simulated line's history, written
//! through the normal store path (`Db::begin_run`, `store_*`, `finish_run`: the same rows, the
//! same ledger, the same checks as the station's); then `fleet` for a month, the overview, a
//! unit's page and the fleet page are timed as a user meets them (the `accelcal` binary, the
//! server over HTTP).

use std::io::{Read, Write};
use std::time::{Duration, Instant};

use accelcal_core::calibrate::{fit_positions, Method};
use accelcal_core::campaign::identity::Identity;
use accelcal_core::conformity::{self, Decision, Measured, RuleKind, Specification};
use accelcal_core::positions::Positions;
use accelcal_core::sim::{simulate, Plan, SimConfig};
use accelcal_core::uncertainty::{self, References, ARCSEC};
use accelcal_db::asset::{Asset, AssetKind};
use accelcal_db::RecalibrationDue;
use accelcal_db::{Db, Outcome, Phase, RunId, RunStart};
use accelcal_line::verify::{PositionCheck, VerifyReport};
use accelcal_shared::record::{Record, MAX_RECORD_LEN};
use accelcal_shared::terms::MODEL_4;
use anyhow::Context;
use rand::{Rng, SeedableRng};
use rand_distr::{Distribution, Normal};

use crate::settings::reader::BenchFleet;

const DAY_S: i64 = 86_400;
/// The line's first day: 2024-01-01T00:00:00Z.
pub const FIRST_DAY_UNIX_S: i64 = 1_704_067_200;
/// Between a unit's calibrations (the certificate's recalibration interval), days.
const INTERVAL_DAYS: i64 = 365;
const STATIONS: [&str; 3] = ["st-1", "st-2", "st-3"];
const OPERATORS: [&str; 6] = ["ana", "ben", "chloe", "dev", "emil", "fay"];
const G: f64 = 9.80665;

/// What a generated line holds: its units, runs, and the span of its runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Line {
    pub units: u32,
    pub runs: u32,
    pub seed: u64,
}

impl Line {
    /// How many runs unit `u` has (the runs shared out, the first units taking the remainder).
    fn runs_of(&self, u: u32) -> u32 {
        self.runs / self.units + u32::from(u < self.runs % self.units)
    }

    /// When unit `u`'s calibration `k` starts: units arrive evenly over the first interval,
    /// each comes back after the interval ± 20 days.
    fn start_of(&self, u: u32, k: u32, rng: &mut impl Rng) -> i64 {
        let arrival = FIRST_DAY_UNIX_S + (i64::from(u) * INTERVAL_DAYS * DAY_S) / i64::from(self.units);
        arrival + i64::from(k) * INTERVAL_DAYS * DAY_S + rng.random_range(-20..=20) * DAY_S * i64::from(k > 0)
    }
}

/// The head assets, one per station.
fn heads() -> Vec<Asset> {
    (0..STATIONS.len())
        .map(|i| Asset {
            asset_id: format!("head-{}", (b'A' + i as u8) as char),
            kind: AssetKind::Head,
            certificate: format!("DKD-K-1234-{i}"),
            due_date: accelcal_db::asset::parse_date("2030-12-31").expect("a date"),
            angle_u_arcsec: 20.0,
            orthogonality_u_arcsec: 10.0,
            operator: "ana".into(),
            registered_unix_s: FIRST_DAY_UNIX_S - DAY_S,
            value: None,
        })
        .collect()
}

/// Unit `u`'s device id (24 hex digits) and serial.
pub fn unit_ids(u: u32) -> (String, String) {
    (format!("{:024x}", 0xacce_1000_0000_u64 + u64::from(u)), format!("MS9-{u:06}"))
}

/// The product's specification the generated line verifies against: 0.05 m/s² on each
/// component, bias 5 mg, scale factor 2000 ppm, misalignment 5000 µrad, guard-band rule.
fn specification() -> Specification {
    Specification {
        unit_type: "MS9002.D triad".into(),
        acceleration_error_m_s2: 0.05,
        rule: RuleKind::GuardBand,
        guard_band_m_s2: None,
        bias_mg: Some(5.0),
        scale_factor_ppm: Some(2000.0),
        misalignment_urad: Some(5000.0),
    }
}

/// A verification at the six ±axis positions with errors of `sd` m/s² per component (U 0.004
/// m/s²), its parameters measured and decided by the core ([`conformity::parameters`]).
fn verification(device: &str, sd: f64, rng: &mut impl Rng) -> anyhow::Result<VerifyReport> {
    let spec = specification();
    let err = Normal::new(0.0, sd).context("a spread")?;
    let u = [0.004; 3];
    let positions: Vec<PositionCheck> = (1..=6)
        .map(|p| {
            let axis = (p - 1) / 2;
            let sign = if p % 2 == 1 { 1.0 } else { -1.0 };
            let mut expected = [0.0; 3];
            expected[axis] = sign * G;
            let e = [err.sample(rng), err.sample(rng), err.sample(rng)];
            PositionCheck {
                position: p,
                alpha_deg: 90.0 * p as f64,
                beta_deg: 0.0,
                read_back_alpha_deg: Some(90.0 * p as f64),
                read_back_beta_deg: Some(0.0),
                expected_m_s2: expected,
                measured_m_s2: std::array::from_fn(|i| expected[i] + e[i]),
                error_m_s2: e,
                sd_mean_m_s2: [1e-4; 3],
                tolerance_m_s2: [spec.acceleration_error_m_s2; 3],
                lost: 0,
                temp_c: None,
                out_of_range: false,
                pass: (0..3).all(|i| spec.decide(e[i], u[i]).accepted()),
                u_expanded_m_s2: Some(u),
                decisions: None,
            }
        })
        .collect();
    let measured: Vec<Measured> = positions
        .iter()
        .map(|p| Measured { expected_m_s2: p.expected_m_s2, error_m_s2: p.error_m_s2, u_expanded_m_s2: u })
        .collect();
    let parameters = conformity::parameters(&spec, G, &measured)?;
    let worst = positions
        .iter()
        .flat_map(|p| (0..3).map(|i| spec.decide(p.error_m_s2[i], u[i])))
        .chain(parameters.iter().map(|p| p.decision))
        .max()
        .unwrap_or(Decision::Pass);
    Ok(VerifyReport {
        version: accelcal_core::document::VERIFY_VERSION,
        device_id: device.into(),
        record: serde_json::json!({"slot": 0, "sequence": 1, "created_unix_s": FIRST_DAY_UNIX_S, "crc": "00000000"}),
        g_m_s2: G,
        chamber_c: None,
        tolerance_rule: "the specification's guard-band rule".into(),
        static_rule: "static".into(),
        pass: worst.accepted(),
        positions,
        interrupted: false,
        fit: None,
        specification: Some(spec),
        decision: Some(worst),
        parameters: Some(parameters),
    })
}

/// One run's pieces: its campaign (the 62-position plan, 4 sample sets per position: the
/// dwell's means are what the line's statistics read; a real campaign holds more sets), the fit
/// of it with its budget, and the record.
struct Pieces {
    campaign: Vec<u8>,
    fit_json: String,
    record: Vec<u8>,
}

fn pieces(device: &str, serial: &str, seed: u64) -> anyhow::Result<Pieces> {
    let cfg = SimConfig {
        seed,
        plan: Plan::head(),
        samples: 4,
        noise: 80.0,
        misalign_sd: 0.002,
        g: G,
        ..SimConfig::default()
    };
    let (mut c, _) = simulate(&cfg);
    c.serial = Some(serial.to_string());
    c.g_m_s2 = Some(G);
    let mut campaign = format!("# device_id: {device}\n").into_bytes();
    c.write(&mut campaign).context("writing a simulated campaign")?;
    let pos = Positions::new(&c, G);
    let stats = pos.channel_stats(&c);
    let fits = fit_positions(&pos, &stats, Method::Lsq, MODEL_4)?;
    let refs = References {
        head_angle_rad: 20.0 * ARCSEC,
        head_orthogonality_rad: 10.0 * ARCSEC,
        g_m_s2: 1e-5,
        lack_of_fit_codes: None,
        temperature: None,
    };
    let only: Vec<_> = fits.iter().map(|(_, f)| f).collect();
    let budget = uncertainty::budget(&pos, &stats, &only, refs).context("a simulated unit's budget")?;
    let m = accelcal_shared::linear::Model4 {
        u0: std::array::from_fn(|c| fits[c].1.coefficients[0]),
        k: std::array::from_fn(|c| std::array::from_fn(|j| fits[c].1.coefficients[j + 1])),
    };
    let id = accelcal_core::calibrate::parse_device_id(device).map_err(|e| anyhow::anyhow!("{e}"))?;
    let rec = Record::from_model4(id, FIRST_DAY_UNIX_S as u64, &m);
    let mut buf = [0u8; MAX_RECORD_LEN];
    let n = rec.emit(&mut buf).map_err(|e| anyhow::anyhow!("a simulated record: {e:?}"))?;
    let identity = Identity {
        device_id: Some(device.to_string()),
        serial: Some(serial.to_string()),
        g_m_s2: G,
        g_source: None,
        campaign_sha256: accelcal_core::digest::sha256_hex(&campaign),
        record_crc: Some(format!("{:08x}", accelcal_shared::record::crc32(&buf[..n]))),
    };
    let doc = super::fit::to_json(Method::Lsq, &fits, 25.0, identity, Some(&budget));
    Ok(Pieces { campaign, fit_json: serde_json::to_string(&doc)?, record: buf[..n].to_vec() })
}

/// A certificate of the size the station issues (its tables reduced to their rows).
fn certificate_html(serial: &str, run: RunId, fit_json: &str) -> String {
    format!(
        "<!DOCTYPE html><html><head><meta charset=\"utf-8\"><title>Calibration certificate {serial}</title></head>\
         <body><h1>Calibration certificate</h1><p>Unit {serial}, run {run}</p><pre>{}</pre></body></html>",
        fit_json.replace('<', "&lt;")
    )
}

/// Writes the line's history through the store path: units `u ≡ writer (mod writers)`, each
/// drawn from its own seed (the rows do not depend on how many writers share the work);
/// `progress` sees each run written.
pub fn generate(
    db: &mut Db,
    line: Line,
    writer: u32,
    writers: u32,
    progress: &(dyn Fn(u64) + Sync),
) -> anyhow::Result<()> {
    let heads = heads();
    for u in (writer..line.units).step_by(writers as usize) {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(
            line.seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ u64::from(u),
        );
        let (device, serial) = unit_ids(u);
        let station = (u as usize) % STATIONS.len();
        for k in 0..line.runs_of(u) {
            let t = line.start_of(u, k, &mut rng);
            let run = RunId::parse(&format!(
                "{:032x}",
                (u128::from(line.seed) << 64) | (u128::from(u) << 8) | u128::from(k)
            ))?;
            let s = RunStart {
                run_id: run,
                device_id: device.clone(),
                serial: serial.clone(),
                station: STATIONS[station].into(),
                head: format!("rig-{}", station + 1),
                operator: OPERATORS[rng.random_range(0..OPERATORS.len())].into(),
                started_unix_s: t,
                software_version: env!("CARGO_PKG_VERSION").into(),
                firmware_version: "0.4.0".into(),
                g_m_s2: G,
                g_source: accelcal_core::campaign::GSource::Given { u_m_s2: None }.tag(),
            };
            db.begin_run(&s, None)?;
            db.store_run_asset(run, &heads[station])?;
            if k > 0 {
                // As found: a year's drift, now and then beyond the limits.
                let sd = if rng.random_bool(0.03) { 0.02 } else { 0.006 };
                db.store_verification(run, Phase::AsFound, &verification(&device, sd, &mut rng)?)?;
            }
            let p = pieces(&device, &serial, rng.random())?;
            db.store_campaign(run, &p.campaign)?;
            let fate: f64 = rng.random();
            if fate < 0.002 {
                // Stopped on the line and never finished.
                progress(1);
                continue;
            }
            if fate < 0.02 {
                db.finish_run(run, Outcome::Rejected, "select: model 4 is not the model GMDH chose")?;
                progress(1);
                continue;
            }
            db.store_fit(run, &p.fit_json)?;
            let rec = db.store_record(run, &p.record)?;
            db.record_flashed(&rec)?;
            db.store_verification(run, Phase::AsLeft, &verification(&device, 0.003, &mut rng)?)?;
            let due = RecalibrationDue {
                due_unix_s: t + INTERVAL_DAYS * DAY_S,
                basis: format!("{INTERVAL_DAYS} days (the line's interval)"),
            };
            db.certificate_number_with_due(run, &due)?;
            db.store_certificate(run, &certificate_html(&serial, run, &p.fit_json))?;
            db.finish_run(run, Outcome::Pass, "verified")?;
            if fate < 0.021 {
                db.void_run(run, "the head's certificate was found wrong", "ana")?;
            }
            progress(1);
        }
    }
    Ok(())
}

/// Registers the line's heads and writes its history with `writers` connections at once.
pub fn generate_all(
    spec: &str,
    line: Line,
    writers: u32,
    progress: &(dyn Fn(u64) + Sync),
) -> anyhow::Result<()> {
    let mut db = Db::open(spec)?;
    for h in heads() {
        db.add_asset(&h)?;
    }
    drop(db);
    std::thread::scope(|s| {
        let jobs: Vec<_> = (0..writers)
            .map(|w| {
                s.spawn(move || -> anyhow::Result<()> {
                    let mut db = Db::open(spec)?;
                    generate(&mut db, line, w, writers, progress)
                })
            })
            .collect();
        jobs.into_iter().try_for_each(|j| j.join().map_err(|_| anyhow::anyhow!("a writer panicked"))?)
    })
}

/// One HTTP GET of `path` from the server at `addr`: (status, body bytes).
fn get(addr: &str, path: &str) -> anyhow::Result<(u16, usize)> {
    let mut s = std::net::TcpStream::connect(addr).with_context(|| format!("connecting to {addr}"))?;
    s.set_read_timeout(Some(Duration::from_secs(120)))?;
    write!(s, "GET {path} HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n\r\n")?;
    let mut answer = Vec::new();
    s.read_to_end(&mut answer)?;
    let text = String::from_utf8_lossy(&answer);
    let status = text.split_whitespace().nth(1).and_then(|c| c.parse().ok()).unwrap_or(0);
    Ok((status, answer.len()))
}

/// The median and the largest of `times`.
fn median_max(mut times: Vec<Duration>) -> (Duration, Duration) {
    times.sort();
    (times[times.len() / 2], times[times.len() - 1])
}

/// Runs `accelcal bench-fleet`.
pub fn run(a: &BenchFleet) -> anyhow::Result<()> {
    let line = Line { units: a.units, runs: a.runs, seed: a.seed };
    let mut db = Db::open(&a.db)?;
    let held = db.fleet_counts(&accelcal_db::fleet::Filter {
        since_unix_s: i64::MIN / 2,
        until_unix_s: i64::MAX / 2,
        station: None,
        head_asset: None,
        serial_prefix: None,
        operator: None,
        // Only whether the line is there: no run is checked against its chain.
        tampered: Some(Default::default()),
    })?;
    if held.runs == 0 {
        let bar = indicatif::ProgressBar::new(u64::from(a.runs));
        bar.set_style(
            indicatif::ProgressStyle::with_template(
                "generating {pos}/{len} runs [{elapsed_precise}, {eta} left]",
            )
            .context("a progress template")?,
        );
        let t = Instant::now();
        drop(db);
        generate_all(&a.db, line, a.writers, &|n| bar.inc(n))?;
        bar.finish_and_clear();
        outln!(
            "generated {} units, {} runs through the store path in {:.0} s",
            a.units,
            a.runs,
            t.elapsed().as_secs_f64()
        )?;
    } else {
        outln!(
            "{} holds {} runs of {} units already: not generated again",
            db.target(),
            held.runs,
            held.units
        )?;
    }
    let exe = std::env::current_exe().context("finding accelcal itself")?;
    let (since, until) = (a.first_day.clone(), a.last_day.clone());
    let json = std::env::temp_dir().join(format!("accelcal-bench-fleet-{}.json", std::process::id()));
    let mut times = Vec::new();
    for _ in 0..a.repeat {
        let t = Instant::now();
        let st = std::process::Command::new(&exe)
            .args(["fleet", "--db", &a.db, "--since", &since, "--until", &until, "--json"])
            .arg(&json)
            .stdout(std::process::Stdio::null())
            .status()
            .context("running accelcal fleet")?;
        times.push(t.elapsed());
        if !st.success() {
            return Err(anyhow::anyhow!("accelcal fleet failed: {st}"));
        }
    }
    let (fleet_med, fleet_max) = median_max(times);
    let json_bytes = std::fs::metadata(&json).map_or(0, |m| m.len());
    let _ = std::fs::remove_file(&json);
    let mut server = std::process::Command::new(&exe)
        .args(["serve", "--db", &a.db, "--bind", "127.0.0.1:0"])
        .stdout(std::process::Stdio::piped())
        .spawn()
        .context("starting accelcal serve")?;
    let mut first = String::new();
    {
        use std::io::BufRead;
        let stdout = server.stdout.take().context("the server's output")?;
        std::io::BufReader::new(stdout).read_line(&mut first)?;
    }
    let addr = first.split("http://").nth(1).and_then(|s| s.split('/').next()).map(str::to_string);
    let result = (|| -> anyhow::Result<Vec<(String, Duration, Duration, usize)>> {
        let addr = addr.context("the server's address")?;
        let (_, serial) = unit_ids(a.units / 2);
        let pages = [
            ("overview /".to_string(), "/".to_string()),
            (format!("unit /unit/{serial}"), format!("/unit/{serial}")),
            (format!("fleet page {since}…{until}"), format!("/fleet?since={since}&until={until}")),
            (format!("charts page {since}…{until}"), format!("/charts?since={since}&until={until}")),
        ];
        let mut rows = Vec::new();
        for (name, path) in pages {
            let mut times = Vec::new();
            let mut size = 0;
            for _ in 0..a.repeat {
                let t = Instant::now();
                let (status, n) = get(&addr, &path)?;
                times.push(t.elapsed());
                if status != 200 {
                    return Err(anyhow::anyhow!("GET {path}: HTTP {status}"));
                }
                size = n;
            }
            let (med, max) = median_max(times);
            rows.push((name, med, max, size));
        }
        Ok(rows)
    })();
    let _ = server.kill();
    let _ = server.wait();
    let rows = result?;
    outln!("{:<40} {:>10} {:>10} {:>10}  aim", "", "median", "max", "bytes")?;
    let ms = |d: Duration| format!("{:.0} ms", d.as_secs_f64() * 1e3);
    outln!(
        "{:<40} {:>10} {:>10} {:>10}  ≤ 1 s",
        format!("fleet --json, {}", a.month),
        ms(fleet_med),
        ms(fleet_max),
        json_bytes
    )?;
    let aims = ["≤ 300 ms", "≤ 100 ms", "-", "-"];
    for ((name, med, max, size), aim) in rows.into_iter().zip(aims) {
        outln!("{name:<40} {:>10} {:>10} {size:>10}  {aim}", ms(med), ms(max))?;
    }
    Ok(())
}
