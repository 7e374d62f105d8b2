//! The commands of the line that talk to a node, a head or a probe: flash, record, monitor,
//! emulate, info, output, acquire, verify, report, station.

use std::path::PathBuf;

use clap::{Args, Subcommand, ValueEnum};

use super::{Count, LocalGravity, Range, RateHz, Real, RunArgs};

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
    #[arg(long, default_value_t = accelcal_line::node::monitor::NODE_BAUD)]
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
    /// The fit JSON written with this record (`accelcal fit CAMPAIGN --record FILE --json F`):
    /// its uncertainty budget is printed, the expanded uncertainty U (k = 2) of the calibrated
    /// acceleration per axis in m/s² and each contributor. Refused when it is another record's
    /// fit (record CRC, device id).
    #[arg(long, value_name = "FIT.json")]
    pub fit: Option<PathBuf>,
    /// Print the same budget from the fit the calibration database stored with this record
    /// (a SQLite file, or postgres://USER@HOST[:PORT]/DB; opened read-only, never created).
    #[arg(long, value_name = "FILE|URL", conflicts_with = "fit")]
    pub db: Option<String>,
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
    #[arg(long, default_value_t = accelcal_line::node::monitor::NODE_BAUD)]
    pub baud: u32,
    /// Stop after this many messages; frames that do not decode are shown (`# bad frame: …`) and
    /// not counted [default: run until interrupted].
    #[arg(long, value_name = "N")]
    pub count: Option<u64>,
    /// First set the node's sampling rate per channel, Hz (100..=4000).
    #[arg(long, alias = "rate", value_name = "HZ", value_parser = RateHz)]
    pub rate_hz: Option<u32>,
    /// Seconds the node may go without sending a message before the command fails, whatever else
    /// arrives (bytes that make no frame, bad frames); the node sends its status every second.
    #[arg(long, default_value_t = 5.0, value_name = "S", value_parser = Real(Range::Seconds))]
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
    #[arg(long, default_value_t = accelcal_line::node::monitor::NODE_BAUD)]
    pub baud: u32,
    /// Seconds the node may take to answer a request (and, while it streams, between two sample
    /// blocks) before the command fails, whatever else it sends meanwhile.
    #[arg(long, alias = "answer-timeout-s", default_value_t = 5.0, value_name = "S", value_parser = Real(Range::Seconds))]
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
    #[arg(long, default_value_t = 60.0, value_name = "DEG_S", value_parser = Real(Range::DegreesPerS))]
    pub head_speed: f64,
    /// The front end converts at this factor times the rate the node asks for (above 1: faster
    /// than the node can take, to provoke overruns).
    #[arg(long, default_value_t = 1.0, value_name = "F", value_parser = Real(Range::RateFactor))]
    pub rate_factor: f64,
    /// TCP port of QEMU's gdbstub on 127.0.0.1 [default: a free one]; with several --unit, the
    /// first node's, node N's is PORT + N - 1.
    #[arg(long, value_name = "PORT")]
    pub gdb_port: Option<u16>,
    /// TCP port of the emulated head on 127.0.0.1 [default: a free one].
    #[arg(long, value_name = "PORT")]
    pub head_port: Option<u16>,
    /// The emulated head's protocol: `sim` (the line protocol, `sim:HOST:PORT`), `zaber`
    /// (Zaber's ASCII protocol over TCP, `zaber:HOST:PORT`) or `zaber-pty` (Zaber's ASCII
    /// protocol on a pseudo-terminal, as a serial chain: `zaber:/dev/pts/N`). The printed line's
    /// `head` is the spec to pass to `--head`. The Zaber stage has α at device 1 axis 1 and β at
    /// device 2 axis 1, 0.000234375 degrees per microstep, and starts not homed.
    #[arg(long = "head", value_enum, default_value = "sim", value_name = "PROTOCOL")]
    pub head_dialect: HeadDialectArg,
    /// Inject one fault into the head at the move --head-fault-at: reject (the move is refused),
    /// stall, limit (α stops half-way with Zaber's FS or WL), not-homed (α loses its reference and
    /// refuses the move), silent (no reply, no motion) or off=ARCSEC (α lands that many arcsec
    /// off, and its read-back says so). The sim head takes reject, silent and off=ARCSEC.
    #[arg(long, value_name = "KIND", value_parser = parse_fault_kind, allow_hyphen_values = true)]
    pub head_fault: Option<accelcal_line::emulate::fault::FaultKind>,
    /// The move the fault strikes: the N-th move the emulated head receives since it started,
    /// 1-based (a Zaber head counts the moves to α), so the same command run again meets no fault.
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u64).range(1..))]
    pub head_fault_at: Option<u64>,
    /// The number of this bench's first node on the line (1..=99): node N reports the device
    /// id QEMU-NODE-NN (node 1 QEMU-B-L475E), so two benches of one line report distinct devices.
    #[arg(long, default_value_t = 1, value_name = "N", value_parser = clap::value_parser!(u8).range(1..=99))]
    pub first_node: u8,
    /// Temperature of the thermal chamber around the head at start, °C (the sensor is soaked
    /// there); `CHAMBER <temp_c>` on the head's protocol (`acquire --chamber`, `verify
    /// --chamber`) changes it. The unit's `temperature` effect and the front end's temperature
    /// channel follow the sensor's temperature.
    #[arg(long, alias = "temp-c", default_value_t = 25.0, value_name = "DEG_C", allow_hyphen_values = true, value_parser = Real(Range::Chamber))]
    pub chamber: f64,
    /// Thermal time constant between the chamber and the sensor, seconds (first-order lag).
    #[arg(long, default_value_t = 30.0, value_name = "S", value_parser = Real(Range::SecondsOrZero))]
    pub thermal_lag_s: f64,
}

