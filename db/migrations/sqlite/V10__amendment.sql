-- The calibration database, version 10 (SQLite): amended certificates (issue 57). The same
-- tables, columns and keys as ../postgres/V10__amendment.sql.
--
-- `amendment`: a certificate issued again for the same run under a new number, because the one
-- it replaces was wrong (`accelcal amend`). Its number comes from the same sequence as
-- `certificate_number`'s (the largest of both plus one), it names the number it replaces and
-- why, and it holds its own page (`html`, carrying its document), which awaits approval as any
-- certificate does. A number is replaced at most once (`replaces` is unique): the certificates
-- of a run form one line, and the one that nothing replaces is the run's certificate in force.
-- It belongs to the run and is chained after the run's other rows.
--
-- `approval` is rebuilt without its foreign key to `certificate_number (number)`: an
-- amendment's number is approved or rejected like any other. Its rows are copied as they are
-- (the ledger's digests cover their values, not where they are stored).

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

CREATE TRIGGER amendment_no_update BEFORE UPDATE ON amendment BEGIN SELECT RAISE(ABORT, 'append-only: amendment rows are never updated'); END;
CREATE TRIGGER amendment_no_delete BEFORE DELETE ON amendment BEGIN SELECT RAISE(ABORT, 'append-only: amendment rows are never deleted'); END;
CREATE TRIGGER amendment_no_replace BEFORE INSERT ON amendment WHEN EXISTS (SELECT 1 FROM amendment WHERE number = NEW.number OR replaces = NEW.replaces) BEGIN SELECT RAISE(ABORT, 'append-only: amendment rows are never replaced'); END;

ALTER TABLE approval RENAME TO approval_v9;
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

CREATE TRIGGER approval_no_update BEFORE UPDATE ON approval BEGIN SELECT RAISE(ABORT, 'append-only: approval rows are never updated'); END;
CREATE TRIGGER approval_no_delete BEFORE DELETE ON approval BEGIN SELECT RAISE(ABORT, 'append-only: approval rows are never deleted'); END;
CREATE TRIGGER approval_no_replace BEFORE INSERT ON approval WHEN EXISTS (SELECT 1 FROM approval WHERE number = NEW.number) BEGIN SELECT RAISE(ABORT, 'append-only: approval rows are never replaced'); END;
