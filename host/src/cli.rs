//! The command line: clap definitions of every subcommand and its options.

use std::path::PathBuf;

use clap::{Args, Parser, Subcommand, ValueEnum};

use accelcal_core::campaign::CodeRange;
use accelcal_core::gmdh::{Criterion, Split};
use accelcal_core::sim::{Layout, TempProfile};

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
    /// Write a unit's calibration certificate: one self-contained HTML page (prints on one A4
    /// page) with identification, g, record CRC, model selection, coefficients ± standard
    /// errors, Table 2 and the verification.
    Report(ReportArgs),
    /// Diagnose the gap between a campaign and its linear-sensor simulation, and attribute it to
    /// effects checked on withheld data.
    Diagnose(DiagnoseArgs),
    /// Blind benchmark of `diagnose` on simulated campaigns with withheld effects.
    BenchDiagnose(BenchDiagnoseArgs),
    /// The whole line for one unit on the head: info, as-found verify (when a record is in
    /// force), acquire, select (model 4 or the unit is rejected), fit, flash, as-left verify,
    /// certificate; each step is the command of that name, run and journalled in the unit's
    /// directory, so that running the same command again after Ctrl-C or a crash goes on where it
    /// stopped. Exit code: 0 the unit passed, 1 it was rejected, 2 bad input, 3 the environment
    /// failed (port, probe, head, file system), 130 stopped.
    Station(StationArgs),
    /// A unit's history from the calibration database: every run, the coefficient drift between
    /// consecutive calibrations with its uncertainty, the as-found and as-left verifications, and
    /// the recommended recalibration date.
    #[command(after_long_help = accelcal_core::db::history::METHOD)]
    History(HistoryArgs),
    /// Take a calibration run out of the unit's history, the fleet's statistics and the
    /// recalibration intervals (a mislabelled or mistaken run): an appended row with the reason;
    /// nothing is deleted, and `history` lists the run as voided.
    Void(VoidArgs),
    /// The calibration database: `db verify` checks every row against its hash chain.
    #[command(subcommand)]
    Db(DbCommand),
}

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
    #[arg(long = "tolerance-m-s2", value_name = "M_S2", default_value_t = accelcal_core::db::history::DEFAULT_RULE.tolerance_m_s2)]
    pub tolerance_m_s2: f64,
    /// Coverage factor k on the drift rate's standard error.
    #[arg(long, value_name = "K", default_value_t = accelcal_core::db::history::DEFAULT_RULE.coverage)]
    pub coverage: f64,
    /// The longest recommended interval between calibrations, days (also the interval after a
    /// single calibration; at most 36525, a century).
    #[arg(long, value_name = "DAYS", default_value_t = accelcal_core::db::history::DEFAULT_RULE.max_interval_days)]
    pub max_interval_days: f64,
    /// Write the history as JSON to this file.
    #[arg(long, value_name = "FILE")]
    pub json: Option<PathBuf>,
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
}

/// `accelcal db`: the calibration database itself.
#[derive(Debug, Subcommand)]
pub enum DbCommand {
    /// Recompute every row's digest and the hash chain that links each run's rows and the runs
    /// to each other, and the rows' content hashes; name the first row that does not match.
    /// Exit code 0 when everything matches, 1 when a row does not.
    Verify(DbVerifyArgs),
}

/// `accelcal db verify`.
#[derive(Debug, Args)]
pub struct DbVerifyArgs {
    #[command(flatten)]
    pub reader: ReaderDb,
    /// Write what was checked and every row that does not match as JSON to this file.
    #[arg(long, value_name = "FILE")]
    pub json: Option<PathBuf>,
}

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
}

