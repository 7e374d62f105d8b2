-- The calibration database, version 9 (SQLite): signers and their decisions on certificates
-- (issue 57). The same tables, columns and keys as ../postgres/V9__signer_approval.sql.
--
-- `signer`: a person who may approve or reject certificates, with their function and the public
-- half of their Ed25519 key (64 hex digits; the private half stays in their encrypted key file).
-- `fingerprint` is the first 16 hex digits of the SHA-256 of the key's 32 bytes, as printed on
-- an approved certificate. A name has at most one key in force (not revoked).
-- `signer_revocation`: a key taken out of use, with the reason; it approves nothing after.
-- Both belong to no run: their ledger entries have `run_id` '' (like `asset`).
--
-- `approval`: one decision per certificate number (approved for issue, or rejected with a
-- reason), signed by the signer's key over the message `core::certificate::approval` defines
-- (its number, the document's SHA-256, the meaning, the reason and `signed_unix_s`). It belongs
-- to the run of the certificate and is chained after the run's other rows.

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

CREATE TRIGGER signer_no_update BEFORE UPDATE ON signer BEGIN SELECT RAISE(ABORT, 'append-only: signer rows are never updated'); END;
CREATE TRIGGER signer_no_delete BEFORE DELETE ON signer BEGIN SELECT RAISE(ABORT, 'append-only: signer rows are never deleted'); END;
CREATE TRIGGER signer_no_replace BEFORE INSERT ON signer WHEN EXISTS (SELECT 1 FROM signer WHERE fingerprint = NEW.fingerprint OR public_key = NEW.public_key) BEGIN SELECT RAISE(ABORT, 'append-only: signer rows are never replaced'); END;
CREATE TRIGGER signer_revocation_no_update BEFORE UPDATE ON signer_revocation BEGIN SELECT RAISE(ABORT, 'append-only: signer_revocation rows are never updated'); END;
CREATE TRIGGER signer_revocation_no_delete BEFORE DELETE ON signer_revocation BEGIN SELECT RAISE(ABORT, 'append-only: signer_revocation rows are never deleted'); END;
CREATE TRIGGER signer_revocation_no_replace BEFORE INSERT ON signer_revocation WHEN EXISTS (SELECT 1 FROM signer_revocation WHERE fingerprint = NEW.fingerprint) BEGIN SELECT RAISE(ABORT, 'append-only: signer_revocation rows are never replaced'); END;
CREATE TRIGGER approval_no_update BEFORE UPDATE ON approval BEGIN SELECT RAISE(ABORT, 'append-only: approval rows are never updated'); END;
CREATE TRIGGER approval_no_delete BEFORE DELETE ON approval BEGIN SELECT RAISE(ABORT, 'append-only: approval rows are never deleted'); END;
CREATE TRIGGER approval_no_replace BEFORE INSERT ON approval WHEN EXISTS (SELECT 1 FROM approval WHERE number = NEW.number) BEGIN SELECT RAISE(ABORT, 'append-only: approval rows are never replaced'); END;
