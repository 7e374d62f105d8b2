-- The calibration database, version 2 (PostgreSQL): the rows' hash chain, voided runs and
-- relabels. The same tables, columns and keys as ../sqlite/V2__chain_void_relabel.sql, which
-- says what they hold.

CREATE TABLE ledger (
    seq               BIGINT PRIMARY KEY NOT NULL,
    run_id            TEXT NOT NULL,
    piece             TEXT NOT NULL,
    row_sha256        TEXT NOT NULL,
    prev_seq          BIGINT NOT NULL,
    prev_sha256       TEXT NOT NULL,
    chain_sha256      TEXT NOT NULL,
    UNIQUE (run_id, piece)
);

CREATE TABLE void (
    run_id            TEXT PRIMARY KEY NOT NULL REFERENCES run (run_id),
    reason            TEXT NOT NULL,
    operator          TEXT NOT NULL,
    voided_unix_s     BIGINT NOT NULL,
    content_sha256    TEXT NOT NULL
);

CREATE TABLE relabel (
    relabel_id        TEXT PRIMARY KEY NOT NULL,
    device_id         TEXT NOT NULL,
    old_serial        TEXT NOT NULL,
    new_serial        TEXT NOT NULL,
    reason            TEXT NOT NULL,
    operator          TEXT NOT NULL,
    relabelled_unix_s BIGINT NOT NULL,
    content_sha256    TEXT NOT NULL
);
CREATE INDEX relabel_device ON relabel (device_id, relabelled_unix_s);

CREATE TRIGGER ledger_append_only BEFORE UPDATE OR DELETE ON ledger FOR EACH ROW EXECUTE FUNCTION accelcal_append_only();
CREATE TRIGGER ledger_no_truncate BEFORE TRUNCATE ON ledger FOR EACH STATEMENT EXECUTE FUNCTION accelcal_append_only();
CREATE TRIGGER void_append_only BEFORE UPDATE OR DELETE ON void FOR EACH ROW EXECUTE FUNCTION accelcal_append_only();
CREATE TRIGGER void_no_truncate BEFORE TRUNCATE ON void FOR EACH STATEMENT EXECUTE FUNCTION accelcal_append_only();
CREATE TRIGGER relabel_append_only BEFORE UPDATE OR DELETE ON relabel FOR EACH ROW EXECUTE FUNCTION accelcal_append_only();
CREATE TRIGGER relabel_no_truncate BEFORE TRUNCATE ON relabel FOR EACH STATEMENT EXECUTE FUNCTION accelcal_append_only();