/// `emulate --head`: the emulated head's protocol.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum HeadDialectArg {
    /// The line protocol over TCP.
    Sim,
    /// Zaber's ASCII protocol over TCP.
    Zaber,
    /// Zaber's ASCII protocol on a pseudo-terminal.
    ZaberPty,
}

/// A `--head-fault` value.
fn parse_fault_kind(s: &str) -> Result<accelcal_line::emulate::fault::FaultKind, String> {
    s.parse()
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
    #[arg(long, default_value_t = accelcal_line::node::monitor::NODE_BAUD)]
    pub baud: u32,
    /// Seconds a node may take to answer a request (and, while it streams, between two sample
    /// blocks) before the command fails, whatever else it sends meanwhile.
    #[arg(long, alias = "answer-timeout-s", default_value_t = 5.0, value_name = "S", value_parser = Real(Range::Seconds))]
    pub timeout_s: f64,
    /// The head: `manual` (the command shows each position's angles and what the unit should
    /// read, and waits for Enter), `sim:HOST:PORT` (the emulated head `accelcal emulate` prints)
    /// `zaber:PORT` (a Zaber head over Zaber's ASCII protocol: a serial port such as
    /// `zaber:/dev/ttyUSB0`, at 115200 Bd 8N1, or a TCP address `zaber:HOST:PORT`) or
    /// `exec:COMMAND` (an adapter program speaking the head protocol on its standard input and
    /// output, e.g. `exec:"python3 examples/head-adapter/zaber_adapter.py HOST:PORT"`).
    #[arg(long, value_name = "HEAD")]
    pub head: accelcal_line::head::HeadSpec,
    /// Seconds a driven head (`--head sim:…`, `zaber:…` or `exec:…`) may take to answer a request
    /// before the command fails; a move is answered once the head stands still, so this bounds the
    /// longest move.
    #[arg(long, default_value_t = 120.0, value_name = "S", value_parser = Real(Range::Seconds))]
    pub head_timeout_s: f64,
    /// Largest accepted deviation of the angles a driven head reads back after a move from the
    /// commanded ones, arcsec (either angle; α modulo 360°). A position read back beyond it is
    /// refused before anything of it is recorded, and the command ends (exit code 3).
    #[arg(long, default_value_t = accelcal_line::head::Settle::TOLERANCE_ARCSEC, value_name = "ARCSEC", value_parser = Real(Range::Arcsec))]
    pub head_tolerance_arcsec: f64,
    /// Seconds to wait after the head reports a move done (or the operator confirms it) before
    /// the static test of the node's stream begins: for a head that rings after it stops.
    #[arg(long, default_value_t = 0.0, value_name = "S", value_parser = Real(Range::SecondsOrZero))]
    pub settle_s: f64,
    /// A Zaber head's axes and scale.
    #[command(flatten)]
    pub zaber: ZaberArgs,
    /// Position plan: head (62 positions), six (the test-turn positions), tumble24, random:N, or a plan
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
    #[arg(long, value_name = "N", value_parser = Count(Range::Sets))]
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
    #[arg(long, alias = "rate", value_name = "HZ", value_parser = RateHz)]
    pub rate_hz: Option<u32>,
    /// Seconds a position may take to become static before it is refused.
    #[arg(long, default_value_t = 30.0, value_name = "S", value_parser = Real(Range::Seconds))]
    pub settle_timeout_s: f64,
    /// Static test: sets per window (two consecutive windows are compared).
    #[arg(long, default_value_t = 64, value_name = "N", value_parser = Count(Range::Window))]
    pub static_window: usize,
    /// Static test: largest change of the window means, in standard errors.
    #[arg(long, default_value_t = 3.0, value_name = "Z", value_parser = Real(Range::Positive))]
    pub static_z: f64,
    /// A thermal campaign: run the plan at each of these chamber setpoints (°C, comma-separated),
    /// each after --soak-s (the node must report its temperature, recorded as `temp_c`).
    #[arg(long, value_name = "T1,T2,…", value_delimiter = ',', allow_hyphen_values = true)]
    pub chamber: Vec<f64>,
    /// Seconds to wait after each change of the chamber setpoint before the first position
    /// [with --chamber].
    #[arg(long, value_name = "S", value_parser = Real(Range::SecondsOrZero))]
    pub soak_s: Option<f64>,
}

