-- The calibration database, version 5 (SQLite): the recalibration date a certificate states, and
-- each verification's decision as a column. The same table, columns and keys as
-- ../postgres/V5__recalibration_due.sql.
--
-- `recalibration_due`: the date by which the certificate recommends the unit be recalibrated
-- (ILAC-G24: from the drift of its coefficients, shortened after an as-found result out of
-- tolerance, method 1), stored in the transaction that numbers the certificate and the same
-- every time it is printed again. `basis` says what set it. One row per certified run, never
-- updated or deleted.
--
-- `verification_decision`: a view of `verification` with the decision rule's outcome of each
-- verification (`pass`, `conditional pass`, `conditional fail`, `fail`; NULL where no
-- specification was applied) and the rule, read from its `verify --json`, so that a query can
-- select the units found out of tolerance without parsing the report.

CREATE TABLE recalibration_due (
    run_id            TEXT PRIMARY KEY NOT NULL REFERENCES certificate_number (run_id),
    due_unix_s        BIGINT NOT NULL,
    basis             TEXT NOT NULL,
    stored_unix_s     BIGINT NOT NULL,
    content_sha256    TEXT NOT NULL
);
CREATE INDEX recalibration_due_by_date ON recalibration_due (due_unix_s);

CREATE TRIGGER recalibration_due_no_update BEFORE UPDATE ON recalibration_due BEGIN SELECT RAISE(ABORT, 'append-only: recalibration_due rows are never updated'); END;
CREATE TRIGGER recalibration_due_no_delete BEFORE DELETE ON recalibration_due BEGIN SELECT RAISE(ABORT, 'append-only: recalibration_due rows are never deleted'); END;

CREATE VIEW verification_decision AS
    SELECT run_id,
           phase,
           pass,
           json_extract(report_json, '$.decision') AS decision,
           json_extract(report_json, '$.specification.rule') AS rule,
           stored_unix_s
    FROM verification;
