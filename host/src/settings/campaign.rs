//! The settings of the commands on simulated or recorded campaigns that need no link to a node
//! (`demo`, `simulate`, `plan`, `select`, `fit`, `compare`, `diagnose`, `bench-diagnose`,
//! `bench-signature`, `uncertainty-check`): their command line checked and resolved into plain
//! values before anything is opened.

use std::path::PathBuf;

use accelcal_core::campaign::CodeRange;
use accelcal_core::design::search::{Head, MIN_POSITIONS};
use accelcal_core::design::{Chamber, DesignError};
use accelcal_core::error::bad;
use accelcal_core::sim::{self, Plan, SimConfig};

use super::values::RunStore;
use crate::cli::{
    Algorithm, BenchDiagnoseArgs, BenchSignatureArgs, CommonArgs, CompareArgs, DemoArgs, DiagnoseArgs,
    FitArgs, GravityOptions, MethodArg, PlanArgs, SelectArgs, SimulateArgs, StructureArg,
    UncertaintyCheckArgs,
};
use crate::resolved::Gravity;

/// `accelcal demo`, settled.
#[derive(Clone, Debug, PartialEq)]
pub struct Demo {
    /// `--out`: the directory of the demo's files.
    pub out: PathBuf,
    /// `--seed` of the simulated unit.
    pub seed: u64,
}

/// `demo`'s settings.
pub fn demo(a: &DemoArgs) -> Demo {
    Demo { out: a.out.clone(), seed: a.seed }
}

/// What `compare` and `diagnose` read: the campaign, its range of codes, and where the JSON goes.
#[derive(Clone, Debug, PartialEq)]
pub struct Campaign {
    /// The campaign file.
    pub path: PathBuf,
    /// `--codes` (`None`: the campaign's `# codes:` line, else unsigned16).
    pub codes: Option<CodeRange>,
    /// `--json`.
    pub json: Option<PathBuf>,
}

impl Campaign {
    /// The campaign file with `--codes` and `--json`.
    fn of(path: &std::path::Path, common: &CommonArgs) -> Campaign {
        Campaign { path: path.to_path_buf(), codes: common.codes, json: common.json.clone() }
    }
}

/// `accelcal compare`, settled.
#[derive(Clone, Debug, PartialEq)]
pub struct Compare {
    pub campaign: Campaign,
    /// `--validate`: a second campaign the fits are judged on.
    pub validate: Option<PathBuf>,
    /// `--plot`.
    pub plot: Option<PathBuf>,
}

/// `compare`'s settings (its files' distinctness is checked by `settings::check`).
pub fn compare(a: &CompareArgs) -> Compare {
    Compare {
        campaign: Campaign::of(&a.campaign, &a.common),
        validate: a.validate.clone(),
        plot: a.plot.clone(),
    }
}

/// `accelcal diagnose`, settled.
#[derive(Clone, Debug, PartialEq)]
pub struct Diagnose {
    pub campaign: Campaign,
    /// `--terms`: the model's terms.
    pub terms: accelcal_shared::Structure,
    /// `--plot`.
    pub plot: Option<PathBuf>,
}

/// `diagnose`'s settings (its files' distinctness is checked by `settings::check`).
pub fn diagnose(a: &DiagnoseArgs) -> anyhow::Result<Diagnose> {
    Ok(Diagnose {
        campaign: Campaign::of(&a.campaign, &a.common),
        terms: accelcal_core::lsq::parse_terms(&a.terms).map_err(|e| bad(format!("--terms {e}")))?,
        plot: a.plot.clone(),
    })
}

/// `accelcal bench-diagnose`, settled.
#[derive(Clone, Debug, PartialEq)]
pub struct BenchDiagnose {
    /// `--campaigns`, at least one.
    pub campaigns: usize,
    /// `--seed`: the master seed.
    pub seed: u64,
    /// `--magnitude LO:HI`, times the per-position noise: 0 < LO ≤ HI.
    pub magnitude: (f64, f64),
    /// `--json`.
    pub json: Option<PathBuf>,
}