/// Options shared by the commands that read a campaign.
#[derive(Debug, Args, Clone)]
pub struct CommonArgs {
    /// Gravity at the rig, m/s² [default: the campaign's `# g_m_s2:` line (written by `acquire`),
    /// else 9.81].
    #[arg(long, default_value_t = accelcal_shared::G_STANDARD, hide_default_value = true)]
    pub g: f64,
    /// Whether --g or --latitude gave g (set by `settings::resolve_gravity`, not a flag).
    #[arg(skip)]
    pub g_given: bool,
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

/// `accelcal plan`.
#[derive(Debug, Args)]
pub struct PlanArgs {
    /// Position plan: `head` (62 positions), `six` (the six test-turn positions), `random:N`, or a
    /// plan file (CSV with columns alpha_deg,beta_deg), as in `simulate --plan`.
    #[arg(long, default_value = "head", value_name = "PLAN")]
    pub plan: String,
    /// Seed of `random:N`.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Gravity at the rig, m/s².
    #[arg(long, default_value_t = accelcal_shared::G_STANDARD)]
    pub g: f64,
    /// Local gravity instead of --g.
    #[command(flatten)]
    pub local: LocalGravity,
    /// Write the positions and their accelerations (m/s²) as JSON.
    #[arg(long, value_name = "FILE")]
    pub json: Option<PathBuf>,
}

/// `accelcal simulate`.
#[derive(Debug, Args)]
pub struct SimulateArgs {
    /// Campaign CSV to write.
    #[arg(long, short, value_name = "FILE")]
    pub out: PathBuf,
    /// Truth JSON to write (the parameters the campaign was made from) [default: OUT with .truth.json].
    #[arg(long, value_name = "FILE")]
    pub truth: Option<PathBuf>,
    /// Seed of every random draw: the same seed gives the same files.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Position plan: `head` (62 positions: beta -60..60 step 30 x alpha every 30 deg, plus beta
    /// +-90), `six` (the six test-turn positions), `random:N` (N orientations uniform on the
    /// sphere), or a plan file (CSV with columns alpha_deg,beta_deg).
    #[arg(long, default_value = "head", value_name = "PLAN")]
    pub plan: String,
    /// Channel layout: `triad` (channels x, y, z) or `block:N` (N single-axis sensors a1..aN with
    /// sensitive axes cycling x, y, z).
    #[arg(long, default_value = "triad", value_parser = parse_layout)]
    pub layout: Layout,
    /// Sample sets per position (the dwell; its mean is what selection and fits use).
    #[arg(long, default_value_t = 400)]
    pub samples: usize,
    /// Sample rate, Hz.
    #[arg(long, default_value_t = 100.0)]
    pub rate_hz: f64,
    /// Time between positions (head moving), s.
    #[arg(long, default_value_t = 2.0)]
    pub move_s: f64,
    /// White noise per sample, ADC codes (one sigma).
    #[arg(long, default_value_t = 80.0)]
    pub noise: f64,
    /// Spread of the zero offsets around mid-scale, codes (one sigma).
    #[arg(long, default_value_t = 300.0)]
    pub bias_sd: f64,
    /// Relative spread of the scale factors around 16384 codes/g (one sigma).
    #[arg(long, default_value_t = 0.01)]
    pub scale_sd: f64,
    /// Misalignment of each sensitive axis, rad (one sigma per angle).
    #[arg(long, default_value_t = 0.01)]
    pub misalign_sd: f64,
    /// Add an error effect, `NAME=KEY:VALUE,...` (repeatable; see --help for the effects, their
    /// keys and units).
    #[arg(long = "effect", value_name = "NAME=PARAMS", long_help = accelcal_core::effects::help_text())]
    pub effects: Vec<String>,
    /// Temperature profile `BASE:AMP:CYCLES` (°C, °C, sine cycles over the campaign); writes a
    /// temp_c column.
    #[arg(long, value_name = "BASE:AMP:CYCLES", value_parser = parse_temp)]
    pub temp_profile: Option<TempProfile>,
    /// A thermal campaign: the plan repeated at each of these chamber setpoints (°C,
    /// comma-separated), each pass after --soak-s, the sensor following the chamber with a
    /// first-order lag of --thermal-lag-s from 25 °C; adds a `temp_c` column (as `acquire
    /// --chamber` records it).
    #[arg(long, value_name = "T1,T2,…", value_delimiter = ',', allow_hyphen_values = true)]
    pub chamber: Vec<f64>,
    /// Seconds the chamber holds each setpoint before its pass starts [with --chamber; default: 900].
    #[arg(long, value_name = "S")]
    pub soak_s: Option<f64>,
    /// Thermal time constant between the chamber and the sensor, seconds (first-order lag) [with
    /// --chamber; default: 30, as `emulate`'s].
    #[arg(long, value_name = "S")]
    pub thermal_lag_s: Option<f64>,
    /// An ideal ADC: no rounding to whole codes, no clipping (for checks against exact values).
    #[arg(long)]
    pub ideal_adc: bool,
    /// Range of the codes written: `unsigned16` (the simulated 16-bit ADC) or `signed16` (the same
    /// codes less 32768, as the two's-complement counts of a digital MEMS, under a `# codes:
    /// signed16` line; the truth's biases are shifted alike).
    #[arg(long, value_name = "RANGE", value_parser = parse_codes, default_value = "unsigned16")]
    pub codes: CodeRange,
    /// Gravity, m/s².
    #[arg(long, default_value_t = accelcal_shared::G_STANDARD)]
    pub g: f64,
    /// Local gravity instead of --g.
    #[command(flatten)]
    pub local: LocalGravity,
    /// The unit's serial number, written into the campaign (`# serial:`, as `acquire --serial`).
    #[arg(long, value_name = "S")]
    pub serial: Option<String>,
    /// Write a summary (rows, positions, channels) as JSON.
    #[arg(long, value_name = "FILE")]
    pub json: Option<PathBuf>,
}

fn parse_layout(s: &str) -> Result<Layout, String> {
    s.parse()
}

fn parse_temp(s: &str) -> Result<TempProfile, String> {
    s.parse()
}

/// Term sets GMDH enumerates.
#[derive(Debug, Clone, Copy, ValueEnum, PartialEq, Eq)]
pub enum BasisArg {
    /// The paper's 11 candidate models (Table 1).
    Paper,
    /// Subsets of 1, ax, ay, az (8 models).
    Linear,
    /// Subsets of the terms up to degree 2 (512 models).
    Quadratic,
    /// Subsets of the terms up to degree 3 (524,288 models).
    Cubic,
    /// Subsets of 1, ax, ay, az, t, t^2, ax*t, ay*t, az*t (256 models; needs `temp_c`).
    LinearThermal,
    /// Subsets of the terms up to degree 2 and t, t^2, ax*t, ay*t, az*t (16,384 models; needs
    /// `temp_c`).
    QuadraticThermal,
}

impl From<BasisArg> for accelcal_shared::Basis {
    fn from(b: BasisArg) -> Self {
        match b {
            BasisArg::Paper => accelcal_shared::Basis::Paper,
            BasisArg::Linear => accelcal_shared::Basis::Linear,
            BasisArg::Quadratic => accelcal_shared::Basis::Quadratic,
            BasisArg::Cubic => accelcal_shared::Basis::Cubic,
            BasisArg::LinearThermal => accelcal_shared::Basis::LinearThermal,
            BasisArg::QuadraticThermal => accelcal_shared::Basis::QuadraticThermal,
        }
    }
}

/// The temperature variable of the thermal terms.
#[derive(Debug, Args)]
pub struct ThermalArgs {
    /// Reference temperature of the thermal terms, °C: their variable t is `temp_c − T_REF`
    /// (the campaign's `temp_c` column, dwell means) [default: 25; only with terms in t].
    #[arg(long, value_name = "DEG_C", allow_hyphen_values = true)]
    pub t_ref: Option<f64>,
}

impl ThermalArgs {
    /// The reference temperature in force, °C.
    pub fn t_ref_c(&self) -> f64 {
        self.t_ref.unwrap_or(accelcal_core::positions::T_REF_DEFAULT_C)
    }
}

/// Where a node reads its temperature.
#[derive(Debug, Clone, Copy, ValueEnum, PartialEq, Eq)]
pub enum TempInputArg {
    /// The MCU's internal temperature sensor (ADC1, factory-calibrated).
    Mcu,
    /// The front end's temperature channel.
    FrontEnd,
}

impl From<TempInputArg> for accelcal_shared::record::TempSource {
    fn from(t: TempInputArg) -> Self {
        match t {
            TempInputArg::Mcu => accelcal_shared::record::TempSource::Mcu,
            TempInputArg::FrontEnd => accelcal_shared::record::TempSource::FrontEnd,
        }
    }
}

/// `accelcal select`.
#[derive(Debug, Args)]
pub struct SelectArgs {
    /// Campaign CSV.
    pub campaign: PathBuf,
    /// Candidate models.
    #[arg(long, value_enum, default_value_t = BasisArg::Paper)]
    pub basis: BasisArg,
    /// External criterion, reported as an RMS in ADC codes of the dwell means' residuals (each
    /// position weighted by its samples).
    #[arg(long, value_enum, default_value_t = CriterionArg::Regularity)]
    pub criterion: CriterionArg,
    /// Division of the positions into A (fitting) and B (checking): `alternate`, `halves`, or
    /// `tail:FRACTION` (the last FRACTION of the positions in B), or `temp:T1[,T2,…]` (every
    /// position within 2.5 °C of a listed temperature in B: the check is on temperatures the fit
    /// did not see).
    #[arg(long, default_value = "alternate", value_parser = parse_split)]
    pub split: Split,
    /// The simplest model whose criterion is within this many ADC codes of the best is selected
    /// (the paper's rule: one ADC code); 0 selects the minimum.
    #[arg(long, default_value_t = 1.0, value_name = "CODES")]
    pub tolerance: f64,
    /// Only these channels (comma-separated names) [default: all].
    #[arg(long, value_delimiter = ',')]
    pub channels: Vec<String>,
    /// Search: `combi` scores every candidate (exhaustive combinatorial GMDH); `multi` is the
    /// multilayer (iterative) GMDH for bases too large for that: layer by layer, each of the
    /// --width best models of the previous layer grows by one term, until the best criterion
    /// stops improving.
    #[arg(long, value_enum, default_value_t = Algorithm::Combi)]
    pub algorithm: Algorithm,
    /// Models kept per layer by `--algorithm multi`.
    #[arg(long, default_value_t = 32)]
    pub width: usize,
    /// Largest number of terms in a candidate, intercept included.
    #[arg(long, value_name = "K", default_value_t = accelcal_shared::N_BASIS)]
    pub max_terms: usize,
    /// Worker threads [default: one per core].
    #[arg(long, value_name = "N")]
    pub threads: Option<usize>,
    /// In JSON, list only the N best candidates per channel (0 = all; default: all up to 4096
    /// candidates, else 1000).
    #[arg(long, value_name = "N")]
    pub top: Option<usize>,
    /// Write the criterion-against-complexity plot (SVG) into this directory.
    #[arg(long, value_name = "DIR")]
    pub plot: Option<PathBuf>,
    #[command(flatten)]
    pub thermal: ThermalArgs,
    #[command(flatten)]
    pub common: CommonArgs,
}

fn parse_split(s: &str) -> Result<Split, String> {
    s.parse()
}

/// External criteria of GMDH.
#[derive(Debug, Clone, Copy, ValueEnum, PartialEq, Eq)]
pub enum CriterionArg {
    /// Error on B of the model fitted on A (the paper's choice).
    Regularity,
    /// Error on B of the A-fit plus error on A of the B-fit.
    Symmetric,
    /// Residual on A∪B of the model fitted on A∪B.
    Rss,
    /// Leave-one-out (PRESS): each position's dwell mean against the model fitted on all the
    /// other positions, no split (so --split does not apply); for campaigns that a split leaves
    /// too few positions to fit on, such as the six test-turn positions.
    Loo,
}

impl From<CriterionArg> for Criterion {
    fn from(c: CriterionArg) -> Self {
        match c {
            CriterionArg::Regularity => Criterion::Regularity,
            CriterionArg::Symmetric => Criterion::Symmetric,
            CriterionArg::Rss => Criterion::Rss,
            CriterionArg::Loo => Criterion::Loo,
        }
    }
}

/// GMDH search algorithms.
#[derive(Debug, Clone, Copy, ValueEnum, PartialEq, Eq)]
pub enum Algorithm {
    /// Exhaustive combinatorial search.
    Combi,
    /// Multilayer (iterative) search.
    Multi,
}

/// Fitting methods.
#[derive(Debug, Clone, Copy, ValueEnum, PartialEq, Eq)]
pub enum MethodArg {
    /// Batch least squares over every position (any model).
    Lsq,
    /// Test turns: each axis along +g and -g (model 4 only).
    TestTurns,
    /// Gravity norm: a raw recording of hand-placed static holds, imu_tk model fitted on |a| = g.
    GravityNorm,
}

/// `accelcal fit`.
#[derive(Debug, Args)]
pub struct FitArgs {
    /// Campaign CSV (with --method gravity-norm: a raw recording, see --format).
    pub campaign: PathBuf,
    /// Fitting method.
    #[arg(long, value_enum, default_value_t = MethodArg::Lsq)]
    pub method: MethodArg,
    /// Model terms, comma-separated (the intercept is always included; `ax,ay,az` is the paper's
    /// model 4).
    #[arg(long, value_name = "LIST", default_value = "ax,ay,az")]
    pub terms: String,
    /// Write the calibration record for the firmware to this file.
    #[arg(long, value_name = "FILE")]
    pub record: Option<PathBuf>,
    /// Device id for the record: the MCU's 96-bit unique id as 24 hex digits [required with
    /// --record: a node accepts only a record made for it].
    #[arg(long, value_name = "HEX")]
    pub device_id: Option<String>,
    /// Creation time written into the record, seconds since the Unix epoch [default: now].
    #[arg(long, value_name = "UNIX_S")]
    pub created: Option<u64>,
    #[command(flatten)]
    pub thermal: ThermalArgs,
    /// Where the node reads the temperature that a record with terms in t applies: `mcu` (the
    /// MCU's internal sensor, the real board) or `front-end` (the front end's temperature channel,
    /// the emulated bench) [required with --record and terms in t].
    #[arg(long, value_enum, value_name = "INPUT")]
    pub temp_input: Option<TempInputArg>,
    #[command(flatten)]
    pub common: CommonArgs,
    /// Options of --method gravity-norm.
    #[command(flatten)]
    pub gravity: GravityOptions,
    /// The calibration database.
    #[command(flatten)]
    pub run: RunArgs,
}

/// `accelcal compare`.
#[derive(Debug, Args)]
pub struct CompareArgs {
    /// Campaign CSV to calibrate from (and to validate on, when no --validate is given: then every
    /// other position outside the test-turn positions is held out of both fits).
    pub campaign: PathBuf,
    /// Validate on this second campaign instead (both methods fit on all of CAMPAIGN).
    #[arg(long, value_name = "CAMPAIGN2")]
    pub validate: Option<PathBuf>,
    /// Write the error-per-position plots (SVG, like the paper's Figures 3 and 4) into this directory.
    #[arg(long, value_name = "DIR")]
    pub plot: Option<PathBuf>,
    #[command(flatten)]
    pub common: CommonArgs,
}

/// `accelcal demo`.
#[derive(Debug, Args)]
pub struct DemoArgs {
    /// Directory for the campaign, JSON results, the calibration record and the plots.
    #[arg(long, short, default_value = "accelcal-demo", value_name = "DIR")]
    pub out: PathBuf,
    /// Seed of the simulated block.
    #[arg(long, default_value_t = 2014)]
    pub seed: u64,
}

/// `accelcal diagnose`.
#[derive(Debug, Args)]
pub struct DiagnoseArgs {
    /// Campaign CSV.
    pub campaign: PathBuf,
    /// Baseline model terms, comma-separated (the intercept is always included; `ax,ay,az` is
    /// model 4); `--baseline` is the former name.
    #[arg(long = "terms", alias = "baseline", value_name = "LIST", default_value = "ax,ay,az")]
    pub terms: String,
    /// Write the gap-map plots (SVG) into this directory.
    #[arg(long, value_name = "DIR")]
    pub plot: Option<PathBuf>,
    #[command(flatten)]
    pub common: CommonArgs,
}

/// `accelcal bench-diagnose`.
#[derive(Debug, Args)]
pub struct BenchDiagnoseArgs {
    /// Number of simulated campaigns.
    #[arg(long, default_value_t = 240)]
    pub campaigns: usize,
    /// Master seed (each campaign's seed, effect and magnitude are drawn from it).
    #[arg(long, default_value_t = 2026)]
    pub seed: u64,
    /// Range of the effects' magnitudes, `LO:HI`, in units of the per-position noise (RMS of the
    /// effect's contribution to the dwell means over σ/√samples).
    #[arg(long, default_value = "3:8", value_name = "LO:HI")]
    pub magnitude: String,
    /// Write the results (confusion table, per-campaign rows) as JSON.
    #[arg(long, value_name = "FILE")]
    pub json: Option<PathBuf>,
}

/// `accelcal flash`: write a calibration record into a node through a debug probe.
#[derive(Debug, Args)]
pub struct FlashArgs {
    /// The calibration record file (from `accelcal fit --record`).
    #[arg(value_name = "RECORD")]
    pub record: PathBuf,
    /// probe-rs target name of the node's MCU.
    #[arg(long, default_value = "STM32L475VGTx")]
    pub chip: String,
    /// Debug probe to use, as VID:PID or VID:PID:SERIAL [default: the first one found].
    #[arg(long, value_name = "SELECTOR")]
    pub probe: Option<String>,
    /// Write through a GDB server instead of probe-rs: Black Magic Probe, OpenOCD, or the
    /// `gdb` address that `accelcal emulate` prints.
    #[arg(long, value_name = "HOST:PORT")]
    pub gdb: Option<String>,
    /// The node's serial port: after the write and the reset, the node is asked which record it
    /// runs (the write is confirmed only if it is the new one); with --gdb, also where the
    /// device id comes from when the server cannot read the MCU's unique id (QEMU).
    #[arg(long, value_name = "DEV")]
    pub port: Option<String>,
    /// Baud rate of the node's USART1 (with --port; a pty ignores it).
    #[arg(long, default_value_t = accelcal_core::node::monitor::NODE_BAUD)]
    pub baud: u32,
    /// Fault injection for tests of the torn-write safety (with --gdb): erase the target slot,
    /// write only this many bytes of its page, then reset the MCU. The old record stays in force.
    #[arg(long, value_name = "BYTES")]
    pub cut_after: Option<usize>,
    /// The calibration database.
    #[command(flatten)]
    pub run: RunArgs,
}

/// `accelcal record`: the calibration record files.
#[derive(Debug, Subcommand)]
pub enum RecordCommand {
    /// Print a calibration record (device id, terms, coefficients, created, CRC, length) and
    /// whether a node would accept it, with the node's reason when not.
    Show(RecordShowArgs),
}

/// `accelcal record show`.
#[derive(Debug, Args)]
pub struct RecordShowArgs {
    /// The calibration record file (from `accelcal fit --record`).
    #[arg(value_name = "FILE")]
    pub file: PathBuf,
    /// Write the same as machine-readable JSON to this file.
    #[arg(long, value_name = "FILE")]
    pub json: Option<PathBuf>,
}

/// `accelcal monitor`: show a node's live stream.
#[derive(Debug, Args)]
pub struct MonitorArgs {
    /// Serial port of the node (the board's ST-LINK virtual COM port, e.g. /dev/ttyACM0).
    #[arg(long, value_name = "DEV")]
    pub port: String,
    /// Baud rate of the node's USART1.
    #[arg(long, default_value_t = accelcal_core::node::monitor::NODE_BAUD)]
    pub baud: u32,
    /// Stop after this many messages; frames that do not decode are shown (`# bad frame: …`) and
    /// not counted [default: run until interrupted].
    #[arg(long, value_name = "N")]
    pub count: Option<u64>,
    /// First set the node's sampling rate per channel, Hz (100..=4000).
    #[arg(long, alias = "rate", value_name = "HZ")]
    pub rate_hz: Option<u32>,
    /// Seconds the node may go without sending a message before the command fails, whatever else
    /// arrives (bytes that make no frame, bad frames); the node sends its status every second.
    #[arg(long, default_value_t = 5.0, value_name = "S")]
    pub timeout_s: f64,
}

/// The node's serial link, shared by the commands that talk to a running node.
#[derive(Debug, Args, Clone)]
pub struct PortArgs {
    /// Serial port of the node: the board's ST-LINK virtual COM port (e.g. /dev/ttyACM0) or the
    /// `port` that `accelcal emulate` prints.
    #[arg(long, value_name = "DEV")]
    pub port: String,
    /// Baud rate of the node's USART1 (a pty ignores it).
    #[arg(long, default_value_t = accelcal_core::node::monitor::NODE_BAUD)]
    pub baud: u32,
    /// Seconds the node may take to answer a request (and, while it streams, between two sample
    /// blocks) before the command fails, whatever else it sends meanwhile.
    #[arg(long, alias = "answer-timeout-s", default_value_t = 5.0, value_name = "S")]
    pub timeout_s: f64,
}

/// `accelcal emulate`: the emulated bench.
#[derive(Debug, Args)]
pub struct EmulateArgs {
    /// The node's QEMU build (firmware/target/thumbv7em-none-eabihf/release/node-qemu).
    #[arg(long = "qemu", value_name = "ELF")]
    pub elf: PathBuf,
    /// The unit on the head: a truth file of `accelcal simulate --truth` (triad x, y, z; its bias,
    /// sensitivities, misalignment, noise and effects are what the front end produces). Repeat it
    /// for several nodes on the one head: one QEMU node per unit, each with its own front end,
    /// link and gdbstub (`nodes` of the printed line, in this order).
    #[arg(long, value_name = "UNIT_JSON", required = true)]
    pub unit: Vec<PathBuf>,
    /// Seed of the front end's noise [default: the unit's seed]; with several --unit, once per
    /// unit in the same order, or not at all.
    #[arg(long)]
    pub seed: Vec<u64>,
    /// A record to put into slot 0 before boot, as if it had been flashed earlier; with several
    /// --unit, once per unit in the same order, or not at all. The first node's device id is
    /// 51454d552d422d4c34373545 (`QEMU-B-L475E`), node N's (N >= 2) `QEMU-NODE-NN` (N in two digits) in
    /// hex (the `device_id` of `nodes` in the printed line).
    #[arg(long, value_name = "RECORD")]
    pub record: Vec<PathBuf>,
    /// The QEMU executable (QEMU >= 9 with the b-l475e-iot01a machine).
    #[arg(long, default_value = "qemu-system-arm", value_name = "PATH")]
    pub qemu_bin: PathBuf,
    /// Angular speed of the head's two axes, degrees per second (each move also takes 0.1 s).
    #[arg(long, default_value_t = 60.0, value_name = "DEG_S")]
    pub head_speed: f64,
    /// The front end converts at this factor times the rate the node asks for (above 1: faster
    /// than the node can take, to provoke overruns).
    #[arg(long, default_value_t = 1.0, value_name = "F")]
    pub rate_factor: f64,
    /// TCP port of QEMU's gdbstub on 127.0.0.1 [default: a free one]; with several --unit, the
    /// first node's, node N's is PORT + N - 1.
    #[arg(long, value_name = "PORT")]
    pub gdb_port: Option<u16>,
    /// TCP port of the emulated head on 127.0.0.1 [default: a free one].
    #[arg(long, value_name = "PORT")]
    pub head_port: Option<u16>,
    /// The number of this bench's first node on the line (1..=99): node N reports the device
    /// id QEMU-NODE-NN (node 1 QEMU-B-L475E), so two benches of one line report distinct devices.
    #[arg(long, default_value_t = 1, value_name = "N", value_parser = clap::value_parser!(u8).range(1..=99))]
    pub first_node: u8,
    /// Temperature of the thermal chamber around the head at start, °C (the sensor is soaked
    /// there); `CHAMBER <temp_c>` on the head's protocol (`acquire --chamber`, `verify
    /// --chamber`) changes it. The unit's `temperature` effect and the front end's temperature
    /// channel follow the sensor's temperature.
    #[arg(long, alias = "temp-c", default_value_t = 25.0, value_name = "DEG_C", allow_hyphen_values = true)]
    pub chamber: f64,
    /// Thermal time constant between the chamber and the sensor, seconds (first-order lag).
    #[arg(long, default_value_t = 30.0, value_name = "S")]
    pub thermal_lag_s: f64,
}

/// `accelcal info`: who the node is.
#[derive(Debug, Args)]
pub struct InfoArgs {
    /// The node's link.
    #[command(flatten)]
    pub link: PortArgs,
    /// Write the answer as JSON to this file: `{"device_id", "firmware", "record": {"slot",
    /// "sequence", "created_unix_s", "crc"} or null, "rate_hz", "overruns", "reset_cause"}`.
    #[arg(long, value_name = "FILE")]
    pub json: Option<PathBuf>,
}

/// What a node streams.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum OutputArg {
    /// Calibrated acceleration, m/s² (raw codes flagged uncalibrated when the node has no record).
    Calibrated,
    /// Raw ADC codes, whatever the record (what a recalibration records).
    Raw,
}

