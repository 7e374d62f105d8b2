//! The commands on the calibration database: history, void, db verify.

use std::path::PathBuf;

use clap::{Args, Subcommand};

use super::{Range, ReaderDb, Real};

/// `accelcal history`: a unit's runs from the calibration database.
#[derive(Debug, Args)]
pub struct HistoryArgs {
    /// The unit: its serial number, or its device id (24 hex digits, the MCU's unique id).
    #[arg(value_name = "SERIAL|DEVICE")]
    pub unit: String,
    /// The calibration database: a SQLite file, or postgres://USER@HOST[:PORT]/DB for a line of
    /// several stations [default: the ACCELCAL_DB environment variable, else calibration.sqlite
    /// in the current directory when there is one, as `station --out UNIT` makes it].
    #[arg(long, value_name = "FILE|URL")]
    pub db: Option<String>,
    /// The tolerance T the drift of a coefficient may reach before the unit is recalibrated,
    /// as an acceleration error at 1 g, m/s².
    #[arg(long = "tolerance-m-s2", value_name = "M_S2", default_value_t = accelcal_db::history::DEFAULT_RULE.tolerance_m_s2, value_parser = Real(Range::Positive))]
    pub tolerance_m_s2: f64,
    /// Coverage factor k on the drift rate's standard error.
    #[arg(long, value_name = "K", default_value_t = accelcal_db::history::DEFAULT_RULE.coverage, value_parser = Real(Range::Positive))]
    pub coverage: f64,
    /// The longest recommended interval between calibrations, days (also the interval after a
    /// single calibration; at most 36525, a century).
    #[arg(long, value_name = "DAYS", default_value_t = accelcal_db::history::DEFAULT_RULE.max_interval_days, value_parser = Real(Range::Positive))]
    pub max_interval_days: f64,
    /// The shortest recommended interval, days: a floor under the drift's interval and under
    /// an interval halved after an as-found result out of tolerance.
    #[arg(long, value_name = "DAYS", default_value_t = accelcal_db::history::DEFAULT_RULE.min_interval_days, value_parser = Real(Range::Positive))]
    pub min_interval_days: f64,
    /// Write the history as JSON to this file.
    #[arg(long, value_name = "FILE")]
    pub json: Option<PathBuf>,
}

/// `accelcal void`.
#[derive(Debug, Args)]
pub struct VoidArgs {
    /// The run to void (a UUID, as `station` and `fit --db` print it and `history --json` lists
    /// it under `runs`).
    #[arg(value_name = "RUN_ID")]
    pub run_id: String,
    /// Why the run is voided (stored with it; `history` shows it).
    #[arg(long, value_name = "TEXT", required = true)]
    pub reason: String,
    #[command(flatten)]
    pub reader: ReaderDb,
    /// Who voids it [default: the account running the command].
    #[arg(long, value_name = "NAME")]
    pub operator: Option<String>,
    /// Append each chain head this command writes to FILE, one line `TIME accelcal-anchor seq=N
    /// chain_sha256=HEX`: a copy of the hash chain's state kept outside the database, which `db
    /// verify --anchors FILE` checks. The file's latest anchor is checked first: a database cut
    /// short or rewritten behind it is refused.
    #[arg(long, value_name = "FILE")]
    pub anchor_log: Option<PathBuf>,
}

/// `accelcal db`: the calibration database itself.
#[derive(Debug, Subcommand)]
pub enum DbCommand {
    /// Recompute every row's digest and the hash chain that links each run's rows and the runs
    /// to each other, and the rows' content hashes; name the first row that does not match.
    /// Exit code 0 when everything matches, 1 when a row does not.
    Verify(DbVerifyArgs),
    /// Bring the database to this build's schema: the one command that migrates (readers never
    /// write). Rows of a database older than the hash chain are chained once, and the chain
    /// records it (a `legacy-seal` event, which `db verify` shows); rows derived from the pieces
    /// are derived. A database already current is left as it is. Exit code 0 when done.
    Migrate(DbMigrateArgs),
}

/// `accelcal db verify`.
#[derive(Debug, Args)]
pub struct DbVerifyArgs {
    #[command(flatten)]
    pub reader: ReaderDb,
    /// Write what was checked and every row that does not match as JSON to this file.
    #[arg(long, value_name = "FILE")]
    pub json: Option<PathBuf>,
    /// Also check the anchors (`accelcal-anchor seq=N chain_sha256=HEX`) these files hold
    /// against the ledger: anchor logs (`--anchor-log`), certificates, station journals. Each
    /// must be the ledger's entry at its place; a ledger cut short or rewritten behind one is
    /// reported. A file that holds no anchor is an error.
    #[arg(long, value_name = "PATH", num_args = 1..)]
    pub anchors: Vec<PathBuf>,
}

