//! One module per subcommand or family; [`run`] matches the settled [`Settings`] exhaustively
//! and dispatches. A module is named after its command where it has one: `simulate`, `plan`
//! (with `design`, `plan --design`), `select`, `fit` (with `gravity`, `fit --method
//! gravity-norm`, and `uncertainty`, `fit`'s budget table and `uncertainty-check`), `compare`,
//! `diagnose`, `demo` (which reuses the others' functions), `record` (`record show`), `emulate`,
//! `station`, `history`, `fleet`, `asset` (`asset add|list|show`), `recall` (`asset found-bad`,
//! `affected`), `certificate`, `signer`, `approve` (`approve`, `reject`). Others hold a family:
//! `live` is `info`, `output`, `acquire` and `verify`; `node` is `flash`, `monitor` and `hil`;
//! `report` is the certificate (`report/method.rs` the technical report); `db` is `void` and `db
//! verify`. The developer benchmarks are `bench_diagnose` (`bench-diagnose`) and `fleet_bench`
//! (`bench-fleet`).
//! `store` is the `--db` side of the commands that write (open before any other I/O, begin or
//! continue a run, store a piece) and `spec` reads `--spec`. This file holds what several share:
//! the campaign readers' warnings ([`print_warnings`], [`error_line`]), [`created`] and
//! [`passphrase`].

pub mod amend;
pub mod approve;
pub mod asset;
pub mod bench_diagnose;
pub mod certificate;
pub mod compare;
pub mod db;
pub mod demo;
pub mod design;
pub mod diagnose;
pub mod emulate;
pub mod fit;
pub mod fleet;
pub mod fleet_bench;
pub mod gravity;
pub mod history;
pub mod live;
pub mod node;
pub mod plan;
pub mod recall;
pub mod record;
pub mod report;
pub mod select;
pub mod signer;
pub mod simulate;
pub mod spec;
pub mod station;
pub mod store;
pub mod uncertainty;

pub use crate::resolved::{check_g, fallback_note as g_fallback, Gravity, Source};
use crate::settings::campaign;
use crate::settings::settled::Settings;

/// Runs a settled command line; the campaign readers' warnings go to `warnings`.
pub fn run(
    settings: Settings,
    resolved: &crate::resolved::Resolved,
    warnings: &mut Warnings,
) -> anyhow::Result<()> {
    let stated = resolved.gravity.as_ref();
    match settings {
        Settings::Fleet(s) => fleet::run(&s),
        Settings::Certificate(s) => certificate::run(&s),
        Settings::CertificateVerify(s) => certificate::verify(&s),
        Settings::History(s) => history::run(&s),
        Settings::Void(s) => db::run_void(&s),
        Settings::DbVerify(s) => db::run_verify(&s),
        Settings::DbMigrate(s) => db::run_migrate(s.as_deref()),
        Settings::Asset(s) => asset::run(&s),
        Settings::Affected(s) => recall::run_affected(&s),
        Settings::Serve(s) => crate::serve::run(&s),
        Settings::ServeUserAdd(s) => crate::serve::auth::run_add(&s),
        Settings::Signer(s) => signer::run(&s),
        Settings::Decide(s) => approve::run(&s),
        Settings::Amend(s) => amend::run(&s),
        Settings::BenchFleet(s) => fleet_bench::run(&s),
        Settings::Demo(s) => demo::run(&s),
        Settings::Compare(s) => compare::run(&s, &campaign_g(stated, &s.campaign.path, warnings)?, warnings),
        Settings::Diagnose(s) => {
            diagnose::run(&s, &campaign_g(stated, &s.campaign.path, warnings)?, warnings)
        }
        Settings::BenchDiagnose(s) => bench_diagnose::run(&s),
        Settings::BenchSignature(s) => fleet::run_bench_signature(&s),
        Settings::UncertaintyCheck(s) => uncertainty::run_check(&s),
        Settings::Info(s) => live::run_info(&s),
        Settings::Output(s) => live::run_output(&s),
        Settings::Monitor(s) => node::run_monitor(&s),
        Settings::RecordShow(s) => record::run_show(&s),
        Settings::Emulate(s) => emulate::run(&s),
        Settings::Flash(s) => node::run_flash(&s),
        Settings::Hil(s) => node::run_hil(&s, warnings),
        Settings::Report(s) => report::run(&s),
        Settings::Simulate(s) => simulate::run(&s),
        Settings::Plan(s) => plan::run(&s),
        Settings::Select(s) => select::run(&s, &campaign_g(stated, &s.campaign.path, warnings)?, warnings),
        Settings::Fit(s) => {
            let input = match &s {
                campaign::FitSettings::Campaign(f) => &f.campaign.path,
                campaign::FitSettings::GravityNorm(f) => &f.input,
            };
            fit::run(&s, &campaign_g(stated, input, warnings)?, warnings)
        }
        Settings::Acquire(s) => live::run_acquire(&s),
        Settings::Verify(s) => live::run_verify(&s),
        Settings::Station(s) => station::run(&s, stated, resolved.config.as_ref()),
    }
}