/// `accelcal output`: switch a node's live stream.
#[derive(Debug, Args)]
pub struct OutputArgs {
    /// The node's link.
    #[command(flatten)]
    pub link: PortArgs,
    /// What the node streams from now on (until it resets: it boots calibrated).
    #[arg(value_enum, value_name = "MODE")]
    pub mode: OutputArg,
}

/// `accelcal acquire`: record a campaign from a node on a dividing head.
#[derive(Debug, Args)]
pub struct AcquireArgs {
    /// Serial port of the node: the board's ST-LINK virtual COM port (e.g. /dev/ttyACM0) or a
    /// `port` that `accelcal emulate` prints. Repeat it for several nodes on the one head (one unit
    /// each, acquired together: one head move per position, every node captured there), each with
    /// its --out and --serial given in the same order.
    #[arg(long, value_name = "DEV", required = true)]
    pub port: Vec<String>,
    /// Baud rate of the nodes' USART1 (a pty ignores it).
    #[arg(long, default_value_t = accelcal_core::node::monitor::NODE_BAUD)]
    pub baud: u32,
    /// Seconds a node may take to answer a request (and, while it streams, between two sample
    /// blocks) before the command fails, whatever else it sends meanwhile.
    #[arg(long, alias = "answer-timeout-s", default_value_t = 5.0, value_name = "S")]
    pub timeout_s: f64,
    /// The head: `manual` (the command shows each position's angles and what the unit should
    /// read, and waits for Enter) or `sim:HOST:PORT` (the emulated head `accelcal emulate` prints).
    #[arg(long, value_name = "HEAD")]
    pub head: accelcal_core::node::head::HeadSpec,
    /// Seconds an emulated head (`--head sim:…`) may take to answer a request before the command
    /// fails; a move is answered once the head stands still, so this bounds the longest move.
    #[arg(long, default_value_t = 120.0, value_name = "S")]
    pub head_timeout_s: f64,
    /// Position plan: head (62 positions), six (the test-turn positions), random:N, or a plan
    /// file (CSV `alpha_deg,beta_deg`).
    #[arg(long, default_value = "head")]
    pub plan: String,
    /// Campaign CSV to write (raw codes, and `temp_c` when the node reports its temperature, as
    /// protocol 4 nodes do; the header comments carry device id, serial, firmware, g, plan, date,
    /// tool version). Must not exist, unless --resume. Once per --port, in the same order: each
    /// node's own campaign.
    #[arg(long, short, value_name = "CAMPAIGN", required = true)]
    pub out: Vec<PathBuf>,
    /// Sample sets recorded per position, after the stream is static [default: 400; with
    /// --resume, the campaign's].
    #[arg(long, value_name = "N")]
    pub samples: Option<usize>,
    /// The unit's serial number, written into the campaign; with several --port, once per port in
    /// the same order, or not at all.
    #[arg(long, value_name = "S")]
    pub serial: Vec<String>,
    /// Gravity at the rig, m/s² [default: 9.81, announced; better --latitude/--height].
    #[arg(long, value_name = "M_S2")]
    pub g: Option<f64>,
    /// Local gravity instead of --g.
    #[command(flatten)]
    pub local: LocalGravity,
    /// Continue an interrupted acquisition in --out (same node and plan): keep its complete
    /// positions and record the rest, with the campaign's samples, rate and g (an option that
    /// contradicts them is refused). With several --port each campaign continues from its own
    /// complete positions (the head revisits a position while a node lacks it; the campaigns must
    /// agree on samples, rate and g).
    #[arg(long)]
    pub resume: bool,
    /// Set the node's sampling rate per channel first, Hz (100..=4000) [default: the node's; with
    /// --resume, the campaign's]; held for every position (set again after a node reset).
    #[arg(long, alias = "rate", value_name = "HZ")]
    pub rate_hz: Option<u32>,
    /// Seconds a position may take to become static before it is refused.
    #[arg(long, default_value_t = 30.0, value_name = "S")]
    pub settle_timeout_s: f64,
    /// Static test: sets per window (two consecutive windows are compared).
    #[arg(long, default_value_t = 64, value_name = "N")]
    pub static_window: usize,
    /// Static test: largest change of the window means, in standard errors.
    #[arg(long, default_value_t = 3.0, value_name = "Z")]
    pub static_z: f64,
    /// A thermal campaign: run the plan at each of these chamber setpoints (°C, comma-separated),
    /// each after --soak-s (the node must report its temperature, recorded as `temp_c`).
    #[arg(long, value_name = "T1,T2,…", value_delimiter = ',', allow_hyphen_values = true)]
    pub chamber: Vec<f64>,
    /// Seconds to wait after each change of the chamber setpoint before the first position
    /// [with --chamber].
    #[arg(long, value_name = "S")]
    pub soak_s: Option<f64>,
}