/// `accelcal db migrate`.
#[derive(Debug, Args)]
pub struct DbMigrateArgs {
    #[command(flatten)]
    pub reader: ReaderDb,
}

/// `accelcal asset`: the line's registered reference equipment.
#[derive(Debug, Subcommand)]
pub enum AssetCommand {
    /// Register a calibration certificate of a reference: a new asset, or one recalibrated (its
    /// new certificate is then the one in force). Registering the same certificate again is a
    /// no-op; a certificate is never changed once registered.
    Add(AssetAddArgs),
    /// Every registered asset: its certificate in force, its due date and whether it is overdue.
    List(AssetListArgs),
    /// One asset: every certificate registered for it, and how many runs used each.
    Show(AssetShowArgs),
    /// Record that a reference was found out of tolerance at its own recalibration: the runs
    /// that used it under the certificate that recalibration ended, from a day on, are affected
    /// (`accelcal affected ID` lists them, `fleet` and `serve` show each unit until it is
    /// recalibrated on another reference or dismissed). Appended to the hash chain; refused,
    /// with nothing stored, for an unknown asset or certificate, a day after today, an empty
    /// reason, or a certificate found out of tolerance already.
    FoundBad(AssetFoundBadArgs),
}

/// `accelcal asset found-bad`.
#[derive(Debug, Args)]
pub struct AssetFoundBadArgs {
    /// The asset found out of tolerance (its id, as `asset list` shows it).
    #[arg(value_name = "ID")]
    pub id: String,
    /// The asset's own certificate it was used under while out of tolerance: the one its
    /// recalibration ended (`asset show ID` lists them).
    #[arg(long, value_name = "NUMBER")]
    pub certificate: String,
    /// The first day (UTC, YYYY-MM-DD) whose runs are affected: typically the day of the last
    /// check that found it in tolerance (not after today).
    #[arg(long, value_name = "YYYY-MM-DD", value_parser = parse_date)]
    pub since: accelcal_db::asset::Date,
    /// What its recalibration found (stored with the finding; `affected` shows it).
    #[arg(long, value_name = "TEXT")]
    pub reason: String,
    /// Who records it [default: the account running the command].
    #[arg(long, value_name = "NAME")]
    pub operator: Option<String>,
    #[command(flatten)]
    pub store: AssetDb,
    /// Append each chain head this command writes to FILE (see `fit --anchor-log`).
    #[arg(long, value_name = "FILE")]
    pub anchor_log: Option<PathBuf>,
}

/// `asset --kind`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum AssetKindArg {
    /// A dividing head (states --angle-u and --orthogonality-u).
    Head,
    /// A thermometer.
    Thermometer,
    /// A gravity value (a survey of the site: states --value and --u).
    Gravity,
}

impl From<AssetKindArg> for accelcal_db::AssetKind {
    fn from(k: AssetKindArg) -> accelcal_db::AssetKind {
        match k {
            AssetKindArg::Head => accelcal_db::AssetKind::Head,
            AssetKindArg::Thermometer => accelcal_db::AssetKind::Thermometer,
            AssetKindArg::Gravity => accelcal_db::AssetKind::Gravity,
        }
    }
}

fn parse_date(s: &str) -> Result<accelcal_db::asset::Date, String> {
    accelcal_db::asset::parse_date(s)
}

/// The database an asset command writes or reads.
#[derive(Debug, Args)]
pub struct AssetDb {
    /// The calibration database: a SQLite file (`asset add` creates it when missing), or
    /// postgres://USER@HOST[:PORT]/DB [default: the ACCELCAL_DB environment variable, else
    /// calibration.sqlite in the current directory].
    #[arg(long, value_name = "FILE|URL")]
    pub db: Option<String>,
}

