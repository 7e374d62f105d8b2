-- The calibration database, version 8 (SQLite): the chain's own events, and (SQLite) no row
-- replaced behind the append-only triggers. The same tables, columns and keys as
-- ../postgres/V8__chain_event_no_replace.sql.
--
-- `chain_event`: what happened to the chain itself, chained like any row (`run_id` '' in the
-- ledger): today only `legacy-seal`, the one-time sealing of rows written before the ledger
-- existed (schema 1), with how many rows it chained. A database whose rows were sealed late says
-- so in `db verify`, and a ledger emptied behind accelcal's back is never sealed again.
--
-- `INSERT OR REPLACE` / `REPLACE INTO` deletes the row it replaces without firing the delete
-- triggers (SQLite fires them only with recursive triggers on): each table refuses an insert
-- whose key is taken, before the conflict is resolved. `device_certificate` is rewritten by
-- accelcal (delete, then insert), so it is checked by `db verify` instead.

CREATE TABLE chain_event (
    event_id          TEXT PRIMARY KEY NOT NULL,   -- a UUID
    kind              TEXT NOT NULL,               -- legacy-seal
    detail            TEXT NOT NULL,
    unix_s            BIGINT NOT NULL,
    content_sha256    TEXT NOT NULL
);
CREATE TRIGGER chain_event_no_update BEFORE UPDATE ON chain_event BEGIN SELECT RAISE(ABORT, 'append-only: chain_event rows are never updated'); END;
CREATE TRIGGER chain_event_no_delete BEFORE DELETE ON chain_event BEGIN SELECT RAISE(ABORT, 'append-only: chain_event rows are never deleted'); END;