/// `accelcal verify`: check a calibrated node on the head.
#[derive(Debug, Args)]
pub struct VerifyArgs {
    /// The node's link.
    #[command(flatten)]
    pub link: PortArgs,
    /// The head: `manual` or `sim:HOST:PORT` (as for `acquire`).
    #[arg(long, value_name = "HEAD")]
    pub head: accelcal_core::node::head::HeadSpec,
    /// Seconds an emulated head (`--head sim:…`) may take to answer a request before the command
    /// fails; a move is answered once the head stands still, so this bounds the longest move.
    #[arg(long, default_value_t = 120.0, value_name = "S")]
    pub head_timeout_s: f64,
    /// Position plan: six (the test-turn positions), head, random:N, or a plan file.
    #[arg(long, default_value = "six")]
    pub plan: String,
    /// Sample sets averaged per position, after the stream is static.
    #[arg(long, default_value_t = 400, value_name = "N")]
    pub samples: usize,
    /// Pass bound on every component's error, m/s² [default: derived per position, K·sqrt(σ_cal² +
    /// σ_mean²), σ_cal from --fit's covariance, σ_mean from the measured scatter, K = --coverage].
    #[arg(long, value_name = "M_S2")]
    pub tolerance: Option<f64>,
    /// Coverage factor K of the derived tolerance (>= 1). With Gaussian errors a good node fails a
    /// six-position verification (18 components) about once in 900 runs at K = 4, once in 10⁵ at
    /// K = 5 [default: 4; not with --tolerance].
    #[arg(long, value_name = "K")]
    pub coverage: Option<f64>,
    /// The `fit --json` output of the record's fit: its covariance matrix enters the derived
    /// tolerance (a thermal fit's terms in t too, at each position's temperature) [not with
    /// --tolerance].
    #[arg(long, value_name = "FIT_JSON")]
    pub fit: Option<PathBuf>,
    /// Gravity at the rig, m/s² [default: 9.81, announced; better --latitude/--height].
    #[arg(long, value_name = "M_S2")]
    pub g: Option<f64>,
    /// Local gravity instead of --g.
    #[command(flatten)]
    pub local: LocalGravity,
    /// Seconds a position may take to become static before it is refused.
    #[arg(long, default_value_t = 30.0, value_name = "S")]
    pub settle_timeout_s: f64,
    /// Write the verification table as JSON to this file.
    #[arg(long, value_name = "FILE")]
    pub json: Option<PathBuf>,
    /// Verify at this chamber setpoint, °C, after --soak-s.
    #[arg(long, value_name = "DEG_C", allow_hyphen_values = true)]
    pub chamber: Option<f64>,
    /// Seconds to wait after setting the chamber before the first position [with --chamber].
    #[arg(long, value_name = "S")]
    pub soak_s: Option<f64>,
    /// The calibration database.
    #[command(flatten)]
    pub run: RunArgs,
    /// Which verification this is, for --db: `as-found` (with the record the unit came in with,
    /// before it is changed) or `as-left` (with the new record, after flashing).
    #[arg(long, value_enum, default_value = "as-left", requires = "db")]
    pub phase: PhaseArg,
}

