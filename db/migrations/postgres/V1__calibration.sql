-- The calibration database, version 1 (PostgreSQL). The same tables, columns and keys as
-- ../sqlite/V1__calibration.sql; only the column types' spelling and the append-only triggers
-- differ (a test compares the two schemas column by column).
--
-- One calibration run of one unit is one `run` row, chosen by the station before anything else
-- (`run_id`, a UUID: a resumed run stores under the same id, so nothing is stored twice). Each
-- piece of the run is one row keyed by the run (and the verification's phase), written in one
-- transaction; `content_sha256` is the hash of what the piece holds, so storing the same piece
-- again is a no-op and storing a different one is refused. Rows are never updated or deleted.

CREATE TABLE run (
    run_id            TEXT PRIMARY KEY NOT NULL,
    device_id         TEXT NOT NULL,           -- the MCU's 96-bit unique id, 24 hex digits
    serial            TEXT NOT NULL,           -- the unit's serial number ('' when not known)
    station           TEXT NOT NULL,
    head              TEXT NOT NULL,
    operator          TEXT NOT NULL,
    started_unix_s    BIGINT NOT NULL,
    software_version  TEXT NOT NULL,
    firmware_version  TEXT NOT NULL,           -- as the node reports it ('' when not asked)
    g_m_s2            DOUBLE PRECISION NOT NULL,
    g_source          TEXT NOT NULL,           -- e.g. '--g', 'latitude 48.1 height 520 m', 'campaign'
    content_sha256    TEXT NOT NULL
);
CREATE INDEX run_device ON run (device_id, started_unix_s);
CREATE INDEX run_serial ON run (serial, started_unix_s);

CREATE TABLE campaign (
    run_id            TEXT PRIMARY KEY NOT NULL REFERENCES run (run_id),
    campaign_sha256   TEXT NOT NULL,           -- SHA-256 of the campaign's uncompressed bytes
    gzip              BYTEA NOT NULL,           -- the campaign file, gzip-compressed
    stored_unix_s     BIGINT NOT NULL,
    content_sha256    TEXT NOT NULL
);

CREATE TABLE fit (
    run_id            TEXT PRIMARY KEY NOT NULL REFERENCES run (run_id),
    fit_json          TEXT NOT NULL,           -- `fit --json`: terms, coefficients, covariance per channel
    stored_unix_s     BIGINT NOT NULL,
    content_sha256    TEXT NOT NULL
);

CREATE TABLE cal_record (
    run_id            TEXT PRIMARY KEY NOT NULL REFERENCES run (run_id),
    bytes             BYTEA NOT NULL,           -- the calibration record, as flashed
    crc32             BIGINT NOT NULL,         -- the record's own CRC-32 (its last 4 bytes)
    stored_unix_s     BIGINT NOT NULL,
    content_sha256    TEXT NOT NULL
);

CREATE TABLE flash (
    run_id            TEXT PRIMARY KEY NOT NULL REFERENCES cal_record (run_id),
    crc32             BIGINT NOT NULL,
    flashed_unix_s    BIGINT NOT NULL,
    content_sha256    TEXT NOT NULL
);

CREATE TABLE verification (
    run_id            TEXT NOT NULL REFERENCES run (run_id),
    phase             TEXT NOT NULL CHECK (phase IN ('as_found', 'as_left')),
    pass              BOOLEAN NOT NULL,
    report_json       TEXT NOT NULL,           -- `verify --json`
    stored_unix_s     BIGINT NOT NULL,
    content_sha256    TEXT NOT NULL,
    PRIMARY KEY (run_id, phase)
);

CREATE TABLE certificate (
    run_id            TEXT PRIMARY KEY NOT NULL REFERENCES run (run_id),
    html              TEXT NOT NULL,           -- `report`'s page
    stored_unix_s     BIGINT NOT NULL,
    content_sha256    TEXT NOT NULL
);

CREATE TABLE run_end (
    run_id            TEXT PRIMARY KEY NOT NULL REFERENCES run (run_id),
    outcome           TEXT NOT NULL CHECK (outcome IN ('pass', 'rejected')),
    reason            TEXT NOT NULL,
    ended_unix_s      BIGINT NOT NULL,
    content_sha256    TEXT NOT NULL
);

-- Append-only: every update, delete or truncate of a calibration row is refused by the engine.
CREATE FUNCTION accelcal_append_only() RETURNS trigger LANGUAGE plpgsql AS $$
BEGIN
    RAISE EXCEPTION 'append-only: % rows are never %', TG_TABLE_NAME, lower(TG_OP) || 'd';
END;
$$;
CREATE TRIGGER run_append_only BEFORE UPDATE OR DELETE ON run FOR EACH ROW EXECUTE FUNCTION accelcal_append_only();
CREATE TRIGGER run_no_truncate BEFORE TRUNCATE ON run FOR EACH STATEMENT EXECUTE FUNCTION accelcal_append_only();
CREATE TRIGGER campaign_append_only BEFORE UPDATE OR DELETE ON campaign FOR EACH ROW EXECUTE FUNCTION accelcal_append_only();
CREATE TRIGGER campaign_no_truncate BEFORE TRUNCATE ON campaign FOR EACH STATEMENT EXECUTE FUNCTION accelcal_append_only();
CREATE TRIGGER fit_append_only BEFORE UPDATE OR DELETE ON fit FOR EACH ROW EXECUTE FUNCTION accelcal_append_only();
CREATE TRIGGER fit_no_truncate BEFORE TRUNCATE ON fit FOR EACH STATEMENT EXECUTE FUNCTION accelcal_append_only();
CREATE TRIGGER cal_record_append_only BEFORE UPDATE OR DELETE ON cal_record FOR EACH ROW EXECUTE FUNCTION accelcal_append_only();
CREATE TRIGGER cal_record_no_truncate BEFORE TRUNCATE ON cal_record FOR EACH STATEMENT EXECUTE FUNCTION accelcal_append_only();
CREATE TRIGGER flash_append_only BEFORE UPDATE OR DELETE ON flash FOR EACH ROW EXECUTE FUNCTION accelcal_append_only();
CREATE TRIGGER flash_no_truncate BEFORE TRUNCATE ON flash FOR EACH STATEMENT EXECUTE FUNCTION accelcal_append_only();
CREATE TRIGGER verification_append_only BEFORE UPDATE OR DELETE ON verification FOR EACH ROW EXECUTE FUNCTION accelcal_append_only();
CREATE TRIGGER verification_no_truncate BEFORE TRUNCATE ON verification FOR EACH STATEMENT EXECUTE FUNCTION accelcal_append_only();
CREATE TRIGGER certificate_append_only BEFORE UPDATE OR DELETE ON certificate FOR EACH ROW EXECUTE FUNCTION accelcal_append_only();
CREATE TRIGGER certificate_no_truncate BEFORE TRUNCATE ON certificate FOR EACH STATEMENT EXECUTE FUNCTION accelcal_append_only();
CREATE TRIGGER run_end_append_only BEFORE UPDATE OR DELETE ON run_end FOR EACH ROW EXECUTE FUNCTION accelcal_append_only();
CREATE TRIGGER run_end_no_truncate BEFORE TRUNCATE ON run_end FOR EACH STATEMENT EXECUTE FUNCTION accelcal_append_only();
