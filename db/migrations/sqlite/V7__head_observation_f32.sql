-- The calibration database, version 7 (SQLite): the heads' observations in a compact form.
-- The same tables, columns and keys as ../postgres/V7__head_observation_f32.sql.
--
-- `head_observation_f32`: a run's `head_observation.obs_json` (when it is not NULL) as bytes
-- (`accelcal_db::derived::Observation::to_bytes`: a version byte, the number of positions, the
-- positions as f64, the residuals and misalignments as f32, little-endian): 1,763 bytes for the
-- paper's 62 positions, where the JSON takes about 4,800 (which a PostgreSQL server compresses
-- and keeps out of line). `fleet` reads a month of them, and this form is read without parsing. Derived like the rows of version 6: written in the transaction that stores the
-- campaign, checked by `db verify`, and for the observations stored before this version written
-- when the database is next opened (the backfill, pending again below).

CREATE TABLE head_observation_f32 (
    run_id            TEXT PRIMARY KEY NOT NULL REFERENCES head_observation (run_id),
    obs               BLOB NOT NULL
);
CREATE TRIGGER head_observation_f32_no_update BEFORE UPDATE ON head_observation_f32 BEGIN SELECT RAISE(ABORT, 'append-only: head_observation_f32 rows are never updated'); END;
CREATE TRIGGER head_observation_f32_no_delete BEFORE DELETE ON head_observation_f32 BEGIN SELECT RAISE(ABORT, 'append-only: head_observation_f32 rows are never deleted'); END;

UPDATE derived_backfill SET pending = 1;
