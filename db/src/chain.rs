//! The rows' hash chain (schema version 2, table `ledger`): every row of every table has one
//! ledger entry, appended in the row's own transaction, that holds the row's digest and chains it
//! to the run's previous entry (a run's first entry, and a relabel, to the latest entry of the
//! whole ledger at the time, so runs are chained to each other). [`verify_all`] recomputes every
//! digest and link and names the first row that does not match; [`verify_run`] does it for one
//! run, before its record is flashed or its certificate issued.
//!
//! The digest of a row ([`row_digest`]) covers its table and every column, name and value, in
//! the order of [`TABLES`]; a row's `content_sha256` is also recomputed from what it holds. What
//! the chain does not stop: someone with write access who rewrites a run's entries and every
//! entry after them consistently. That is seen only against a chain value kept outside the
//! database ([`RunSeal`], printed on the certificate and kept in the station's journal).

use serde::Serialize;
use sha2::{Digest, Sha256};

pub use super::content::{event_content, relabel_content, run_content};
use super::engine::{Tx, Val};
use super::DbError;

/// A table's columns in the order its digest takes them (its key columns first).
pub struct Table {
    /// The table.
    pub name: &'static str,
    /// Its columns.
    pub columns: &'static [&'static str],
}

/// Every table of the calibration, as the chain sees it.
pub const TABLES: [Table; 21] = [
    Table {
        name: "run",
        columns: &[
            "run_id",
            "device_id",
            "serial",
            "station",
            "head",
            "operator",
            "started_unix_s",
            "software_version",
            "firmware_version",
            "g_m_s2",
            "g_source",
            "content_sha256",
        ],
    },
    Table {
        name: "campaign",
        columns: &["run_id", "campaign_sha256", "gzip", "stored_unix_s", "content_sha256"],
    },
    Table { name: "fit", columns: &["run_id", "fit_json", "stored_unix_s", "content_sha256"] },
    Table { name: "cal_record", columns: &["run_id", "bytes", "crc32", "stored_unix_s", "content_sha256"] },
    Table { name: "flash", columns: &["run_id", "crc32", "flashed_unix_s", "content_sha256"] },
    Table {
        name: "verification",
        columns: &["run_id", "phase", "pass", "report_json", "stored_unix_s", "content_sha256"],
    },
    Table { name: "certificate", columns: &["run_id", "html", "stored_unix_s", "content_sha256"] },
    Table { name: "run_end", columns: &["run_id", "outcome", "reason", "ended_unix_s", "content_sha256"] },
    Table { name: "void", columns: &["run_id", "reason", "operator", "voided_unix_s", "content_sha256"] },
    Table {
        name: "relabel",
        columns: &[
            "relabel_id",
            "device_id",
            "old_serial",
            "new_serial",
            "reason",
            "operator",
            "relabelled_unix_s",
            "content_sha256",
        ],
    },
    Table {
        name: "asset",
        columns: &[
            "asset_id",
            "certificate",
            "kind",
            "due_date",
            "angle_u_arcsec",
            "orthogonality_u_arcsec",
            "operator",
            "registered_unix_s",
            "content_sha256",
            "value_si",
            "value_u_si",
        ],
    },
    Table {
        name: "run_asset",
        columns: &["run_id", "kind", "asset_id", "certificate", "stored_unix_s", "content_sha256"],
    },
    Table {
        name: "certificate_number",
        columns: &["run_id", "sequence", "number", "issued_unix_s", "content_sha256"],
    },
    Table {
        name: "recalibration_due",
        columns: &["run_id", "due_unix_s", "basis", "stored_unix_s", "content_sha256"],
    },
    Table { name: "chain_event", columns: &["event_id", "kind", "detail", "unix_s", "content_sha256"] },
    Table {
        name: "signer",
        columns: &[
            "fingerprint",
            "name",
            "function",
            "public_key",
            "operator",
            "registered_unix_s",
            "content_sha256",
        ],
    },
    Table {
        name: "signer_revocation",
        columns: &["fingerprint", "reason", "operator", "revoked_unix_s", "content_sha256"],
    },
    Table {
        name: "approval",
        columns: &[
            "run_id",
            "number",
            "document_sha256",
            "meaning",
            "reason",
            "fingerprint",
            "signature",
            "signed_unix_s",
            "content_sha256",
        ],
    },
    Table {
        name: "amendment",
        columns: &[
            "run_id",
            "number",
            "sequence",
            "replaces",
            "reason",
            "operator",
            "html",
            "issued_unix_s",
            "content_sha256",
        ],
    },
    Table {
        name: "asset_found_bad",
        columns: &[
            "asset_id",
            "certificate",
            "since_date",
            "reason",
            "operator",
            "recorded_unix_s",
            "content_sha256",
        ],
    },
    Table {
        name: "recall_dismissal",
        columns: &[
            "asset_id",
            "certificate",
            "device_id",
            "serial",
            "reason",
            "operator",
            "dismissed_unix_s",
            "content_sha256",
        ],
    },
];

