//! The calibration database on a real PostgreSQL server (Debian's package, installed by
//! `scripts/setup-postgres.sh`; each test starts a throwaway cluster of its own with
//! `scripts/postgres-cluster.sh`): the scenarios of `tests/db.rs`, the triggers that keep rows
//! append-only, two stations writing at once, a station killed mid-unit, and `history`.

use crate::dbkit;

use accelcal_db::{Db, RunId};
use dbkit::*;

#[test]
fn pieces_are_stored_once_and_a_finished_run_takes_nothing_more() {
    let pg = Cluster::start();
    pieces_are_stored_once(&pg.url);
    assert_eq!(Db::open(&pg.url).unwrap().engine(), "postgres");
}

#[test]
fn a_reader_does_not_wait_for_a_writer() {
    let pg = Cluster::start();
    dbkit::a_reader_does_not_wait_for_a_writer(&pg.url, || {
        let mut c = postgres::Client::connect(&pg.url, postgres::NoTls).unwrap();
        c.batch_execute(&format!("BEGIN; SELECT pg_advisory_xact_lock({})", accelcal_db::LEDGER_LOCK))
            .unwrap();
        c
    });
}

#[test]
fn calibration_rows_are_never_updated_deleted_or_truncated() {
    let pg = Cluster::start();
    let mut db = Db::open(&pg.url).unwrap();
    with_head_asset(&mut db);
    let mut c = postgres::Client::connect(&pg.url, postgres::NoTls).unwrap();
    for table in APPEND_ONLY {
        for (sql, verb) in [
            (format!("UPDATE {table} SET content_sha256 = 'x'"), "updated"),
            (format!("DELETE FROM {table}"), "deleted"),
            (format!("TRUNCATE {table} CASCADE"), "truncated"),
        ] {
            let e = c.batch_execute(&sql).unwrap_err();
            let msg = e.as_db_error().map(|d| d.message().to_string()).unwrap_or_else(|| e.to_string());
            assert_eq!(msg, format!("append-only: {table} rows are never {verb}"), "{sql}");
        }
    }
    let n: i64 = c.query_one("SELECT count(*) FROM run", &[]).unwrap().get(0);
    assert_eq!(n, 1);
}

#[test]
fn assets_are_registered_once_refused_when_overdue_and_traced_to_their_runs() {
    let pg = Cluster::start();
    assets_register_and_trace(&pg.url);
}

#[test]
fn every_column_of_the_migrated_database_is_in_the_chain_in_order() {
    let pg = Cluster::start();
    drop(Db::open(&pg.url).unwrap());
    let mut c = postgres::Client::connect(&pg.url, postgres::NoTls).unwrap();
    columns_are_the_chain_s(&mut |t| {
        c.query(
            "SELECT column_name::text FROM information_schema.columns WHERE table_name = $1 ORDER BY ordinal_position",
            &[&t],
        )
        .unwrap()
        .iter()
        .map(|r| r.get(0))
        .collect()
    });
}

#[test]
fn a_station_killed_mid_unit_resumes_with_no_duplicate_and_no_partial_row() {
    if writer_child() {
        return;
    }
    let pg = Cluster::start();
    let run = killed_writer_resumes(
        &pg.url,
        module_path!(),
        "a_station_killed_mid_unit_resumes_with_no_duplicate_and_no_partial_row",
    );
    let mut c = postgres::Client::connect(&pg.url, postgres::NoTls).unwrap();
    for table in ["run", "campaign", "fit", "cal_record", "flash", "verification", "run_end"] {
        let n: i64 = c
            .query_one(&format!("SELECT count(*) FROM {table} WHERE run_id = $1"), &[&run.to_string()])
            .unwrap()
            .get(0);
        assert_eq!(n, 1, "{table}");
    }
}

#[test]
fn two_stations_writing_at_once_lose_nothing() {
    let pg = Cluster::start();
    two_writers_lose_nothing(&pg.url, 20);
}

#[test]
fn history_reads_the_server_and_matches_sqlite() {
    let pg = Cluster::start();
    let d = tempfile::tempdir().unwrap();
    let file = d.path().join("cal.sqlite").display().to_string();
    for spec in [&pg.url, &file] {
        let mut db = Db::open(spec).unwrap();
        for i in 0..2 {
            let id = RunId::parse(&format!("00000000-0000-4000-8000-00000000000{i}")).unwrap();
            calibrate(
                &mut db,
                &start(id, DEVICE, "SN-7", "st-1", T0 + 90 * DAY * i as i64),
                &coefs(30.0, i),
                None,
            );
        }
    }
    let (code, on_pg, err) = accelcal(&["history", "SN-7", "--db", &pg.url]);
    assert_eq!(code, Some(0), "{err}");
    let (code, on_sqlite, err) = accelcal(&["history", "SN-7", "--db", &file]);
    assert_eq!(code, Some(0), "{err}");
    assert_eq!(on_pg.replace(&pg.url, "<db>"), on_sqlite.replace(&file, "<db>"));
    assert!(on_pg.contains("2 runs, 2 calibrations"), "{on_pg}");
}