/// `accelcal asset add`.
#[derive(Debug, Args)]
pub struct AssetAddArgs {
    /// Append each chain head this command writes to FILE (see `fit --anchor-log`).
    #[arg(long, value_name = "FILE")]
    pub anchor_log: Option<PathBuf>,
    /// The asset's id, as the line names it (`--head-asset`): 1 to 64 letters, digits, `.`,
    /// `_` or `-`.
    #[arg(value_name = "ID")]
    pub id: String,
    /// What the asset is.
    #[arg(long, value_enum)]
    pub kind: AssetKindArg,
    /// The number of the asset's own calibration certificate (its traceability).
    #[arg(long, value_name = "NUMBER")]
    pub certificate: String,
    /// The last day (UTC) the asset may be used under this certificate, YYYY-MM-DD: a station run
    /// after it is refused.
    #[arg(long, value_name = "YYYY-MM-DD", value_parser = parse_date)]
    pub due: accelcal_db::asset::Date,
    /// A head's angle setting uncertainty, arcsec: one sigma of the error of each head angle at
    /// each position, from the head's certificate (`fit --head-angle-u`) [required for a head;
    /// refused for other kinds].
    #[arg(long, value_name = "ARCSEC", value_parser = Real(Range::Arcsec))]
    pub angle_u: Option<f64>,
    /// A head's orthogonality uncertainty, arcsec: one sigma of each of the three rotations
    /// between its stages (`fit --head-orthogonality-u`) [required for a head; refused for other
    /// kinds].
    #[arg(long, value_name = "ARCSEC", value_parser = Real(Range::Arcsec))]
    pub orthogonality_u: Option<f64>,
    /// A gravity survey's value of g at the line's site, m/s², from its certificate (9.7 to 9.9)
    /// [required for --kind gravity; refused for other kinds].
    #[arg(long, value_name = "M_S2")]
    pub value: Option<f64>,
    /// A gravity survey's standard uncertainty of --value, m/s², or a thermometer's of each
    /// reading, K (one sigma; the certificate's expanded uncertainty divided by its coverage
    /// factor) [required for --kind gravity; optional for a thermometer; refused for a head].
    #[arg(long, value_name = "M_S2")]
    pub u: Option<f64>,
    #[command(flatten)]
    pub store: AssetDb,
    /// Who registers it [default: the account running the command].
    #[arg(long, value_name = "NAME")]
    pub operator: Option<String>,
}

/// `accelcal asset list`.
#[derive(Debug, Args)]
pub struct AssetListArgs {
    #[command(flatten)]
    pub store: AssetDb,
    /// Write the assets (each one's certificate in force, `overdue` true or false) as JSON to
    /// this file.
    #[arg(long, value_name = "FILE")]
    pub json: Option<PathBuf>,
}

/// `accelcal asset show`.
#[derive(Debug, Args)]
pub struct AssetShowArgs {
    /// The asset's id.
    #[arg(value_name = "ID")]
    pub id: String,
    #[command(flatten)]
    pub store: AssetDb,
    /// Write the asset's certificates and its runs as JSON to this file.
    #[arg(long, value_name = "FILE")]
    pub json: Option<PathBuf>,
}

/// `accelcal affected`.
#[derive(Debug, Args)]
pub struct AffectedArgs {
    /// The asset found out of tolerance (its id, as `asset list` shows it).
    #[arg(value_name = "ASSET")]
    pub asset: String,
    /// Every run that used the asset from this day on (UTC, YYYY-MM-DD), whether or not it was
    /// found out of tolerance [default: the runs its findings (`asset found-bad`) affect].
    #[arg(long, value_name = "YYYY-MM-DD", value_parser = parse_date)]
    pub since: Option<accelcal_db::asset::Date>,
    /// Only the runs under this certificate of the asset (with --dismiss: the finding under it,
    /// when the unit is affected under several).
    #[arg(long, value_name = "NUMBER")]
    pub certificate: Option<String>,
    /// Record that this unit (its serial, or its device id), whose runs a finding of the asset
    /// affects, was reviewed and needs no recall (with --reason; appended to the hash chain):
    /// `fleet` and `serve` no longer show it.
    #[arg(long, value_name = "SERIAL")]
    pub dismiss: Option<String>,
    /// Why the unit needs no recall [required with --dismiss].
    #[arg(long, value_name = "TEXT")]
    pub reason: Option<String>,
    /// Who dismisses it [with --dismiss; default: the account running the command].
    #[arg(long, value_name = "NAME")]
    pub operator: Option<String>,
    /// Append each chain head this command writes to FILE [with --dismiss] (see `fit
    /// --anchor-log`).
    #[arg(long, value_name = "FILE")]
    pub anchor_log: Option<PathBuf>,
    #[command(flatten)]
    pub store: AssetDb,
    /// Write the runs (run id, device, serial, station, start, the asset's certificate,
    /// outcome, the unit's certificate in force and its state, the customer, what became of
    /// it) as JSON to this file.
    #[arg(long, value_name = "FILE")]
    pub json: Option<PathBuf>,
    /// Write the same list as CSV to this file, one row per run (for the recall letters).
    #[arg(long, value_name = "FILE")]
    pub csv: Option<PathBuf>,
}