/// `accelcal report`: a unit's calibration certificate.
#[derive(Debug, Args)]
pub struct ReportArgs {
    /// The unit's campaign (from `accelcal acquire`: its header names serial, device, firmware, g).
    #[arg(long, value_name = "CAMPAIGN")]
    pub campaign: PathBuf,
    /// The record written to the node (from `fit --record`).
    #[arg(long, value_name = "RECORD")]
    pub record: PathBuf,
    /// The fit JSON written with the record (`fit --record R --json F`): it ties the record to
    /// the campaign (its SHA-256) and gives the method, g and the standard errors.
    #[arg(long, value_name = "FIT_JSON")]
    pub fit: PathBuf,
    /// The verification after flashing (`verify --json`); without it the page says "not verified".
    #[arg(long, value_name = "VERIFY_JSON")]
    pub verify: Option<PathBuf>,
    /// Gravity at the rig, m/s² [default: the fit's; given, it must be the fit's].
    #[arg(long, value_name = "M_S2")]
    pub g: Option<f64>,
    /// The certificate to write (HTML).
    #[arg(long, short, value_name = "FILE")]
    pub out: PathBuf,
    /// The calibration database.
    #[command(flatten)]
    pub run: RunArgs,
    /// The as-found verification (`verify --json` with the record the unit came in with): the
    /// certificate shows it next to the as-left one.
    #[arg(long, value_name = "VERIFY_JSON")]
    pub as_found: Option<PathBuf>,
}

