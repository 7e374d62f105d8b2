-- The calibration database, version 12 (PostgreSQL): recalls (issue 59). The same tables,
-- columns and keys as ../sqlite/V12__recall.sql, which says what they hold.

CREATE TABLE asset_found_bad (
    asset_id          TEXT NOT NULL,
    certificate       TEXT NOT NULL,
    since_date        TEXT NOT NULL,      -- YYYY-MM-DD: the runs from this day on are affected
    reason            TEXT NOT NULL,
    operator          TEXT NOT NULL,
    recorded_unix_s   BIGINT NOT NULL,
    content_sha256    TEXT NOT NULL,
    PRIMARY KEY (asset_id, certificate),
    FOREIGN KEY (asset_id, certificate) REFERENCES asset (asset_id, certificate)
);

CREATE TABLE recall_dismissal (
    asset_id          TEXT NOT NULL,
    certificate       TEXT NOT NULL,
    device_id         TEXT NOT NULL,
    serial            TEXT NOT NULL,
    reason            TEXT NOT NULL,
    operator          TEXT NOT NULL,
    dismissed_unix_s  BIGINT NOT NULL,
    content_sha256    TEXT NOT NULL,
    PRIMARY KEY (asset_id, certificate, device_id),
    FOREIGN KEY (asset_id, certificate) REFERENCES asset_found_bad (asset_id, certificate)
);

CREATE TRIGGER asset_found_bad_append_only BEFORE UPDATE OR DELETE ON asset_found_bad FOR EACH ROW EXECUTE FUNCTION accelcal_append_only();
CREATE TRIGGER asset_found_bad_no_truncate BEFORE TRUNCATE ON asset_found_bad FOR EACH STATEMENT EXECUTE FUNCTION accelcal_append_only();
CREATE TRIGGER recall_dismissal_append_only BEFORE UPDATE OR DELETE ON recall_dismissal FOR EACH ROW EXECUTE FUNCTION accelcal_append_only();
CREATE TRIGGER recall_dismissal_no_truncate BEFORE TRUNCATE ON recall_dismissal FOR EACH STATEMENT EXECUTE FUNCTION accelcal_append_only();