/// `accelcal verify`: check a calibrated node on the head.
#[derive(Debug, Args)]
pub struct VerifyArgs {
    /// The node's link.
    #[command(flatten)]
    pub link: PortArgs,
    /// The head: `manual`, `sim:HOST:PORT`, `zaber:PORT` or `exec:COMMAND` (as for `acquire`).
    #[arg(long, value_name = "HEAD")]
    pub head: accelcal_line::head::HeadSpec,
    /// Seconds a driven head (`--head sim:…`, `zaber:…` or `exec:…`) may take to answer a request
    /// before the command fails; a move is answered once the head stands still, so this bounds the
    /// longest move.
    #[arg(long, default_value_t = 120.0, value_name = "S", value_parser = Real(Range::Seconds))]
    pub head_timeout_s: f64,
    /// Largest accepted deviation of the angles a driven head reads back after a move from the
    /// commanded ones, arcsec (either angle; α modulo 360°). A position read back beyond it is
    /// refused before anything of it is recorded, and the command ends (exit code 3).
    #[arg(long, default_value_t = accelcal_line::head::Settle::TOLERANCE_ARCSEC, value_name = "ARCSEC", value_parser = Real(Range::Arcsec))]
    pub head_tolerance_arcsec: f64,
    /// Seconds to wait after the head reports a move done (or the operator confirms it) before
    /// the static test of the node's stream begins: for a head that rings after it stops.
    #[arg(long, default_value_t = 0.0, value_name = "S", value_parser = Real(Range::SecondsOrZero))]
    pub settle_s: f64,
    /// A Zaber head's axes and scale.
    #[command(flatten)]
    pub zaber: ZaberArgs,
    /// Position plan: six (the test-turn positions), head, tumble24, random:N, or a plan file.
    #[arg(long, default_value = "six")]
    pub plan: String,
    /// Sample sets averaged per position, after the stream is static.
    #[arg(long, default_value_t = 400, value_name = "N", value_parser = Count(Range::Sets))]
    pub samples: usize,
    /// Pass bound on every component's error, m/s² [default: derived per position, K·sqrt(σ_cal² +
    /// σ_mean²), σ_cal from --fit's covariance, σ_mean from the measured scatter, K = --coverage].
    #[arg(long, value_name = "M_S2", value_parser = Real(Range::MetresPerS2))]
    pub tolerance: Option<f64>,
    /// Coverage factor K of the derived tolerance (>= 1). With Gaussian errors a good node fails a
    /// six-position verification (18 components) about once in 900 runs at K = 4, once in 10⁵ at
    /// K = 5 [default: 4; not with --tolerance].
    #[arg(long, value_name = "K", value_parser = Real(Range::Coverage))]
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
    #[arg(long, default_value_t = 30.0, value_name = "S", value_parser = Real(Range::Seconds))]
    pub settle_timeout_s: f64,
    /// Write the verification table as JSON to this file.
    #[arg(long, value_name = "FILE")]
    pub json: Option<PathBuf>,
    /// Verify at this chamber setpoint, °C, after --soak-s.
    #[arg(long, value_name = "DEG_C", allow_hyphen_values = true)]
    pub chamber: Option<f64>,
    /// Seconds to wait after setting the chamber before the first position [with --chamber].
    #[arg(long, value_name = "S", value_parser = Real(Range::SecondsOrZero))]
    pub soak_s: Option<f64>,
    /// The calibration database.
    #[command(flatten)]
    pub run: RunArgs,
    /// Which verification this is, for --db: `as-found` (with the record the unit came in with,
    /// before it is changed) or `as-left` (with the new record, after flashing).
    #[arg(long, value_enum, default_value = "as-left", requires = "db")]
    pub phase: PhaseArg,
    /// The product specification of the unit type and its decision rule, a TOML file
    /// (`unit_type`, `acceleration_error_m_s2` = the limit T on each component's error, m/s²,
    /// `rule` = `simple` or `guard-band`, optional `guard_band_m_s2`): each position's components
    /// are decided pass, conditional pass, conditional fail or fail against T with the expanded
    /// uncertainty U (k = 2) of each measured error, and a position passes when every component
    /// is a pass [default: the consistency check against the fit's --coverage bound].
    #[arg(long, value_name = "FILE", conflicts_with_all = ["tolerance", "coverage"])]
    pub spec: Option<PathBuf>,
    /// The head's angle setting uncertainty, arcsec (one sigma, from its certificate): it enters
    /// U of each measured error [with --spec; default: not stated, named as not included].
    #[arg(long, value_name = "ARCSEC", value_parser = Real(Range::Arcsec), requires = "spec")]
    pub head_angle_u: Option<f64>,
    /// The head's orthogonality uncertainty, arcsec (one sigma of each rotation between its
    /// stages): it enters U of each measured error [with --spec; default: not stated].
    #[arg(long, value_name = "ARCSEC", value_parser = Real(Range::Arcsec), requires = "spec")]
    pub head_orthogonality_u: Option<f64>,
    #[arg(long, value_name = "ID", requires = "db", help = crate::cli::GRAVITY_ASSET_HELP)]
    pub gravity_asset: Option<String>,
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
    /// Also write the certificate as a PDF (A4, fonts embedded, text extractable) to this file.
    #[arg(long, value_name = "FILE")]
    pub pdf: Option<PathBuf>,
    /// Also write the certificate as a Digital Calibration Certificate (PTB's DCC XML, schema
    /// 3.3.0, quantities in D-SI 2.2.1, its document attached) to this file.
    #[arg(long, value_name = "FILE")]
    pub dcc: Option<PathBuf>,
    /// Also write the technical report (the coefficients with their standard errors, GMDH's
    /// model selection and the paper's Table 2: engineering material, not the certificate) to
    /// this HTML file.
    #[arg(long, value_name = "FILE")]
    pub technical: Option<PathBuf>,
    /// The calibration database.
    #[command(flatten)]
    pub run: RunArgs,
    /// The as-found verification (`verify --json` with the record the unit came in with): the
    /// certificate shows it next to the as-left one.
    #[arg(long, value_name = "VERIFY_JSON")]
    pub as_found: Option<PathBuf>,
    /// The certificate's issuer.
    #[command(flatten)]
    pub issuer: Issuer,
}

