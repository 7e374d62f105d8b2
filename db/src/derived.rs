//! Rows derived from the stored pieces (schema 6): what the fleet's statistics read, as numbers
//! SQL can aggregate, instead of every document of a period parsed in the process.
//!
//! Each is written in the transaction that stores its piece (a fit, a verification, a campaign),
//! by the one function here that derives it; a database migrated from version 5 gets them for
//! the pieces it holds when it is next opened ([`backfill`], under the migration's lock). They
//! are not pieces: the ledger does not chain them; [`check`] derives them again from the
//! chained pieces and compares (`db verify`).

use serde::{Deserialize, Serialize};

use super::engine::{Conn, Tx, Val};
use super::DbError;
use accelcal_core::document::verify::VerifyReport;
use accelcal_core::document::FitDoc;

const AXES: [&str; 3] = ["x", "y", "z"];

/// A fit's derived rows: its model-4 coefficients and U (`fit_summary`), its IEEE 1293
/// parameters (`fit_parameter`: name, unit, value, in `fleet`'s order).
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct FitRows {
    pub model4: Option<[[f64; 4]; 3]>,
    pub u_m_s2: Option<[f64; 3]>,
    pub parameters: Vec<(String, &'static str, f64)>,
}

/// The names of a model-4 triad's IEEE 1293 parameters in `fleet`'s order, with their units:
/// `K0 x…z` (mg), `K1 x…z` (codes/g), then `δ c→j` (µrad).
pub fn fit_parameter_names() -> Vec<(String, &'static str)> {
    let mut out: Vec<(String, &'static str)> = Vec::new();
    out.extend(AXES.iter().map(|a| (format!("K0 {a}"), "mg")));
    out.extend(AXES.iter().map(|a| (format!("K1 {a}"), "codes/g")));
    for c in 0..3 {
        for j in (0..3).filter(|&j| j != c) {
            out.push((format!("δ {}→{}", AXES[c], AXES[j]), "µrad"));
        }
    }
    out
}

pub(crate) fn fit_rows(doc: &FitDoc) -> FitRows {
    let model4 = super::history::model4_of(doc).ok().map(|m| m.coef);
    let parameters = model4.as_ref().map(fit_parameters).unwrap_or_default();
    FitRows { model4, u_m_s2: doc.uncertainty.as_ref().map(|u| u.u_m_s2), parameters }
}

/// A model-4 triad's IEEE 1293 parameters (`[channel][term 1, ax, ay, az]`), as
/// `fit_parameter` holds them: name, unit and value, in [`fit_parameter_names`]' order.
pub fn fit_parameters(model4: &[[f64; 4]; 3]) -> Vec<(String, &'static str, f64)> {
    use accelcal_core::ieee1293::Parameters;
    let p: [Parameters; 3] = std::array::from_fn(|c| Parameters::of(c, model4[c]));
    let mut values: Vec<f64> = Vec::new();
    values.extend(p.iter().map(|p| p.k0_mg));
    values.extend(p.iter().map(|p| p.k1_codes_per_g));
    for (c, pc) in p.iter().enumerate() {
        values.extend((0..3).filter(|&j| j != c).map(|j| pc.delta_urad[j]));
    }
    fit_parameter_names().into_iter().zip(values).map(|((name, unit), v)| (name, unit, v)).collect()
}

/// A verification's derived rows: decision and rule, largest |error|, and the parameters it
/// measured (name, unit, value, limit).
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct VerificationRows {
    pub decision: Option<String>,
    pub rule: Option<String>,
    pub max_abs_error_m_s2: f64,
    pub parameters: Vec<(String, &'static str, f64, f64)>,
}

pub(crate) fn verification_rows(report: &VerifyReport) -> VerificationRows {
    // As the report's JSON spells them (the view `verification_decision` read them from it).
    fn spelled<T: Serialize>(v: &T) -> Option<String> {
        serde_json::to_value(v).ok().and_then(|v| v.as_str().map(str::to_string))
    }
    VerificationRows {
        decision: report.decision.as_ref().and_then(spelled),
        rule: report.specification.as_ref().and_then(|s| spelled(&s.rule)),
        max_abs_error_m_s2: report.max_abs_error_m_s2(),
        parameters: report
            .parameters
            .iter()
            .flatten()
            .map(|p| {
                let unit = match p.unit.as_str() {
                    "mg" => "mg",
                    "ppm" => "ppm",
                    _ => "µrad",
                };
                (format!("{} {}", p.parameter.replace('_', " "), p.axis), unit, p.value, p.limit)
            })
            .collect(),
    }
}

/// What a campaign shows of the head, as `head_observation` holds it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Observation {
    /// The commanded positions `(α, β)`, degrees.
    pub positions: Vec<(f64, f64)>,
    /// The model-4 residual at each, m/s².
    pub resid_m_s2: Vec<[f64; 3]>,
    /// The misalignments, µrad ([`accelcal_core::headsig::CROSS_TERMS`]).
    pub misalign_urad: [f64; 6],
}

/// Version byte of [`Observation::to_bytes`].
const OBS_BYTES_VERSION: u8 = 1;

impl Observation {
    /// Bytes before the positions in [`Observation::to_bytes`]: the version and the count.
    const HEAD: usize = 3;
    /// Bytes per position: α and β (f64), the three residuals (f32).
    const PER_POSITION: usize = 16 + 12;
    /// Bytes of the six misalignments (f32).
    const TAIL: usize = 24;

    /// The compact form `head_observation_f32` holds: a version byte, the number of positions
    /// (u16), the positions (α, β as f64: a plan's angles exactly), the residuals (three f32 per
    /// position, m/s²: seven significant digits of a number whose noise is the fourth) and the
    /// misalignments (six f32, µrad), little-endian. `None` when the positions and residuals
    /// differ in number or exceed a u16 (the observation then stays in JSON only).
    pub fn to_bytes(&self) -> Option<Vec<u8>> {
        let n = self.positions.len();
        if n != self.resid_m_s2.len() || n > usize::from(u16::MAX) {
            return None;
        }
        let mut b = Vec::with_capacity(Self::HEAD + n * Self::PER_POSITION + Self::TAIL);
        b.push(OBS_BYTES_VERSION);
        b.extend_from_slice(&(n as u16).to_le_bytes());
        for &(alpha, beta) in &self.positions {
            b.extend_from_slice(&alpha.to_le_bytes());
            b.extend_from_slice(&beta.to_le_bytes());
        }
        for v in self.resid_m_s2.as_flattened().iter().chain(&self.misalign_urad) {
            b.extend_from_slice(&(*v as f32).to_le_bytes());
        }
        Some(b)
    }

    /// Reads [`Observation::to_bytes`]'s form back; any other bytes are an error that says why
    /// (never a panic: the bytes come from a database anyone may write to).
    pub fn from_bytes(b: &[u8]) -> Result<Observation, String> {
        let (&version, rest) = b.split_first().ok_or("no bytes")?;
        if version != OBS_BYTES_VERSION {
            return Err(format!("format version {version}, this build reads {OBS_BYTES_VERSION}"));
        }
        let n = match rest {
            [lo, hi, ..] => usize::from(u16::from_le_bytes([*lo, *hi])),
            _ => return Err("no count of positions".into()),
        };
        let want = Self::HEAD + n * Self::PER_POSITION + Self::TAIL;
        if b.len() != want {
            return Err(format!("{} bytes for {n} positions, not {want}", b.len()));
        }
        // The lengths are checked: each section splits into whole values.
        let (angles, singles) = b[Self::HEAD..].split_at(16 * n);
        let f64_at = |c: &[u8]| f64::from_le_bytes(c.try_into().expect("8 bytes"));
        let f32s: Vec<f64> = singles
            .chunks_exact(4)
            .map(|c| f64::from(f32::from_le_bytes(c.try_into().expect("4 bytes"))))
            .collect();
        let (resid, misalign) = f32s.split_at(3 * n);
        let positions = angles.chunks_exact(16).map(|c| (f64_at(&c[..8]), f64_at(&c[8..]))).collect();
        let resid_m_s2 = resid.chunks_exact(3).map(|r| [r[0], r[1], r[2]]).collect();
        let misalign_urad = misalign.try_into().expect("six misalignments");
        Ok(Observation { positions, resid_m_s2, misalign_urad })
    }
}

/// The observation of a stored campaign (its plain bytes) at `g`: `Ok(None)` for a campaign
/// that is not a triad model 4 fits with an invertible sensitivity (nothing to observe), `Err`
/// for one that does not read.
pub(crate) fn observation(plain: &[u8], g: f64) -> Result<Option<Observation>, String> {
    use accelcal_core::campaign::Campaign;
    let reduced =
        Campaign::reduce_reader(plain, std::path::Path::new("stored campaign")).map_err(|e| e.to_string())?;
    let pos = reduced.positions(g);
    Ok(accelcal_core::headsig::observe(&pos, &reduced.channel_stats()).map(|o| Observation {
        positions: o.positions,
        resid_m_s2: o.resid_m_s2,
        misalign_urad: o.misalign_urad,
    }))
}

fn json<T: Serialize>(v: &T) -> Val {
    Val::from(serde_json::to_string(v).expect("numbers serialise"))
}

pub(crate) fn insert_fit(tx: &mut Tx<'_>, run: &str, doc: &FitDoc) -> Result<(), DbError> {
    let rows = fit_rows(doc);
    let opt = |v: Option<Val>| v.unwrap_or(Val::Null);
    tx.execute(
        "INSERT INTO fit_summary (run_id, model4_json, u_json) VALUES ($1, $2, $3)",
        &[run.to_string().into(), opt(rows.model4.as_ref().map(json)), opt(rows.u_m_s2.as_ref().map(json))],
    )?;
    for (ord, (name, unit, value)) in rows.parameters.into_iter().enumerate() {
        tx.execute(
            "INSERT INTO fit_parameter (run_id, ord, name, unit, value) VALUES ($1, $2, $3, $4, $5)",
            &[
                run.to_string().into(),
                (ord as i64).into(),
                name.into(),
                unit.to_string().into(),
                value.into(),
            ],
        )?;
    }
    Ok(())
}

pub(crate) fn insert_verification(
    tx: &mut Tx<'_>,
    run: &str,
    phase: &str,
    report: &VerifyReport,
) -> Result<(), DbError> {
    let rows = verification_rows(report);
    let text = |v: Option<String>| v.map_or(Val::Null, Val::from);
    tx.execute(
        "INSERT INTO verification_summary (run_id, phase, decision, rule, max_abs_error_m_s2) \
         VALUES ($1, $2, $3, $4, $5)",
        &[
            run.to_string().into(),
            phase.to_string().into(),
            text(rows.decision),
            text(rows.rule),
            rows.max_abs_error_m_s2.into(),
        ],
    )?;
    for (ord, (name, unit, value, limit)) in rows.parameters.into_iter().enumerate() {
        tx.execute(
            "INSERT INTO verification_parameter (run_id, phase, ord, name, unit, value, limit_value) \
             VALUES ($1, $2, $3, $4, $5, $6, $7)",
            &[
                run.to_string().into(),
                phase.to_string().into(),
                (ord as i64).into(),
                name.into(),
                unit.to_string().into(),
                value.into(),
                limit.into(),
            ],
        )?;
    }
    Ok(())
}

/// Inserts the observation [`observation`] made of a run's campaign (made before the
/// transaction: reading a campaign takes time the ledger's lock should not wait for).
pub(crate) fn insert_observation(
    tx: &mut Tx<'_>,
    run: &str,
    seen: &Result<Option<Observation>, String>,
) -> Result<(), DbError> {
    let (obs, why) = match seen {
        Ok(o) => (o.as_ref().map_or(Val::Null, json), Val::Null),
        Err(why) => (Val::Null, Val::from(why.clone())),
    };
    tx.execute(
        "INSERT INTO head_observation (run_id, obs_json, why) VALUES ($1, $2, $3)",
        &[run.to_string().into(), obs, why],
    )?;
    if let Ok(Some(o)) = seen {
        insert_compact(tx, run, o)?;
    }
    Ok(())
}

/// Writes `head_observation_f32`'s row of an observation (none when it has no compact form).
fn insert_compact(tx: &mut Tx<'_>, run: &str, o: &Observation) -> Result<(), DbError> {
    if let Some(bytes) = o.to_bytes() {
        tx.execute(
            "INSERT INTO head_observation_f32 (run_id, obs) VALUES ($1, $2)",
            &[run.to_string().into(), Val::Bytes(bytes)],
        )?;
    }
    Ok(())
}

/// The latest certified run of each device that is not voided, as `device_certificate` holds
/// it: `(device_id, run_id, due_unix_s)`, from `device` only when given.
const LATEST_CERTIFICATES: &str = "SELECT device_id, run_id, due_unix_s FROM (SELECT r.device_id, r.run_id, \
     d.due_unix_s, ROW_NUMBER() OVER (PARTITION BY r.device_id ORDER BY r.started_unix_s DESC, r.run_id DESC) AS n \
     FROM recalibration_due d JOIN run r ON r.run_id = d.run_id \
     WHERE ($1 = '' OR r.device_id = $1) AND NOT EXISTS (SELECT 1 FROM void v WHERE v.run_id = d.run_id)) latest \
     WHERE n = 1";

/// Rewrites `device_certificate`'s row of `device` (after a certificate's date is stored, or a
/// run of it voided).
pub(crate) fn refresh_device_certificate(tx: &mut Tx<'_>, device: &str) -> Result<(), DbError> {
    tx.execute("DELETE FROM device_certificate WHERE device_id = $1", &[device.into()])?;
    tx.execute(
        &format!("INSERT INTO device_certificate (device_id, run_id, due_unix_s) {LATEST_CERTIFICATES}"),
        &[device.into()],
    )?;
    Ok(())
}

fn gunzip(run: &str, gz: &[u8]) -> Result<Vec<u8>, DbError> {
    use std::io::Read;
    let mut plain = Vec::new();
    flate2::read::GzDecoder::new(gz).read_to_end(&mut plain).map_err(|e| DbError::BadPiece {
        run_id: run.to_string(),
        piece: "campaign",
        cause: format!("its stored gzip does not decompress: {e}"),
    })?;
    Ok(plain)
}

/// Rows a batch of the backfill takes in one transaction.
const BATCH: i64 = 500;

/// Whether a migration left rows to derive ([`backfill`]).
pub(crate) fn pending(tx: &mut Tx<'_>) -> Result<bool, DbError> {
    let pending = tx.query("SELECT pending FROM derived_backfill", &[])?;
    Ok(pending.iter().any(|r| matches!(r[0], Val::Int(p) if p != 0)))
}

/// Derives the rows of every stored piece that has none yet (a database written before schema
/// 6, or its compact head observations before schema 7), a batch at a time; how many rows it
/// derived. The open calls it when [`pending`] says so, under the migration's lock.
pub(crate) fn backfill(c: &mut Conn) -> Result<usize, DbError> {
    let mut n = 0;
    // Each table is walked once in key order (a batch starts after the last key of the one
    // before), so that a batch does not scan again the rows the batches before it derived.
    let (mut after_fit, mut after_v, mut after_c, mut after_h) =
        (String::new(), (String::new(), String::new()), String::new(), String::new());
    loop {
        let done = c.transaction(|tx| {
            let rows = tx.query(
                &format!(
                    "SELECT f.run_id, f.fit_json FROM fit f WHERE f.run_id > $1 AND NOT EXISTS \
                     (SELECT 1 FROM fit_summary s WHERE s.run_id = f.run_id) ORDER BY f.run_id LIMIT {BATCH}"
                ),
                &[after_fit.clone().into()],
            )?;
            for r in &rows {
                let run = r[0].text()?;
                // A fit stored before documents were checked may not parse: it derives nothing
                // but its summary row, so that it is not read again.
                let doc = FitDoc::parse(&r[1].text()?).unwrap_or(FitDoc {
                    version: 0,
                    method: String::new(),
                    identity: None,
                    t_ref_c: None,
                    channels: Vec::new(),
                    uncertainty: None,
                });
                insert_fit(tx, &run, &doc)?;
                after_fit = run;
            }
            let vs = tx.query(
                &format!(
                    "SELECT v.run_id, v.phase, v.report_json FROM verification v \
                     WHERE (v.run_id > $1 OR (v.run_id = $1 AND v.phase > $2)) AND NOT EXISTS \
                     (SELECT 1 FROM verification_summary s WHERE s.run_id = v.run_id AND s.phase = v.phase) \
                     ORDER BY v.run_id, v.phase LIMIT {BATCH}"
                ),
                &[after_v.0.clone().into(), after_v.1.clone().into()],
            )?;
            for r in &vs {
                let (run, phase) = (r[0].text()?, r[1].text()?);
                after_v = (run.clone(), phase.clone());
                match VerifyReport::parse(&r[2].text()?) {
                    Ok(report) => insert_verification(tx, &run, &phase, &report)?,
                    Err(_) => {
                        tx.execute(
                            "INSERT INTO verification_summary (run_id, phase, decision, rule, max_abs_error_m_s2) \
                             VALUES ($1, $2, NULL, NULL, NULL)",
                            &[run.into(), phase.into()],
                        )?;
                    }
                }
            }
            let cs = tx.query(
                &format!(
                    "SELECT c.run_id, c.gzip, r.g_m_s2 FROM campaign c JOIN run r ON r.run_id = c.run_id \
                     WHERE c.run_id > $1 AND NOT EXISTS (SELECT 1 FROM head_observation h WHERE h.run_id = c.run_id) \
                     ORDER BY c.run_id LIMIT {BATCH}"
                ),
                &[after_c.clone().into()],
            )?;
            for r in &cs {
                let run = r[0].text()?;
                let plain = gunzip(&run, &r[1].bytes()?)?;
                insert_observation(tx, &run, &observation(&plain, r[2].real()?))?;
                after_c = run;
            }
            // Observations stored before schema 7: their compact form, from their JSON (one
            // that does not parse is left in JSON, where `db verify` names it).
            let hs = tx.query(
                &format!(
                    "SELECT h.run_id, h.obs_json FROM head_observation h WHERE h.run_id > $1 \
                     AND h.obs_json IS NOT NULL AND NOT EXISTS \
                     (SELECT 1 FROM head_observation_f32 b WHERE b.run_id = h.run_id) ORDER BY h.run_id LIMIT {BATCH}"
                ),
                &[after_h.clone().into()],
            )?;
            for r in &hs {
                let run = r[0].text()?;
                if let Ok(o) = serde_json::from_str::<Observation>(&r[1].text()?) {
                    insert_compact(tx, &run, &o)?;
                }
                after_h = run;
            }
            Ok(rows.len() + vs.len() + cs.len() + hs.len())
        })?;
        if done == 0 {
            c.transaction(|tx| {
                tx.execute("DELETE FROM device_certificate", &[])?;
                tx.execute(
                    &format!("INSERT INTO device_certificate (device_id, run_id, due_unix_s) {LATEST_CERTIFICATES}"),
                    &["".into()],
                )?;
                tx.execute("UPDATE derived_backfill SET pending = 0", &[])
            })?;
            return Ok(n);
        }
        n += done;
    }
}

/// Whether two lists of numbers derived from the same piece agree: to `rel` relative
/// ([`F64_CLOSE`], [`F32_CLOSE`]). A number read back from JSON may differ from the one written
/// in its last bit (serde_json's parser), and a later version may compute an observation in
/// another order; a changed row differs by far more.
fn close(a: &[f64], b: &[f64], rel: f64) -> bool {
    a.len() == b.len() && a.iter().zip(b).all(|(x, y)| (x - y).abs() <= rel * x.abs().max(y.abs()).max(1e-12))
}

/// How close a number stored as f64 is to the same number derived again, relative.
const F64_CLOSE: f64 = 1e-9;

/// How close a number stored as f32 is to the f64 it was made from, relative: f32 rounds to
/// 6e-8, and a later version may compute the f64 in another order.
const F32_CLOSE: f64 = 1e-6;

/// Whether two observations (or their absence) agree, numbers to `rel` relative ([`close`]).
fn same_observation(a: Option<&Observation>, b: Option<&Observation>, rel: f64) -> bool {
    match (a, b) {
        (Some(a), Some(b)) => {
            let flat = |o: &Observation| o.positions.iter().flat_map(|&(x, y)| [x, y]).collect::<Vec<f64>>();
            close(&flat(a), &flat(b), rel)
                && close(a.resid_m_s2.as_flattened(), b.resid_m_s2.as_flattened(), rel)
                && close(&a.misalign_urad, &b.misalign_urad, rel)
        }
        (a, b) => a.is_none() && b.is_none(),
    }
}

/// Derives every piece's rows again and compares them with the stored ones: the runs whose
/// derived rows differ (or are missing): run, tables, what.
pub(crate) fn check(tx: &mut Tx<'_>) -> Result<Vec<(String, &'static str, String)>, DbError> {
    let mut bad = Vec::new();
    for r in tx.query(
        "SELECT f.run_id, f.fit_json, s.model4_json, s.u_json FROM fit f \
         LEFT JOIN fit_summary s ON s.run_id = f.run_id",
        &[],
    )? {
        let key = r[0].text().unwrap_or_default();
        let each = |bad: &mut Vec<(String, &'static str, String)>, tx: &mut Tx<'_>| -> Result<(), DbError> {
            let run = r[0].text()?;
            let Ok(doc) = FitDoc::parse(&r[1].text()?) else { return Ok(()) };
            let want = fit_rows(&doc);
            let text = |v: &Val| -> Result<Option<String>, DbError> {
                match v {
                    Val::Null => Ok(None),
                    v => v.text().map(Some),
                }
            };
            let m4: Option<[[f64; 4]; 3]> = text(&r[2])?.and_then(|t| serde_json::from_str(&t).ok());
            let u: Option<[f64; 3]> = text(&r[3])?.and_then(|t| serde_json::from_str(&t).ok());
            // Every column of the derived rows: the name, the unit and the value, in order.
            let params: Vec<(i64, String, String, f64)> = tx
                .query(
                    "SELECT ord, name, unit, value FROM fit_parameter WHERE run_id = $1 ORDER BY ord",
                    &[run.clone().into()],
                )?
                .iter()
                .map(|p| Ok((p[0].int()?, p[1].text()?, p[2].text()?, p[3].real()?)))
                .collect::<Result<_, DbError>>()?;
            let want_params: Vec<(i64, String, String, f64)> = want
                .parameters
                .iter()
                .enumerate()
                .map(|(i, (n, u, v))| (i as i64, n.clone(), u.to_string(), *v))
                .collect();
            let m4_same = match (m4, want.model4) {
                (Some(a), Some(b)) => close(a.as_flattened(), b.as_flattened(), F64_CLOSE),
                (a, b) => a.is_none() && b.is_none(),
            };
            let u_same = match (u, want.u_m_s2) {
                (Some(a), Some(b)) => close(&a, &b, F64_CLOSE),
                (a, b) => a.is_none() && b.is_none(),
            };
            if !m4_same || !u_same || params != want_params {
                bad.push((run, "fit_summary/fit_parameter", "not what its fit derives".into()));
            }
            Ok(())
        };
        // A cell that does not read (`db verify` names it) is this run's finding, not the end of the check.
        if let Err(e) = each(&mut bad, tx) {
            bad.push((key, "fit_summary/fit_parameter", format!("a cell does not read as its type: {e}")));
        }
    }
    for r in tx.query(
        "SELECT v.run_id, v.phase, v.report_json, s.decision, s.max_abs_error_m_s2, s.rule, s.run_id FROM verification v \
         LEFT JOIN verification_summary s ON s.run_id = v.run_id AND s.phase = v.phase",
        &[],
    )? {
        let key = r[0].text().unwrap_or_default();
        let each = |bad: &mut Vec<(String, &'static str, String)>, tx: &mut Tx<'_>| -> Result<(), DbError> {
            let (run, phase) = (r[0].text()?, r[1].text()?);
            let Ok(report) = VerifyReport::parse(&r[2].text()?) else { return Ok(()) };
            let want = verification_rows(&report);
            let decision = match &r[3] {
                Val::Null => None,
                v => Some(v.text()?),
            };
            let max = match &r[4] {
                Val::Null => f64::NAN,
                v => v.real()?,
            };
            let rule = r[5].opt_text()?;
            let params: Vec<(i64, String, String, f64, f64)> = tx
                .query(
                    "SELECT ord, name, unit, value, limit_value FROM verification_parameter WHERE run_id = $1 \
                     AND phase = $2 ORDER BY ord",
                    &[run.clone().into(), phase.clone().into()],
                )?
                .iter()
                .map(|p| Ok((p[0].int()?, p[1].text()?, p[2].text()?, p[3].real()?, p[4].real()?)))
                .collect::<Result<_, DbError>>()?;
            let want_params: Vec<(i64, String, String, f64, f64)> = want
                .parameters
                .iter()
                .enumerate()
                .map(|(i, (n, u, v, l))| (i as i64, n.clone(), u.to_string(), *v, *l))
                .collect();
            if r[6] == Val::Null
                || decision != want.decision
                || rule != want.rule
                || max.to_bits() != want.max_abs_error_m_s2.to_bits()
                || params != want_params
            {
                bad.push((
                    run,
                    "verification_summary/verification_parameter",
                    format!("not what its {phase} verification derives"),
                ));
            }
            Ok(())
        };
        // A cell that does not read (`db verify` names it) is this run's finding, not the end of the check.
        if let Err(e) = each(&mut bad, tx) {
            bad.push((key, "verification_summary/verification_parameter", format!("a cell does not read as its type: {e}")));
        }
    }
    let mut want: Vec<Vec<String>> = Vec::new();
    for r in tx.query(LATEST_CERTIFICATES, &["".into()])? {
        want.push(vec![r[0].text()?, r[1].text()?, r[2].int()?.to_string()]);
    }
    let mut held: Vec<Vec<String>> = Vec::new();
    for r in tx.query("SELECT device_id, run_id, due_unix_s FROM device_certificate", &[])? {
        held.push(vec![r[0].text()?, r[1].text()?, r[2].int()?.to_string()]);
    }
    want.sort();
    held.sort();
    if want != held {
        let differ = want.iter().zip(&held).find(|(w, h)| w != h).map(|(w, _)| w.clone());
        let device =
            differ.or_else(|| want.last().cloned()).or_else(|| held.last().cloned()).unwrap_or_default();
        bad.push((
            device.get(1).cloned().unwrap_or_default(),
            "device_certificate",
            "not each unit's latest certified run".into(),
        ));
    }
    for r in tx.query(
        "SELECT c.run_id, c.gzip, r.g_m_s2, h.obs_json, b.obs FROM campaign c JOIN run r ON r.run_id = c.run_id \
         LEFT JOIN head_observation h ON h.run_id = c.run_id LEFT JOIN head_observation_f32 b ON b.run_id = c.run_id",
        &[],
    )? {
        let key = r[0].text().unwrap_or_default();
        let each = |bad: &mut Vec<(String, &'static str, String)>, _tx: &mut Tx<'_>| -> Result<(), DbError> {
            let run = r[0].text()?;
            let Ok(plain) = gunzip(&run, &r[1].bytes()?) else { return Ok(()) };
            let want = observation(&plain, r[2].real()?).ok().flatten();
            let stored: Option<Observation> = match &r[3] {
                Val::Null => None,
                v => serde_json::from_str(&v.text()?).ok(),
            };
            if !same_observation(stored.as_ref(), want.as_ref(), F64_CLOSE) {
                bad.push((run.clone(), "head_observation", "not what its campaign derives".into()));
            }
            // The compact form: there exactly when the observation has one, and the same to f32's
            // precision.
            let compact = match &r[4] {
                Val::Null => None,
                v => Some(Observation::from_bytes(&v.bytes()?)),
            };
            let same = match (compact, want.as_ref().filter(|w| w.to_bytes().is_some())) {
                (None, None) => true,
                (Some(Ok(a)), Some(b)) => same_observation(Some(&a), Some(b), F32_CLOSE),
                _ => false,
            };
            if !same {
                bad.push((run, "head_observation_f32", "not what its campaign derives".into()));
            }
            Ok(())
        };
        // A cell that does not read (`db verify` names it) is this run's finding, not the end of the check.
        if let Err(e) = each(&mut bad, tx) {
            bad.push((key, "head_observation", format!("a cell does not read as its type: {e}")));
        }
    }
    Ok(bad)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn observation(n: usize) -> Observation {
        Observation {
            positions: (0..n).map(|i| (i as f64 * 22.5 - 90.0, 12.345_678_9 * i as f64)).collect(),
            resid_m_s2: (0..n).map(|i| [1e-3 * i as f64, -2.5e-4, 1.0 / (i as f64 + 3.0)]).collect(),
            misalign_urad: [1.0, -2.0, 300.5, 1e-3, 0.0, -7.25],
        }
    }

    #[test]
    fn the_compact_form_keeps_the_positions_exactly_and_the_rest_to_f32() {
        let o = observation(62);
        let b = o.to_bytes().unwrap();
        assert_eq!(b.len(), 1_763, "the paper's 62 positions");
        let back = Observation::from_bytes(&b).unwrap();
        assert_eq!(back.positions, o.positions);
        assert!(same_observation(Some(&back), Some(&o), F32_CLOSE));
        assert!(!same_observation(Some(&back), Some(&o), F64_CLOSE), "f32, not f64");
        let none = Observation::from_bytes(&observation(0).to_bytes().unwrap()).unwrap();
        assert!(none.positions.is_empty() && same_observation(Some(&none), Some(&observation(0)), F32_CLOSE));
    }

    #[test]
    fn bytes_of_another_form_are_an_error_never_a_panic() {
        let b = observation(3).to_bytes().unwrap();
        for cut in 0..b.len() {
            assert!(Observation::from_bytes(&b[..cut]).is_err(), "{cut} bytes");
        }
        let mut longer = b.clone();
        longer.push(0);
        assert_eq!(Observation::from_bytes(&longer).unwrap_err(), "112 bytes for 3 positions, not 111");
        let mut other = b;
        other[0] = 2;
        assert_eq!(Observation::from_bytes(&other).unwrap_err(), "format version 2, this build reads 1");
        // A count larger than the bytes that follow.
        assert!(Observation::from_bytes(&[1, 0xff, 0xff, 0, 0]).is_err());
        let odd = Observation { resid_m_s2: Vec::new(), ..observation(2) };
        assert_eq!(odd.to_bytes(), None, "positions and residuals differ in number");
    }
}