/// `accelcal fleet`.
#[derive(Debug, Args)]
pub struct FleetArgs {
    #[command(flatten)]
    pub reader: ReaderDb,
    /// The first day (UTC) of the period [default: 30 days before --until].
    #[arg(long, value_name = "YYYY-MM-DD", value_parser = parse_date)]
    pub since: Option<accelcal_db::asset::Date>,
    /// The last day (UTC) of the period, included [default: today].
    #[arg(long, value_name = "YYYY-MM-DD", value_parser = parse_date)]
    pub until: Option<accelcal_db::asset::Date>,
    /// Only the runs of this station (its name, as `station --station` stores it).
    #[arg(long, value_name = "NAME")]
    pub station: Option<String>,
    /// Only the runs on this head (its asset id, as `station --head-asset` stores it).
    #[arg(long, value_name = "ID")]
    pub head_asset: Option<String>,
    /// Only the units whose serial starts so.
    #[arg(long, value_name = "TEXT")]
    pub serial_prefix: Option<String>,
    /// Only the runs of this operator (as `station --operator` stores it).
    #[arg(long, value_name = "NAME")]
    pub operator: Option<String>,
    /// The units and assets due within this many days of --until are listed (overdue ones too).
    #[arg(long, value_name = "DAYS", default_value_t = 30, value_parser = clap::value_parser!(u32).range(0..=3660))]
    pub due_days: u32,
    /// Write the summary, the runs and the populations as JSON to this file.
    #[arg(long, value_name = "FILE")]
    pub json: Option<PathBuf>,
    /// Write one row per run as CSV to this file (the columns an MES takes: run, serial, device
    /// id, station, head, operator, start and end (UTC), state, reason, decisions, model-4
    /// coefficients, U per axis, the certificate in force, its state and
    /// recalibration date, the record's CRC).
    #[arg(long, value_name = "FILE")]
    pub csv: Option<PathBuf>,
}

/// `accelcal serve`.
#[derive(Debug, Args)]
pub struct ServeArgs {
    #[command(flatten)]
    pub reader: ReaderDb,
    /// The address to listen on (`IP:PORT`; port 0 takes a free port, and the line printed at the
    /// start says which). An address beyond loopback (anything but 127.0.0.0/8 and ::1, 0.0.0.0
    /// and :: included) needs --users.
    #[arg(long, value_name = "IP:PORT", default_value = "127.0.0.1:8080")]
    pub bind: std::net::SocketAddr,
    /// Ask every request for a user name and password (HTTP Basic authentication) checked against
    /// this file of argon2 hashes, written by `accelcal serve-user add NAME --file FILE`; read
    /// once at the start. Basic authentication sends the password in the clear: off this machine,
    /// put a reverse proxy that terminates TLS in front.
    #[arg(long, value_name = "FILE")]
    pub users: Option<PathBuf>,
    /// Seconds a connection has to send a request's whole header, counted from its opening and
    /// again from each answer (so also how long an idle keep-alive connection is kept); then it
    /// is closed.
    #[arg(long, value_name = "SECONDS", default_value_t = 10, value_parser = clap::value_parser!(u32).range(1..=3600))]
    pub header_timeout_s: u32,
    /// Connections open at once, at most. At the cap, a new connection takes the place of the
    /// oldest idle one (waiting for a request); when all are answering requests it gets `503
    /// Service Unavailable`. The open-file limit (ulimit -n) is raised to fit, or the cap refused.
    #[arg(long, value_name = "N", default_value_t = 256, value_parser = clap::value_parser!(u32).range(1..=65536))]
    pub max_connections: u32,
    /// The units and assets due within this many days of today are listed on the overview
    /// (overdue ones too).
    #[arg(long, value_name = "DAYS", default_value_t = 30, value_parser = clap::value_parser!(u32).range(0..=3660))]
    pub due_days: u32,
}

/// `accelcal serve-user`.
#[derive(Debug, Subcommand)]
pub enum ServeUserCommand {
    /// Add a user to a `serve --users` file, or change their password: the password (asked on
    /// the terminal twice without echo, or the first line of --password-file) is stored as an
    /// argon2id hash with a random salt; the file is written whole and readable by its owner
    /// only. A running `serve` reads it again when restarted.
    Add(ServeUserAddArgs),
}