/// `accelcal station`.
#[derive(Debug, Args)]
pub struct StationArgs {
    /// Serial port of a node on the head (the board's ST-LINK virtual COM port, or a `port` that
    /// `accelcal emulate` prints). Repeat it for several nodes on one head, one unit each: they
    /// are acquired together, and --serial, --out (and --gdb or --probe when given) are given
    /// once per --port, in the same order.
    #[arg(long = "port", value_name = "DEV")]
    pub ports: Vec<String>,
    /// The line's settings, a TOML file: each key is the option of the same name (`_` for `-`,
    /// `station` for --station), the nodes are `[[node]]` tables with `port` and, optionally,
    /// `gdb` or `probe`, and the laboratory is a `[laboratory]` table with `name` and
    /// `address`. An option on the command line overrides its key; --port replaces every
    /// `[[node]]` (their gdb and probe too); --g, --latitude or --height replace the file's
    /// gravity. Relative paths in it (spec, a SQLite db) are relative to the file's directory,
    /// and its db is used before the ACCELCAL_DB environment variable. An unknown key is refused
    /// with its line.
    #[arg(long, value_name = "FILE")]
    pub config: Option<PathBuf>,
    /// Baud rate of the nodes' USART1 (a pty ignores it).
    #[arg(long, default_value_t = accelcal_line::node::monitor::NODE_BAUD)]
    pub baud: u32,
    /// Seconds a node may stay silent (no answer to a request) before a step fails.
    #[arg(long, alias = "answer-timeout-s", default_value_t = 5.0, value_name = "S", value_parser = Real(Range::Seconds))]
    pub timeout_s: f64,
    /// The head: `manual` (the operator turns it; each step prompts), `sim:HOST:PORT` or
    /// `zaber:PORT` or `exec:COMMAND` (as for `acquire`).
    #[arg(long, value_name = "HEAD", value_parser = parse_head_text)]
    pub head: Option<String>,
    /// The unit's serial number (written into the campaign and the certificate; the unit's
    /// directory is its own); one per --port.
    #[arg(long = "serial", value_name = "S", required_unless_present = "check_standard")]
    pub serials: Vec<String>,
    /// Check the station with its check standard, the unit of serial S (a known unit whose record
    /// is in force; one --port): its as-found verification only, nothing recalibrated. The
    /// check's value per axis, the mean error of that component over the verification's
    /// positions (m/s²), goes on the station's individuals chart (limits x̄ ± 3σ̂, σ̂ = MR̄/1.128,
    /// from its first 20 checks, at least 5; Western Electric rules 1 to 4). A check out of
    /// control ends with exit code 3 naming the rule and the check, and the station then refuses
    /// production runs (exit code 3) until a check is in control again. Needs a database.
    #[arg(long, value_name = "S")]
    pub check_standard: Option<String>,
    /// The unit's directory: the journal `station.json` and every file of the line (info.json,
    /// as-found-fit.json, as-found.json, campaign.csv, select.json, fit.json, record.rec, as-left.json,
    /// certificate.html). Created if missing; the same directory again resumes the unit. One per
    /// --port.
    #[arg(long = "out", short, value_name = "DIR", required = true)]
    pub outs: Vec<PathBuf>,
    /// Position plan of the campaign (head, six, tumble24, random:N, or a plan file; see
    /// `acquire`). A plan file's header lines `# samples:` and `# rate_hz:` (as `plan --design`
    /// writes them) are the campaign's samples and rate; a --samples or --rate-hz that
    /// contradicts them is refused.
    #[arg(long, default_value = "head")]
    pub plan: String,
    /// Sample sets recorded per position in the campaign (a plan file's `# samples:` when it
    /// states one), and in each verification unless --verify-samples (this option's value, never
    /// the plan file's).
    #[arg(long, default_value_t = 400, value_name = "N", value_parser = Count(Range::Sets))]
    pub samples: usize,
    /// Sample sets recorded per position in the as-found and as-left verifications, so that a
    /// long dwell for the campaign does not lengthen them [default: --samples].
    #[arg(long, value_name = "N", value_parser = Count(Range::Sets))]
    pub verify_samples: Option<usize>,
    /// Set the node's sampling rate per channel for the campaign, Hz (100..=4000) [default: the
    /// plan file's `# rate_hz:`, else the node's].
    #[arg(long, value_name = "HZ", value_parser = RateHz)]
    pub rate_hz: Option<u32>,
    /// Gravity at the rig, m/s² [default: 9.81, announced; better --latitude/--height].
    #[arg(long, value_name = "M_S2")]
    pub g: Option<f64>,
    /// Local gravity instead of --g.
    #[command(flatten)]
    pub local: LocalGravity,
    /// The selection's tolerance, ADC codes: `select --tolerance` (the simplest model within it of
    /// the best is selected; the paper's rule is one code).
    #[arg(long, default_value_t = 1.0, value_name = "CODES", value_parser = Real(Range::Codes))]
    pub select_tolerance: f64,
    /// The selection's external criterion: `select --criterion` (regularity, the paper's; loo,
    /// leave-one-out, which `plan --design` advises for plans a split leaves too few positions
    /// to fit on).
    #[arg(long, value_enum, default_value_t = super::CriterionArg::Regularity)]
    pub criterion: super::CriterionArg,
    /// Coverage factor K of the verifications' derived tolerance (>= 1) [default: verify's, 4].
    #[arg(long, value_name = "K", value_parser = Real(Range::Coverage))]
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
    /// Append each chain head the station and its steps write to FILE (a line `TIME
    /// accelcal-anchor seq=N chain_sha256=HEX`; `db verify --anchors FILE` checks them). The
    /// file's latest anchor is checked first: a database cut short or rewritten behind it stops
    /// the station before it touches a node. The unit's journal keeps the chain head after each
    /// step, and its certificate the head at issue, either way.
    #[arg(long, value_name = "FILE")]
    pub anchor_log: Option<PathBuf>,
    /// The dividing head as a registered asset (`accelcal asset add ID --kind head`): the run
    /// stores it, and the fit's uncertainty budget takes the head's stated uncertainties from its
    /// certificate in force. An overdue, unknown or non-head asset stops the station before it
    /// touches a node (exit code 3, nothing done) [default: the head is not a registered asset,
    /// and the budget names its uncertainties as not stated].
    #[arg(long, value_name = "ID")]
    pub head_asset: Option<String>,
    #[arg(long, value_name = "ID", help = crate::cli::GRAVITY_ASSET_HELP)]
    pub gravity_asset: Option<String>,
    /// The environment's thermometer as a registered asset (`accelcal asset add ID --kind
    /// thermometer --u K`): the run stores it, and the certificate states --ambient-c as read on
    /// it, with U (k = 2) from its certificate. An overdue, unknown or non-thermometer asset stops
    /// the station before it touches a node (exit code 3) [with --ambient-c; default: the
    /// certificate states the unit's own sensor, not traceable].
    #[arg(long, value_name = "ID")]
    pub thermometer_asset: Option<String>,
    /// The unit type's temperature coefficients for the fit's uncertainty budget (as for `fit`).
    #[command(flatten)]
    pub tempco: crate::cli::campaign::TempcoArgs,
    /// The product specification of the unit type and its decision rule, a TOML file (as for
    /// `verify --spec`): both verifications decide each component against it (with the head
    /// asset's stated uncertainties in U when --head-asset is given), and an as-found result out
    /// of tolerance is named on the station's last line [default: the consistency check].
    #[arg(long, value_name = "FILE", conflicts_with = "coverage")]
    pub spec: Option<PathBuf>,
    /// The station's name in the database [default: the host name].
    #[arg(long = "station", value_name = "NAME")]
    pub station_name: Option<String>,
    /// Who runs the station, for the database [default: the USER environment variable].
    #[arg(long, value_name = "NAME")]
    pub operator: Option<String>,
    /// Seconds a driven head (`--head sim:…`, `zaber:…`) may take to answer a request before a step
    /// fails (passed to acquire and the verifications); a move is answered once the head
    /// stands still, so this bounds the longest move.
    #[arg(long, default_value_t = 120.0, value_name = "S", value_parser = Real(Range::Seconds))]
    pub head_timeout_s: f64,
    /// Largest accepted deviation of a driven head's read-back angles from the commanded ones,
    /// arcsec (passed to acquire and the verifications) [default: 10].
    #[arg(long, value_name = "ARCSEC", value_parser = Real(Range::Arcsec))]
    pub head_tolerance_arcsec: Option<f64>,
    /// Seconds to wait after each move before the static test (passed to acquire and the
    /// verifications) [default: 0].
    #[arg(long, value_name = "S", value_parser = Real(Range::SecondsOrZero))]
    pub settle_s: Option<f64>,
    /// A Zaber head's axes and scale (passed to acquire and the verifications).
    #[command(flatten)]
    pub zaber: ZaberArgs,
    /// Begin the run even though the database ties this --serial to another device, or the
    /// node's device to another serial: the serial moves to this device, stored as a relabel row
    /// with REASON (with several --port, it applies to each unit whose label clashes).
    #[arg(long, value_name = "REASON")]
    pub relabel: Option<String>,
    /// The certificate's issuer.
    #[command(flatten)]
    pub issuer: Issuer,
}