#[test]
fn serials_stay_tied_to_their_devices_and_voided_runs_leave_history() {
    let pg = Cluster::start();
    labels_and_voids(&pg.url);
}

#[test]
fn a_row_changed_with_the_triggers_off_is_named_and_never_flashed() {
    let pg = Cluster::start();
    let url = pg.url.clone();
    a_changed_row_breaks_the_chain(&pg.url, true, &|sql| {
        let mut c = postgres::Client::connect(&url, postgres::NoTls).unwrap();
        // A superuser can switch the append-only triggers off for its session.
        c.batch_execute(&format!("SET session_replication_role = replica; {sql}")).unwrap();
    });
}

/// Issue 28 item 7: the server's own words reach the user.
#[test]
fn postgresql_errors_keep_the_server_s_message() {
    let pg = Cluster::start();
    // The cluster's libpq words, another database named.
    let missing: Vec<String> = pg
        .url
        .split_whitespace()
        .map(|w| if w.starts_with("dbname=") { "dbname=no_such_db".to_string() } else { w.to_string() })
        .collect();
    let missing = missing.join(" ");
    assert!(missing.contains("dbname=no_such_db"), "{}", pg.url);
    let (code, _, err) = accelcal(&["history", "SN-1", "--db", &missing]);
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("database \"no_such_db\" does not exist"), "{err}");
    let refused = "postgres://accelcal@127.0.0.1:1/accelcal";
    let (code, _, err) = accelcal(&["history", "SN-1", "--db", refused]);
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("Connection refused"), "{err}");
}

#[test]
fn writers_racing_on_one_run_id_store_each_row_once() {
    let pg = Cluster::start();
    writers_racing_on_one_run(&pg.url);
}

/// Issue 57: signers decide once, and amendments take the next number and supersede.
#[test]
fn signers_decide_once_and_amendments_supersede() {
    let pg = Cluster::start();
    dbkit::release::signers_decide_and_amend(&pg.url);
}

#[test]
fn certificate_numbers_are_unique_stable_and_never_reused() {
    let pg = Cluster::start();
    certificate_numbers_are_never_reused(&pg.url);
}

#[test]
fn the_recalibration_date_is_stored_with_the_number_and_decisions_are_columns() {
    let pg = Cluster::start();
    let url = pg.url.clone();
    recalibration_dates_and_decisions_are_stored(&pg.url, &mut || {
        let mut c = postgres::Client::connect(&url, postgres::NoTls).unwrap();
        c.query("SELECT run_id, decision, rule FROM verification_decision", &[])
            .unwrap()
            .iter()
            .map(|r| (r.get(0), r.get(1), r.get(2)))
            .collect()
    });
}

#[test]
fn the_fleet_is_counted_by_the_database() {
    let pg = Cluster::start();
    dbkit::fleet::the_fleet_is_counted_by_the_database(&pg.url);
}

#[test]
fn check_runs_are_the_station_s_checks_on_this_engine() {
    let pg = dbkit::Cluster::start();
    check_runs_are_the_station_s_checks(&pg.url);
}

/// Issue 55: Ctrl-C ends serve on PostgreSQL with exit code 0 (the synchronous client's
/// connections are closed outside the server's runtime), and a failing query is 503.
#[test]
fn serve_stops_on_ctrl_c_and_answers_503_when_a_query_fails() {
    let pg = Cluster::start();
    dbkit::serve::a_signal_stops_the_server_cleanly(&pg.url);
    let pg = Cluster::start();
    let url = pg.url.clone();
    dbkit::serve::a_database_failure_is_503(&pg.url, move || {
        let mut c = postgres::Client::connect(&url, postgres::NoTls).unwrap();
        c.batch_execute("ALTER TABLE run RENAME TO run_gone").unwrap();
    });
}

#[test]
fn serve_reads_the_server_s_numbers_and_shows_a_hostile_serial_as_text() {
    let pg = Cluster::start();
    dbkit::serve::the_pages_hold_the_database_s_numbers(&pg.url);
    let pg = Cluster::start();
    dbkit::serve::a_hostile_serial_is_text_and_a_stored_script_does_not_run(&pg.url);
    let pg = Cluster::start();
    dbkit::serve::only_get_is_answered_and_bad_requests_say_why(&pg.url);
    let pg = Cluster::start();
    dbkit::serve::search_finds_a_unit_and_says_what_it_missed(&pg.url);
    let pg = Cluster::start();
    dbkit::serve::the_morning_view_needs_attention_finds_and_ticks(&pg.url);
    let pg = Cluster::start();
    let url = pg.url.clone();
    dbkit::serve::connections_are_pooled_and_bounded(&pg.url, move || {
        let mut c = postgres::Client::connect(&url, postgres::NoTls).unwrap();
        c.query(
            "SELECT pid FROM pg_stat_activity WHERE datname = current_database() AND pid <> pg_backend_pid()",
            &[],
        )
        .unwrap()
        .iter()
        .map(|r| r.get(0))
        .collect()
    });
}