/// `accelcal serve-user add`.
#[derive(Debug, Args)]
pub struct ServeUserAddArgs {
    /// The user's name (plain text: no `:`, no control or format character).
    pub name: String,
    /// The users file (created when missing).
    #[arg(long, value_name = "FILE")]
    pub file: PathBuf,
    /// Read the password from the first line of this file instead of the terminal (for scripts).
    #[arg(long, value_name = "FILE")]
    pub password_file: Option<PathBuf>,
}

/// `accelcal bench-fleet`.
#[derive(Debug, Args)]
pub struct BenchFleetArgs {
    /// The database (`postgres://…`, `host=… dbname=…`, or a SQLite file); filled when it holds
    /// no run, else timed as it is.
    #[arg(long, value_name = "URL")]
    pub db: String,
    /// Units of the generated line (each with a serial `MS9-NNNNNN`).
    #[arg(long, default_value_t = 100_000, value_parser = clap::value_parser!(u32).range(1..))]
    pub units: u32,
    /// Runs of the generated line, shared out among the units (one a year each; about 2 % are
    /// rejected, 0.2 % never finish, 0.1 % are voided).
    #[arg(long, default_value_t = 300_000, value_parser = clap::value_parser!(u32).range(1..))]
    pub runs: u32,
    /// Seed of the generated line: the same seed gives the same rows.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// The month `fleet` and the fleet page show (`YYYY-MM`; the generated line starts in
    /// January 2024).
    #[arg(long, value_name = "YYYY-MM", default_value = "2026-06")]
    pub month: String,
    /// Connections writing the generated line at once.
    #[arg(long, default_value_t = 2, value_parser = clap::value_parser!(u32).range(1..=16))]
    pub writers: u32,
    /// How often each command and page is timed.
    #[arg(long, default_value_t = 5, value_parser = clap::value_parser!(u32).range(1..=100))]
    pub repeat: u32,
}

/// `accelcal certificate`.
#[derive(Debug, Args)]
#[command(args_conflicts_with_subcommands = true, subcommand_negates_reqs = true)]
pub struct CertificateArgs {
    /// Check a certificate file instead of printing one.
    #[command(subcommand)]
    pub action: Option<CertificateAction>,
    /// The certificate to print again: its number (YYYY-NNNNNN, as printed on it), or its run's
    /// id (a UUID, as `station` prints it and `fleet` lists it) or the beginning of it (8 or more
    /// of its digits, when no other run id begins so): the run's certificate in force.
    #[arg(value_name = "NUMBER|RUN_ID", required = true)]
    pub certificate: Option<String>,
    /// Write the stored certificate (an HTML page, as issued) to this file.
    #[arg(long, short = 'o', value_name = "FILE")]
    pub out: Option<PathBuf>,
    /// Write the certificate as a PDF (A4, fonts embedded, text extractable), rendered from the
    /// document its page carries, to this file.
    #[arg(long, value_name = "FILE")]
    pub pdf: Option<PathBuf>,
    /// Write the certificate as a Digital Calibration Certificate (PTB's DCC XML, schema 3.3.0,
    /// quantities in D-SI 2.2.1), with its document attached for `certificate verify`, to this
    /// file.
    #[arg(long, value_name = "FILE")]
    pub dcc: Option<PathBuf>,
    #[command(flatten)]
    pub reader: ReaderDb,
}

/// `accelcal signer …`: the people who may release certificates.
#[derive(Debug, Subcommand)]
pub enum SignerCommand {
    /// Create a signer's Ed25519 signing key and register its public half: the key is written
    /// to --key FILE as an encrypted PKCS#8 file (PEM; PBES2: scrypt, AES-256-CBC) under a
    /// passphrase asked on the terminal twice without echo, or the first line of
    /// --passphrase-file; a FILE that exists is refused (nothing is overwritten). The public key,
    /// its fingerprint (the first 16 hex digits of the SHA-256 of its 32 bytes), the name and the
    /// function are registered in the database's hash chain. A name has one key in force.
    Add(SignerAddArgs),
    /// Revoke a signer's key in force: an appended, chained row with the reason; the key
    /// approves and rejects nothing after. Decisions it signed before stay valid.
    Revoke(SignerRevokeArgs),
    /// List the registered signers: name, function, key fingerprint, registered and revoked
    /// (UTC dates).
    List(SignerListArgs),
}