impl StationArgs {
    /// The head, from --head or the settings file (`settings::apply_config` refuses a station
    /// without one).
    pub fn head(&self) -> &str {
        self.head.as_deref().expect("settings::apply_config refuses a station without a head")
    }
}

/// The laboratory that issues a certificate, and its customer.
#[derive(Debug, Args, Clone, Default)]
pub struct Issuer {
    /// The name of the calibration laboratory, printed on the certificate [default: none
    /// printed].
    #[arg(long, value_name = "NAME")]
    pub laboratory: Option<String>,
    /// The laboratory's address, printed after its name (with --laboratory).
    #[arg(long, value_name = "TEXT")]
    pub laboratory_address: Option<String>,
    /// The laboratory's country, ISO 3166-1 alpha-2 (two capital letters, e.g. DE), which the DCC
    /// states (with --laboratory) [default: the DCC says ZZ, unknown].
    #[arg(long, value_name = "CC")]
    pub laboratory_country: Option<String>,
    /// The customer the unit is calibrated for, printed on the certificate [default: none
    /// printed].
    #[arg(long, value_name = "NAME")]
    pub customer: Option<String>,
    /// The customer's address or contact, printed after its name (with --customer).
    #[arg(long, value_name = "TEXT")]
    pub customer_address: Option<String>,
    /// The environment's temperature during the calibration, °C (-50 to 100), as read on the
    /// run's registered thermometer (`station --thermometer-asset`): the certificate states it with
    /// U (k = 2) from the thermometer's certificate [report: with --db and --run-id; station: with
    /// --thermometer-asset].
    #[arg(long, value_name = "DEG_C", allow_hyphen_values = true)]
    pub ambient_c: Option<f64>,
    /// The day the item was received, YYYY-MM-DD, printed with the dates.
    #[arg(long, value_name = "DATE")]
    pub received: Option<String>,
    /// Where the item is calibrated (the station and the site), printed on the certificate.
    #[arg(long, value_name = "TEXT")]
    pub place: Option<String>,
    /// The person who authorises the certificate, printed on it [default: none; the page then
    /// says it is a draft].
    #[arg(long, value_name = "NAME")]
    pub authorised_by: Option<String>,
    /// The recalibration interval the laboratory decides for this unit, days: the certificate
    /// states it as the laboratory's decision, with the interval the drift rule gives beside it
    /// [default: the drift rule's interval].
    #[arg(long, value_name = "DAYS", value_parser = Real(Range::Positive))]
    pub interval_days: Option<f64>,
    /// The shortest recalibration interval the certificate recommends, days: a floor under the
    /// drift's interval and under an interval halved after an as-found result out of tolerance
    /// (station.toml: min_interval_days) [default: 30].
    #[arg(long, value_name = "DAYS", value_parser = Real(Range::Positive))]
    pub min_interval_days: Option<f64>,
}