impl Table {
    /// Whether its rows belong to no run (a relabel, an asset): their ledger entries have
    /// `run_id` `''` and chain to the ledger's latest entry.
    pub fn is_global(&self) -> bool {
        matches!(
            self.name,
            "relabel"
                | "asset"
                | "chain_event"
                | "signer"
                | "signer_revocation"
                | "asset_found_bad"
                | "recall_dismissal"
        )
    }
}

/// The table `name`.
pub fn table(name: &str) -> &'static Table {
    TABLES.iter().find(|t| t.name == name).expect("a table of the calibration schema")
}

/// The ledger's name of a row: its table, with the verification's phase or the relabel's id.
pub fn piece_key(table: &str, row: &[Val]) -> Result<String, DbError> {
    Ok(match table {
        "verification" => format!("verification:{}", row[1].text()?),
        "relabel" => format!("relabel:{}", row[0].text()?),
        "asset" => format!("asset:{}:{}", row[0].text()?, row[1].text()?),
        "chain_event" => format!("chain_event:{}", row[0].text()?),
        "run_asset" => format!("run_asset:{}", row[1].text()?),
        "signer" => format!("signer:{}", row[0].text()?),
        "signer_revocation" => format!("signer_revocation:{}", row[0].text()?),
        "approval" => format!("approval:{}", row[1].text()?),
        "amendment" => format!("amendment:{}", row[1].text()?),
        "asset_found_bad" => format!("asset_found_bad:{}:{}", row[0].text()?, row[1].text()?),
        "recall_dismissal" => {
            format!("recall_dismissal:{}:{}:{}", row[0].text()?, row[1].text()?, row[2].text()?)
        }
        t => t.to_string(),
    })
}

/// The run a row belongs to (`''` for a relabel or an asset).
fn run_of(table: &Table, row: &[Val]) -> Result<String, DbError> {
    if table.is_global() {
        Ok(String::new())
    } else {
        row[0].text()
    }
}

/// The digest of a row: its table, then each column's name, type and value.
pub fn row_digest(table: &Table, row: &[Val]) -> String {
    let mut h = Sha256::new();
    h.update(table.name.as_bytes());
    h.update([0]);
    for (c, v) in table.columns.iter().zip(row) {
        h.update(c.as_bytes());
        h.update([0]);
        let bytes = |h: &mut Sha256, tag: &[u8], b: &[u8]| {
            h.update(tag);
            h.update((b.len() as u64).to_le_bytes());
            h.update(b);
        };
        match v {
            Val::Null => h.update(b"n"),
            // SQLite keeps a BOOLEAN as 0 or 1: both engines' reads digest the same.
            Val::Int(i) => bytes(&mut h, b"i", &i.to_le_bytes()),
            Val::Bool(b) => bytes(&mut h, b"i", &i64::from(*b).to_le_bytes()),
            Val::Real(f) => bytes(&mut h, b"r", &f.to_bits().to_le_bytes()),
            Val::Text(s) => bytes(&mut h, b"t", s.as_bytes()),
            Val::Bytes(b) => bytes(&mut h, b"b", b),
        }
    }
    super::hex(&h.finalize())
}

/// An entry's chain value.
fn chain_value(seq: i64, prev_seq: i64, prev: &str, run: &str, piece: &str, row: &str) -> String {
    super::sha256_hex(format!("{seq}\n{prev_seq}\n{prev}\n{run}\n{piece}\n{row}").as_bytes())
}

/// Inserts a row of `table` (a value per column, in its order) and its ledger entry.
pub(crate) fn insert_row(tx: &mut Tx<'_>, table: &Table, row: &[Val]) -> Result<(), DbError> {
    let placeholders: Vec<String> = (1..=row.len()).map(|i| format!("${i}")).collect();
    tx.execute(
        &format!(
            "INSERT INTO {} ({}) VALUES ({})",
            table.name,
            table.columns.join(", "),
            placeholders.join(", ")
        ),
        row,
    )?;
    append(tx, table, row)
}

/// Appends the ledger entry of a row just inserted (in the same transaction).
pub fn append(tx: &mut Tx<'_>, table: &Table, row: &[Val]) -> Result<(), DbError> {
    let run = run_of(table, row)?;
    let piece = piece_key(table.name, row)?;
    let digest = row_digest(table, row);
    let seq = tx.query("SELECT COALESCE(MAX(seq), 0) FROM ledger", &[])?[0][0].int()? + 1;
    // The run's previous entry, or (a run's first row, a relabel) the ledger's latest.
    let mut prev = if run.is_empty() || table.name == "run" {
        Vec::new()
    } else {
        tx.query(
            "SELECT seq, chain_sha256 FROM ledger WHERE run_id = $1 ORDER BY seq DESC LIMIT 1",
            &[run.clone().into()],
        )?
    };
    if prev.is_empty() {
        prev = tx.query("SELECT seq, chain_sha256 FROM ledger ORDER BY seq DESC LIMIT 1", &[])?;
    }
    let (prev_seq, prev_sha) = match prev.first() {
        Some(r) => (r[0].int()?, r[1].text()?),
        None => (0, String::new()),
    };
    let chain = chain_value(seq, prev_seq, &prev_sha, &run, &piece, &digest);
    tx.execute(
        "INSERT INTO ledger (seq, run_id, piece, row_sha256, prev_seq, prev_sha256, chain_sha256) \
         VALUES ($1, $2, $3, $4, $5, $6, $7)",
        &[
            seq.into(),
            run.into(),
            piece.into(),
            digest.into(),
            prev_seq.into(),
            prev_sha.into(),
            chain.into(),
        ],
    )?;
    Ok(())
}

