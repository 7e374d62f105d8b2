-- The calibration database, version 8 (PostgreSQL): the chain's own events, and (SQLite) no row
-- replaced behind the append-only triggers. The same tables, columns and keys as
-- ../sqlite/V8__chain_event_no_replace.sql.
--
-- `chain_event`: what happened to the chain itself, chained like any row (`run_id` '' in the
-- ledger): today only `legacy-seal`, the one-time sealing of rows written before the ledger
-- existed (schema 1), with how many rows it chained. A database whose rows were sealed late says
-- so in `db verify`, and a ledger emptied behind accelcal's back is never sealed again.
--
-- PostgreSQL has no REPLACE; `INSERT … ON CONFLICT DO UPDATE` fires the update triggers, which
-- refuse it.

CREATE TABLE chain_event (
    event_id          TEXT PRIMARY KEY NOT NULL,
    kind              TEXT NOT NULL,
    detail            TEXT NOT NULL,
    unix_s            BIGINT NOT NULL,
    content_sha256    TEXT NOT NULL
);
CREATE TRIGGER chain_event_append_only BEFORE UPDATE OR DELETE ON chain_event FOR EACH ROW EXECUTE FUNCTION accelcal_append_only();
CREATE TRIGGER chain_event_no_truncate BEFORE TRUNCATE ON chain_event FOR EACH STATEMENT EXECUTE FUNCTION accelcal_append_only();
