//! The commands on campaign files: plan, simulate, select, fit (gravity-norm too), compare,
//! demo, diagnose, bench-diagnose, hil.

use std::path::PathBuf;

use clap::{Args, ValueEnum};

use accelcal_core::campaign::CodeRange;
use accelcal_core::gmdh::{Criterion, Split};
use accelcal_core::sim::{Layout, TempProfile};

use super::{parse_codes, CommonArgs, Count, LocalGravity, Range, Real, RunArgs};

/// `accelcal plan`.
#[derive(Debug, Args)]
pub struct PlanArgs {
    /// Position plan: `head` (62 positions), `six` (the six test-turn positions), `tumble24` (a
    /// 24-position multipoint tumble, three circles in 45° steps), `random:N`, or a
    /// plan file (CSV with columns alpha_deg,beta_deg), as in `simulate --plan`.
    #[arg(long, default_value = "head", value_name = "PLAN")]
    pub plan: String,
    /// Seed of `random:N`, and of the design's random starts with --design (the same seed, the
    /// same plan).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Gravity at the rig, m/s².
    #[arg(long, default_value_t = accelcal_shared::G_STANDARD)]
    pub g: f64,
    /// Local gravity instead of --g.
    #[command(flatten)]
    pub local: LocalGravity,
    /// Write the positions and their accelerations (m/s²) as JSON; with --design, the designed
    /// plan: `positions` (how many), `samples_per_position`, `head_time_s`, the predicted
    /// `U_m_s2` (worst axis at its worst orientation at 1 g), its criteria and the plans compared.
    #[arg(long, value_name = "FILE")]
    pub json: Option<PathBuf>,
    #[command(flatten)]
    pub design: DesignArgs,
}