/// `accelcal signer add`.
#[derive(Debug, Args)]
pub struct SignerAddArgs {
    /// The signer's name, as certificates print it ("Dr. A. Reviewer"; one line).
    pub name: String,
    /// Their function, as certificates print it ("Head of laboratory"; one line).
    #[arg(long, value_name = "TEXT")]
    pub function: String,
    /// The key file to create (refused when it exists); keep it where only the signer reads it.
    #[arg(long, value_name = "FILE")]
    pub key: PathBuf,
    /// Read the passphrase from the first line of this file instead of the terminal (for
    /// scripts).
    #[arg(long, value_name = "FILE")]
    pub passphrase_file: Option<PathBuf>,
    #[command(flatten)]
    pub reader: ReaderDb,
    /// Who registers it [default: the account running the command].
    #[arg(long, value_name = "NAME")]
    pub operator: Option<String>,
}

/// `accelcal signer revoke`.
#[derive(Debug, Args)]
pub struct SignerRevokeArgs {
    /// The signer whose key in force is revoked.
    pub name: String,
    /// Why (one line, stored with the revocation).
    #[arg(long, value_name = "TEXT")]
    pub reason: String,
    #[command(flatten)]
    pub reader: ReaderDb,
    /// Who revokes it [default: the account running the command].
    #[arg(long, value_name = "NAME")]
    pub operator: Option<String>,
}

/// `accelcal signer list`.
#[derive(Debug, Args)]
pub struct SignerListArgs {
    #[command(flatten)]
    pub reader: ReaderDb,
    /// Print the signers as JSON instead of a table.
    #[arg(long)]
    pub json: bool,
}

/// `accelcal approve` and `accelcal reject`: one signed decision on a stored certificate.
#[derive(Debug, Args)]
pub struct DecideArgs {
    /// The certificate: its number (YYYY-NNNNNN, as printed on it and as `station` prints it).
    #[arg(value_name = "NUMBER")]
    pub number: String,
    /// The signer's key file (from `signer add`).
    #[arg(long, value_name = "FILE")]
    pub key: PathBuf,
    /// Read the key's passphrase from the first line of this file instead of the terminal (for
    /// scripts).
    #[arg(long, value_name = "FILE")]
    pub passphrase_file: Option<PathBuf>,
    /// The line's settings file (station.toml): its key `allow_self_approval = true` lets the
    /// operator of a run approve its certificate [default: refused].
    #[arg(long, value_name = "FILE")]
    pub config: Option<PathBuf>,
    #[command(flatten)]
    pub reader: ReaderDb,
}

/// `accelcal reject`.
#[derive(Debug, Args)]
pub struct RejectArgs {
    #[command(flatten)]
    pub decide: DecideArgs,
    /// Why the certificate is not released (one line, signed and stored with the decision).
    #[arg(long, value_name = "TEXT")]
    pub reason: String,
}

/// `accelcal amend`: a certificate issued again under a new number.
#[derive(Debug, Args)]
pub struct AmendArgs {
    /// The certificate to amend: its number (YYYY-NNNNNN), the one in force for its run.
    #[arg(value_name = "NUMBER")]
    pub number: String,
    /// Why it is amended (one line, printed on the amendment and stored with it).
    #[arg(long, value_name = "TEXT")]
    pub reason: String,
    /// Who amends it [default: the account running the command].
    #[arg(long, value_name = "NAME")]
    pub operator: Option<String>,
    #[command(flatten)]
    pub reader: ReaderDb,
}

/// `accelcal certificate`'s subcommands.
#[derive(Debug, Subcommand)]
pub enum CertificateAction {
    /// Check a certificate file, the PDF (`certificate --pdf`, the station's certificate.pdf)
    /// or the DCC (`--dcc`): its attached document's SHA-256 is computed again, the file is
    /// rendered again from that document and compared with it (one value edited anywhere
    /// fails), and a signed decision it carries is checked with the signer's key it carries, so
    /// it is checked offline. With --db, the database must hold that certificate as this
    /// document, with the same decision. Prints "valid: …" (exit code 0) or names the first
    /// difference (exit code 2).
    Verify {
        /// The PDF or DCC XML file.
        #[arg(value_name = "FILE")]
        file: PathBuf,
        /// Also check the file against this calibration database (a SQLite file or a
        /// PostgreSQL connection string) [default: offline, the file alone].
        #[arg(long, value_name = "DB")]
        db: Option<String>,
    },
}