/// The schema version that brought the ledger: a database opened at an older one predates the
/// chain, and its rows are sealed once ([`seal_legacy`]).
pub const LEDGER_SCHEMA: i64 = 2;

/// The ledger's shape against the rows it chains, counted (cheap enough for every writer's
/// open): what [`Shape::broken`] reads.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Shape {
    /// Rows of the chained tables.
    pub rows: i64,
    /// Ledger entries.
    pub entries: i64,
    /// The largest entry number (0 for none).
    pub max_seq: i64,
}

impl Shape {
    /// Rows and no ledger entry: a database of schema 1, or a ledger emptied behind accelcal's
    /// back.
    pub fn unsealed(&self) -> bool {
        self.entries == 0 && self.rows > 0
    }

    /// What is wrong, if anything: an emptied ledger, entries missing from the middle, rows
    /// without an entry or entries without a row.
    pub fn broken(&self) -> Option<String> {
        if self.unsealed() {
            Some(format!("the ledger is empty and {} rows are in the database", self.rows))
        } else if self.max_seq != self.entries {
            Some(format!(
                "the ledger holds {} entries numbered up to {}: entries were removed",
                self.entries, self.max_seq
            ))
        } else if self.rows != self.entries {
            Some(format!("{} rows for {} ledger entries: every row has exactly one", self.rows, self.entries))
        } else {
            None
        }
    }
}

/// Counts the chained rows and the ledger's entries.
pub(crate) fn shape(tx: &mut Tx<'_>) -> Result<Shape, DbError> {
    let counts: Vec<String> = TABLES.iter().map(|t| format!("(SELECT COUNT(*) FROM {})", t.name)).collect();
    let r = tx.query(
        &format!(
            "SELECT {}, (SELECT COUNT(*) FROM ledger), (SELECT COALESCE(MAX(seq), 0) FROM ledger)",
            counts.join(" + ")
        ),
        &[],
    )?;
    Ok(Shape { rows: r[0][0].int()?, entries: r[0][1].int()?, max_seq: r[0][2].int()? })
}

/// Rows written before the ledger existed (a database of schema 1, migrated by a writer) get
/// their entries, once: every run in the order it started, each run's rows in the order a
/// station writes them; then a `legacy-seal` event, chained too, says how many rows were sealed
/// and when, so that `db verify` tells rows chained as written from rows chained late.
pub fn seal_legacy(tx: &mut Tx<'_>) -> Result<usize, DbError> {
    if !shape(tx)?.unsealed() {
        return Ok(0);
    }
    let runs = tx.query("SELECT run_id FROM run ORDER BY started_unix_s, run_id", &[])?;
    let mut n = 0;
    let count = runs.len();
    for r in runs {
        let id = r[0].text()?;
        for t in TABLES.iter().filter(|t| !t.is_global()) {
            for row in rows_of(tx, t, &id)? {
                append(tx, t, &row)?;
                n += 1;
            }
        }
    }
    let detail =
        format!("{n} rows of {count} runs written before the ledger existed (schema 1), chained once");
    let row: Vec<Val> = vec![
        uuid::Uuid::new_v4().to_string().into(),
        LEGACY_SEAL.into(),
        detail.clone().into(),
        super::now_unix_s().into(),
        super::sha256_hex(event_content(LEGACY_SEAL, &detail).as_bytes()).into(),
    ];
    insert_row(tx, table("chain_event"), &row)?;
    Ok(n)
}

/// The chain event of [`seal_legacy`].
pub const LEGACY_SEAL: &str = "legacy-seal";

/// The chain's events, oldest first: kind, detail, Unix seconds.
pub(crate) fn events(tx: &mut Tx<'_>) -> Result<Vec<(String, String, i64)>, DbError> {
    tx.query("SELECT kind, detail, unix_s FROM chain_event ORDER BY unix_s, event_id", &[])?
        .iter()
        .map(|r| Ok((r[0].text()?, r[1].text()?, r[2].int()?)))
        .collect()
}