CREATE TRIGGER run_no_replace BEFORE INSERT ON run WHEN EXISTS (SELECT 1 FROM run WHERE run_id = NEW.run_id) BEGIN SELECT RAISE(ABORT, 'append-only: run rows are never replaced'); END;
CREATE TRIGGER campaign_no_replace BEFORE INSERT ON campaign WHEN EXISTS (SELECT 1 FROM campaign WHERE run_id = NEW.run_id) BEGIN SELECT RAISE(ABORT, 'append-only: campaign rows are never replaced'); END;
CREATE TRIGGER fit_no_replace BEFORE INSERT ON fit WHEN EXISTS (SELECT 1 FROM fit WHERE run_id = NEW.run_id) BEGIN SELECT RAISE(ABORT, 'append-only: fit rows are never replaced'); END;
CREATE TRIGGER cal_record_no_replace BEFORE INSERT ON cal_record WHEN EXISTS (SELECT 1 FROM cal_record WHERE run_id = NEW.run_id) BEGIN SELECT RAISE(ABORT, 'append-only: cal_record rows are never replaced'); END;
CREATE TRIGGER flash_no_replace BEFORE INSERT ON flash WHEN EXISTS (SELECT 1 FROM flash WHERE run_id = NEW.run_id) BEGIN SELECT RAISE(ABORT, 'append-only: flash rows are never replaced'); END;
CREATE TRIGGER verification_no_replace BEFORE INSERT ON verification WHEN EXISTS (SELECT 1 FROM verification WHERE run_id = NEW.run_id AND phase = NEW.phase) BEGIN SELECT RAISE(ABORT, 'append-only: verification rows are never replaced'); END;
CREATE TRIGGER certificate_no_replace BEFORE INSERT ON certificate WHEN EXISTS (SELECT 1 FROM certificate WHERE run_id = NEW.run_id) BEGIN SELECT RAISE(ABORT, 'append-only: certificate rows are never replaced'); END;
CREATE TRIGGER run_end_no_replace BEFORE INSERT ON run_end WHEN EXISTS (SELECT 1 FROM run_end WHERE run_id = NEW.run_id) BEGIN SELECT RAISE(ABORT, 'append-only: run_end rows are never replaced'); END;
CREATE TRIGGER void_no_replace BEFORE INSERT ON void WHEN EXISTS (SELECT 1 FROM void WHERE run_id = NEW.run_id) BEGIN SELECT RAISE(ABORT, 'append-only: void rows are never replaced'); END;
CREATE TRIGGER relabel_no_replace BEFORE INSERT ON relabel WHEN EXISTS (SELECT 1 FROM relabel WHERE relabel_id = NEW.relabel_id) BEGIN SELECT RAISE(ABORT, 'append-only: relabel rows are never replaced'); END;
CREATE TRIGGER asset_no_replace BEFORE INSERT ON asset WHEN EXISTS (SELECT 1 FROM asset WHERE asset_id = NEW.asset_id AND certificate = NEW.certificate) BEGIN SELECT RAISE(ABORT, 'append-only: asset rows are never replaced'); END;
CREATE TRIGGER run_asset_no_replace BEFORE INSERT ON run_asset WHEN EXISTS (SELECT 1 FROM run_asset WHERE run_id = NEW.run_id AND kind = NEW.kind) BEGIN SELECT RAISE(ABORT, 'append-only: run_asset rows are never replaced'); END;
CREATE TRIGGER certificate_number_no_replace BEFORE INSERT ON certificate_number WHEN EXISTS (SELECT 1 FROM certificate_number WHERE run_id = NEW.run_id) BEGIN SELECT RAISE(ABORT, 'append-only: certificate_number rows are never replaced'); END;
CREATE TRIGGER recalibration_due_no_replace BEFORE INSERT ON recalibration_due WHEN EXISTS (SELECT 1 FROM recalibration_due WHERE run_id = NEW.run_id) BEGIN SELECT RAISE(ABORT, 'append-only: recalibration_due rows are never replaced'); END;
CREATE TRIGGER ledger_no_replace BEFORE INSERT ON ledger WHEN EXISTS (SELECT 1 FROM ledger WHERE seq = NEW.seq) BEGIN SELECT RAISE(ABORT, 'append-only: ledger rows are never replaced'); END;
CREATE TRIGGER fit_summary_no_replace BEFORE INSERT ON fit_summary WHEN EXISTS (SELECT 1 FROM fit_summary WHERE run_id = NEW.run_id) BEGIN SELECT RAISE(ABORT, 'append-only: fit_summary rows are never replaced'); END;
CREATE TRIGGER fit_parameter_no_replace BEFORE INSERT ON fit_parameter WHEN EXISTS (SELECT 1 FROM fit_parameter WHERE run_id = NEW.run_id AND ord = NEW.ord) BEGIN SELECT RAISE(ABORT, 'append-only: fit_parameter rows are never replaced'); END;
CREATE TRIGGER verification_summary_no_replace BEFORE INSERT ON verification_summary WHEN EXISTS (SELECT 1 FROM verification_summary WHERE run_id = NEW.run_id AND phase = NEW.phase) BEGIN SELECT RAISE(ABORT, 'append-only: verification_summary rows are never replaced'); END;
CREATE TRIGGER verification_parameter_no_replace BEFORE INSERT ON verification_parameter WHEN EXISTS (SELECT 1 FROM verification_parameter WHERE run_id = NEW.run_id AND phase = NEW.phase AND ord = NEW.ord) BEGIN SELECT RAISE(ABORT, 'append-only: verification_parameter rows are never replaced'); END;
CREATE TRIGGER head_observation_no_replace BEFORE INSERT ON head_observation WHEN EXISTS (SELECT 1 FROM head_observation WHERE run_id = NEW.run_id) BEGIN SELECT RAISE(ABORT, 'append-only: head_observation rows are never replaced'); END;
CREATE TRIGGER head_observation_f32_no_replace BEFORE INSERT ON head_observation_f32 WHEN EXISTS (SELECT 1 FROM head_observation_f32 WHERE run_id = NEW.run_id) BEGIN SELECT RAISE(ABORT, 'append-only: head_observation_f32 rows are never replaced'); END;
CREATE TRIGGER chain_event_no_replace BEFORE INSERT ON chain_event WHEN EXISTS (SELECT 1 FROM chain_event WHERE event_id = NEW.event_id) BEGIN SELECT RAISE(ABORT, 'append-only: chain_event rows are never replaced'); END;
