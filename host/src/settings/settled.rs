//! The settled command line ([`Settings`]) that `main` hands to the commands: `settle` runs after
//! the checks of `settings.rs`, with what they resolved, and gives one variant per command, each a
//! plain value with nothing of clap. Defaults are resolved here (the fleet's period, a design's
//! head and dwell, a station's database), values parsed once (run ids, device ids, `--terms`,
//! `--plan`, `--magnitude`, the gravity norm's hold detector), and the checks that involve several
//! options done (`--chamber` with `--soak-s`, `--change-at` within the period). The values live
//! beside the commands' families in the sibling modules (`reader`, `asset`, `campaign`, `line`,
//! `station`, `release`); `values` holds what several share with the station's steps.

use super::{asset, campaign, line, reader, release, station};
use crate::cli::Command;
use crate::resolved::Resolved;

/// A command line, checked (`settings::check`) and settled before anything is opened: one variant
/// per command, plain values with nothing of clap. The commands take these, never a clap struct.
pub enum Settings {
    /// `accelcal fleet`.
    Fleet(reader::Fleet),
    /// `accelcal certificate`.
    Certificate(reader::Certificate),
    /// `accelcal certificate verify FILE [--db DB]`.
    CertificateVerify(reader::CertificateVerify),
    /// `accelcal history`.
    History(reader::History),
    /// `accelcal void`.
    Void(reader::Void),
    /// `accelcal db verify`.
    DbVerify(reader::DbVerify),
    /// `db migrate`: the database named (`--db`, else the default reader's).
    DbMigrate(Option<String>),
    /// `accelcal asset add|list|show`.
    Asset(asset::Asset),
    /// `accelcal affected`.
    Affected(asset::Affected),
    /// `accelcal serve`.
    Serve(reader::Serve),
    /// `accelcal serve-user add`.
    ServeUserAdd(reader::AddUser),
    /// `accelcal signer add|revoke|list`.
    Signer(release::Signer),
    /// `accelcal approve` and `accelcal reject`.
    Decide(release::Decide),
    /// `accelcal amend`.
    Amend(release::Amend),
    /// `accelcal bench-fleet`.
    BenchFleet(reader::BenchFleet),
    /// `accelcal demo`.
    Demo(campaign::Demo),
    /// `accelcal compare`.
    Compare(campaign::Compare),
    /// `accelcal diagnose`.
    Diagnose(campaign::Diagnose),
    /// `accelcal bench-diagnose`.
    BenchDiagnose(campaign::BenchDiagnose),
    /// `accelcal bench-signature`.
    BenchSignature(campaign::BenchSignature),
    /// `accelcal uncertainty-check`.
    UncertaintyCheck(campaign::UncertaintyCheck),
    /// `accelcal info`.
    Info(line::Info),
    /// `accelcal output`.
    Output(line::SetOutput),
    /// `accelcal monitor`.
    Monitor(line::Monitor),
    /// `accelcal record show`.
    RecordShow(line::RecordShow),
    /// `accelcal emulate`.
    Emulate(line::Emulate),
    /// `accelcal flash`.
    Flash(line::Flash),
    /// `accelcal hil`.
    Hil(line::Hil),
    /// `accelcal report`.
    Report(line::Report),
    /// `accelcal simulate`.
    Simulate(campaign::Simulate),
    /// `accelcal plan`.
    Plan(campaign::PlanSettings),
    /// `accelcal select`.
    Select(campaign::Select),
    /// `accelcal fit`.
    Fit(campaign::FitSettings),
    /// `accelcal acquire`.
    Acquire(line::Acquire),
    /// `accelcal verify`.
    Verify(Box<line::Verify>),
    /// `accelcal station`.
    Station(Box<station::Station>),
}

/// Settles a checked command line (`settings::check` first).
pub fn settle(command: Command, resolved: &Resolved) -> anyhow::Result<Settings> {
    let stated = resolved.gravity.as_ref();
    Ok(match command {
        Command::Fleet(a) => Settings::Fleet(reader::fleet(&a, accelcal_db::asset::today_utc())?),
        Command::Certificate(a) => match &a.action {
            Some(crate::cli::CertificateAction::Verify { file, db }) => {
                Settings::CertificateVerify(reader::CertificateVerify { file: file.clone(), db: db.clone() })
            }
            None => Settings::Certificate(reader::certificate(&a)?),
        },
        Command::History(a) => Settings::History(reader::history(&a)?),
        Command::Void(a) => Settings::Void(reader::void(&a)?),
        Command::Db(crate::cli::DbCommand::Verify(a)) => Settings::DbVerify(reader::db_verify(&a)),
        Command::Db(crate::cli::DbCommand::Migrate(a)) => Settings::DbMigrate(a.reader.db.clone()),
        Command::Asset(c) => Settings::Asset(asset::asset(&c)?),
        Command::Affected(a) => Settings::Affected(asset::affected(&a)?),
        Command::Serve(a) => Settings::Serve(reader::serve(&a)?),
        Command::Signer(c) => Settings::Signer(release::signer(&c)?),
        Command::Approve(a) => Settings::Decide(release::approve(&a)?),
        Command::Reject(a) => Settings::Decide(release::reject(&a)?),
        Command::Amend(a) => Settings::Amend(release::amend(&a)?),
        Command::ServeUser(crate::cli::ServeUserCommand::Add(a)) => {
            Settings::ServeUserAdd(reader::add_user(&a)?)
        }
        Command::BenchFleet(a) => Settings::BenchFleet(reader::bench_fleet(&a)?),
        Command::Demo(a) => Settings::Demo(campaign::demo(&a)),
        Command::Compare(a) => Settings::Compare(campaign::compare(&a)),
        Command::Diagnose(a) => Settings::Diagnose(campaign::diagnose(&a)?),
        Command::BenchDiagnose(a) => Settings::BenchDiagnose(campaign::bench_diagnose(&a)?),
        Command::BenchSignature(a) => Settings::BenchSignature(campaign::bench_signature(&a)?),
        Command::UncertaintyCheck(a) => Settings::UncertaintyCheck(campaign::uncertainty_check(&a)),
        Command::Info(a) => Settings::Info(line::info(&a)),
        Command::Output(a) => Settings::Output(line::output(&a)),
        Command::Monitor(a) => Settings::Monitor(line::monitor(&a)),
        Command::Record(crate::cli::RecordCommand::Show(a)) => Settings::RecordShow(line::record_show(&a)),
        Command::Emulate(a) => Settings::Emulate(line::emulate(&a)?),
        Command::Flash(a) => Settings::Flash(line::flash(&a)?),
        Command::Hil(a) => Settings::Hil(line::hil(&a)),
        Command::Report(a) => Settings::Report(line::report(&a)?),
        Command::Simulate(a) => Settings::Simulate(campaign::simulate(&a, stated)?),
        Command::Plan(a) => Settings::Plan(campaign::plan(&a, stated)?),
        Command::Select(a) => Settings::Select(campaign::select(&a)?),
        Command::Fit(a) => Settings::Fit(campaign::fit(&a)?),
        Command::Acquire(a) => Settings::Acquire(line::acquire(&a, stated)?),
        Command::Verify(a) => Settings::Verify(Box::new(line::verify(&a, stated)?)),
        Command::Station(a) => Settings::Station(Box::new(station::station(&a, resolved.plan.as_ref()))),
    })
}