/// The rows of `table` of run `run` (verifications: as found, then as left).
fn rows_of(tx: &mut Tx<'_>, table: &Table, run: &str) -> Result<Vec<Vec<Val>>, DbError> {
    let order = match table.name {
        "verification" => " ORDER BY phase DESC",
        "run_asset" => " ORDER BY kind",
        "approval" => " ORDER BY number",
        _ => "",
    };
    tx.query(
        &format!("SELECT {} FROM {} WHERE run_id = $1{order}", table.columns.join(", "), table.name),
        &[run.to_string().into()],
    )
}

/// A ledger entry as read.
#[derive(Clone, Debug)]
struct Entry {
    seq: i64,
    run: String,
    piece: String,
    row: String,
    prev_seq: i64,
    prev: String,
    chain: String,
}

fn entries(tx: &mut Tx<'_>, run: Option<&str>) -> Result<Vec<Entry>, DbError> {
    let cols = "seq, run_id, piece, row_sha256, prev_seq, prev_sha256, chain_sha256";
    let rows = match run {
        Some(r) => tx.query(
            &format!("SELECT {cols} FROM ledger WHERE run_id = $1 ORDER BY seq"),
            &[r.to_string().into()],
        )?,
        None => tx.query(&format!("SELECT {cols} FROM ledger ORDER BY seq"), &[])?,
    };
    rows.iter().map(|r| entry(r)).collect()
}

fn entry(r: &[Val]) -> Result<Entry, DbError> {
    Ok(Entry {
        seq: r[0].int()?,
        run: r[1].text()?,
        piece: r[2].text()?,
        row: r[3].text()?,
        prev_seq: r[4].int()?,
        prev: r[5].text()?,
        chain: r[6].text()?,
    })
}

/// A row or entry that does not match.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Mismatch {
    /// The ledger entry's number (the first entry it breaks), 0 for a row without an entry.
    pub seq: i64,
    /// The run (`''` for a relabel).
    pub run_id: String,
    /// The row: its table, with the verification's phase or the relabel's id.
    pub piece: String,
    /// What does not match.
    pub what: String,
}

impl std::fmt::Display for Mismatch {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let run = if self.run_id.is_empty() { String::new() } else { format!(" of run {}", self.run_id) };
        let at = if self.seq > 0 { format!(" (ledger entry {})", self.seq) } else { String::new() };
        write!(f, "the {} row{run}{at}: {}", self.piece, self.what)
    }
}

/// What [`verify_all`] found.
#[derive(Clone, Debug, Serialize)]
pub struct ChainReport {
    /// Ledger entries checked.
    pub entries: usize,
    /// Rows checked.
    pub rows: usize,
    /// Runs checked.
    pub runs: usize,
    /// Everything that does not match, the first first.
    pub mismatches: Vec<Mismatch>,
    /// The chain's own events, oldest first (`legacy-seal`: rows chained late, not as written).
    pub events: Vec<ChainEvent>,
    /// Cells that do not read as their column's type (SQLite), each named.
    pub bad_cells: Vec<super::cells::BadCell>,
}

/// An event of the chain itself ([`LEGACY_SEAL`]).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ChainEvent {
    /// Its kind.
    pub kind: String,
    /// What it did.
    pub detail: String,
    /// When, Unix seconds.
    pub unix_s: i64,
}

/// The chain value of a run's last entry: what a certificate and a journal keep of it.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RunSeal {
    /// The run's last ledger entry.
    pub seq: i64,
    /// Its chain value.
    pub chain_sha256: String,
}

/// Checks the chain links and values of `list` (sorted by seq); `prev_of` finds the chain value
/// of an entry outside the list.
fn check_entries(
    list: &[Entry],
    all: Option<&std::collections::HashMap<i64, String>>,
    tx: &mut Tx<'_>,
    out: &mut Vec<Mismatch>,
) -> Result<(), DbError> {
    let bad = |e: &Entry, what: String| Mismatch {
        seq: e.seq,
        run_id: e.run.clone(),
        piece: e.piece.clone(),
        what,
    };
    for (i, e) in list.iter().enumerate() {
        if chain_value(e.seq, e.prev_seq, &e.prev, &e.run, &e.piece, &e.row) != e.chain {
            out.push(bad(e, "its ledger entry's chain value is not the hash of the entry".into()));
            continue;
        }
        if e.prev_seq >= e.seq || (e.prev_seq == 0) != e.prev.is_empty() {
            out.push(bad(e, format!("its ledger entry points forward, to entry {}", e.prev_seq)));
            continue;
        }
        if e.prev_seq == 0 {
            continue;
        }
        // Within a run, an entry follows the run's previous one.
        let in_run_prev =
            if e.run.is_empty() || e.piece == "run" { None } else { i.checked_sub(1).map(|j| &list[j]) };
        let prev_chain = match (in_run_prev, all) {
            (Some(p), _) if all.is_none() || p.run == e.run => {
                if p.seq != e.prev_seq {
                    out.push(bad(
                        e,
                        format!(
                            "it follows ledger entry {}, not its run's previous row (entry {})",
                            e.prev_seq, p.seq
                        ),
                    ));
                    continue;
                }
                Some(p.chain.clone())
            }
            (_, Some(map)) => map.get(&e.prev_seq).cloned(),
            (_, None) => tx
                .query("SELECT chain_sha256 FROM ledger WHERE seq = $1", &[e.prev_seq.into()])?
                .first()
                .map(|r| r[0].text())
                .transpose()?,
        };
        match prev_chain {
            Some(c) if c == e.prev => {}
            Some(_) => {
                out.push(bad(e, format!("the entry it follows (ledger entry {}) was changed", e.prev_seq)))
            }
            None => out.push(bad(e, format!("the entry it follows (ledger entry {}) is gone", e.prev_seq))),
        }
    }
    Ok(())
}

