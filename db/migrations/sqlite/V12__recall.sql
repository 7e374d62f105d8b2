-- The calibration database, version 12 (SQLite): recalls (issue 59). The same tables, columns and
-- keys as ../postgres/V12__recall.sql.
--
-- `asset_found_bad`: a reference found out of tolerance at its own recalibration (`accelcal asset
-- found-bad`): the asset and the certificate of its own that it was used under (the period the
-- finding covers), the first day (UTC, YYYY-MM-DD) from which the runs on it are in doubt
-- (`since_date`), why, who and when. One per certificate of an asset: the runs that used the
-- asset under that certificate and began on or after that day are affected (`accelcal
-- affected`). Its ledger entry belongs to no run (`run_id` '', piece
-- `asset_found_bad:ID:CERTIFICATE`), chained to the ledger's latest entry, as an asset's is.
--
-- `recall_dismissal`: a unit whose runs a finding affects, reviewed and found to need no recall
-- (`accelcal affected ID --dismiss SERIAL --reason TEXT`): the finding (its asset and
-- certificate), the unit's device id and its serial, why, who and when. One per finding and unit.
-- Its ledger entry belongs to no run either (piece `recall_dismissal:ID:CERTIFICATE:DEVICE`).

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

CREATE TRIGGER asset_found_bad_no_update BEFORE UPDATE ON asset_found_bad BEGIN SELECT RAISE(ABORT, 'append-only: asset_found_bad rows are never updated'); END;
CREATE TRIGGER asset_found_bad_no_delete BEFORE DELETE ON asset_found_bad BEGIN SELECT RAISE(ABORT, 'append-only: asset_found_bad rows are never deleted'); END;
CREATE TRIGGER asset_found_bad_no_replace BEFORE INSERT ON asset_found_bad WHEN EXISTS (SELECT 1 FROM asset_found_bad WHERE asset_id = NEW.asset_id AND certificate = NEW.certificate) BEGIN SELECT RAISE(ABORT, 'append-only: asset_found_bad rows are never replaced'); END;
CREATE TRIGGER recall_dismissal_no_update BEFORE UPDATE ON recall_dismissal BEGIN SELECT RAISE(ABORT, 'append-only: recall_dismissal rows are never updated'); END;
CREATE TRIGGER recall_dismissal_no_delete BEFORE DELETE ON recall_dismissal BEGIN SELECT RAISE(ABORT, 'append-only: recall_dismissal rows are never deleted'); END;
CREATE TRIGGER recall_dismissal_no_replace BEFORE INSERT ON recall_dismissal WHEN EXISTS (SELECT 1 FROM recall_dismissal WHERE asset_id = NEW.asset_id AND certificate = NEW.certificate AND device_id = NEW.device_id) BEGIN SELECT RAISE(ABORT, 'append-only: recall_dismissal rows are never replaced'); END;
