-- The calibration database, version 2 (SQLite): the rows' hash chain, voided runs and relabels.
-- The same tables, columns and keys as ../postgres/V2__chain_void_relabel.sql.
--
-- `ledger`: one entry per row of every other table, appended in the same transaction as its
-- row. `row_sha256` is the digest of the row's columns (core/src/db/chain.rs says how);
-- `chain_sha256` hashes the entry with `prev_sha256`, the chain value of the run's previous
-- entry, or for a run's first entry (and a relabel) of the latest entry of the whole ledger at
-- the time: each run chained to its own rows, and runs to each other. `accelcal db verify`
-- recomputes it all and names the first row that does not match.

CREATE TABLE ledger (
    seq               BIGINT PRIMARY KEY NOT NULL, -- 1, 2, 3… in order of writing
    run_id            TEXT NOT NULL,               -- '' for a relabel
    piece             TEXT NOT NULL,               -- run, campaign, fit, cal_record, flash, verification:as_found, …, void, relabel:ID
    row_sha256        TEXT NOT NULL,
    prev_seq          BIGINT NOT NULL,             -- the entry `prev_sha256` is of (0: none, the first entry)
    prev_sha256       TEXT NOT NULL,
    chain_sha256      TEXT NOT NULL,
    UNIQUE (run_id, piece)
);

-- A run taken out of history, fleet and intervals; the run's rows stay.
CREATE TABLE void (
    run_id            TEXT PRIMARY KEY NOT NULL REFERENCES run (run_id),
    reason            TEXT NOT NULL,
    operator          TEXT NOT NULL,
    voided_unix_s     BIGINT NOT NULL,
    content_sha256    TEXT NOT NULL
);

-- A device given another serial number on purpose (`--relabel REASON`).
CREATE TABLE relabel (
    relabel_id        TEXT PRIMARY KEY NOT NULL,   -- a UUID
    device_id         TEXT NOT NULL,
    old_serial        TEXT NOT NULL,               -- '' when the device had none
    new_serial        TEXT NOT NULL,
    reason            TEXT NOT NULL,
    operator          TEXT NOT NULL,
    relabelled_unix_s BIGINT NOT NULL,
    content_sha256    TEXT NOT NULL
);
CREATE INDEX relabel_device ON relabel (device_id, relabelled_unix_s);

CREATE TRIGGER ledger_no_update BEFORE UPDATE ON ledger BEGIN SELECT RAISE(ABORT, 'append-only: ledger rows are never updated'); END;
CREATE TRIGGER ledger_no_delete BEFORE DELETE ON ledger BEGIN SELECT RAISE(ABORT, 'append-only: ledger rows are never deleted'); END;
CREATE TRIGGER void_no_update BEFORE UPDATE ON void BEGIN SELECT RAISE(ABORT, 'append-only: void rows are never updated'); END;
CREATE TRIGGER void_no_delete BEFORE DELETE ON void BEGIN SELECT RAISE(ABORT, 'append-only: void rows are never deleted'); END;
CREATE TRIGGER relabel_no_update BEFORE UPDATE ON relabel BEGIN SELECT RAISE(ABORT, 'append-only: relabel rows are never updated'); END;
CREATE TRIGGER relabel_no_delete BEFORE DELETE ON relabel BEGIN SELECT RAISE(ABORT, 'append-only: relabel rows are never deleted'); END;