/// `bench-diagnose`'s settings.
pub fn bench_diagnose(a: &BenchDiagnoseArgs) -> anyhow::Result<BenchDiagnose> {
    let v: Vec<Option<f64>> = a.magnitude.split(':').map(|x| x.trim().parse::<f64>().ok()).collect();
    let magnitude = match v[..] {
        [Some(lo), Some(hi)] if lo.is_finite() && hi.is_finite() && lo > 0.0 && hi >= lo => (lo, hi),
        _ => return Err(bad(format!("--magnitude `{}`: expected LO:HI with 0 < LO <= HI", a.magnitude))),
    };
    Ok(BenchDiagnose { campaigns: a.campaigns, seed: a.seed, magnitude, json: a.json.clone() })
}

/// `accelcal bench-signature`, settled.
#[derive(Clone, Debug, PartialEq)]
pub struct BenchSignature {
    /// `--fleets`, `--units` per fleet, `--change-at`: the units at which the head changes,
    /// each at or after the tracking's first tracked unit and before the last unit.
    pub fleets: u32,
    pub units: u32,
    pub change_at: Vec<u32>,
    /// `--after`: units simulated after each change.
    pub after: u32,
    /// `--head-u`, arcsec.
    pub head_u: f64,
    /// `--json`.
    pub json: Option<PathBuf>,
}

/// `bench-signature`'s settings.
pub fn bench_signature(a: &BenchSignatureArgs) -> anyhow::Result<BenchSignature> {
    let baseline = accelcal_core::headsig::Settings::default().baseline;
    for &at in &a.change_at {
        if at >= a.units {
            return Err(bad(format!("--change-at {at} is not before --units {}", a.units)));
        }
        if (at as usize) < baseline {
            return Err(bad(format!(
                "--change-at {at} is before the tracking's first tracked unit (unit {baseline}, from 0)"
            )));
        }
    }
    if !(a.head_u.is_finite() && a.head_u >= 0.0) {
        return Err(bad(format!("--head-u {}: expected a finite uncertainty, at least 0", a.head_u)));
    }
    if a.change_at.is_empty() {
        return Err(bad("--change-at: no unit given".to_string()));
    }
    Ok(BenchSignature {
        fleets: a.fleets,
        units: a.units,
        change_at: a.change_at.clone(),
        after: a.after,
        head_u: a.head_u,
        json: a.json.clone(),
    })
}

/// `accelcal uncertainty-check`, settled.
#[derive(Clone, Debug, PartialEq)]
pub struct UncertaintyCheck {
    /// `--units` per scenario, `--samples` per position, `--orientations` of the head, `--seed`.
    pub units: u32,
    pub samples: u32,
    pub orientations: u32,
    pub seed: u64,
    /// `--json`.
    pub json: Option<PathBuf>,
}

/// `uncertainty-check`'s settings.
pub fn uncertainty_check(a: &UncertaintyCheckArgs) -> UncertaintyCheck {
    UncertaintyCheck {
        units: a.units,
        samples: a.samples,
        orientations: a.orientations,
        seed: a.seed,
        json: a.json.clone(),
    }
}

/// `accelcal simulate`, settled: the simulator's settings checked, at the gravity stated (`--g`,
/// `--latitude`) or the command's default.
pub struct Simulate {
    /// The simulator's settings (its g the stated gravity, else `--g`'s default).
    pub config: SimConfig,
    /// `--out`: the campaign; `--truth`: its truth (default: beside it, `.truth.json`).
    pub out: PathBuf,
    pub truth: PathBuf,
    /// `--serial` written into the campaign's header.
    pub serial: Option<String>,
    /// `--codes`: the range of the codes written.
    pub codes: CodeRange,
    /// `--json`.
    pub json: Option<PathBuf>,
    /// Where the simulator's g came from, written as the campaign's `# g_source:`.
    pub g_source: accelcal_core::campaign::GSource,
}

/// `simulate`'s settings; `stated`: the gravity the command line states.
pub fn simulate(a: &SimulateArgs, stated: Option<&Gravity>) -> anyhow::Result<Simulate> {
    let gravity = Gravity::default_of(stated, a.g);
    Ok(Simulate {
        g_source: gravity.provenance(),
        config: config(a, gravity.g)?,
        out: a.out.clone(),
        truth: a.truth.clone().unwrap_or_else(|| a.out.with_extension("truth.json")),
        serial: a.serial.clone(),
        codes: a.codes,
        json: a.json.clone(),
    })
}