/// SQL run with the append-only triggers off for the session, as a superuser can.
fn as_superuser(url: &str) -> impl Fn(&str) + '_ {
    move |sql: &str| {
        let mut c = postgres::Client::connect(url, postgres::NoTls).unwrap();
        c.batch_execute(&format!("SET session_replication_role = replica; {sql}")).unwrap();
    }
}

/// Issue 59: a head found out of tolerance traced to its units, their dismissal and
/// recalibration, on PostgreSQL.
#[test]
fn a_bad_head_is_traced_to_its_units_and_their_recalls() {
    let pg = Cluster::start();
    dbkit::recall::a_bad_head_is_traced_to_its_units(&pg.url, &as_superuser(&pg.url));
}

#[test]
fn laundering_is_reported_and_no_reader_writes() {
    let pg = Cluster::start();
    tamper::laundering_is_reported_and_no_reader_writes(&pg.url, true, &as_superuser(&pg.url));
}

#[test]
fn a_tampered_run_is_marked_by_fleet_history_and_serve() {
    let pg = Cluster::start();
    tamper::a_tampered_run_is_marked_where_it_is_listed(&pg.url, &as_superuser(&pg.url));
}

#[test]
fn a_cut_tail_is_found_against_an_anchor_log_and_a_certificate() {
    let pg = Cluster::start();
    tamper::a_cut_tail_is_found_against_the_anchors(&pg.url, &as_superuser(&pg.url));
}

#[test]
fn a_forged_asset_is_refused_and_derived_edits_are_found() {
    let pg = Cluster::start();
    tamper::a_forged_asset_is_refused(&pg.url, true, &as_superuser(&pg.url));
    let pg = Cluster::start();
    tamper::derived_edits_are_found(&pg.url, &as_superuser(&pg.url));
    let pg = Cluster::start();
    tamper::a_missing_certificate_number_is_reported(&pg.url, &as_superuser(&pg.url));
}

/// Issue 55 on PostgreSQL: a migration history whose newest row was deleted, or whose checksum
/// was edited, stops every command with one line naming the table; `db migrate` records it
/// again when the schema's tables are exactly those of one of this build's versions, and says
/// to restore a backup when they are none's.
#[test]
fn a_damaged_migration_history_is_named_and_db_migrate_records_it_again() {
    let pg = Cluster::start();
    let spec = pg.url.as_str();
    let mut db = Db::open(spec).unwrap();
    calibrate(&mut db, &start(RunId::new(), DEVICE, "SN-1", "st-1", T0), &coefs(0.0, 0), None);
    drop(db);
    let plain =
        |sql: &str| postgres::Client::connect(spec, postgres::NoTls).unwrap().batch_execute(sql).unwrap();
    let latest = accelcal_db::schema_version();
    let table = "its migration history (table refinery_schema_history) is damaged: ";
    let cases = [
        (
            "DELETE FROM refinery_schema_history WHERE version = (SELECT MAX(version) FROM refinery_schema_history)"
                .to_string(),
            format!(
                "it records schema version {}, and the schema is that of version {latest}: the rows of the versions after {} were removed",
                latest - 1,
                latest - 1
            ),
        ),
        (
            "UPDATE refinery_schema_history SET checksum = '1' WHERE version = 5".to_string(),
            "the row of version 5: its checksum is '1', not ".to_string(),
        ),
    ];
    for (sql, what) in &cases {
        plain(sql);
        for args in [vec!["history", "SN-1"], vec!["db", "verify"]] {
            let mut args = args.clone();
            args.extend(["--db", spec]);
            let (code, out, err) = accelcal(&args);
            assert_eq!(code, Some(1), "{args:?}: {out}{err}");
            assert!(err.contains(table) && err.contains(what.as_str()), "{args:?}: {err}");
            assert!(err.contains("run `accelcal db migrate --db "), "{err}");
            assert_eq!(err.trim_end().lines().count(), 1, "one line: {err}");
        }
        let e = Db::open(spec).err().expect("a writer refuses the database");
        assert!(e.to_string().contains(what.as_str()), "{e}");
        let (code, out, err) = accelcal(&["db", "migrate", "--db", spec]);
        assert_eq!(code, Some(0), "{sql}: {out}{err}");
        assert!(
            out.contains(&format!(
                "recorded again as versions 1 to {latest}, the schema being exactly that of version {latest}"
            )),
            "{out}"
        );
        let (code, out, err) = accelcal(&["history", "SN-1", "--db", spec]);
        assert_eq!(code, Some(0), "read again after db migrate: {out}{err}");
    }
    // Tables that are no version's cannot be recorded again: a backup restores them.
    plain("UPDATE refinery_schema_history SET name = 'x' WHERE version = 4; CREATE TABLE extra (x integer)");
    let (code, out, err) = accelcal(&["db", "migrate", "--db", spec]);
    assert_eq!(code, Some(1), "{out}{err}");
    assert!(
        err.contains(table)
            && err.contains("its name is 'x', not `")
            && err.contains(
                "the schema is that of none of this build's versions: restore the database from a backup"
            ),
        "{err}"
    );
}
