//! The view across units on SQLite: `fleet`, the head's tracking and its measured error in the
//! budget, the check standard's runs, `serve` in Chromium, and the derived rows they read.

use super::*;

/// `accelcal fleet --db SPEC` over January 2026, with `extra` options.
fn fleet_in_january(spec: &str, extra: &[&str]) -> (Option<i32>, String, String) {
    let mut args = vec!["fleet", "--db", spec, "--since", "2026-01-01", "--until", "2026-01-31"];
    args.extend_from_slice(extra);
    accelcal(&args)
}

#[test]
fn the_fleet_is_counted_by_the_database_and_printed() {
    let d = tempfile::tempdir().unwrap();
    let spec = db_file(&d);
    dbkit::fleet::the_fleet_is_counted_by_the_database(&spec);
    let (json, csv) = (d.path().join("f.json"), d.path().join("f.csv"));
    let (code, out, err) =
        fleet_in_january(&spec, &["--json", json.to_str().unwrap(), "--csv", csv.to_str().unwrap()]);
    assert_eq!(code, Some(0), "{err}");
    assert!(out.contains(": 6 runs of 5 units"), "{out}");
    assert!(out.contains("runs: 3 pass, 1 rejected, 1 unfinished, 1 voided"), "{out}");
    assert!(out.contains("yield: first pass 2/3 units (66.7 %), final 3/3 (100.0 %)"), "{out}");
    assert!(out.contains("rejected 1×: selection beyond model 4"), "{out}");
    assert!(out.contains("certificates: 4 awaiting approval, 0 approved, 0 rejected"), "{out}");
    assert!(out.contains("as found out of tolerance: SN-C1 (aabbccddeeff001122334455)"), "{out}");
    assert!(out.contains("HEAD-1 (head) certificate DKD-17-001, due 2026-01-20"), "{out}");
    // The fixture's campaigns have no time column: the head's signature leaves them out, said.
    assert!(out.contains("head HEAD-1: 0 units, no change point"), "{out}");
    assert!(
        err.contains("warning: head HEAD-1: run ")
            && err.contains("'s stored campaign: missing required column `t_s`")
            && err.contains("left out of the head's signature"),
        "{err}"
    );
    let j: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!(j["counts"]["first_pass_units"], 2);
    assert_eq!(j["runs"].as_array().unwrap().len(), 6);
    assert_eq!(j["as_found_out_of_tolerance"][0]["serial"], "SN-C1");
    let mut rows = csv::Reader::from_path(&csv).unwrap();
    let header = rows.headers().unwrap().clone();
    assert_eq!(&header[0], "run_id");
    let u_z = header.iter().position(|h| h == "U_z_m_s2").unwrap();
    // Issue 59: the certificate, its state, its recalibration date and the record's CRC, after U;
    // and what became of a run a reference found out of tolerance calibrated.
    let after: Vec<&str> = header.iter().skip(u_z + 1).take(4).collect();
    assert_eq!(after, ["certificate_number", "certificate_state", "due_date", "record_crc"]);
    assert!(header.iter().any(|h| h == "recall") && header.iter().any(|h| h == "recall_reference"));
    let rows: Vec<csv::StringRecord> = rows.records().map(|r| r.unwrap()).collect();
    assert_eq!(rows.len(), 6);
    assert_eq!(&rows[0][1], "SN-A1");
    assert_eq!(&rows[0][4], "HEAD-1");
    assert!(rows[0][12].parse::<f64>().is_ok(), "{:?}", rows[0]);
    let col = |name: &str| header.iter().position(|h| h == name).unwrap();
    let b =
        rows.iter().find(|r| &r[1] == "SN-B1" && !r[col("due_date")].is_empty()).expect("unit B's due date");
    assert_eq!(&b[col("due_date")], "2026-01-21", "{b:?}");
    assert!(rows.iter().all(|r| r[col("record_crc")].is_empty() || r[col("record_crc")].len() == 8));
    // The units due within the default 30 days of --until: unit B, due T0 + 20 days.
    assert!(out.contains("SN-B1") && out.contains("due 2026-01-21"), "{out}");
    // A stored certificate, printed again as issued; a run without one is refused.
    let run = j["runs"][3]["run_id"].as_str().unwrap().to_string();
    let html = d.path().join("c.html");
    let (code, _, err) = accelcal(&["certificate", &run, "--db", &spec, "-o", html.to_str().unwrap()]);
    assert_eq!(code, Some(0), "{err}");
    assert_eq!(std::fs::read_to_string(&html).unwrap(), "<html>certificate of SN-C1</html>");
    // Issue 59: the beginning of a run id (8 or more of its digits) works as the id does.
    let (code, _, err) = accelcal(&["certificate", &run[..8], "--db", &spec, "-o", html.to_str().unwrap()]);
    assert_eq!(code, Some(0), "{err}");
    let (code, _, err) = accelcal(&["certificate", &run[..5], "--db", &spec, "-o", html.to_str().unwrap()]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("nor a run id or the beginning of one (8 or more of its hex digits)"), "{err}");
    let open = j["runs"][4]["run_id"].as_str().unwrap().to_string();
    let (code, _, err) = accelcal(&["certificate", &open, "--db", &spec, "-o", html.to_str().unwrap()]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("has no certificate"), "{err}");
    // Refused before anything is opened: an empty period, the database as an output.
    let (code, _, err) =
        accelcal(&["fleet", "--db", &spec, "--since", "2026-02-01", "--until", "2026-01-31"]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("--since 2026-02-01 is after --until 2026-01-31"), "{err}");
    let (code, _, err) = accelcal(&["fleet", "--db", &spec, "--csv", &spec]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("is the database: refusing to overwrite it"), "{err}");
}