/// Checks the rows of run `run` (or the relabels and assets, `run` empty) against their entries.
fn check_rows(
    tx: &mut Tx<'_>,
    run: &str,
    by_piece: &std::collections::HashMap<String, Entry>,
    out: &mut Vec<Mismatch>,
) -> Result<usize, DbError> {
    let mut seen = std::collections::HashSet::new();
    let mut n = 0;
    let tables: Vec<&Table> = TABLES.iter().filter(|t| t.is_global() == run.is_empty()).collect();
    for t in tables {
        let rows = if run.is_empty() {
            tx.query(
                &format!("SELECT {} FROM {} ORDER BY {}", t.columns.join(", "), t.name, t.columns[0]),
                &[],
            )?
        } else {
            rows_of(tx, t, run)?
        };
        for row in rows {
            n += 1;
            check_row(t, &row, run, by_piece, &mut seen, out)?;
        }
    }
    gone(run, by_piece, &seen, out);
    Ok(n)
}

/// Checks one row of `t` against its entry in `by_piece` (and notes the entry `seen`): an entry,
/// the same digest, and a `content_sha256` that is the hash of what the row holds.
fn check_row(
    t: &Table,
    row: &[Val],
    run: &str,
    by_piece: &std::collections::HashMap<String, Entry>,
    seen: &mut std::collections::HashSet<String>,
    out: &mut Vec<Mismatch>,
) -> Result<(), DbError> {
    let piece = piece_key(t.name, row)?;
    let m = |seq: i64, what: String| Mismatch { seq, run_id: run.to_string(), piece: piece.clone(), what };
    let Some(e) = by_piece.get(&piece) else {
        out.push(m(0, "it has no ledger entry (written behind accelcal's back)".into()));
        return Ok(());
    };
    seen.insert(piece.clone());
    if row_digest(t, row) != e.row {
        out.push(m(
            e.seq,
            "it is not the row that was stored (its digest differs from its ledger entry's)".into(),
        ));
        return Ok(());
    }
    match content_mismatch(t, row) {
        Ok(Some(why)) => out.push(m(e.seq, why)),
        Ok(None) => {}
        Err(err) => out.push(m(e.seq, format!("a cell does not read as its type: {err}"))),
    }
    Ok(())
}

/// The entries of `by_piece` whose row was not seen: the row is gone.
fn gone(
    run: &str,
    by_piece: &std::collections::HashMap<String, Entry>,
    seen: &std::collections::HashSet<String>,
    out: &mut Vec<Mismatch>,
) {
    for (piece, e) in by_piece {
        if !seen.contains(piece) {
            out.push(Mismatch {
                seq: e.seq,
                run_id: run.to_string(),
                piece: piece.clone(),
                what: "its row is gone".into(),
            });
        }
    }
}