/// Soak at each chamber setpoint when --soak-s is not given, s.
pub const SOAK_DEFAULT_S: f64 = 900.0;
/// Chamber-to-sensor lag when --thermal-lag-s is not given, s (`emulate`'s default).
const THERMAL_LAG_DEFAULT_S: f64 = 30.0;

/// The thermal plan of `--chamber`, `--soak-s` and `--thermal-lag-s` (settings refuses the last two
/// without the first).
fn thermal_plan(a: &SimulateArgs) -> anyhow::Result<Option<sim::ThermalPlan>> {
    if a.chamber.is_empty() {
        return Ok(None);
    }
    if let Some(t) = a.chamber.iter().find(|t| !accelcal_line::head::CHAMBER_RANGE_C.contains(*t)) {
        return Err(bad(format!("--chamber: each setpoint must be a temperature in -60..=150 °C, got {t}")));
    }
    let soak_s = a.soak_s.unwrap_or(SOAK_DEFAULT_S);
    let tau_s = a.thermal_lag_s.unwrap_or(THERMAL_LAG_DEFAULT_S);
    Ok(Some(sim::ThermalPlan { chamber_c: a.chamber.clone(), soak_s, tau_s }))
}

/// The simulator's settings from `simulate`'s command line, at gravity `g`.
fn config(a: &SimulateArgs, g: f64) -> anyhow::Result<SimConfig> {
    let plan = Plan::from_spec(&a.plan, a.seed).map_err(|e| bad(format!("--plan {e}")))?;
    let effects = a
        .effects
        .iter()
        .map(|s| sim::effects::parse(s).map_err(|e| bad(format!("--effect {e}"))))
        .collect::<anyhow::Result<Vec<_>>>()?;
    let thermal = thermal_plan(a)?;
    if a.temp_profile.is_some() && thermal.is_some() {
        return Err(bad("--temp-profile and --chamber both set the temperature: give one"));
    }
    if a.temp_profile.is_none() && thermal.is_none() {
        if let Some(e) = effects.iter().find(|e| e.needs_temperature()) {
            return Err(bad(format!(
                "--effect {} needs a temperature: --temp-profile BASE:AMP:CYCLES or --chamber T1,T2,…",
                e.name()
            )));
        }
    }
    Ok(SimConfig {
        seed: a.seed,
        plan,
        layout: a.layout.clone(),
        g,
        samples: a.samples,
        rate_hz: a.rate_hz,
        move_s: a.move_s,
        noise: a.noise,
        bias_sd: a.bias_sd,
        scale_sd: a.scale_sd,
        misalign_sd: a.misalign_sd,
        effects,
        quantize: !a.ideal_adc,
        temp: a.temp_profile,
        thermal,
    })
}

/// What `--design` asks for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DesignSize {
    /// This many positions.
    Positions(usize),
    /// The number of positions and the dwell too.
    Auto,
}

/// `accelcal plan`, settled: a plan shown, or one designed.
pub enum PlanSettings {
    /// `plan --plan SPEC`: the positions and what a triad reads at each.
    Show(ShowPlan),
    /// `plan --design N|auto`.
    Design(Box<Design>),
}

/// `plan` without `--design`.
pub struct ShowPlan {
    /// `--plan` as given, and the plan it names (`--seed` for `random:N`).
    pub spec: String,
    pub plan: Plan,
    /// The stated gravity, else `--g`.
    pub gravity: Gravity,
    /// `--json`.
    pub json: Option<PathBuf>,
}

/// The unit type a design is for.
#[derive(Clone, Debug, PartialEq)]
pub enum UnitType {
    /// `--like CAMPAIGN`: an earlier campaign of the same kind of unit.
    Like(PathBuf),
    /// `--noise CODES`: the nominal triad with this noise per sample.
    Noise(f64),
}

