-- The calibration database, version 7 (PostgreSQL): the heads' observations in a compact form.
-- The same tables, columns and keys as ../sqlite/V7__head_observation_f32.sql.
--
-- `head_observation_f32`: a run's `head_observation.obs_json` (when it is not NULL) as bytes
-- (`accelcal_db::derived::Observation::to_bytes`: a version byte, the number of positions, the
-- positions as f64, the residuals and misalignments as f32, little-endian): 1,763 bytes for the
-- paper's 62 positions, where the JSON takes about 4,800, which PostgreSQL compresses and keeps
-- out of line. `fleet` reads a month of them, and this form is stored in the row and read without
-- parsing. Derived like the rows of version 6: written in the transaction that stores the
-- campaign, checked by `db verify`, and for the observations stored before this version written
-- when the database is next opened (the backfill, pending again below).

CREATE TABLE head_observation_f32 (
    run_id            TEXT PRIMARY KEY NOT NULL REFERENCES head_observation (run_id),
    obs               BYTEA NOT NULL
);
CREATE TRIGGER head_observation_f32_append_only BEFORE UPDATE OR DELETE ON head_observation_f32 FOR EACH ROW EXECUTE FUNCTION accelcal_append_only();
CREATE TRIGGER head_observation_f32_no_truncate BEFORE TRUNCATE ON head_observation_f32 FOR EACH STATEMENT EXECUTE FUNCTION accelcal_append_only();

UPDATE derived_backfill SET pending = 1;
