//! The command line: clap definitions of every subcommand and its options, the only place that
//! knows clap with `settings`. This file holds the `Command` enum and the options several
//! commands share (`--g` and the site, `--db`/`--run-id`, `--codes`); `campaign.rs` the commands
//! on campaign files, `line.rs` those that talk to a node, a head or a probe, `db.rs` those on the
//! database. Value enums of the command line map onto core types (`CriterionArg` →
//! `gmdh::Criterion`, `MethodArg` → `calibrate::Method` or the gravity-norm command). `range.rs`:
//! every range an option's number must lie in, written once with its words and checked as the
//! line is parsed (the station's settings file checks its keys with the same ranges).

use std::path::PathBuf;

use clap::{Args, Parser, Subcommand};

use accelcal_core::campaign::CodeRange;

mod campaign;
mod db;
mod line;
pub mod range;

pub use campaign::*;
pub use db::*;
pub use line::*;
pub use range::{Count, Range, RateHz, Real};

/// Production calibration of analog MEMS accelerometer blocks (MS9002.D class) on a dividing
/// head: GMDH model-structure selection, least-squares and test-turn fits, and their comparison.
///
/// Every command prints human tables to stdout and, with --json FILE, machine output. Exit code
/// 0 on success, 2 on bad input (the message names file, line and column), 1 otherwise.
#[derive(Debug, Parser)]
#[command(name = "accelcal", version, propagate_version = true)]
pub struct Cli {
    /// The command to run.
    #[command(subcommand)]
    pub command: Command,
}