/// `plan --design`, each default resolved.
pub struct Design {
    /// How many positions (or `auto`).
    pub size: DesignSize,
    /// `--out`: the designed plan; `--json`: the comparison.
    pub out: PathBuf,
    pub json: Option<PathBuf>,
    pub unit: UnitType,
    /// `--head-angle-u`, arcsec (0 when not given).
    pub head_angle_u_arcsec: f64,
    /// `--move-s`, `--samples` per position.
    pub move_s: f64,
    pub samples: u32,
    /// `--rate-hz` when given; else the `--like` campaign's `# rate_hz:` line, else
    /// [`DESIGN_RATE_HZ`] (the command reads the campaign).
    pub rate_hz: Option<f64>,
    /// `--target-U` (auto only), m/s².
    pub target_u: Option<f64>,
    /// The head's reachable positions.
    pub head: Head,
    /// `--chamber` and `--soak-s`.
    pub chamber: Option<Chamber>,
    /// `--montecarlo`: units simulated per plan.
    pub montecarlo: Option<u32>,
    /// `--seed` of the design's random starts.
    pub seed: u64,
    /// The stated gravity, else `--g`'s default (which a `--like` campaign's `# g_m_s2:` then
    /// replaces: the command reads it).
    pub gravity: Gravity,
}

/// `plan`'s settings; `stated`: the gravity the command line states.
pub fn plan(a: &PlanArgs, stated: Option<&Gravity>) -> anyhow::Result<PlanSettings> {
    let gravity = Gravity::default_of(stated, a.g);
    let d = &a.design;
    let Some(size) = d.design else {
        let plan = Plan::from_spec(&a.plan, a.seed).map_err(|e| bad(format!("--plan {e}")))?;
        return Ok(PlanSettings::Show(ShowPlan {
            spec: a.plan.clone(),
            plan,
            gravity,
            json: a.json.clone(),
        }));
    };
    let Some(out) = d.out.clone() else {
        return Err(bad("--design needs --out FILE: where to write the designed plan"));
    };
    let unit = match (&d.like, d.noise) {
        (Some(path), _) => UnitType::Like(path.clone()),
        (None, Some(noise)) => UnitType::Noise(noise),
        (None, None) => {
            return Err(bad(
                "--design needs the unit type: --like CAMPAIGN (an earlier campaign of the same kind of unit) or --noise CODES (the nominal triad with that noise per sample)",
            ))
        }
    };
    check_design(a, size, &out)?;
    Ok(PlanSettings::Design(Box::new(Design {
        size,
        out,
        json: a.json.clone(),
        unit,
        head_angle_u_arcsec: d.head_angle_u.unwrap_or(0.0),
        move_s: d.move_s.unwrap_or(MOVE_S),
        rate_hz: d.rate_hz,
        samples: d.samples.unwrap_or(SAMPLES),
        target_u: d.target_u,
        head: head(a),
        chamber: chamber(a)?,
        montecarlo: d.montecarlo,
        seed: a.seed,
        gravity,
    })))
}

/// The defaults of the design's options.
const MOVE_S: f64 = 10.0;
/// The design's rate, Hz, when neither `--rate-hz` nor a `--like` campaign's header gives one.
pub const DESIGN_RATE_HZ: f64 = 100.0;
const SAMPLES: u32 = 400;
const STEP_DEG: f64 = 15.0;
const BETA_MAX_DEG: f64 = 90.0;

/// Checks the design's options before any I/O: what does not apply to the size asked for is
/// refused.
fn check_design(a: &PlanArgs, size: DesignSize, out: &std::path::Path) -> anyhow::Result<()> {
    let d = &a.design;
    if Some(out) == d.like.as_deref() || Some(out) == a.json.as_deref() {
        return Err(bad(format!(
            "--out {} is also {}: the designed plan would overwrite it",
            out.display(),
            if Some(out) == d.like.as_deref() { "--like" } else { "--json" }
        )));
    }
    if a.json.is_some() && a.json.as_deref() == d.like.as_deref() {
        return Err(bad("--json is also --like: the design's JSON would overwrite the campaign"));
    }
    if let DesignSize::Positions(n) = size {
        if n < MIN_POSITIONS {
            return Err(DesignError::TooFew { n, min: MIN_POSITIONS }.into());
        }
    }
    if !d.chamber.is_empty() {
        chamber(a).map_err(|e| bad(format!("--chamber: {e}")))?;
        if d.montecarlo.is_some() {
            return Err(bad(
                "--montecarlo does not apply with --chamber: the simulation calibrates model 4 on one pass (the thermal model's check by simulation is not built)",
            ));
        }
    }
    if d.target_u.is_some() && size != DesignSize::Auto {
        return Err(bad(
            "--target-U applies to --design auto only (with --design N the number of positions is yours)",
        ));
    }
    head(a).reachable().map_err(|e| bad(format!("--alpha-step-deg/--beta-step-deg/--beta-max-deg: {e}")))?;
    Ok(())
}