pub use accelcal_core::campaign::Warnings;
pub use accelcal_core::reduce::reduce_campaign;

/// Prints the warnings on stderr, one `warning:` line each, then the notes, one `note:` line
/// each (after a success).
pub fn print_warnings(w: &Warnings) {
    for line in w.lines() {
        errln!("warning: {line}");
    }
    for line in w.notes() {
        errln!("note: {line}");
    }
}

/// The one line (without the `error: ` prefix) that reports the failure `e`, with the readers'
/// warnings folded in (they may explain it).
pub fn error_line(w: &Warnings, e: &anyhow::Error) -> String {
    let line = crate::words::line(e);
    if w.lines().is_empty() {
        line
    } else {
        format!("{line} (note: {})", w.lines().join("; "))
    }
}

/// The gravity a command that reads a campaign works at: what the user stated; else the
/// campaign's `# g_m_s2:` line (written by `acquire` and `simulate`), with its `# g_source:`;
/// else 9.81, and a note says so (once).
fn campaign_g(
    stated: Option<&Gravity>,
    campaign: &std::path::Path,
    warnings: &mut Warnings,
) -> anyhow::Result<Gravity> {
    if let Some(g) = stated {
        return Ok(g.clone());
    }
    if !campaign.is_file() {
        // The reader names the missing file.
        return Ok(Gravity::assumed());
    }
    let header = accelcal_core::campaign::header(campaign)?;
    match header_g(campaign, &header)? {
        Some(g) => Ok(g),
        None => {
            warnings.note(g_fallback(&format!(
                "{} does not state its gravity (`# g_m_s2:`) and neither --g nor --latitude was given",
                campaign.display()
            )));
            Ok(Gravity::assumed())
        }
    }
}

/// The gravity a campaign's header states: its `# g_m_s2:` line, with its `# g_source:`;
/// `None` when it has no `# g_m_s2:` line. `campaign` names the file in errors.
fn header_g(campaign: &std::path::Path, header: &[(String, String)]) -> anyhow::Result<Option<Gravity>> {
    use accelcal_core::campaign::identity::{G_KEY, G_SOURCE_KEY};
    let get = |key: &str| header.iter().find(|(k, _)| k == key).map(|(_, v)| v.clone());
    let Some(v) = get(G_KEY) else { return Ok(None) };
    let g: f64 = v.parse().map_err(|_| {
        accelcal_core::error::bad(format!("{}: `# g_m_s2: {v}` is not a number of m/s²", campaign.display()))
    })?;
    check_g(g)?;
    Ok(Some(Gravity {
        g,
        source: Source::Campaign(
            get(G_SOURCE_KEY).filter(|s| !s.is_empty()).map(|s| accelcal_core::campaign::GSource::parse(&s)),
        ),
    }))
}

/// The creation time of a record: `--created`, or now.
pub fn created(given: Option<u64>) -> u64 {
    given.unwrap_or_else(|| {
        std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map(|d| d.as_secs()).unwrap_or(0)
    })
}

/// A key file's passphrase: the first line of `file`, else asked on the terminal without echo
/// (`twice`: asked again, for a new key). `what` names the key in the prompt.
pub fn passphrase(file: Option<&std::path::Path>, what: &str, twice: bool) -> anyhow::Result<String> {
    use accelcal_core::error::{bad, environment};
    if let Some(f) = file {
        let text = std::fs::read_to_string(f)
            .map_err(|e| environment(format!("reading the passphrase file {}", f.display()), e))?;
        let first = text.lines().next().unwrap_or("");
        if first.is_empty() {
            return Err(bad(format!("the passphrase file {}: its first line is empty", f.display())));
        }
        return Ok(first.to_string());
    }
    let ask = |prompt: &str| {
        rpassword::prompt_password(prompt).map_err(|e| {
            environment(
                format!("reading the passphrase of {what} from the terminal (or give --passphrase-file)"),
                e,
            )
        })
    };
    let p = ask(&format!("passphrase for {what}: "))?;
    if p.is_empty() {
        return Err(bad("the passphrase is empty"));
    }
    if twice && ask("the same again: ")? != p {
        return Err(bad("the two passphrases differ"));
    }
    Ok(p)
}
