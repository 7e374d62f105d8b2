-- The calibration database, version 5 (PostgreSQL): the recalibration date a certificate states,
-- and each verification's decision as a column. The same table, columns and keys as
-- ../sqlite/V5__recalibration_due.sql.
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

CREATE TRIGGER recalibration_due_append_only BEFORE UPDATE OR DELETE ON recalibration_due FOR EACH ROW EXECUTE FUNCTION accelcal_append_only();
CREATE TRIGGER recalibration_due_no_truncate BEFORE TRUNCATE ON recalibration_due FOR EACH STATEMENT EXECUTE FUNCTION accelcal_append_only();

CREATE VIEW verification_decision AS
    SELECT run_id,
           phase,
           pass,
           report_json::jsonb ->> 'decision' AS decision,
           report_json::jsonb -> 'specification' ->> 'rule' AS rule,
           stored_unix_s
    FROM verification;
