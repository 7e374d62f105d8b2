//! The exit code of a failure, read off the error: the policy is the binary's, the facts are the
//! libraries'. Every error type of the library crates (core, line, db) states what its
//! failures are ([`Classify`], implemented next to each type's definition, variant by variant
//! where they differ), and this module only finds the first classified error in the chain.
//!
//! - 130: the user stopped the command ([`Kind::Interrupted`], anywhere in the chain);
//! - 2: bad input ([`Kind::BadInput`]): a campaign, a recording, a record, an option;
//! - 1: anything else: the environment failed (a port, a process, a device, the file system),
//!   the unit was rejected by a check, or an error that no type classified (an internal failure
//!   is not the user's input to fix, so it is never reported as such).
//!
//! The outermost classified error decides: a context that says "writing out.json" over a file
//! system error is the environment whatever the error below it says. Every error type of the
//! libraries is in [`registry!`]'s list; a test reads their sources and fails on a
//! `thiserror::Error` type missing from it.

use accelcal_core::error::{Classify, Kind};

/// Lists the core's error types: [`kind_of`] tries each, the tests check the list is complete.
macro_rules! registry {
    ($($t:ty),* $(,)?) => {
        /// The kind of one error of the chain, when its type is one of the core's.
        fn kind_of(e: &(dyn std::error::Error + 'static)) -> Option<Kind> {
            $(if let Some(x) = e.downcast_ref::<$t>() {
                return Some(Classify::kind(x));
            })*
            None
        }

        /// The listed types' names (the last path segment).
        #[cfg(test)]
        fn registered() -> Vec<&'static str> {
            vec![$(stringify!($t).rsplit("::").next().unwrap().trim()),*]
        }

        /// The name of the listed type `e` is, if any.
        #[cfg(test)]
        fn registered_name(e: &(dyn std::error::Error + 'static)) -> Option<&'static str> {
            $(if e.is::<$t>() {
                return Some(stringify!($t).rsplit("::").next().unwrap().trim());
            })*
            None
        }
    };
}

registry!(
    accelcal_core::error::BadInput,
    accelcal_core::error::Environment,
    accelcal_core::error::Interrupted,
    accelcal_line::verify::Failed,
    accelcal_core::campaign::CampaignError,
    accelcal_core::campaign::WriteError,
    accelcal_core::text::TextError,
    accelcal_core::campaign::identity::IdentityError,
    accelcal_core::campaign::identity::Mismatch,
    accelcal_db::DbError,
    accelcal_db::LabelClash,
    accelcal_db::AssetError,
    accelcal_db::ReleaseError,
    accelcal_core::certificate::approval::SigningError,
    accelcal_db::anchor::AnchorLogError,
    accelcal_core::certificate::DocumentError,
    accelcal_core::gmdh::GmdhError,
    accelcal_core::compare::CompareError,
    accelcal_core::calibrate::RecordError,
    accelcal_core::lsq::LsqError,
    accelcal_core::uncertainty::UncertaintyError,
    accelcal_core::design::DesignError,
    accelcal_core::conformity::SpecError,
    accelcal_core::testturn::TestTurnError,
    accelcal_core::diagnose::DiagnoseError,
    accelcal_core::gravity::GravityError,
    accelcal_core::gravity::fit::FitError,
    accelcal_core::gravity::holds::HoldError,
    accelcal_core::gravity::imutk::ImuTkError,
    accelcal_core::gravity::imutk::RowProblem,
    accelcal_core::sim::unit::UnitError,
    accelcal_line::emulate::head::HeadServerError,
    accelcal_line::emulate::frontend::FrontendError,
    accelcal_line::node::flash::FlashError,
    accelcal_line::node::gdb::GdbError,
    accelcal_line::head::HeadError,
    accelcal_line::node::hil::HilError,
    accelcal_line::node::link::LinkError,
    accelcal_line::node::qemu::QemuError,
    accelcal_line::node::session::SessionError,
    accelcal_line::station::StationError,
);

/// What the failure `e` is: [`Kind::Interrupted`] when the user stopped the command, else the
/// kind of the outermost classified error of the chain, else [`Kind::Environment`].
pub fn kind(e: &anyhow::Error) -> Kind {
    if e.chain().any(|c| c.is::<accelcal_core::error::Interrupted>()) {
        return Kind::Interrupted;
    }
    e.chain().find_map(kind_of).unwrap_or(Kind::Environment)
}

/// Whether an error is the user's input to fix.
#[cfg(test)]
pub fn is_bad_input(e: &anyhow::Error) -> bool {
    kind(e) == Kind::BadInput
}

/// The process exit code of a failure: 130 when the user stopped the command, 2 for bad input,
/// 1 otherwise.
pub fn code(e: &anyhow::Error) -> i32 {
    match kind(e) {
        Kind::Interrupted => 130,
        Kind::BadInput => 2,
        Kind::Environment | Kind::Rejected => 1,
    }
}

/// `accelcal station`'s exit code, which tells a rejected unit from a failed station: 1 the unit
/// was rejected, 2 bad input, 3 the environment (port, probe, head, file system), 130 stopped.
pub fn station_code(e: &anyhow::Error) -> i32 {
    match kind(e) {
        Kind::Interrupted => 130,
        Kind::BadInput => 2,
        Kind::Rejected => 1,
        Kind::Environment => 3,
    }
}

#[cfg(test)]
mod tests {
    use std::path::PathBuf;
    use std::time::Duration;

    use super::*;
    use accelcal_core::error::{bad, environment};

    fn io() -> std::io::Error {
        std::io::Error::new(std::io::ErrorKind::AddrInUse, "Address already in use (os error 98)")
    }

    fn exit_status() -> std::process::ExitStatus {
        use std::os::unix::process::ExitStatusExt;
        std::process::ExitStatus::from_raw(1 << 8)
    }

    fn asset_error() -> accelcal_db::AssetError {
        accelcal_db::AssetError::Unknown { asset_id: "h".into(), target: "t".into() }
    }

    fn label_clash() -> accelcal_db::LabelClash {
        accelcal_db::LabelClash::NothingToRelabel { device: "d".into(), serial: "s".into() }
    }

    /// One error of every variant of every registered type, with the kind it must have.
    fn every_variant() -> Vec<(anyhow::Error, Kind)> {
        use accelcal_core::campaign::identity::IdentityError;
        use accelcal_core::campaign::CampaignError;
        use accelcal_core::certificate::approval::SigningError;
        use accelcal_core::diagnose::DiagnoseError;
        use accelcal_core::gmdh::GmdhError;
        use accelcal_core::gravity::fit::FitError;
        use accelcal_core::gravity::holds::HoldError;
        use accelcal_core::gravity::imutk::{ImuTkError, RowProblem};
        use accelcal_core::gravity::GravityError;
        use accelcal_core::lsq::LsqError;
        use accelcal_core::sim::unit::UnitError;
        use accelcal_db::{DbError, ReleaseError};
        use accelcal_line::emulate::frontend::FrontendError;
        use accelcal_line::emulate::head::HeadServerError;
        use accelcal_line::head::HeadError;
        use accelcal_line::node::flash::FlashError;
        use accelcal_line::node::gdb::GdbError;
        use accelcal_line::node::hil::HilError;
        use accelcal_line::node::link::LinkError;
        use accelcal_line::node::qemu::QemuError;
        use accelcal_line::node::session::SessionError;
        use accelcal_shared::boot::BootError;
        use accelcal_shared::record::RecordError;
        use accelcal_shared::slots::SlotError;
        use accelcal_shared::wire::{FrameError, RecordFault, Refusal};
        use Kind::*;

        let p = || PathBuf::from("c.csv");
        let addr = || "127.0.0.1:3333".to_string();
        fn e<E: std::error::Error + Send + Sync + 'static>(x: E) -> anyhow::Error {
            anyhow::Error::new(x)
        }
        let gdb = || GdbError::Io { addr: addr(), cause: io() };
        let link = || LinkError::Io(io());
        let unit_read = || UnitError::Read { path: "t.json".into(), cause: io() };
        let json_err = serde_json::from_str::<u8>("x").unwrap_err();
        let text_err = || accelcal_core::text::single_line("--serial", "A\nB").unwrap_err();
        let qemu_spawn = || QemuError::Spawn { qemu: "qemu-system-arm".into(), cause: io() };
        vec![
            (bad("x.csv:3:1: expected a number"), BadInput),
            (environment("writing out.json", io()), Environment),
            (e(accelcal_core::error::Interrupted("stopped".into())), Interrupted),
            (
                e(accelcal_line::verify::Failed {
                    failed: 1,
                    conditional: 0,
                    total: 6,
                    parameters: Vec::new(),
                }),
                Rejected,
            ),
            (e(accelcal_line::station::StationError::NotDeployable("m".into())), Rejected),
            (e(accelcal_line::station::StationError::Rejected { units: "a".into(), total: 2 }), Rejected),
            (
                e(accelcal_line::station::StationError::RejectedBefore {
                    serial: "s".into(),
                    run_id: "r".into(),
                    dir: p(),
                }),
                Rejected,
            ),
            (e(accelcal_line::station::StationError::BadJournal { path: p(), reason: "m".into() }), BadInput),
            (
                e(accelcal_line::station::StationError::OtherUnit {
                    dir: p(),
                    journal: "a".into(),
                    given: "b".into(),
                }),
                BadInput,
            ),
            (
                e(accelcal_line::station::StationError::OtherDevice {
                    dir: p(),
                    journal: "a".into(),
                    node: "b".into(),
                    serial: "s".into(),
                }),
                BadInput,
            ),
            (e(accelcal_line::station::StationError::Changed { file: p(), step: "info" }), BadInput),
            (
                e(accelcal_line::station::StationError::RecordReplaced {
                    serial: "U".into(),
                    node: "record CRC 00000001".into(),
                    certified: "00000002".into(),
                    run_id: "r".into(),
                }),
                Rejected,
            ),
            (e(CampaignError::Io { path: p(), cause: io() }), BadInput),
            (e(CampaignError::Line { path: p(), line: 1, msg: "m".into() }), BadInput),
            (e(CampaignError::File { path: p(), msg: "m".into() }), BadInput),
            (e(CampaignError::Field { path: p(), line: 1, column: 1, msg: "m".into() }), BadInput),
            (e(accelcal_core::campaign::WriteError::Header(text_err())), BadInput),
            (e(accelcal_core::campaign::WriteError::Csv { cause: io().into() }), Environment),
            (e(text_err()), BadInput),
            (
                e(accelcal_core::text::TextError::Padded { field: "serial".into(), value: " U-1".into() }),
                BadInput,
            ),
            (
                e(accelcal_core::text::TextError::Format {
                    field: "serial".into(),
                    value: "U\u{200b}1".into(),
                    ch: '\u{200b}',
                    at: 2,
                }),
                BadInput,
            ),
            (
                e(IdentityError::Mismatch(Box::new(accelcal_core::campaign::identity::Mismatch {
                    a: "f.json".into(),
                    field: "serial",
                    a_value: "1".into(),
                    b: "c.csv".into(),
                    b_value: "2".into(),
                    consequence: "not the same unit",
                }))),
                BadInput,
            ),
            (
                e(accelcal_core::campaign::identity::Mismatch {
                    a: "f.json".into(),
                    field: "g",
                    a_value: "9.81 m/s²".into(),
                    b: "v.json".into(),
                    b_value: "9.8 m/s²".into(),
                    consequence: "the certificate states one g",
                }),
                BadInput,
            ),
            (e(IdentityError::NoIdentity { what: "f.json".into() }), BadInput),
            (e(IdentityError::BadIdentity { what: "f.json".into(), msg: "m".into() }), BadInput),
            (e(IdentityError::BadDeviceId { path: p(), value: "1".into() }), BadInput),
            (e(IdentityError::Campaign(CampaignError::File { path: p(), msg: "m".into() })), BadInput),
            (e(DbError::BadTarget { spec: "x".into(), why: "m".into() }), BadInput),
            (e(DbError::NoDatabase { path: p() }), BadInput),
            (e(DbError::NotCreated { target: "postgres://line@db/new".into() }), BadInput),
            (e(DbError::Unreachable { target: "t".into(), cause: "m".into() }), Environment),
            (e(DbError::Migration { cause: "m".into() }), Environment),
            (e(DbError::Engine { cause: "m".into() }), Environment),
            (e(DbError::Schema { what: "m".into() }), Environment),
            (e(DbError::NoRun { run_id: "r".into() }), BadInput),
            (e(DbError::Conflict { run_id: "r".into(), what: "m".into() }), BadInput),
            (e(DbError::Mismatch { run_id: "r".into(), what: "m".into() }), BadInput),
            (e(DbError::BadPiece { run_id: "r".into(), piece: "fit", cause: "m".into() }), BadInput),
            (e(DbError::NoUnit { key: "k".into(), target: "t".into() }), BadInput),
            (e(DbError::Ambiguous { key: "k".into(), devices: "a, b".into() }), BadInput),
            (e(DbError::ReadOnly { path: p() }), BadInput),
            (e(DbError::Raced { cause: "m".into() }), Environment),
            (
                e(DbError::Tampered {
                    run_id: "r".into(),
                    first: Box::new(accelcal_db::Mismatch {
                        seq: 1,
                        run_id: "r".into(),
                        piece: "fit".into(),
                        what: "m".into(),
                    }),
                    more: 0,
                }),
                BadInput,
            ),
            (e(DbError::Label(Box::new(label_clash()))), BadInput),
            (e(label_clash()), BadInput),
            (e(DbError::Asset(asset_error())), Environment),
            (e(asset_error()), Environment),
            (
                e(accelcal_db::anchor::AnchorLogError {
                    path: "anchors.log".into(),
                    cause: "No space left on device".into(),
                }),
                Environment,
            ),
            (e(accelcal_core::certificate::DocumentError::Format { found: 9 }), BadInput),
            (
                e(DbError::ChainBroken {
                    target: "cal.sqlite".into(),
                    what: "the ledger is empty and 3 rows are in the database".into(),
                }),
                Environment,
            ),
            (
                e(DbError::NeedsMigration {
                    target: "cal.sqlite".into(),
                    why: "it is at schema version 7, this build reads version 9".into(),
                }),
                Environment,
            ),
            (
                e(accelcal_db::AssetError::Overdue {
                    asset_id: "h".into(),
                    certificate: "c".into(),
                    due_date: accelcal_db::asset::parse_date("2020-01-31").unwrap(),
                    today: accelcal_db::asset::parse_date("2020-02-01").unwrap(),
                }),
                Environment,
            ),
            (
                e(accelcal_db::AssetError::WrongKind {
                    asset_id: "h".into(),
                    is: "thermometer",
                    wanted: "head",
                }),
                Environment,
            ),
            (e(accelcal_db::AssetError::Bad { asset_id: "h".into(), why: "m".into() }), BadInput),
            (e(DbError::Release(ReleaseError::UnknownKey { fingerprint: "f".into() })), BadInput),
            (
                e(ReleaseError::Revoked { name: "n".into(), fingerprint: "f".into(), reason: "r".into() }),
                BadInput,
            ),
            (e(ReleaseError::SelfApproval { name: "n".into(), run_id: "r".into() }), BadInput),
            (
                e(ReleaseError::Decided {
                    number: "2026-000001".into(),
                    meaning: "rejected".into(),
                    name: "n".into(),
                    date: "2026-01-01".into(),
                }),
                BadInput,
            ),
            (e(ReleaseError::NoCertificate { number: "n".into(), target: "t".into() }), BadInput),
            (e(ReleaseError::Voided { number: "n".into(), run_id: "r".into() }), BadInput),
            (e(ReleaseError::NameInForce { name: "n".into(), fingerprint: "f".into() }), BadInput),
            (e(ReleaseError::KeyRegistered { fingerprint: "f".into(), name: "n".into() }), BadInput),
            (e(ReleaseError::NoSigner { name: "n".into(), target: "t".into() }), BadInput),
            (e(ReleaseError::Signing(SigningError::Invalid)), BadInput),
            (e(SigningError::WrongPassphrase), BadInput),
            (e(SigningError::Encrypt { cause: "m".into() }), Environment),
            (e(SigningError::Random { cause: "m".into() }), Environment),
            (e(SigningError::BadPublicKey { why: "m".into() }), BadInput),
            (e(SigningError::BadSignature { why: "m".into() }), BadInput),
            (e(SigningError::NotOneLine { field: "reason" }), BadInput),
            (e(GmdhError::EmptyPart('A', 3)), BadInput),
            (e(GmdhError::NoTemperature), BadInput),
            (e(GmdhError::NothingIdentifiable), BadInput),
            (e(accelcal_core::compare::CompareError::NothingToValidate), BadInput),
            (
                e(accelcal_core::compare::CompareError::CodesDiffer {
                    codes: accelcal_core::campaign::CodeRange::Signed16,
                    vcodes: accelcal_core::campaign::CodeRange::Unsigned16,
                }),
                BadInput,
            ),
            (e(accelcal_core::calibrate::RecordError::G { g: 1.0 }), BadInput),
            (
                e(accelcal_core::calibrate::RecordError::File {
                    path: "r.rec".into(),
                    why: Box::new(accelcal_core::calibrate::RecordError::Refused(
                        accelcal_shared::boot::BootError::NotModel4,
                    )),
                }),
                BadInput,
            ),
            (e(GmdhError::Refit(LsqError::Unidentifiable { terms: vec!["ax".into()] })), BadInput),
            (e(LsqError::TooFewPositions { model: "m".into(), terms: 4, positions: 3 }), BadInput),
            (e(accelcal_core::uncertainty::UncertaintyError::TooFewPositions { positions: 5 }), BadInput),
            (e(accelcal_core::design::DesignError::TooFew { n: 5, min: 8 }), BadInput),
            (e(accelcal_core::conformity::SpecError("m".into())), BadInput),
            (e(accelcal_core::testturn::TestTurnError::NoPairs), BadInput),
            (e(DiagnoseError::TooFewPositions { positions: 6, need: 8 }), BadInput),
            (e(DiagnoseError::NoNoiseEstimate), BadInput),
            (e(DiagnoseError::Unfittable), BadInput),
            (e(DiagnoseError::NoTemperature("t".into())), BadInput),
            (e(GravityError::Holds(HoldError::BadSampling)), BadInput),
            (
                e(GravityError::Fit {
                    holds: 3,
                    detected: accelcal_core::gravity::holds::Summary {
                        kept: 3,
                        too_short_s: Vec::new(),
                        not_static: 0,
                    },
                    source: FitError::Singular,
                }),
                BadInput,
            ),
            (e(FitError::TooFewHolds { holds: 3, params: 9 }), BadInput),
            (e(FitError::BadGravity(0.0)), BadInput),
            (e(FitError::NonFinite(1)), BadInput),
            (e(FitError::NoSpread { axis: 'x' }), BadInput),
            (e(FitError::NotConverged("m".into())), BadInput),
            (e(HoldError::TooShort { samples: 1, window: 2 }), BadInput),
            (e(HoldError::BadConfig("m".into())), BadInput),
            (e(ImuTkError::Io { file: "f".into(), source: io() }), BadInput),
            (e(ImuTkError::NotUtf8 { file: "f".into(), line: 1 }), BadInput),
            (
                e(ImuTkError::Row {
                    file: "f".into(),
                    line: 1,
                    column: 1,
                    problem: RowProblem::FieldCount(3),
                }),
                BadInput,
            ),
            (e(ImuTkError::Empty { file: "f".into() }), BadInput),
            (e(RowProblem::NotANumber("x".into())), BadInput),
            (e(RowProblem::NotFinite("x".into())), BadInput),
            (e(RowProblem::TimeNotIncreasing { prev: 1.0, now: 0.0 }), BadInput),
            (e(unit_read()), BadInput),
            (e(UnitError::Json { path: "t.json".into(), cause: json_err }), BadInput),
            (e(UnitError::Invalid("m".into())), BadInput),
            (e(UnitError::InFile { path: "t.json".into(), cause: Box::new(unit_read()) }), BadInput),
            (e(UnitError::Effect { index: 0, message: "m".into() }), BadInput),
            (e(UnitError::NotATriad("m".into())), BadInput),
            (e(HeadServerError::Listen { addr: addr(), cause: io() }), Environment),
            (e(FrontendError::Write(io())), Environment),
            (e(FrontendError::Read(io())), Environment),
            (e(FrontendError::Options("m".into())), BadInput),
            (e(FlashError::Record(RecordError::BadMagic)), BadInput),
            (e(FlashError::Refused(BootError::NoDeviceId)), BadInput),
            (e(FlashError::Plan(SlotError::BadLength)), BadInput),
            (e(FlashError::WrongDevice { record: "a".into(), mcu: "b".into() }), BadInput),
            (e(FlashError::NoProbe(String::new())), Environment),
            (e(FlashError::Verify(0)), Environment),
            (e(FlashError::Probe("m".into())), Environment),
            (e(FlashError::Gdb(gdb())), Environment),
            (e(FlashError::NoDeviceId("m".into())), Environment),
            (
                e(FlashError::NotReset { error: Box::new(FlashError::Verify(0)), reset: "m".into() }),
                Environment,
            ),
            (e(gdb()), Environment),
            (e(GdbError::Protocol { addr: addr(), what: "m".into() }), Environment),
            (e(GdbError::Closed { addr: addr() }), Environment),
            (e(HeadError::Io { addr: addr(), cause: io() }), Environment),
            (e(HeadError::Protocol { addr: addr(), message: "m".into() }), Environment),
            (e(HeadError::Timeout { addr: addr(), request: "WHERE".into(), secs: 1.0 }), Environment),
            (e(HilError::Record(SlotError::BadLength)), BadInput),
            (e(HilError::Spawn { qemu: "q".into(), cause: io() }), Environment),
            (e(HilError::QemuExited { status: exit_status(), stderr: "m".into() }), Environment),
            (e(HilError::Timeout(Duration::from_secs(3))), Environment),
            (e(HilError::Qemu(qemu_spawn())), Environment),
            (e(HilError::Link(link())), Environment),
            (e(HilError::Rejected(RecordFault::Singular)), Environment),
            (e(HilError::Protocol("m".into())), Environment),
            (e(HilError::Io(io())), Environment),
            (e(link()), Environment),
            (e(LinkError::Closed), Environment),
            (e(LinkError::Encode(FrameError::TooLong)), Environment),
            (e(LinkError::Deadline), Environment),
            (e(qemu_spawn()), Environment),
            (e(QemuError::Exited { status: exit_status(), stderr: "m".into() }), Environment),
            (e(QemuError::Timeout(Duration::from_secs(3))), Environment),
            (e(QemuError::SlotSize { slot: 0, len: 5000 }), Environment),
            (e(QemuError::Io(io())), Environment),
            (e(SessionError::Link { port: "p".into(), cause: link() }), Environment),
            (
                e(SessionError::Timeout {
                    port: "p".into(),
                    what: "answer",
                    secs: 1.0,
                    heard: Default::default(),
                }),
                Environment,
            ),
            (
                e(SessionError::Refused {
                    port: "p".into(),
                    refusal: Refusal::RateOutOfRange { requested_hz: 5, min_hz: 100, max_hz: 4000 },
                }),
                Environment,
            ),
            (e(SessionError::Protocol { port: "p".into(), node: 3, host: 4 }), Environment),
            (
                e(accelcal_line::station::StationError::OutOfControl {
                    station: "line-1".into(),
                    serial: "GOLD-1".into(),
                    why: "mean error x: rule 1".into(),
                }),
                Environment,
            ),
        ]
    }

    #[test]
    fn every_variant_of_every_error_type_has_its_kind_and_exit_code() {
        for (e, want) in every_variant() {
            assert_eq!(kind(&e), want, "{e:#}");
            // Behind a context (as the commands add them) the kind is the same.
            let e = e.context("running the command");
            assert_eq!(kind(&e), want, "{e:#}");
            let code_want = match want {
                Kind::BadInput => 2,
                Kind::Interrupted => 130,
                Kind::Environment | Kind::Rejected => 1,
            };
            assert_eq!(code(&e), code_want, "{e:#}");
        }
    }

    #[test]
    fn no_message_prints_its_cause_twice() {
        for (e, _) in every_variant() {
            let links: Vec<String> = e.chain().map(|c| c.to_string()).collect();
            for w in links.windows(2) {
                assert!(!w[0].contains(&w[1]), "`{e:#}` prints `{}` twice", w[1]);
            }
        }
    }

    #[test]
    fn every_error_type_of_the_core_is_registered_and_exercised() {
        // Every `thiserror::Error` type defined in the library crates' sources.
        let mut defined = Vec::new();
        for (_, text) in crate::sources::library_sources(&["core", "line", "db"]) {
            let mut lines = text.lines();
            while let Some(l) = lines.next() {
                if !(l.trim_start().starts_with("#[derive(") && l.contains("thiserror::Error")) {
                    continue;
                }
                let decl = lines.by_ref().find(|l| l.contains(" enum ") || l.contains(" struct ")).unwrap();
                if decl.starts_with("        ") {
                    continue; // a type local to a test
                }
                let name =
                    decl.split_whitespace().skip_while(|w| *w != "enum" && *w != "struct").nth(1).unwrap();
                defined.push(name.split(['{', '(', ';']).next().unwrap().to_string());
            }
        }
        defined.sort();
        let mut registered: Vec<String> = registered().into_iter().map(String::from).collect();
        registered.sort();
        assert_eq!(
            defined, registered,
            "every error type of the core states its kind and is in the registry"
        );
        // And the table above has an error of each.
        let exercised: std::collections::BTreeSet<String> = every_variant()
            .iter()
            .filter_map(|(e, _)| registered_name(e.chain().next().unwrap()).map(String::from))
            .collect();
        assert_eq!(exercised.into_iter().collect::<Vec<_>>(), registered);
    }

    #[test]
    fn an_error_no_type_classifies_is_not_called_bad_input() {
        let e = anyhow::anyhow!("QEMU did not give the link a pseudo-terminal");
        assert_eq!((kind(&e), code(&e)), (Kind::Environment, 1));
        let e = anyhow::Error::new(io()).context("writing out.json");
        assert!(!is_bad_input(&e));
        // The outermost classified error decides.
        let e = environment("writing out.json", bad("x")).context("fit");
        assert_eq!(kind(&e), Kind::Environment);
        assert_eq!(format!("{e:#}"), "fit: writing out.json: x");
    }
}