/// `accelcal hil`: replay a campaign through the node's QEMU build.
#[derive(Debug, Args)]
pub struct HilArgs {
    /// The node's QEMU build (firmware/target/thumbv7em-none-eabihf/release/node-qemu).
    #[arg(long = "qemu", value_name = "ELF")]
    pub elf: PathBuf,
    /// Calibration record loaded into the node's flash (its device id must be the QEMU node's,
    /// 51454d552d422d4c34373545 = "QEMU-B-L475E").
    #[arg(long, value_name = "RECORD")]
    pub record: PathBuf,
    /// Campaign CSV whose channels x, y, z are replayed, row by row.
    #[arg(value_name = "CAMPAIGN")]
    pub campaign: PathBuf,
    /// CSV to write: `t_s,ax,ay,az`, the node's calibrated acceleration in m/s².
    #[arg(long, short, value_name = "FILE")]
    pub out: PathBuf,
    /// The QEMU executable (QEMU >= 9 with the b-l475e-iot01a machine).
    #[arg(long, default_value = "qemu-system-arm", value_name = "PATH")]
    pub qemu_bin: PathBuf,
    /// Seconds the node may stay silent (no frame) before the run fails.
    #[arg(long, default_value_t = 20.0, value_name = "S")]
    pub timeout_s: f64,
    /// Range of the campaign's raw codes [default: its `# codes:` line, else unsigned16]. Only
    /// unsigned16 can be replayed: the node samples a 16-bit unsigned ADC.
    #[arg(long, value_name = "RANGE", value_parser = parse_codes)]
    pub codes: Option<CodeRange>,
}