/// `verify --phase`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum PhaseArg {
    /// Before the unit is changed, with the record it came in with.
    AsFound,
    /// After the new record was flashed.
    AsLeft,
}

/// A Zaber head's axes and scale (`--head zaber:…` only), each passed on as given.
#[derive(Debug, Clone, Default, PartialEq, Args)]
pub struct ZaberArgs {
    /// A Zaber head's α axis (the spindle) as DEVICE/AXIS: its device number on the chain
    /// (1..=99) and its axis on the device (1..=9) [default: 1/1].
    #[arg(long, value_name = "D/A", value_parser = parse_zaber_axis)]
    pub zaber_alpha: Option<accelcal_line::head::zaber::codec::Address>,
    /// A Zaber head's β axis (the tilt) as DEVICE/AXIS [default: 2/1].
    #[arg(long, value_name = "D/A", value_parser = parse_zaber_axis)]
    pub zaber_beta: Option<accelcal_line::head::zaber::codec::Address>,
    /// Degrees per microstep of a Zaber head's two rotary stages, from their datasheet: the
    /// commanded angles are rounded to it [default: 0.000234375, 0.84375 arcsec].
    #[arg(long, value_name = "DEG", value_parser = Real(Range::DegPerStep))]
    pub zaber_deg_per_step: Option<f64>,
}

impl ZaberArgs {
    /// The axes and scale, the defaults where not given.
    pub fn axes(&self) -> accelcal_line::head::ZaberAxes {
        let d = accelcal_line::head::ZaberAxes::default();
        accelcal_line::head::ZaberAxes {
            alpha: self.zaber_alpha.unwrap_or(d.alpha),
            beta: self.zaber_beta.unwrap_or(d.beta),
            deg_per_step: self.zaber_deg_per_step.unwrap_or(d.deg_per_step),
        }
    }

    /// The clap ids of the options, for refusing them with another head.
    pub const IDS: [&'static str; 3] = ["zaber_alpha", "zaber_beta", "zaber_deg_per_step"];
}

/// A `--zaber-alpha`/`--zaber-beta` value.
pub fn parse_zaber_axis(s: &str) -> Result<accelcal_line::head::zaber::codec::Address, String> {
    s.parse()
}

/// A `--head` value, checked and kept as written (the station passes it on to each step).
fn parse_head_text(s: &str) -> Result<String, String> {
    s.parse::<accelcal_line::head::HeadSpec>().map(|_| s.to_string())
}