/// The options of `accelcal plan --design`.
#[derive(Debug, Args)]
pub struct DesignArgs {
    /// Design a plan instead of printing one: `N` positions chosen among those the head reaches
    /// (--alpha-step-deg, --beta-step-deg, --beta-max-deg), each dwelling --samples sample sets,
    /// that minimise the predicted expanded uncertainty (k = 2) of the calibrated acceleration
    /// (model 4, worst axis, worst orientation at 1 g); or `auto`: the number of positions and the
    /// dwell too, for the least head time (positions × (--move-s + dwell)) that reaches
    /// --target-U. The positions are ordered for short moves, and so that both parts of GMDH's
    /// default alternate split identify every model of the paper a head plan can (else
    /// leave-one-out; the output says which). At least 8 positions.
    #[arg(long, value_name = "N|auto", value_parser = parse_design, conflicts_with = "plan")]
    pub design: Option<DesignSize>,
    /// The designed plan file to write: CSV `alpha_deg,beta_deg`, as simulate, acquire, verify
    /// and station read it, with its dwell in its header (`# samples:`, `# rate_hz:`), which the
    /// station takes [required with --design].
    #[arg(long, short, value_name = "FILE", requires = "design")]
    pub out: Option<PathBuf>,
    /// An earlier campaign of the same kind of unit (campaign CSV): its sensitivities (model 4 by
    /// least squares) and its noise per sample (the scatter within its dwells) are the unit
    /// type's; its header's rate (`# rate_hz:`) and g (`# g_m_s2:`, `# g_source:`) are the
    /// design's unless --rate-hz, --g or --latitude say otherwise [with --design; or --noise].
    #[arg(long, value_name = "CAMPAIGN", requires = "design", conflicts_with = "noise")]
    pub like: Option<PathBuf>,
    /// Without --like: the nominal triad (16384 codes per g) with this white noise per sample,
    /// ADC codes (one sigma) [with --design].
    #[arg(long, value_name = "CODES", requires = "design", value_parser = Real(Range::Sigma))]
    pub noise: Option<f64>,
    /// The dividing head's angle setting uncertainty, arcsec: one sigma of each angle at each
    /// position, from its certificate (as `fit --head-angle-u`) [with --design; default 0].
    #[arg(long, value_name = "ARCSEC", value_parser = Real(Range::Arcsec), requires = "design")]
    pub head_angle_u: Option<f64>,
    /// Move plus settling time per position, s [with --design; default 10].
    #[arg(long, value_name = "S", requires = "design", value_parser = Real(Range::SecondsOrZero))]
    pub move_s: Option<f64>,
    /// The node's sample rate, Hz [with --design; default: the --like campaign's `# rate_hz:`,
    /// else 100].
    #[arg(long, value_name = "HZ", requires = "design", value_parser = Real(Range::Positive))]
    pub rate_hz: Option<f64>,
    /// Sample sets per position: the designed plan's dwell with --design N, and the dwell of the
    /// plans it is compared with (the paper's 62 positions, tumble24, six) [with --design;
    /// default 400].
    #[arg(long, value_name = "N", requires = "design", value_parser = clap::value_parser!(u32).range(1..=1_000_000))]
    pub samples: Option<u32>,
    /// The expanded uncertainty to reach with --design auto, m/s² (worst axis, worst orientation
    /// at 1 g, k = 2) [default: the paper's 62-position plan's, at --samples].
    #[arg(long = "target-U", value_name = "M_S2", requires = "design", value_parser = Real(Range::Positive))]
    pub target_u: Option<f64>,
    /// The head's α step, degrees (α all round) [with --design; default 15].
    #[arg(long, value_name = "DEG", requires = "design", value_parser = Real(Range::Positive))]
    pub alpha_step_deg: Option<f64>,
    /// The head's β step, degrees [with --design; default 15].
    #[arg(long, value_name = "DEG", requires = "design", value_parser = Real(Range::Positive))]
    pub beta_step_deg: Option<f64>,
    /// The head's β limit either side of 0, degrees (at most 90) [with --design; default 90].
    #[arg(long, value_name = "DEG", requires = "design", value_parser = Real(Range::Sigma))]
    pub beta_max_deg: Option<f64>,
    /// Check the prediction by simulation (JCGM 101): this many simulated units calibrated on
    /// each plan compared (the paper's, tumble24, six, the designed one) with the unit type's
    /// noise and the head's angle errors, their budgets' U, its coverage of the true error at
    /// orientations none of the plans chose (95 % when right) and that error's RMS [with --design].
    #[arg(long, value_name = "UNITS", requires = "design", value_parser = clap::value_parser!(u32).range(10..=100_000))]
    pub montecarlo: Option<u32>,
    /// A thermal campaign: the plan is run once at each of these chamber setpoints (°C,
    /// comma-separated, as `acquire --chamber` runs it) and the linear thermal model (`1, ax, ay,
    /// az, t, ax*t, ay*t, az*t`) is fitted. U is then predicted at the worst temperature of the
    /// calibrated range (an end of it), and the head time counts every pass and its soak [with
    /// --design; not with --montecarlo].
    #[arg(
        long = "chamber",
        value_name = "T1,T2,…",
        value_delimiter = ',',
        allow_hyphen_values = true,
        requires = "design"
    )]
    pub chamber: Vec<f64>,
    /// Seconds the chamber holds each setpoint before its pass, counted in the head time [with
    /// --chamber; default: 900, as simulate's].
    #[arg(long = "soak-s", value_name = "S", requires = "chamber", value_parser = Real(Range::SecondsOrZero))]
    pub soak_s: Option<f64>,
}

pub use crate::settings::campaign::DesignSize;