/// Why a row's `content_sha256` is not the hash of what it holds, if it is not.
fn content_mismatch(t: &Table, row: &[Val]) -> Result<Option<String>, DbError> {
    let col = |name: &str| -> &Val {
        &row[t.columns.iter().position(|c| *c == name).expect("a column of the table")]
    };
    let stored = col("content_sha256").text()?;
    let content = match t.name {
        "run" => {
            let s = super::run_start(row)?;
            serde_json::to_string(&s).expect("a run start serialises")
        }
        .into_bytes(),
        "campaign" => {
            let mut plain = Vec::new();
            let gz = col("gzip").bytes()?;
            if std::io::Read::read_to_end(&mut flate2::read::GzDecoder::new(gz.as_slice()), &mut plain)
                .is_err()
            {
                return Ok(Some("its campaign does not decompress".into()));
            }
            if super::sha256_hex(&plain) != col("campaign_sha256").text()? {
                return Ok(Some("its campaign is not the one its campaign_sha256 names".into()));
            }
            plain
        }
        "fit" => col("fit_json").text()?.into_bytes(),
        "cal_record" => {
            let b = col("bytes").bytes()?;
            if b.len() < 4 || i64::from(super::record_crc(&b)) != col("crc32").int()? {
                return Ok(Some("its crc32 is not the record's own".into()));
            }
            b
        }
        "flash" => u32::try_from(col("crc32").int()?).unwrap_or_default().to_le_bytes().to_vec(),
        "verification" => col("report_json").text()?.into_bytes(),
        "certificate" => col("html").text()?.into_bytes(),
        "run_end" => format!("{}\n{}", col("outcome").text()?, col("reason").text()?).into_bytes(),
        "void" => col("reason").text()?.into_bytes(),
        "relabel" => relabel_content(
            &col("device_id").text()?,
            &col("old_serial").text()?,
            &col("new_serial").text()?,
            &col("reason").text()?,
        )
        .into_bytes(),
        "asset" => super::content::asset_content(row)?.into_bytes(),
        "run_asset" => super::content::run_asset_content(
            &col("kind").text()?,
            &col("asset_id").text()?,
            &col("certificate").text()?,
        )
        .into_bytes(),
        "certificate_number" => {
            super::content::certificate_number_content(col("sequence").int()?, &col("number").text()?)
                .into_bytes()
        }
        "recalibration_due" => {
            super::content::recalibration_due_content(col("due_unix_s").int()?, &col("basis").text()?)
                .into_bytes()
        }
        "chain_event" => event_content(&col("kind").text()?, &col("detail").text()?).into_bytes(),
        "signer" => super::content::signer_content(
            &col("name").text()?,
            &col("function").text()?,
            &col("public_key").text()?,
        )
        .into_bytes(),
        "signer_revocation" => col("reason").text()?.into_bytes(),
        "approval" => super::content::approval_content(
            &super::content::decision_of_row(row)?,
            &col("fingerprint").text()?,
            &col("signature").text()?,
        )?
        .into_bytes(),
        "amendment" => super::content::amendment_content(
            col("sequence").int()?,
            &col("number").text()?,
            &col("replaces").text()?,
            &col("reason").text()?,
            &col("html").text()?,
        )
        .into_bytes(),
        "asset_found_bad" => super::content::found_bad_content(
            &col("asset_id").text()?,
            &col("certificate").text()?,
            &col("since_date").text()?,
            &col("reason").text()?,
        )
        .into_bytes(),
        "recall_dismissal" => super::content::dismissal_content(
            &col("asset_id").text()?,
            &col("certificate").text()?,
            &col("device_id").text()?,
            &col("serial").text()?,
            &col("reason").text()?,
        )
        .into_bytes(),
        other => unreachable!("table {other} is in TABLES"),
    };
    Ok((super::sha256_hex(&content) != stored)
        .then(|| "its content_sha256 is not the hash of what it holds".into()))
}

/// Orders mismatches by the ledger entry they break (rows without one last): the first first.
fn first_first(out: &mut [Mismatch]) {
    out.sort_by_key(|m| (if m.seq == 0 { i64::MAX } else { m.seq }, m.piece.clone()));
}

/// Checks the whole ledger and every row.
pub fn verify_all(tx: &mut Tx<'_>) -> Result<ChainReport, DbError> {
    let list = entries(tx, None)?;
    let mut out = Vec::new();
    for (i, e) in list.iter().enumerate() {
        if e.seq != i as i64 + 1 {
            out.push(Mismatch {
                seq: e.seq,
                run_id: e.run.clone(),
                piece: e.piece.clone(),
                what: format!("ledger entries before it are missing (entry {} expected)", i + 1),
            });
            break;
        }
    }
    let map: std::collections::HashMap<i64, String> = list.iter().map(|e| (e.seq, e.chain.clone())).collect();
    // Links: each run's entries in order, then the relabels.
    let mut by_run: std::collections::BTreeMap<String, Vec<Entry>> = Default::default();
    for e in &list {
        by_run.entry(e.run.clone()).or_default().push(e.clone());
    }
    let mut rows = 0;
    let run_ids: Vec<String> = tx
        .query("SELECT run_id FROM run ORDER BY run_id", &[])?
        .iter()
        .map(|r| r[0].text())
        .collect::<Result<_, _>>()?;
    let mut all_runs: std::collections::BTreeSet<String> = run_ids.iter().cloned().collect();
    all_runs.insert(String::new());
    all_runs.extend(by_run.keys().cloned());
    for run in &all_runs {
        let es = by_run.remove(run).unwrap_or_default();
        check_entries(&es, Some(&map), tx, &mut out)?;
        let by_piece = es.into_iter().map(|e| (e.piece.clone(), e)).collect();
        rows += check_rows(tx, run, &by_piece, &mut out)?;
    }
    first_first(&mut out);
    let events =
        events(tx)?.into_iter().map(|(kind, detail, unix_s)| ChainEvent { kind, detail, unix_s }).collect();
    Ok(ChainReport {
        entries: list.len(),
        rows,
        runs: run_ids.len(),
        mismatches: out,
        events,
        bad_cells: Vec::new(),
    })
}