/// Issue 31 item 3 end to end: 70 units on one registered head, their simulated campaigns
/// stored; from the 56th unit on, the head reaches position 27's α 2 mrad off what it says.
/// `fleet --json` names the head, flags a change point at a unit after the change, at that
/// position, and the signature since shows it there.
/// Issue 55: text that a spreadsheet would run as a formula (a serial `=HYPERLINK(…)`, an
/// operator `@SUM(…)`, a station `-2+3`) comes out of `fleet --csv` prefixed with `'`, quoted;
/// the numbers stay numbers (serve's `/fleet.csv` is the same function, `csv_of`).
#[test]
fn fleet_csv_neutralises_formulas_in_text_cells() {
    let d = tempfile::tempdir().unwrap();
    let spec = db_file(&d);
    let serial = r#"=HYPERLINK("http://x","y")"#;
    let mut db = Db::open(&spec).unwrap();
    let run = RunId::new();
    let s =
        accelcal_db::RunStart { operator: "@SUM(A1)".into(), ..start(run, DEVICE, serial, "-2+3", T0 + DAY) };
    db.begin_run(&s, None).unwrap();
    let mut c = coefs(0.0, 0);
    c[0][0] = -1.5;
    db.store_fit(run, &fit_json(&c)).unwrap();
    drop(db);
    let csv = d.path().join("f.csv");
    let (code, _, err) = fleet_in_january(&spec, &["--csv", csv.to_str().unwrap()]);
    assert_eq!(code, Some(0), "{err}");
    let text = std::fs::read_to_string(&csv).unwrap();
    assert!(text.contains(r#""'=HYPERLINK(""http://x"",""y"")""#), "{text}");
    let mut rows = csv::Reader::from_path(&csv).unwrap();
    let row = rows.records().next().unwrap().unwrap();
    assert_eq!(&row[1], format!("'{serial}"));
    assert_eq!(&row[3], "'-2+3");
    assert_eq!(&row[5], "'@SUM(A1)");
    // The coefficients: numbers, negative ones too, written unquoted.
    assert_eq!(&row[12], "-1.5");
    assert!(text.contains(",-1.5,"), "{text}");
}

#[test]
fn fleet_flags_a_head_knocked_out_of_true_from_the_units_campaigns() {
    let d = tempfile::tempdir().unwrap();
    let spec = db_file(&d);
    let mut db = Db::open(&spec).unwrap();
    dbkit::fleet::head_knocked_out(&mut db);
    drop(db);
    let json = d.path().join("f.json");
    let (code, out, err) = fleet_in_january(&spec, &["--json", json.to_str().unwrap()]);
    assert_eq!(code, Some(0), "{err}");
    assert!(out.contains("head HEAD-2: 70 units, 1 change point, the last at unit SN-H"), "{out}");
    let j: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let h = &j["heads"][0];
    assert_eq!(h["asset"], "HEAD-2");
    assert_eq!(h["units"], 70);
    let cp = &h["change_points"][0];
    let at: usize = cp["serial"].as_str().unwrap()["SN-H".len()..].parse().unwrap();
    assert!((55..70).contains(&at), "{cp}");
    assert!(cp["rule"].as_str().unwrap().contains("position 27 (α 60°, β 0°)"), "{cp}");
    // 2 mrad is 413 arcsec; model 4 absorbs a part, and the estimate averages from where the
    // CUSUM left zero.
    let est = cp["estimate"].as_f64().unwrap();
    assert!((200.0..500.0).contains(&est), "{cp}");
    assert_eq!(cp["run_id"].as_str().unwrap().len(), 36);
    assert!(cp["started_unix_s"].as_i64().unwrap() >= T0 + 55 * 3600);
    let arcsec = |p: usize| h["signature"]["positions"][p]["arcsec"].as_f64().unwrap();
    assert!(arcsec(26) > 200.0, "{}", h["signature"]);
    // The control charts of the head's 70 units: the 12 coefficients, each with the I-MR lines
    // of its points (the as-left error is not stored here).
    let charts = j["charts"].as_array().unwrap();
    assert_eq!(charts.len(), 12, "{charts:?}");
    let k0 = charts.iter().find(|c| c["group"] == "head HEAD-2" && c["quantity"] == "K0 x").unwrap();
    let values: Vec<f64> =
        k0["points"].as_array().unwrap().iter().map(|p| p["value"].as_f64().unwrap()).collect();
    assert_eq!(values.len(), 70);
    let want = accelcal_core::spc::ImrLimits::of(&values).unwrap();
    assert!((k0["limits"]["ucl"].as_f64().unwrap() - want.ucl).abs() < 1e-9 * want.ucl.abs().max(1.0));
    assert_eq!(k0["limits"]["mr_bar"].as_f64().unwrap(), want.mr_bar);
    // What an in-control chart of 70 points shows by chance, with each chart that breaks a rule.
    assert!((k0["expected_by_chance"].as_f64().unwrap() - 0.0218 * 70.0).abs() < 1e-9, "{k0}");
    let broken: Vec<&str> = out.lines().filter(|l| l.contains(" violation")).collect();
    assert!(
        broken.iter().all(|l| l.contains(" in 70 points (about 1.5 by chance), the last rule ")),
        "{out}"
    );
    assert!(
        out.contains(
            "control charts (I-MR, Western Electric rules, limits from the points charted): 12 charts"
        ),
        "{out}"
    );
}

/// Issue 60: 40 units on one registered head (its certificate states 3″), stored through the
/// normal path (campaign, asset, fit, pass); from unit 12 (from 0) the head reaches position
/// 27's α (β 0°) 2 mrad off what it says. `fleet --json` flags it at or after unit 12 and before
/// unit 23, at that position, with nothing flagged before the change. (These units have 30 sets
/// per position, against the bench's 100: 0.5 mrad moves a unit's statistic by about half a
/// standard deviation here, and is not flagged within the 28 units after it.)
#[test]
fn fleet_flags_a_change_at_unit_12_of_40_within_ten_units_and_nothing_before() {
    let d = tempfile::tempdir().unwrap();
    let spec = db_file(&d);
    let mut db = Db::open(&spec).unwrap();
    let head = head_asset("HEAD-3", "DKD-17-012", "2099-12-31", 3.0, T0 - DAY);
    dbkit::fleet::head_line(&mut db, &head, 40, |u, plan| {
        if u >= 12 {
            plan.positions[26].0 += (2e-3f64).to_degrees();
        }
    });
    drop(db);
    let json = d.path().join("f.json");
    let (code, _, err) = fleet_in_january(&spec, &["--json", json.to_str().unwrap()]);
    assert_eq!(code, Some(0), "{err}");
    let j: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let h = &j["heads"][0];
    assert_eq!((h["asset"].as_str(), h["units"].as_u64()), (Some("HEAD-3"), Some(40)));
    let cps = h["change_points"].as_array().unwrap();
    let first = cps.first().unwrap_or_else(|| panic!("not flagged: {h}"));
    // `index` counts the head's units from 0, as the serials do.
    let at = first["index"].as_u64().unwrap();
    assert_eq!(first["serial"], format!("SN-H{at:03}"));
    assert!((12..23).contains(&at), "{first}");
    assert!(first["rule"].as_str().unwrap().contains("position 27 (α 60°, β 0°)"), "{first}");
    // 2 mrad is 413″.
    let est = first["estimate"].as_f64().unwrap();
    assert!((290.0..540.0).contains(&est), "{first}");
    // The settings' fields are those `fleet --json` always had.
    let settings = h["signature"]["settings"].as_object().unwrap();
    let mut keys: Vec<&str> = settings.keys().map(|k| k.as_str()).collect();
    keys.sort_unstable();
    assert_eq!(keys, ["baseline", "h", "k"]);
}

#[test]
fn check_runs_are_the_station_s_checks_on_this_engine() {
    let d = tempfile::tempdir().unwrap();
    check_runs_are_the_station_s_checks(&db_file(&d));
}

#[test]
fn serve_s_pages_hold_the_database_s_numbers_in_chromium() {
    let d = tempfile::tempdir().unwrap();
    dbkit::serve::the_pages_hold_the_database_s_numbers(&db_file(&d));
}

/// Issue 59: the overview's attention panel, the search box and the charts' ticks, in Chromium.
#[test]
fn serve_s_morning_view_lists_what_needs_attention_finds_and_ticks_in_chromium() {
    let d = tempfile::tempdir().unwrap();
    dbkit::serve::the_morning_view_needs_attention_finds_and_ticks(&db_file(&d));
}

/// Issue 59: the search box and the unit's title over HTTP.
#[test]
fn serve_s_search_finds_a_unit_and_says_what_it_missed() {
    let d = tempfile::tempdir().unwrap();
    dbkit::serve::search_finds_a_unit_and_says_what_it_missed(&db_file(&d));
}

#[test]
fn serve_shows_a_hostile_serial_as_text_and_runs_no_stored_script() {
    let d = tempfile::tempdir().unwrap();
    dbkit::serve::a_hostile_serial_is_text_and_a_stored_script_does_not_run(&db_file(&d));
}

/// Issue 55: no control character of a stored certificate reaches `/run/ID/certificate`.
#[test]
fn serve_shows_a_stored_certificate_s_control_characters_escaped() {
    let d = tempfile::tempdir().unwrap();
    dbkit::serve::a_stored_certificate_s_controls_are_shown_escaped(&db_file(&d));
}

#[test]
fn serve_answers_only_get_and_says_why_a_request_is_bad() {
    let d = tempfile::tempdir().unwrap();
    dbkit::serve::only_get_is_answered_and_bad_requests_say_why(&db_file(&d));
}

/// Issue 55: 1,100 idle connections under `ulimit -n 1024` do not stop a page.
#[test]
fn serve_answers_a_page_within_a_second_past_1100_idle_connections() {
    let d = tempfile::tempdir().unwrap();
    dbkit::serve::idle_connections_do_not_stop_a_page(&db_file(&d));
}

/// Issue 55: Ctrl-C and SIGTERM end serve with exit code 0.
#[test]
fn serve_stops_on_ctrl_c_with_exit_code_0() {
    let d = tempfile::tempdir().unwrap();
    dbkit::serve::a_signal_stops_the_server_cleanly(&db_file(&d));
}

/// Issue 55: beyond loopback only with `--users`, and then every request needs the password.
#[test]
fn serve_beyond_loopback_needs_users_and_asks_every_request_for_the_password() {
    let d = tempfile::tempdir().unwrap();
    dbkit::serve::a_bind_beyond_loopback_needs_a_password(&db_file(&d));
}

/// Issue 55: a date beyond the range is a 400 naming its field; no control character reaches a page.
#[test]
fn serve_answers_hostile_urls_in_words() {
    let d = tempfile::tempdir().unwrap();
    dbkit::serve::hostile_urls_are_answered_in_words(&db_file(&d));
}

/// Issue 55: a failing query is 503, a unit that is not there 404.
#[test]
fn serve_answers_503_when_the_database_fails() {
    let d = tempfile::tempdir().unwrap();
    let spec = db_file(&d);
    let s = spec.clone();
    dbkit::serve::a_database_failure_is_503(&spec, move || {
        let c = rusqlite::Connection::open(&s).unwrap();
        c.execute_batch("ALTER TABLE run RENAME TO run_gone").unwrap();
    });
}

/// Issue 55: the database file removed is 503, another one moved into its place is read.
#[test]
fn serve_reads_a_database_file_replaced_while_it_runs() {
    let d = tempfile::tempdir().unwrap();
    dbkit::serve::a_database_file_replaced_is_read_anew(&db_file(&d));
}

/// The pages in Chromium's screenshots, in `target/tmp/serve-screenshots/` (the guide's pictures).
#[test]
fn serve_s_pages_render_to_screenshots() {
    let d = tempfile::tempdir().unwrap();
    dbkit::serve::the_pages_render_to_screenshots(&db_file(&d));
}

/// Issue 31 item 5: the rows derived from the pieces (schema 6) are written with them, derived
/// again for a database that lacks them when it is next opened (a database of version 5), and
/// `db verify` names a derived row changed behind accelcal's back.
#[test]
fn derived_rows_are_backfilled_on_open_and_checked_by_db_verify() {
    let d = tempfile::tempdir().unwrap();
    let spec = db_file(&d);
    dbkit::fleet::the_fleet_is_counted_by_the_database(&spec);
    // More pieces than one batch of the backfill takes (500 of each table), and simulated
    // campaigns that the head's observation reads (a number read back from JSON may differ from
    // the one written in its last bit: `db verify` must not call that a change).
    let mut db = Db::open(&spec).unwrap();
    dbkit::fleet::head_knocked_out(&mut db);
    for i in 0..260 {
        let device = format!("{:024x}", 0xb0_0000 + i);
        let s = start(RunId::new(), &device, &format!("BF-{i:03}"), "st-9", T0 + 40 * DAY + i as i64);
        calibrate(&mut db, &s, &coefs(0.0, 0), Some(0.01));
    }
    drop(db);
    const DERIVED: [&str; 6] = [
        "fit_summary",
        "fit_parameter",
        "verification_summary",
        "verification_parameter",
        "head_observation_f32",
        "head_observation",
    ];
    let dump = || -> Vec<Vec<String>> {
        let c = rusqlite::Connection::open(&spec).unwrap();
        DERIVED
            .iter()
            .map(|t| {
                let mut s = c.prepare(&format!("SELECT * FROM {t} ORDER BY 1, 2")).unwrap();
                let n = s.column_count();
                s.query_map([], |r| {
                    Ok((0..n).map(|i| format!("{:?}", r.get_ref(i).unwrap())).collect::<Vec<_>>().join("|"))
                })
                .unwrap()
                .map(|r| r.unwrap())
                .collect()
            })
            .collect()
    };
    let stored = dump();
    assert!(stored.iter().all(|rows| !rows.is_empty()), "every derived table holds rows: {stored:?}");
    // As a database of version 5 is once migrated: no derived rows, the backfill pending.
    let c = rusqlite::Connection::open(&spec).unwrap();
    for t in DERIVED {
        c.execute_batch(&format!("DROP TRIGGER {t}_no_delete; DELETE FROM {t};")).unwrap();
    }
    c.execute_batch("DELETE FROM device_certificate").unwrap();
    drop(c);
    drop(Db::open(&spec).unwrap());
    assert!(dump().iter().all(|rows| rows.is_empty()), "an open reads the pending flag only");
    rusqlite::Connection::open(&spec)
        .unwrap()
        .execute_batch("UPDATE derived_backfill SET pending = 1")
        .unwrap();
    let mut db = Db::open(&spec).unwrap();
    assert_eq!(dump(), stored, "the backfill derives what the store path derived");
    assert!(db.verify_chain().unwrap().mismatches.is_empty());
    let (code, out, err) = accelcal(&["db", "verify", "--db", &spec]);
    assert_eq!(code, Some(0), "{out}{err}");
    drop(db);
    // The observations in JSON only, as in a database of version 6: a reader takes the JSON
    // where the compact form is missing (here the backfill is not pending, so `fleet` reads
    // them so), and once migrated the compact form is made from them; `fleet` reads the same
    // either way.
    let fleet =
        || accelcal(&["fleet", "--db", &spec, "--since", "2026-01-01", "--until", "2026-12-31", "--json"]);
    let before = fleet();
    let c = rusqlite::Connection::open(&spec).unwrap();
    c.execute_batch("DELETE FROM head_observation_f32").unwrap();
    let count =
        |t: &str| c.query_row(&format!("SELECT COUNT(*) FROM {t}"), [], |r| r.get::<_, i64>(0)).unwrap();
    assert_eq!(fleet(), before, "a reader takes the JSON where the compact form is missing");
    assert_eq!(count("head_observation_f32"), 0);
    c.execute_batch("UPDATE derived_backfill SET pending = 1").unwrap();
    drop(Db::open(&spec).unwrap());
    let observed = "SELECT COUNT(*) FROM head_observation WHERE obs_json IS NOT NULL";
    assert!(count("head_observation_f32") > 0);
    assert_eq!(count("head_observation_f32"), c.query_row(observed, [], |r| r.get::<_, i64>(0)).unwrap());
    assert_eq!(dump(), stored, "the backfill from JSON writes what the store path wrote");
    assert_eq!(fleet(), before);
    drop(c);
    rusqlite::Connection::open(&spec)
        .unwrap()
        .execute_batch(
            "DROP TRIGGER fit_parameter_no_update; UPDATE fit_parameter SET value = value + 1 WHERE ord = 0;",
        )
        .unwrap();
    let r = Db::open(&spec).unwrap().verify_chain().unwrap();
    assert!(
        !r.mismatches.is_empty() && r.mismatches.iter().all(|m| m.piece == "fit_summary/fit_parameter"),
        "{:?}",
        r.mismatches
    );
    let (code, out, _) = accelcal(&["db", "verify", "--db", &spec]);
    assert_eq!(code, Some(1), "{out}");
    assert!(
        out.contains("the fit_summary/fit_parameter row of run") && out.contains("not what its fit derives"),
        "{out}"
    );
    // A compact observation changed behind accelcal's back is named too.
    rusqlite::Connection::open(&spec)
        .unwrap()
        .execute_batch(
            "DROP TRIGGER head_observation_f32_no_update; \
             UPDATE head_observation_f32 SET obs = X'01' WHERE run_id = (SELECT MIN(run_id) FROM head_observation_f32);",
        )
        .unwrap();
    let r = Db::open(&spec).unwrap().verify_chain().unwrap();
    assert!(r.mismatches.iter().any(|m| m.piece == "head_observation_f32"), "{:?}", r.mismatches);
}

/// Issue 31 item 3's last part: the head's signature feeds the budget. 30 units on HEAD-E,
/// whose certificate states 3″, every angle of which is off by a draw of N(0, 30″): `fit
/// --head-asset HEAD-E --db` of a 31st unit on it takes the 30″ or so its units measure, says
/// so in the head_angle contributor and in a warning; that contributor is the measured value's
/// multiple of the one the certificate's 3″ gives.
#[test]
fn the_head_s_measured_angle_error_feeds_the_budget_when_it_exceeds_the_certificate() {
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};
    let d = tempfile::tempdir().unwrap();
    let spec = db_file(&d);
    let mut db = Db::open(&spec).unwrap();
    let errors: Vec<(f64, f64)> = {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let e = Normal::new(0.0, 30.0 / 3600.0).unwrap();
        (0..62).map(|_| (e.sample(&mut rng), e.sample(&mut rng))).collect()
    };
    let reach = |plan: &mut accelcal_core::sim::Plan| {
        for (p, e) in plan.positions.iter_mut().zip(&errors) {
            (p.0, p.1) = (p.0 + e.0, p.1 + e.1);
        }
    };
    let head = head_asset("HEAD-E", "DKD-17-010", "2099-12-31", 3.0, T0 - DAY);
    dbkit::fleet::head_line(&mut db, &head, 30, |_, plan| reach(plan));
    // The newest 10 of them, oldest first.
    let last = db.latest_head_observations("HEAD-E", i64::MAX, 10).unwrap();
    assert_eq!(last.len(), 10);
    assert_eq!((last[0].serial.as_str(), last[9].serial.as_str()), ("SN-H020", "SN-H029"));
    assert!(db.latest_head_observations("HEAD-2", i64::MAX, 10).unwrap().is_empty());
    drop(db);
    let campaign = d.path().join("unit.csv");
    let mut f = std::fs::File::create(&campaign).unwrap();
    dbkit::fleet::head_campaign(999, reach).write(&mut f).unwrap();
    drop(f);
    let c = campaign.to_str().unwrap();
    let (by_head, stated) = (d.path().join("head.json"), d.path().join("stated.json"));
    let rec = d.path().join("r.rec");
    let (code, _, err) = accelcal(&[
        "fit",
        c,
        "--db",
        &spec,
        "--head-asset",
        "HEAD-E",
        "--json",
        by_head.to_str().unwrap(),
        "--record",
        rec.to_str().unwrap(),
        "--device-id",
        "51454d552d422d4c34373545",
    ]);
    assert_eq!(code, Some(0), "{err}");
    assert!(err.contains("warning: head asset HEAD-E: its last 30 units measure"), "{err}");
    assert!(err.contains("more than its certificate's 3″: the budget takes the measured value"), "{err}");
    ok(&["fit", c, "--head-angle-u", "3", "--head-orthogonality-u", "6", "--json", stated.to_str().unwrap()]);
    let read = |p: &Path| -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap()
    };
    let (h, s) = (read(&by_head), read(&stated));
    let angle = h["uncertainty"]["contributors"]
        .as_array()
        .unwrap()
        .iter()
        .find(|c| c["name"] == "head_angle")
        .unwrap()
        .clone();
    let src = angle["source"].as_str().unwrap();
    let want = "arcsec per angle and position, measured by the head's last 30 units (RMS over 122 head angles): more than the 3 arcsec that head asset HEAD-E's certificate DKD-17-010 (due 2099-12-31) states";
    assert!(src.contains(want), "{src}");
    // The measured RMS is near the draw's 30″ (the α of a position at β = ±90° does not show).
    let rms: f64 = src.split(' ').next().unwrap().parse().unwrap();
    assert!((22.0..38.0).contains(&rms), "{src}");
    // The head_angle contributor is linear in the angle's u: the measured value over the 3″.
    let head_u = |j: &serde_json::Value| -> f64 {
        let c = j["uncertainty"]["contributors"].as_array().unwrap();
        c.iter().find(|c| c["name"] == "head_angle").unwrap()["u_m_s2"].as_f64().unwrap()
    };
    let ratio = head_u(&h) / head_u(&s);
    assert!((ratio / (rms / 3.0) - 1.0).abs() < 0.01, "{ratio} for {rms}″ over 3″");
    // U is much the same either way: the residuals already carry the head's error (the guide,
    // `line/database.md`, quotes these).
    let u_max = |j: &serde_json::Value| -> f64 {
        j["uncertainty"]["U_m_s2"].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).fold(0.0, f64::max)
    };
    eprintln!(
        "U: {:.2e} m/s² with the measured {rms}″, {:.2e} with the certificate's 3″",
        u_max(&h),
        u_max(&s)
    );
    // `fleet` and serve's charts page say the same of the head.
    let (code, out, err) = fleet_in_january(&spec, &[]);
    assert_eq!(code, Some(0), "{err}");
    let said =
        out.lines().find_map(|l| l.trim().strip_prefix("its angle error as its last 30 units measure it: "));
    let said = said.unwrap_or_else(|| panic!("{out}"));
    assert!(said.ends_with("″ RMS over 122 head angles"), "{said}");
    let fleet_rms: f64 = said.split('″').next().unwrap().parse().unwrap();
    assert!((fleet_rms - rms).abs() <= 0.051, "{fleet_rms} against the budget's {rms}");
    let said = format!("its angle error as its last 30 units measure it: {said}");
    let charts = dbkit::serve::page(&spec, "/charts?since=2026-01-01&until=2026-01-31&head_asset=HEAD-E");
    assert!(charts.contains(&said), "{said}: {charts}");
    // Issue 60: each bar of the signature carries its uncertainty.
    assert!(charts.contains("bars: ±2 standard errors") && !charts.contains("not enough units"), "{charts}");
}