/// `--chamber` and `--soak-s`, or `None` without a chamber.
fn chamber(a: &PlanArgs) -> Result<Option<Chamber>, DesignError> {
    let d = &a.design;
    if d.chamber.is_empty() {
        return Ok(None);
    }
    Chamber::new(d.chamber.clone(), d.soak_s.unwrap_or(SOAK_DEFAULT_S)).map(Some)
}

/// The head's reachable positions: `--alpha-step-deg`, `--beta-step-deg`, `--beta-max-deg`.
fn head(a: &PlanArgs) -> Head {
    let d = &a.design;
    Head {
        alpha_step_deg: d.alpha_step_deg.unwrap_or(STEP_DEG),
        beta_step_deg: d.beta_step_deg.unwrap_or(STEP_DEG),
        beta_max_deg: d.beta_max_deg.unwrap_or(BETA_MAX_DEG),
    }
}

/// `accelcal select`, settled.
pub struct Select {
    pub campaign: Campaign,
    /// GMDH's settings: basis, criterion, split, tolerance (codes, ≥ 0), largest model.
    pub settings: accelcal_core::gmdh::Settings,
    /// `--t-ref`, °C: the thermal terms' reference.
    pub t_ref_c: f64,
    /// How the models are searched.
    pub search: Search,
    /// `--channels` (empty: every channel).
    pub channels: Vec<String>,
    /// `--threads` (`None`: one per core).
    pub threads: Option<usize>,
    /// `--top`: the candidates the JSON lists.
    pub top: Option<usize>,
    /// `--plot`.
    pub plot: Option<PathBuf>,
}

/// How `select` searches the models.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Search {
    /// Every combination of the basis's terms (combinatorial GMDH).
    Combi,
    /// Multi-row GMDH, a beam this wide.
    Multi { width: usize },
}

/// `select`'s settings (the options of another mode refused by `settings::check`).
pub fn select(a: &SelectArgs) -> anyhow::Result<Select> {
    Ok(Select {
        campaign: Campaign::of(&a.campaign, &a.common),
        settings: accelcal_core::gmdh::Settings {
            basis: a.basis.into(),
            criterion: a.criterion.into(),
            split: a.split,
            tolerance: a.tolerance,
            max_terms: a.max_terms.min(accelcal_shared::N_BASIS),
        },
        t_ref_c: a.thermal.t_ref_c(),
        search: match a.algorithm {
            Algorithm::Combi => Search::Combi,
            Algorithm::Multi => Search::Multi { width: a.width },
        },
        channels: a.channels.clone(),
        threads: a.threads,
        top: a.top,
        plot: a.plot.clone(),
    })
}

/// `accelcal fit`, settled: a campaign fitted by least squares or test turns, or a recording
/// calibrated by the gravity norm.
pub enum FitSettings {
    Campaign(Box<Fit>),
    GravityNorm(Box<GravityNormFit>),
}

/// `fit --method lsq|test-turns`.
pub struct Fit {
    pub campaign: Campaign,
    pub method: accelcal_core::calibrate::Method,
    /// `--terms`.
    pub structure: accelcal_shared::Structure,
    /// `--record`, with `--device-id` (parsed; the campaign's `# device_id:` otherwise) and
    /// `--created`.
    pub record: Option<PathBuf>,
    pub device_id: Option<[u8; 12]>,
    pub created: Option<u64>,
    /// `--t-ref`, °C, and `--temp-input` (with `--record` only).
    pub t_ref_c: f64,
    pub temp_input: Option<accelcal_shared::record::TempSource>,
    /// The head's stated uncertainties, arcsec, or its asset in the register (with `--db`).
    pub head_angle_u: Option<f64>,
    pub head_orthogonality_u: Option<f64>,
    pub head_asset: Option<String>,
    /// The unit type's temperature coefficients (all or none).
    pub tempco: Option<accelcal_core::uncertainty::TempCoefficients>,
    /// `--db`, `--run-id`, `--relabel`.
    pub store: Option<RunStore>,
}