/// Checks one run's rows and entries, and the register rows of the assets it used; its seal
/// when they match.
pub fn verify_run(tx: &mut Tx<'_>, run: &str) -> Result<Result<RunSeal, Vec<Mismatch>>, DbError> {
    let list = entries(tx, Some(run))?;
    let mut out = Vec::new();
    check_entries(&list, None, tx, &mut out)?;
    let last = list.last().map(|e| RunSeal { seq: e.seq, chain_sha256: e.chain.clone() });
    let by_piece = list.into_iter().map(|e| (e.piece.clone(), e)).collect();
    check_rows(tx, run, &by_piece, &mut out)?;
    let used: Vec<String> = tx
        .query("SELECT DISTINCT asset_id FROM run_asset WHERE run_id = $1", &[run.to_string().into()])?
        .iter()
        .map(|r| r[0].text())
        .collect::<Result<_, _>>()?;
    for id in used {
        out.extend(verify_asset(tx, &id)?);
    }
    let signers: Vec<String> = tx
        .query("SELECT DISTINCT fingerprint FROM approval WHERE run_id = $1", &[run.to_string().into()])?
        .iter()
        .map(|r| r[0].text())
        .collect::<Result<_, _>>()?;
    for fp in signers {
        out.extend(verify_signer(tx, &fp)?);
    }
    first_first(&mut out);
    Ok(match (out.is_empty(), last) {
        (true, Some(seal)) => Ok(seal),
        (true, None) => Err(vec![Mismatch {
            seq: 0,
            run_id: run.into(),
            piece: "run".into(),
            what: "the run has no ledger entries".into(),
        }]),
        (false, _) => Err(out),
    })
}

/// Checks the runs a selection names as [`verify_run`] checks one (each entry's chain value and
/// link, each row of every run's table against its entry, its `content_sha256`, no entry whose
/// row is gone, the register rows of the assets the runs used), with one statement for their
/// entries and one per table instead of a handful per run: what a reader that lists many runs
/// (`fleet`, `serve`) marks. `sel` is a common table expression `WITH sel AS (…)` whose
/// `run_id` are the runs, `params` its parameters. Each run that does not match, with its
/// mismatches, the first first.
pub(crate) fn verify_selected(
    tx: &mut Tx<'_>,
    sel: &str,
    params: &[Val],
) -> Result<std::collections::BTreeMap<String, Vec<Mismatch>>, DbError> {
    use std::collections::{BTreeMap, HashMap, HashSet};
    // Each entry with the chain value of the entry it follows (by its key: no lookup per run).
    let listed = tx.query(
        &format!(
            "{sel} SELECT l.seq, l.run_id, l.piece, l.row_sha256, l.prev_seq, l.prev_sha256, l.chain_sha256, \
             p.chain_sha256 FROM ledger l JOIN sel ON sel.run_id = l.run_id \
             LEFT JOIN ledger p ON p.seq = l.prev_seq ORDER BY l.seq"
        ),
        params,
    )?;
    let mut followed: HashMap<i64, String> = HashMap::new();
    let mut by_run: BTreeMap<String, Vec<Entry>> = BTreeMap::new();
    for r in &listed {
        let e = entry(r)?;
        if let Some(c) = r[7].opt_text()? {
            followed.insert(e.prev_seq, c);
        }
        by_run.entry(e.run.clone()).or_default().push(e);
    }
    drop(listed);
    let mut out: BTreeMap<String, Vec<Mismatch>> = BTreeMap::new();
    let mut pieces: HashMap<String, HashMap<String, Entry>> = HashMap::new();
    for (run, es) in by_run {
        let mut found = Vec::new();
        check_entries(&es, Some(&followed), tx, &mut found)?;
        if !found.is_empty() {
            out.entry(run.clone()).or_default().extend(found);
        }
        pieces.insert(run, es.into_iter().map(|e| (e.piece.clone(), e)).collect());
    }
    // The rows, a table at a time (the campaigns' bytes are not all held at once).
    let none = HashMap::new();
    let mut seen: HashMap<String, HashSet<String>> = HashMap::new();
    for t in TABLES.iter().filter(|t| !t.is_global()) {
        let cols: Vec<String> = t.columns.iter().map(|c| format!("t.{c}")).collect();
        let rows = tx.query(
            &format!("{sel} SELECT {} FROM {} t JOIN sel ON sel.run_id = t.run_id", cols.join(", "), t.name),
            params,
        )?;
        for row in rows {
            let run = row[0].text()?;
            let mut found = Vec::new();
            let by_piece = pieces.get(&run).unwrap_or(&none);
            check_row(t, &row, &run, by_piece, seen.entry(run.clone()).or_default(), &mut found)?;
            if !found.is_empty() {
                out.entry(run).or_default().extend(found);
            }
        }
    }
    for (run, by_piece) in &pieces {
        let mut found = Vec::new();
        gone(run, by_piece, seen.get(run).unwrap_or(&HashSet::new()), &mut found);
        if !found.is_empty() {
            out.entry(run.clone()).or_default().extend(found);
        }
    }
    // The register rows of the assets the runs used, each asset checked once.
    let used = tx.query(
        &format!("{sel} SELECT ra.run_id, ra.asset_id FROM run_asset ra JOIN sel ON sel.run_id = ra.run_id"),
        params,
    )?;
    let mut assets: HashMap<String, Vec<Mismatch>> = HashMap::new();
    for r in &used {
        let (run, id) = (r[0].text()?, r[1].text()?);
        if !assets.contains_key(&id) {
            let found = verify_asset(tx, &id)?;
            assets.insert(id.clone(), found);
        }
        let found = &assets[&id];
        if !found.is_empty() {
            out.entry(run).or_default().extend(found.iter().cloned());
        }
    }
    for found in out.values_mut() {
        first_first(found);
    }
    Ok(out)
}

