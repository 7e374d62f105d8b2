-- The calibration database, version 9 (PostgreSQL): signers and their decisions on certificates
-- (issue 57). The same tables, columns and keys as ../sqlite/V9__signer_approval.sql, which
-- says what each holds.

CREATE TABLE signer (
    fingerprint       TEXT PRIMARY KEY NOT NULL,
    name              TEXT NOT NULL,
    function          TEXT NOT NULL,
    public_key        TEXT NOT NULL UNIQUE,
    operator          TEXT NOT NULL,
    registered_unix_s BIGINT NOT NULL,
    content_sha256    TEXT NOT NULL
);
CREATE INDEX signer_name ON signer (name);

CREATE TABLE signer_revocation (
    fingerprint       TEXT PRIMARY KEY NOT NULL REFERENCES signer (fingerprint),
    reason            TEXT NOT NULL,
    operator          TEXT NOT NULL,
    revoked_unix_s    BIGINT NOT NULL,
    content_sha256    TEXT NOT NULL
);

CREATE TABLE approval (
    run_id            TEXT NOT NULL REFERENCES run (run_id),
    number            TEXT PRIMARY KEY NOT NULL REFERENCES certificate_number (number),
    document_sha256   TEXT NOT NULL,
    meaning           TEXT NOT NULL,
    reason            TEXT NOT NULL,
    fingerprint       TEXT NOT NULL REFERENCES signer (fingerprint),
    signature         TEXT NOT NULL,
    signed_unix_s     BIGINT NOT NULL,
    content_sha256    TEXT NOT NULL
);
CREATE INDEX approval_run ON approval (run_id);

CREATE TRIGGER signer_append_only BEFORE UPDATE OR DELETE ON signer FOR EACH ROW EXECUTE FUNCTION accelcal_append_only();
CREATE TRIGGER signer_no_truncate BEFORE TRUNCATE ON signer FOR EACH STATEMENT EXECUTE FUNCTION accelcal_append_only();
CREATE TRIGGER signer_revocation_append_only BEFORE UPDATE OR DELETE ON signer_revocation FOR EACH ROW EXECUTE FUNCTION accelcal_append_only();
CREATE TRIGGER signer_revocation_no_truncate BEFORE TRUNCATE ON signer_revocation FOR EACH STATEMENT EXECUTE FUNCTION accelcal_append_only();
CREATE TRIGGER approval_append_only BEFORE UPDATE OR DELETE ON approval FOR EACH ROW EXECUTE FUNCTION accelcal_append_only();
CREATE TRIGGER approval_no_truncate BEFORE TRUNCATE ON approval FOR EACH STATEMENT EXECUTE FUNCTION accelcal_append_only();