/// Input file formats accepted by the gravity-norm fit.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum InputFormat {
    /// imu_tk text: whitespace-separated `t x y z` rows, raw codes, optionally gzip-compressed.
    #[value(name = "imu-tk")]
    ImuTk,
}

/// Model structure requested on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum StructureArg {
    /// Bias and scale only (6 parameters).
    #[value(name = "bias-scale")]
    BiasScale,
    /// imu_tk: bias, scale, 3 misalignment angles (9 parameters).
    #[value(name = "imu-tk")]
    ImuTk,
    /// imu_tk plus a per-axis quadratic term (12 parameters).
    #[value(name = "quadratic")]
    Quadratic,
    /// The structure with the smallest residual on withheld holds (GMDH selection).
    #[value(name = "auto")]
    Auto,
}

/// Options of the gravity-norm fit other than the input, `--g` and `--json`; flattened into
/// `accelcal fit` (they apply to `--method gravity-norm` only).
#[derive(Debug, Clone, clap::Args)]
#[command(next_help_heading = "Gravity-norm options (--method gravity-norm)")]
pub struct GravityOptions {
    /// Format of the raw recording.
    #[arg(long, value_enum, default_value = "imu-tk")]
    pub format: InputFormat,
    /// Write SVG plots (residual per hold, detector trace) into this directory.
    #[arg(long, value_name = "DIR")]
    pub plot: Option<PathBuf>,
    /// Shortest accepted static hold, in seconds.
    #[arg(long, default_value_t = 2.0)]
    pub min_hold_s: f64,
    /// Detector threshold in codes² (sum of the three axis variances) [default: 4 x the lower
    /// quartile of the detector trace].
    #[arg(long)]
    pub threshold: Option<f64>,
    /// Length of the detector's sliding window, in seconds.
    #[arg(long, default_value_t = 1.0)]
    pub window_s: f64,
    /// Model structure to fit (`auto`: selected on withheld holds).
    #[arg(long, value_enum, default_value = "imu-tk")]
    pub structure: StructureArg,
    /// Also write the holds as a campaign CSV (the samples of every accepted hold, with the head
    /// angles alpha_deg, beta_deg of the hold's calibrated gravity direction), so that `accelcal
    /// diagnose` can examine a recording made without a dividing head.
    #[arg(long, value_name = "FILE")]
    pub campaign_out: Option<PathBuf>,
}