/// Checks asset `id`'s register rows (every certificate of it) against their ledger entries:
/// each row's digest and content, each entry's chain value and link, and no entry whose row
/// is gone. Empty when they match.
pub fn verify_asset(tx: &mut Tx<'_>, id: &str) -> Result<Vec<Mismatch>, DbError> {
    verify_global(tx, &[(table("asset"), "asset_id")], id, &format!("asset:{id}:"))
}

/// Checks signer `fingerprint`'s register rows (the key and its revocation, when it has one)
/// against their ledger entries, as [`verify_asset`] does an asset's. Empty when they match.
pub fn verify_signer(tx: &mut Tx<'_>, fingerprint: &str) -> Result<Vec<Mismatch>, DbError> {
    let mut out = verify_global(
        tx,
        &[(table("signer"), "fingerprint")],
        fingerprint,
        &format!("signer:{fingerprint}"),
    )?;
    out.extend(verify_global(
        tx,
        &[(table("signer_revocation"), "fingerprint")],
        fingerprint,
        &format!("signer_revocation:{fingerprint}"),
    )?);
    first_first(&mut out);
    Ok(out)
}

/// Checks asset `id`'s recall rows (the findings that it was out of tolerance, and the
/// dismissals of the units they affect) against their ledger entries, as [`verify_asset`] does
/// its register rows. Empty when they match.
pub fn verify_recall(tx: &mut Tx<'_>, id: &str) -> Result<Vec<Mismatch>, DbError> {
    let mut out =
        verify_global(tx, &[(table("asset_found_bad"), "asset_id")], id, &format!("asset_found_bad:{id}:"))?;
    out.extend(verify_global(
        tx,
        &[(table("recall_dismissal"), "asset_id")],
        id,
        &format!("recall_dismissal:{id}:"),
    )?);
    first_first(&mut out);
    Ok(out)
}

/// Checks the global rows of `tables` whose key column equals `id` against their ledger
/// entries (those whose piece begins with `prefix`).
fn verify_global(
    tx: &mut Tx<'_>,
    tables: &[(&Table, &str)],
    id: &str,
    prefix: &str,
) -> Result<Vec<Mismatch>, DbError> {
    let cols = "seq, run_id, piece, row_sha256, prev_seq, prev_sha256, chain_sha256";
    let list: Vec<Entry> = tx
        .query(
            &format!(
                "SELECT {cols} FROM ledger WHERE run_id = '' AND substr(piece, 1, length($1)) = $1 ORDER BY seq"
            ),
            &[prefix.to_string().into()],
        )?
        .iter()
        .map(|r| entry(r))
        .collect::<Result<_, _>>()?;
    let mut out = Vec::new();
    // Each entry stands alone in the chain (it follows the ledger's latest at its time).
    for e in &list {
        check_entries(std::slice::from_ref(e), None, tx, &mut out)?;
    }
    let by_piece: std::collections::HashMap<String, Entry> =
        list.into_iter().map(|e| (e.piece.clone(), e)).collect();
    let mut seen = std::collections::HashSet::new();
    for (t, key) in tables {
        let rows = tx.query(
            &format!(
                "SELECT {} FROM {} WHERE {key} = $1 ORDER BY {}",
                t.columns.join(", "),
                t.name,
                t.columns[1]
            ),
            &[id.to_string().into()],
        )?;
        for row in rows {
            check_row(t, &row, "", &by_piece, &mut seen, &mut out)?;
        }
    }
    gone("", &by_piece, &seen, &mut out);
    first_first(&mut out);
    Ok(out)
}

/// The ledger's latest entry: the chain head an anchor keeps (`None`: an empty ledger).
pub fn head(tx: &mut Tx<'_>) -> Result<Option<RunSeal>, DbError> {
    tx.query("SELECT seq, chain_sha256 FROM ledger ORDER BY seq DESC LIMIT 1", &[])?
        .first()
        .map(|r| Ok(RunSeal { seq: r[0].int()?, chain_sha256: r[1].text()? }))
        .transpose()
}

/// The chain value of ledger entry `seq`, if the ledger holds it.
pub fn chain_at(tx: &mut Tx<'_>, seq: i64) -> Result<Option<String>, DbError> {
    tx.query("SELECT chain_sha256 FROM ledger WHERE seq = $1", &[seq.into()])?
        .first()
        .map(|r| r[0].text())
        .transpose()
}