/// The subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Simulate a calibration campaign on the dividing head (campaign CSV + truth JSON).
    Simulate(SimulateArgs),
    /// Select each channel's model structure by combinatorial GMDH.
    Select(SelectArgs),
    /// Print a position plan: the head angles and what each axis should read there (m/s², g).
    Plan(PlanArgs),
    /// Fit model coefficients by least squares or test turns; optionally write a calibration record.
    Fit(FitArgs),
    /// Compare LSQ and test turns by the error of the calibrated acceleration (the paper's Table 2).
    Compare(CompareArgs),
    /// Run the whole job on built-in simulated data: simulate, select, fit, compare, plot.
    Demo(DemoArgs),
    /// Write a calibration record into a sensor node's flash through a debug probe (the inactive
    /// record slot; the firmware is never erased, the old record stays in force until the new
    /// one is complete).
    Flash(FlashArgs),
    /// Inspect calibration record files.
    #[command(subcommand)]
    Record(RecordCommand),
    /// Show a sensor node's live stream (calibrated samples and status) from its serial port.
    Monitor(MonitorArgs),
    /// Replay a campaign through the node firmware running in QEMU and write what it computed.
    Hil(HilArgs),
    /// Run the emulated bench: the node's QEMU build fed live by a simulated unit on an emulated
    /// dividing head. Prints one JSON line `{"port", "gdb", "head"}` and runs until Ctrl-C.
    Emulate(EmulateArgs),
    /// Ask a node who it is: device id (what `fit --record --device-id` needs), firmware, record
    /// in force, sampling rate, overruns, last reset.
    Info(InfoArgs),
    /// Switch a node's live stream between calibrated acceleration and raw ADC codes.
    Output(OutputArgs),
    /// Record a campaign from a node on a dividing head: set each position of a plan (operator
    /// or emulated head), wait for a static stream, record raw code sets.
    Acquire(AcquireArgs),
    /// Check a calibrated node on the head: at each position compare its mean calibrated
    /// acceleration with g times the head's kinematics. Exit code 0 when every position passes,
    /// 1 when one fails.
    Verify(VerifyArgs),
    /// Write a unit's calibration certificate (ISO/IEC 17025 §7.8): one self-contained HTML page,
    /// printed on A4 pages numbered "Page i of n", with its number (from --db), the laboratory,
    /// item, method, traceability, decision rule, U (k = 2) and the IEEE 1293 parameters, the
    /// budget, the verifications, the coefficients, the model selection and Table 2.
    Report(ReportArgs),
    /// Diagnose the gap between a campaign and its linear-sensor simulation, and attribute it to
    /// effects checked on withheld data.
    Diagnose(DiagnoseArgs),
    /// Blind benchmark of `diagnose` on simulated campaigns with withheld effects.
    BenchDiagnose(BenchDiagnoseArgs),
    /// Benchmark of the head's signature across units: simulated fleets on a head that is
    /// knocked out of true at a unit the tracking is not told (units 10, 25 and 100; one
    /// position's α off by 0.5 mrad at β = 0° and at β = −60°, by 0.25 mrad at both, and by 0.1
    /// mrad at β = 0°; the mount rotated by 1 and by 0.5 mrad), and on true heads: how many
    /// fleets are flagged, how many units after the change, beside an oracle CUSUM told the
    /// change, how near the estimate, and the false alarms per 1,000 units of a true head.
    BenchSignature(BenchSignatureArgs),
    /// Check the uncertainty budget by Monte Carlo (JCGM 101): simulate units on heads whose
    /// errors are drawn from their stated uncertainties, calibrate each, and count how often the
    /// true error of the calibrated acceleration lies within the expanded uncertainty (k = 2) its
    /// budget gives: 95 ± 1.5 % with every contributor on, 93–97 % with each alone. Exit code 1
    /// when a scenario misses its range.
    UncertaintyCheck(UncertaintyCheckArgs),
    /// The whole line for one unit on the head: info, as-found verify (when a record is in
    /// force), acquire, select (model 4 or the unit is rejected), fit, flash, as-left verify,
    /// certificate; each step is the command of that name, run and journalled in the unit's
    /// directory, so that running the same command again after Ctrl-C or a crash goes on where it
    /// stopped. Exit code: 0 the unit passed, 1 it was rejected, 2 bad input, 3 the environment
    /// failed (port, probe, head, file system), 130 stopped.
    Station(Box<StationArgs>),
    /// A unit's history from the calibration database: every run, the coefficient drift between
    /// consecutive calibrations with its uncertainty, the as-found and as-left verifications, and
    /// the recommended recalibration date.
    #[command(after_long_help = accelcal_db::history::METHOD)]
    History(HistoryArgs),
    /// Take a calibration run out of the unit's history, the fleet's statistics and the
    /// recalibration intervals (a mislabelled or mistaken run): an appended row with the reason;
    /// nothing is deleted, and `history` lists the run as voided.
    Void(VoidArgs),
    /// The calibration database: `db verify` checks every row against its hash chain.
    #[command(subcommand)]
    Db(DbCommand),
    /// The line's registered reference equipment (the dividing head, a thermometer, a gravity
    /// value): each one's calibration certificate and due date, and a head's stated
    /// uncertainties, which `fit --head-asset` and `station --head-asset` take; a station refuses
    /// an overdue or unknown asset before it touches the node. `asset found-bad` records one
    /// found out of tolerance at its own recalibration (`affected` lists the runs it affects).
    #[command(subcommand)]
    Asset(AssetCommand),
    /// Reverse traceability: the runs, and their units, that an asset found out of tolerance at
    /// its own recalibration calibrated (`asset found-bad`), each with its serial, its
    /// certificate in force and whether one was issued, the customer, and whether a later
    /// calibration on another reference superseded it; or every run that used an asset since a
    /// date (--since). `--dismiss SERIAL --reason TEXT` records that a unit needs no recall.
    Affected(AffectedArgs),
    /// The line across units over a period: runs and units, first-pass and final yield,
    /// rejections by reason, the units found out of tolerance as found, the populations of the
    /// coefficients (mean, spread) and of the as-left parameters with their Cpk against the
    /// specification's limits, the units and assets due, the units calibrated on a reference found
    /// out of tolerance until each is recalibrated or dismissed (`affected`), and each station's
    /// check standard (its checks are not calibrations: they are left out of the counts).
    #[command(after_long_help = accelcal_db::fleet::METHOD)]
    Fleet(FleetArgs),
    /// Print a stored certificate again, from the calibration database, as it was issued, with
    /// its release as the database holds it (a draft until approved; approved: the authoriser's
    /// name, function, date and key fingerprint; rejected: marked on every page).
    Certificate(CertificateArgs),
    /// The people who may release certificates: `signer add NAME --function TEXT --key FILE`
    /// creates a personal signing key (Ed25519, in a passphrase-encrypted file) and registers
    /// its public half; `signer revoke`, `signer list`.
    #[command(subcommand)]
    Signer(SignerCommand),
    /// Approve a stored certificate for issue with a signer's key: the key file is decrypted
    /// with its passphrase, the key must be registered and not revoked, and it signs the
    /// certificate document's SHA-256, its number, the meaning "approved for issue" and the
    /// time (Unix seconds); the signature is stored in the hash chain after the run's chain is
    /// checked. One decision per certificate; the run's operator may not approve it unless the
    /// settings file allows self-approval. Refused: nothing is stored.
    Approve(DecideArgs),
    /// Reject a stored certificate with a signer's key and a reason: signed and stored as
    /// `approve` is, with the meaning "rejected"; the unit is not released and every printed
    /// page is marked REJECTED.
    Reject(RejectArgs),
    /// Amend a stored certificate that was wrong: the same run's certificate issued again under
    /// a new number (the next in the database's sequence), stating "replaces certificate
    /// NUMBER" and the reason on its first page. The amendment awaits approval as any
    /// certificate does (`approve NEW`); the certificate it replaces is superseded everywhere
    /// (`history`, `fleet`, `serve`) and is still printed as it was, marked SUPERSEDED on every
    /// page. Only the certificate in force is amended; nothing is stored when refused.
    Amend(AmendArgs),
    /// A read-only web view of the calibration database for the line: the overview (today's
    /// units, yield, stations, assets, the units to recall and the units due), each unit's page
    /// (runs, as found and as left, drift, stored certificates, recalls), the control charts and the heads' signatures, and the
    /// fleet table with `fleet`'s filters and a CSV download. Server-side HTML, no JavaScript, no
    /// write endpoint (GET only); stops on Ctrl-C or SIGTERM (exit code 0). Every connection has
    /// a header-read and idle timeout, their number is capped (503 past the cap), and a bind
    /// beyond loopback needs --users (HTTP Basic authentication; TLS belongs to a reverse proxy
    /// in front).
    Serve(ServeArgs),
    /// The users of `serve --users FILE`: `serve-user add NAME --file FILE` adds a user or
    /// changes their password (an argon2id hash per line).
    #[command(subcommand)]
    ServeUser(ServeUserCommand),
    /// Benchmark of `fleet` and `serve` on a line-sized database: an empty one is first filled
    /// with a simulated line's history through the normal store path (units calibrated once a
    /// year on three stations, each with its head); then `fleet --json` for a month, the
    /// overview, a unit's page and the fleet page are timed (median and largest of the repeats).
    BenchFleet(BenchFleetArgs),
}