/// `accelcal station`.
#[derive(Debug, Args)]
pub struct StationArgs {
    /// Serial port of a node on the head (the board's ST-LINK virtual COM port, or a `port` that
    /// `accelcal emulate` prints). Repeat it for several nodes on one head, one unit each: they
    /// are acquired together, and --serial, --out (and --gdb or --probe when given) are given
    /// once per --port, in the same order.
    #[arg(long = "port", value_name = "DEV", required = true)]
    pub ports: Vec<String>,
    /// Baud rate of the nodes' USART1 (a pty ignores it).
    #[arg(long, default_value_t = accelcal_core::node::monitor::NODE_BAUD)]
    pub baud: u32,
    /// Seconds a node may stay silent (no answer to a request) before a step fails.
    #[arg(long, alias = "answer-timeout-s", default_value_t = 5.0, value_name = "S")]
    pub timeout_s: f64,
    /// The head: `manual` (the operator turns it; each step prompts) or `sim:HOST:PORT` (as for
    /// `acquire`).
    #[arg(long, value_name = "HEAD", value_parser = parse_head_text)]
    pub head: String,
    /// The unit's serial number (written into the campaign and the certificate; the unit's
    /// directory is its own); one per --port.
    #[arg(long = "serial", value_name = "S", required = true)]
    pub serials: Vec<String>,
    /// The unit's directory: the journal `station.json` and every file of the line (info.json,
    /// as-found-fit.json, as-found.json, campaign.csv, select.json, fit.json, record.rec, as-left.json,
    /// certificate.html). Created if missing; the same directory again resumes the unit. One per
    /// --port.
    #[arg(long = "out", short, value_name = "DIR", required = true)]
    pub outs: Vec<PathBuf>,
    /// Position plan of the campaign (head, six, random:N, or a plan file; see `acquire`).
    #[arg(long, default_value = "head")]
    pub plan: String,
    /// Sample sets recorded per position, in the campaign and in each verification.
    #[arg(long, default_value_t = 400, value_name = "N")]
    pub samples: usize,
    /// Set the node's sampling rate per channel for the campaign, Hz (100..=4000) [default: the
    /// node's].
    #[arg(long, value_name = "HZ")]
    pub rate_hz: Option<u32>,
    /// Gravity at the rig, m/s² [default: 9.81, announced; better --latitude/--height].
    #[arg(long, value_name = "M_S2")]
    pub g: Option<f64>,
    /// Local gravity instead of --g.
    #[command(flatten)]
    pub local: LocalGravity,
    /// The selection's tolerance, ADC codes: `select --tolerance` (the simplest model within it of
    /// the best is selected; the paper's rule is one code).
    #[arg(long, default_value_t = 1.0, value_name = "CODES")]
    pub select_tolerance: f64,
    /// Coverage factor K of the verifications' derived tolerance (>= 1) [default: verify's, 4].
    #[arg(long, value_name = "K")]
    pub coverage: Option<f64>,
    /// The `fit --json` of the record in force, for the as-found verification's tolerance
    /// [default: the database's fit of that record (its CRC), else the tolerance from the
    /// measured scatter alone].
    #[arg(long, value_name = "FIT_JSON")]
    pub as_found_fit: Option<PathBuf>,
    /// Flash through a GDB server (Black Magic Probe, OpenOCD, or `emulate`'s `gdb` address)
    /// instead of probe-rs; one per --port.
    #[arg(long, value_name = "HOST:PORT")]
    pub gdb: Vec<String>,
    /// probe-rs target name of the node's MCU [without --gdb].
    #[arg(long, default_value = "STM32L475VGTx")]
    pub chip: String,
    /// Debug probe, as VID:PID or VID:PID:SERIAL [without --gdb; one per --port; default with
    /// one node: the first one found].
    #[arg(long, value_name = "SELECTOR")]
    pub probe: Vec<String>,
    /// The calibration database every piece of the run is stored in (the record is flashed
    /// only once it is stored): a SQLite file, or postgres://USER@HOST[:PORT]/DB for a line of
    /// several stations [default: the ACCELCAL_DB environment variable, else calibration.sqlite
    /// in the directory that holds --out].
    #[arg(long, value_name = "FILE|URL")]
    pub db: Option<String>,
    /// The station's name in the database [default: the host name].
    #[arg(long = "station", value_name = "NAME")]
    pub station_name: Option<String>,
    /// Who runs the station, for the database [default: the USER environment variable].
    #[arg(long, value_name = "NAME")]
    pub operator: Option<String>,
    /// Seconds an emulated head (`--head sim:…`) may take to answer a request before a step
    /// fails (passed to acquire and the verifications); a move is answered once the head
    /// stands still, so this bounds the longest move.
    #[arg(long, default_value_t = 120.0, value_name = "S")]
    pub head_timeout_s: f64,
    /// Begin the run even though the database ties this --serial to another device, or the
    /// node's device to another serial: the serial moves to this device, stored as a relabel row
    /// with REASON (with several --port, it applies to each unit whose label clashes).
    #[arg(long, value_name = "REASON")]
    pub relabel: Option<String>,
}

/// `verify --phase`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum PhaseArg {
    /// Before the unit is changed, with the record it came in with.
    AsFound,
    /// After the new record was flashed.
    AsLeft,
}

/// A `--head` value, checked and kept as written (the station passes it on to each step).
fn parse_head_text(s: &str) -> Result<String, String> {
    s.parse::<accelcal_core::node::head::HeadSpec>().map(|_| s.to_string())
}