/// `N` or `auto`.
fn parse_design(s: &str) -> Result<DesignSize, String> {
    match s.trim() {
        "auto" => Ok(DesignSize::Auto),
        n => match n.parse::<usize>() {
            Ok(n) if n > 0 => Ok(DesignSize::Positions(n)),
            _ => Err("expected a number of positions or `auto`".into()),
        },
    }
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
    /// +-90), `six` (the six test-turn positions), `tumble24` (IEEE 1293's multipoint tumble for a
    /// triad: a circle in 45° steps in each plane of two axes, 24 positions), `random:N` (N orientations uniform on the
    /// sphere), or a plan file (CSV with columns alpha_deg,beta_deg).
    #[arg(long, default_value = "head", value_name = "PLAN")]
    pub plan: String,
    /// Channel layout: `triad` (channels x, y, z) or `block:N` (N single-axis sensors a1..aN with
    /// sensitive axes cycling x, y, z).
    #[arg(long, default_value = "triad", value_parser = parse_layout)]
    pub layout: Layout,
    /// Sample sets per position (the dwell; its mean is what selection and fits use).
    #[arg(long, default_value_t = 400, value_parser = Count(Range::AtLeast1))]
    pub samples: usize,
    /// Sample rate, Hz.
    #[arg(long, default_value_t = 100.0, value_parser = Real(Range::Positive))]
    pub rate_hz: f64,
    /// Time between positions (head moving), s.
    #[arg(long, default_value_t = 2.0, value_parser = Real(Range::SecondsOrZero))]
    pub move_s: f64,
    /// White noise per sample, ADC codes (one sigma).
    #[arg(long, default_value_t = 80.0, value_parser = Real(Range::Sigma))]
    pub noise: f64,
    /// Spread of the zero offsets around mid-scale, codes (one sigma).
    #[arg(long, default_value_t = 300.0, value_parser = Real(Range::Sigma))]
    pub bias_sd: f64,
    /// Relative spread of the scale factors around 16384 codes/g (one sigma).
    #[arg(long, default_value_t = 0.01, value_parser = Real(Range::Sigma))]
    pub scale_sd: f64,
    /// Misalignment of each sensitive axis, rad (one sigma per angle).
    #[arg(long, default_value_t = 0.01, value_parser = Real(Range::Sigma))]
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
    #[arg(long, value_name = "S", value_parser = Real(Range::SecondsOrZero))]
    pub soak_s: Option<f64>,
    /// Thermal time constant between the chamber and the sensor, seconds (first-order lag) [with
    /// --chamber; default: 30, as `emulate`'s].
    #[arg(long, value_name = "S", value_parser = Real(Range::SecondsOrZero))]
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

/// The unit type's temperature sensitivity and the thermometer, for the uncertainty budget.
#[derive(Args, Debug, Clone, Default)]
pub struct TempcoArgs {
    /// The unit type's bias temperature coefficient, mg/°C: one sigma of each channel's
    /// coefficient (from its data sheet). With --scale-tempco-u and --thermometer-u, the
    /// budget's `temperature` contributor: the coefficients are measured at the campaign's mean
    /// temperature T̄ and stated at the reference --t-ref, so each channel's bias is uncertain by
    /// this × √((T̄ − t_ref)² + u(T)²) [--method lsq, model 4, a campaign with `temp_c`; default:
    /// named on the budget as not included].
    #[arg(long, value_name = "MG_PER_C", value_parser = Real(Range::Sigma), requires_all = ["scale_tempco_u", "thermometer_u"])]
    pub bias_tempco_u: Option<f64>,
    /// The unit type's scale-factor temperature coefficient, ppm/°C, one sigma (see
    /// --bias-tempco-u).
    #[arg(long, value_name = "PPM_PER_C", value_parser = Real(Range::Sigma), requires_all = ["bias_tempco_u", "thermometer_u"])]
    pub scale_tempco_u: Option<f64>,
    /// The standard uncertainty of the campaign's temperature reading (`temp_c`), °C (see
    /// --bias-tempco-u).
    #[arg(long, value_name = "C", value_parser = Real(Range::Sigma), requires_all = ["bias_tempco_u", "scale_tempco_u"])]
    pub thermometer_u: Option<f64>,
}

impl TempcoArgs {
    /// The stated coefficients, when given.
    pub fn coefficients(&self) -> Option<accelcal_core::uncertainty::TempCoefficients> {
        Some(accelcal_core::uncertainty::TempCoefficients {
            bias_mg_per_c: self.bias_tempco_u?,
            scale_ppm_per_c: self.scale_tempco_u?,
            thermometer_c: self.thermometer_u?,
        })
    }
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
    #[arg(long, value_name = "DEG_C", allow_hyphen_values = true, value_parser = Real(Range::TRef))]
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
    #[arg(long, default_value_t = 1.0, value_name = "CODES", value_parser = Real(Range::Codes))]
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
    #[arg(long, default_value_t = 32, value_parser = Count(Range::AtLeast1))]
    pub width: usize,
    /// Largest number of terms in a candidate, intercept included.
    #[arg(long, value_name = "K", default_value_t = accelcal_shared::N_BASIS, value_parser = Count(Range::AtLeast1))]
    pub max_terms: usize,
    /// Worker threads [default: one per core].
    #[arg(long, value_name = "N", value_parser = Count(Range::AtLeast1))]
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
    /// The dividing head's angle setting uncertainty, arcsec: one sigma of the error of each
    /// angle at each position (as the simulator's `angle_error` draws it), from the head's
    /// calibration certificate; it enters the uncertainty budget [--method lsq, model 4; default:
    /// not stated, the setting errors count only as far as the dwell scatter shows them].
    #[arg(long, value_name = "ARCSEC", value_parser = Real(Range::Arcsec))]
    pub head_angle_u: Option<f64>,
    /// The dividing head's orthogonality uncertainty, arcsec: one sigma of each of the three
    /// rotations between its stages (the simulator's `head_misalignment`) [--method lsq, model 4;
    /// default: not stated, and named on the budget as not included].
    #[arg(long, value_name = "ARCSEC", value_parser = Real(Range::Arcsec))]
    pub head_orthogonality_u: Option<f64>,
    /// The dividing head as a registered asset (`accelcal asset add ID --kind head`): its
    /// certificate in force states the angle and orthogonality uncertainties of the budget, and
    /// the run stores which head and certificate it used. The head's own units measure its angle
    /// error too (its last 1,000 passed runs in the database, since their last change point,
    /// as `fleet` tracks them): when that exceeds the certificate's angle uncertainty, the
    /// budget takes it and a warning says so [with --db; instead of --head-angle-u and
    /// --head-orthogonality-u; an overdue, unknown or non-head asset is refused].
    #[arg(long, value_name = "ID", conflicts_with_all = ["head_angle_u", "head_orthogonality_u"])]
    pub head_asset: Option<String>,
    #[arg(long, value_name = "ID", help = super::GRAVITY_ASSET_HELP)]
    pub gravity_asset: Option<String>,
    #[command(flatten)]
    pub tempco: TempcoArgs,
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
    #[arg(long, default_value_t = 240, value_parser = Count(Range::AtLeast1))]
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

/// `accelcal bench-signature`.
#[derive(Debug, Args)]
pub struct BenchSignatureArgs {
    /// Fleets simulated per case (each with its own seed).
    #[arg(long, default_value_t = 20, value_parser = clap::value_parser!(u32).range(1..=1000))]
    pub fleets: u32,
    /// Units of each true head's fleet, in time order (the 62-position plan, 100 sample sets per
    /// position, 80 codes of noise, 2 mrad of misalignment spread); a changed head's fleet ends
    /// `--after` units after its change, or here. The false alarms are counted over the true
    /// heads' units and the units before each change.
    #[arg(long, default_value_t = 1000, value_parser = clap::value_parser!(u32).range(60..=5000))]
    pub units: u32,
    /// The units (0-based) at which the head changes, one study of every change per unit given
    /// (the tracking starts at the 5th unit, index 4).
    #[arg(long, value_delimiter = ',', default_value = "10,25,100")]
    pub change_at: Vec<u32>,
    /// The simulated head's stated angle uncertainty, arcsec (its certificate's; the head itself
    /// is true until the change): the prior of its signature.
    #[arg(long, default_value_t = 3.0)]
    pub head_u: f64,
    /// Units simulated after each change (at most to `--units`): a flag later than this is none.
    #[arg(long, default_value_t = 200, value_parser = clap::value_parser!(u32).range(1..))]
    pub after: u32,
    /// Write the cases as JSON to this file.
    #[arg(long, value_name = "FILE")]
    pub json: Option<PathBuf>,
}

/// `accelcal uncertainty-check`.
#[derive(Debug, Args)]
pub struct UncertaintyCheckArgs {
    /// Units simulated and calibrated per scenario (≥ 100; JCGM 101 asks for enough that the
    /// coverage is known to a few tenths of a percent).
    #[arg(long, default_value_t = 1000, value_parser = clap::value_parser!(u32).range(100..))]
    pub units: u32,
    /// Sample sets per position of each simulated campaign (the 62-position head plan).
    #[arg(long, default_value_t = 100, value_parser = clap::value_parser!(u32).range(2..))]
    pub samples: u32,
    /// Random orientations (at 1 g) each calibrated unit is checked at.
    #[arg(long, default_value_t = 20, value_parser = clap::value_parser!(u32).range(1..))]
    pub orientations: u32,
    /// Seed of every draw: the same seed gives the same table.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Write the scenarios and their coverage as JSON.
    #[arg(long, value_name = "FILE")]
    pub json: Option<PathBuf>,
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
    #[arg(long, default_value_t = 20.0, value_name = "S", value_parser = Real(Range::Seconds))]
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
    #[arg(long, default_value_t = 2.0, value_parser = Real(Range::SecondsOrZero))]
    pub min_hold_s: f64,
    /// Detector threshold in codes² (sum of the three axis variances) [default: 4 x the lower
    /// quartile of the detector trace].
    #[arg(long, value_parser = Real(Range::Positive))]
    pub threshold: Option<f64>,
    /// Length of the detector's sliding window, in seconds.
    #[arg(long, default_value_t = 1.0, value_parser = Real(Range::Seconds))]
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