/// `fit --method gravity-norm`.
pub struct GravityNormFit {
    /// The recording (imu_tk's format) and `--json`.
    pub input: PathBuf,
    pub json: Option<PathBuf>,
    /// `--record` with `--device-id` (parsed) and `--created`.
    pub record: Option<PathBuf>,
    pub device_id: Option<[u8; 12]>,
    pub created: Option<u64>,
    /// How the holds are found (`--window-s`, `--min-hold-s`, `--threshold`) and the model
    /// (`--structure`).
    pub detector: accelcal_core::gravity::holds::DetectorConfig,
    pub structure: accelcal_core::gravity::StructureChoice,
    /// `--plot`, `--campaign-out`.
    pub plot: Option<PathBuf>,
    pub campaign_out: Option<PathBuf>,
}

/// `fit`'s settings (what does not apply to the method refused by `settings::check`).
pub fn fit(a: &FitArgs) -> anyhow::Result<FitSettings> {
    use accelcal_core::calibrate::{parse_device_id, Method};
    let method = match a.method {
        MethodArg::Lsq => Method::Lsq,
        MethodArg::TestTurns => Method::TestTurns,
        MethodArg::GravityNorm => {
            if a.temp_input.is_some() {
                return Err(bad(
                    "--temp-input does not apply to fit --method gravity-norm (its model has no terms in t)",
                ));
            }
            if a.common.codes.is_some() {
                return Err(bad(
                    "--codes does not apply to fit --method gravity-norm (it applies to --method lsq and test-turns, which fit a campaign)",
                ));
            }
            let device_id = a.device_id.as_deref().map(parse_device_id).transpose()?;
            let o = &a.gravity;
            return Ok(FitSettings::GravityNorm(Box::new(GravityNormFit {
                input: a.campaign.clone(),
                json: a.common.json.clone(),
                record: a.record.clone(),
                device_id,
                created: a.created,
                detector: detector(o)?,
                structure: structure_choice(o),
                plot: o.plot.clone(),
                campaign_out: o.campaign_out.clone(),
            })));
        }
    };
    let structure = accelcal_core::lsq::parse_terms(&a.terms).map_err(|e| bad(format!("--terms: {e}")))?;
    let device_id = a.device_id.as_deref().map(parse_device_id).transpose()?;
    if a.temp_input.is_some() && a.record.is_none() {
        return Err(bad("--temp-input applies to --record only"));
    }
    Ok(FitSettings::Campaign(Box::new(Fit {
        campaign: Campaign::of(&a.campaign, &a.common),
        method,
        structure,
        record: a.record.clone(),
        device_id,
        created: a.created,
        t_ref_c: a.thermal.t_ref_c(),
        temp_input: a.temp_input.map(Into::into),
        head_angle_u: a.head_angle_u,
        head_orthogonality_u: a.head_orthogonality_u,
        head_asset: a.head_asset.clone(),
        tempco: a.tempco.coefficients(),
        store: RunStore::of(&a.run)?,
    })))
}

/// The gravity norm's hold detector: `--window-s` (positive), `--min-hold-s` (≥ 0),
/// `--threshold` (positive, when given).
fn detector(o: &GravityOptions) -> anyhow::Result<accelcal_core::gravity::holds::DetectorConfig> {
    Ok(accelcal_core::gravity::holds::DetectorConfig {
        window_s: o.window_s,
        min_hold_s: o.min_hold_s,
        threshold: o.threshold,
        ..Default::default()
    })
}

/// The gravity norm's model: `--structure`.
fn structure_choice(o: &GravityOptions) -> accelcal_core::gravity::StructureChoice {
    use accelcal_core::gravity::fit::GravityStructure;
    use accelcal_core::gravity::StructureChoice;
    match o.structure {
        StructureArg::BiasScale => StructureChoice::Fixed(GravityStructure::BiasScale),
        StructureArg::ImuTk => StructureChoice::Fixed(GravityStructure::ImuTk),
        StructureArg::Quadratic => StructureChoice::Fixed(GravityStructure::ImuTkQuadratic),
        StructureArg::Auto => StructureChoice::Auto,
    }
}
