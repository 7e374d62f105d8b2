-- The calibration database, version 3 (PostgreSQL): the line's registered reference equipment and
-- the runs that used it. The same tables, columns and keys as ../sqlite/V3__assets.sql.
--
-- `asset`: one row per calibration certificate of a reference (a dividing head, a thermometer,
-- a gravity value): the asset recalibrated is registered again with its new certificate, and the
-- row registered last is the one in force. A head's row states the uncertainties the budget
-- takes from it (`fit`'s --head-angle-u and --head-orthogonality-u, arcseconds, one sigma); the
-- other kinds hold 0 there. Its ledger entry is not a run's (`run_id` '', piece
-- `asset:ID:CERTIFICATE`), chained to the ledger's latest entry, as a relabel is.
--
-- `run_asset`: the asset (and which of its certificates) a run was calibrated with, one per kind:
-- what `accelcal affected ASSET --since DATE` reads back when an asset is found out of tolerance.

CREATE TABLE asset (
    asset_id                TEXT NOT NULL,
    certificate             TEXT NOT NULL,      -- the asset's own calibration certificate number
    kind                    TEXT NOT NULL CHECK (kind IN ('head', 'thermometer', 'gravity')),
    due_date                TEXT NOT NULL,      -- YYYY-MM-DD: the last day it may be used
    angle_u_arcsec          DOUBLE PRECISION NOT NULL, -- head: one-sigma setting error of each angle (0 otherwise)
    orthogonality_u_arcsec  DOUBLE PRECISION NOT NULL, -- head: one-sigma of each axis rotation (0 otherwise)
    operator                TEXT NOT NULL,
    registered_unix_s       BIGINT NOT NULL,
    content_sha256          TEXT NOT NULL,
    PRIMARY KEY (asset_id, certificate)
);

CREATE TABLE run_asset (
    run_id                  TEXT NOT NULL REFERENCES run (run_id),
    kind                    TEXT NOT NULL CHECK (kind IN ('head', 'thermometer', 'gravity')),
    asset_id                TEXT NOT NULL,
    certificate             TEXT NOT NULL,
    stored_unix_s           BIGINT NOT NULL,
    content_sha256          TEXT NOT NULL,
    PRIMARY KEY (run_id, kind),
    FOREIGN KEY (asset_id, certificate) REFERENCES asset (asset_id, certificate)
);
CREATE INDEX run_asset_asset ON run_asset (asset_id);

CREATE TRIGGER asset_append_only BEFORE UPDATE OR DELETE ON asset FOR EACH ROW EXECUTE FUNCTION accelcal_append_only();
CREATE TRIGGER asset_no_truncate BEFORE TRUNCATE ON asset FOR EACH STATEMENT EXECUTE FUNCTION accelcal_append_only();
CREATE TRIGGER run_asset_append_only BEFORE UPDATE OR DELETE ON run_asset FOR EACH ROW EXECUTE FUNCTION accelcal_append_only();
CREATE TRIGGER run_asset_no_truncate BEFORE TRUNCATE ON run_asset FOR EACH STATEMENT EXECUTE FUNCTION accelcal_append_only();