/// Storing a command's result in the calibration database (`fit`, `verify`, `flash`, `report`).
#[derive(Debug, Args, Clone, Default)]
pub struct RunArgs {
    /// Store this command's result in the calibration database: a SQLite file (created when
    /// missing) or postgres://USER@HOST[:PORT]/DB. Opened before anything else is done, so an
    /// unreachable database stops the command before it touches the node.
    #[arg(long, value_name = "FILE|URL")]
    pub db: Option<String>,
    /// The calibration run the result belongs to (a UUID, as `fit --db` or `station` print it)
    /// [with --db; `fit` and `verify` begin a run under this id when the database has none, or
    /// under a new one when it is not given; `flash` and `report` need an existing run].
    #[arg(long, value_name = "UUID")]
    pub run_id: Option<String>,
    /// Begin the run even though the database ties this serial to another device, or this
    /// device to another serial: the serial moves to this device, stored as a relabel row with
    /// REASON [with --db, for `fit` and `verify` when they begin a run].
    #[arg(long, value_name = "REASON")]
    pub relabel: Option<String>,
    /// Append each chain head this command writes to FILE [with --db], one line `TIME accelcal-anchor seq=N
    /// chain_sha256=HEX`: a copy of the hash chain's state kept outside the database, which `db
    /// verify --anchors FILE` checks. The file's latest anchor is checked first: a database cut
    /// short or rewritten behind it is refused.
    #[arg(long, value_name = "FILE")]
    pub anchor_log: Option<PathBuf>,
}

