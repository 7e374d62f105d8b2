-- The calibration database, version 6 (PostgreSQL): rows derived from the stored pieces for the
-- fleet's statistics. The same tables, columns and keys as ../sqlite/V6__derived.sql.
--
-- `fit_summary`, `fit_parameter`, `verification_summary`, `verification_parameter`,
-- `head_observation`: rows derived from a stored piece (`accelcal_db::derived`), written in the
-- transaction that stores it, so that the fleet's statistics are aggregated by SQL over numbers
-- instead of by reading every document into the process. They are not pieces: the ledger does
-- not chain them, `db verify` derives them again from the chained pieces and compares. A
-- database migrated from version 5 gets them for its stored pieces when it is next opened.
--
-- `fit_summary`: one row per fit; `model4_json` its model-4 coefficients `[[u0, kx, ky, kz]; 3]`
-- by axis (NULL: not a model-4 triad), `u_json` its budget's U per axis, m/s² (NULL: none).
-- `fit_parameter`: a model-4 fit's IEEE 1293 parameters (`K0 x` mg, `K1 x` codes/g, `δ x→y`
-- µrad), `ord` their order in `fleet`. `verification_summary`: one row per verification, its
-- decision and rule (NULL: none decided) and its largest |error|, m/s².
-- `verification_parameter`: the parameters it measured (`bias x` mg, `scale factor x` ppm,
-- `misalignment x→y` µrad) with the specification's limit. `head_observation`: what the run's
-- campaign shows of the head (`accelcal_core::headsig::observe`) as JSON (NULL: not a triad model 4
-- fits), or NULL and `why` its campaign does not read.

CREATE TABLE fit_summary (
    run_id            TEXT PRIMARY KEY NOT NULL REFERENCES fit (run_id),
    model4_json       TEXT,
    u_json            TEXT
);

CREATE TABLE fit_parameter (
    run_id            TEXT NOT NULL REFERENCES fit (run_id),
    ord               BIGINT NOT NULL,
    name              TEXT NOT NULL,
    unit              TEXT NOT NULL,
    value             DOUBLE PRECISION NOT NULL,
    PRIMARY KEY (run_id, ord)
);

CREATE TABLE verification_summary (
    run_id            TEXT NOT NULL,
    phase             TEXT NOT NULL,
    decision          TEXT,
    rule              TEXT,
    max_abs_error_m_s2 DOUBLE PRECISION,
    PRIMARY KEY (run_id, phase),
    FOREIGN KEY (run_id, phase) REFERENCES verification (run_id, phase)
);

CREATE TABLE verification_parameter (
    run_id            TEXT NOT NULL,
    phase             TEXT NOT NULL,
    ord               BIGINT NOT NULL,
    name              TEXT NOT NULL,
    unit              TEXT NOT NULL,
    value             DOUBLE PRECISION NOT NULL,
    limit_value       DOUBLE PRECISION NOT NULL,
    PRIMARY KEY (run_id, phase, ord),
    FOREIGN KEY (run_id, phase) REFERENCES verification (run_id, phase)
);

CREATE TABLE head_observation (
    run_id            TEXT PRIMARY KEY NOT NULL REFERENCES campaign (run_id),
    obs_json          TEXT,
    why               TEXT
);

CREATE INDEX run_by_start ON run (started_unix_s);
-- The runs of the stations' check standards (`accelcal_db::check::IS_CHECK`), found without
-- reading every run's end.
CREATE INDEX run_end_check_standard ON run_end (run_id) WHERE substr(reason, 1, 14) = 'check standard';
CREATE TRIGGER fit_summary_append_only BEFORE UPDATE OR DELETE ON fit_summary FOR EACH ROW EXECUTE FUNCTION accelcal_append_only();
CREATE TRIGGER fit_summary_no_truncate BEFORE TRUNCATE ON fit_summary FOR EACH STATEMENT EXECUTE FUNCTION accelcal_append_only();
CREATE TRIGGER fit_parameter_append_only BEFORE UPDATE OR DELETE ON fit_parameter FOR EACH ROW EXECUTE FUNCTION accelcal_append_only();
CREATE TRIGGER fit_parameter_no_truncate BEFORE TRUNCATE ON fit_parameter FOR EACH STATEMENT EXECUTE FUNCTION accelcal_append_only();
CREATE TRIGGER verification_summary_append_only BEFORE UPDATE OR DELETE ON verification_summary FOR EACH ROW EXECUTE FUNCTION accelcal_append_only();
CREATE TRIGGER verification_summary_no_truncate BEFORE TRUNCATE ON verification_summary FOR EACH STATEMENT EXECUTE FUNCTION accelcal_append_only();
CREATE TRIGGER verification_parameter_append_only BEFORE UPDATE OR DELETE ON verification_parameter FOR EACH ROW EXECUTE FUNCTION accelcal_append_only();
CREATE TRIGGER verification_parameter_no_truncate BEFORE TRUNCATE ON verification_parameter FOR EACH STATEMENT EXECUTE FUNCTION accelcal_append_only();
CREATE TRIGGER head_observation_append_only BEFORE UPDATE OR DELETE ON head_observation FOR EACH ROW EXECUTE FUNCTION accelcal_append_only();
CREATE TRIGGER head_observation_no_truncate BEFORE TRUNCATE ON head_observation FOR EACH STATEMENT EXECUTE FUNCTION accelcal_append_only();

DROP VIEW verification_decision;
CREATE VIEW verification_decision AS
    SELECT v.run_id, v.phase, v.pass, s.decision, s.rule, v.stored_unix_s
    FROM verification v LEFT JOIN verification_summary s ON s.run_id = v.run_id AND s.phase = v.phase;

-- `device_certificate`: each unit's latest certified run (a `recalibration_due` row) that is not
-- voided, and the date it is due, kept in the transactions that number a certificate or void a
-- run: the units due are read from it by the date's index, not found by ranking every certificate.
-- A projection, not a record: rewritten for its device, never chained.
CREATE TABLE device_certificate (
    device_id         TEXT PRIMARY KEY NOT NULL,
    run_id            TEXT NOT NULL REFERENCES recalibration_due (run_id),
    due_unix_s        BIGINT NOT NULL
);
CREATE INDEX device_certificate_by_due ON device_certificate (due_unix_s);

-- Whether the pieces stored before this version still wait for their derived rows: one row, set
-- to 0 once `accelcal_db::derived::backfill` has derived them (each open reads this row only).
CREATE TABLE derived_backfill (
    pending           BIGINT NOT NULL
);
INSERT INTO derived_backfill (pending) VALUES (1);
