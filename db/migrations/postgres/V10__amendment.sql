-- The calibration database, version 10 (PostgreSQL): amended certificates (issue 57). The same
-- tables, columns and keys as ../sqlite/V10__amendment.sql, which says what they hold.
--
-- `approval` is rebuilt without its foreign key to `certificate_number (number)` (as SQLite
-- must rebuild it), its rows copied as they are.

CREATE TABLE amendment (
    run_id            TEXT NOT NULL REFERENCES run (run_id),
    number            TEXT PRIMARY KEY NOT NULL,
    sequence          BIGINT NOT NULL UNIQUE,
    replaces          TEXT NOT NULL UNIQUE,
    reason            TEXT NOT NULL,
    operator          TEXT NOT NULL,
    html              TEXT NOT NULL,
    issued_unix_s     BIGINT NOT NULL,
    content_sha256    TEXT NOT NULL
);
CREATE INDEX amendment_run ON amendment (run_id);

CREATE TRIGGER amendment_append_only BEFORE UPDATE OR DELETE ON amendment FOR EACH ROW EXECUTE FUNCTION accelcal_append_only();
CREATE TRIGGER amendment_no_truncate BEFORE TRUNCATE ON amendment FOR EACH STATEMENT EXECUTE FUNCTION accelcal_append_only();

ALTER TABLE approval RENAME TO approval_v9;
ALTER INDEX approval_run RENAME TO approval_v9_run;
ALTER INDEX approval_pkey RENAME TO approval_v9_pkey;
CREATE TABLE approval (
    run_id            TEXT NOT NULL REFERENCES run (run_id),
    number            TEXT PRIMARY KEY NOT NULL,
    document_sha256   TEXT NOT NULL,
    meaning           TEXT NOT NULL,
    reason            TEXT NOT NULL,
    fingerprint       TEXT NOT NULL REFERENCES signer (fingerprint),
    signature         TEXT NOT NULL,
    signed_unix_s     BIGINT NOT NULL,
    content_sha256    TEXT NOT NULL
);
INSERT INTO approval (run_id, number, document_sha256, meaning, reason, fingerprint, signature, signed_unix_s, content_sha256)
    SELECT run_id, number, document_sha256, meaning, reason, fingerprint, signature, signed_unix_s, content_sha256 FROM approval_v9;
DROP TABLE approval_v9;
CREATE INDEX approval_run ON approval (run_id);

CREATE TRIGGER approval_append_only BEFORE UPDATE OR DELETE ON approval FOR EACH ROW EXECUTE FUNCTION accelcal_append_only();
CREATE TRIGGER approval_no_truncate BEFORE TRUNCATE ON approval FOR EACH STATEMENT EXECUTE FUNCTION accelcal_append_only();