/// The database a command that only reads it (or appends one row) names.
#[derive(Debug, Args)]
pub struct ReaderDb {
    /// The calibration database: a SQLite file, or postgres://USER@HOST[:PORT]/DB [default: the
    /// ACCELCAL_DB environment variable, else calibration.sqlite in the current directory when
    /// there is one].
    #[arg(long, value_name = "FILE|URL")]
    pub db: Option<String>,
}

/// `--gravity-asset`'s help (`fit`, `verify`, `station`): one text, since clap takes a doc
/// comment per field.
pub const GRAVITY_ASSET_HELP: &str =
    "The site's gravity as a registered survey (`accelcal asset add ID --kind gravity \
--value M_S2 --u M_S2`): its certificate in force sets g and u(g), the run stores which survey \
and certificate it used, and the certificate names it [with --db; instead of --g, --g-u and \
--latitude; an overdue, unknown or non-gravity asset is refused, nothing done].";

/// Local gravity from the site instead of `--g`: WGS84 normal gravity with the free-air
/// correction (`accelcal_shared::normal_gravity`).
#[derive(Debug, Args, Clone, Default)]
pub struct LocalGravity {
    /// Geodetic latitude of the rig, degrees (-90..=90): g becomes WGS84 normal gravity there
    /// (Somigliana) with the free-air correction for --height, instead of --g.
    #[arg(long, value_name = "DEG", allow_negative_numbers = true)]
    pub latitude: Option<f64>,
    /// Height of the rig above the WGS84 ellipsoid, m (with --latitude; 0 when not given).
    #[arg(long, value_name = "M", allow_negative_numbers = true)]
    pub height: Option<f64>,
    /// The standard uncertainty of --g, m/s² (one sigma, e.g. from the survey that measured it)
    /// [with --g; default: --g taken as rounded, half a unit of its last digit, rectangular].
    #[arg(long, value_name = "M_S2")]
    pub g_u: Option<f64>,
}

/// Options shared by the commands that read a campaign.
#[derive(Debug, Args, Clone)]
pub struct CommonArgs {
    /// Gravity at the rig, m/s² [default: the campaign's `# g_m_s2:` line (written by `acquire`),
    /// else 9.81].
    #[arg(long, default_value_t = accelcal_shared::G_STANDARD, hide_default_value = true)]
    pub g: f64,
    /// Local gravity instead of --g.
    #[command(flatten)]
    pub local: LocalGravity,
    /// Write machine-readable results to this JSON file.
    #[arg(long, value_name = "FILE")]
    pub json: Option<PathBuf>,
    /// Range of the campaign's raw codes (help: `CODES_HELP`, `CODES_LONG_HELP`).
    #[arg(long, value_name = "RANGE", value_parser = parse_codes, help = CODES_HELP, long_help = CODES_LONG_HELP)]
    pub codes: Option<CodeRange>,
}

/// The short help of `--codes`.
const CODES_HELP: &str = "Range of the raw codes: unsigned16 or signed16 [default: the campaign's `# codes:` line, else unsigned16]";

/// The long help of `--codes` (`--help`).
const CODES_LONG_HELP: &str = "Range of the campaign's raw codes: `unsigned16` (0..=65535, a 16-bit \
ADC; 0 and 65535 are saturation) or `signed16` (-32768..=32767, the two's-complement counts of a \
digital MEMS; -32768 and 32767 are saturation). Rows with a code at a rail or outside the range are \
excluded with a warning. A campaign states its range with a comment line `# codes: signed16` (or \
`unsigned16`) before its header row; a --codes that contradicts it is an error. Without either, \
unsigned16.";

fn parse_codes(s: &str) -> Result<CodeRange, String> {
    s.parse()
}
