-- The calibration database, version 4 (SQLite): certificate numbers. The same table, columns and
-- keys as ../postgres/V4__certificate_number.sql.
--
-- `certificate_number`: the number of a run's certificate (ISO/IEC 17025 §7.8.2.1: a unique
-- identification), given when `report --db --run-id` first prints it and the same every time the
-- run's certificate is printed again. `sequence` counts over the whole database (1, 2, ...): it is
-- the largest one plus one, and a row is never updated or deleted, so no number is ever given
-- twice, even when its run is later voided. `number` is YEAR-SEQUENCE (`2026-000017`), the year
-- of issue in UTC.

CREATE TABLE certificate_number (
    run_id            TEXT PRIMARY KEY NOT NULL REFERENCES run (run_id),
    sequence          BIGINT NOT NULL UNIQUE,
    number            TEXT NOT NULL UNIQUE,
    issued_unix_s     BIGINT NOT NULL,
    content_sha256    TEXT NOT NULL
);

CREATE TRIGGER certificate_number_no_update BEFORE UPDATE ON certificate_number BEGIN SELECT RAISE(ABORT, 'append-only: certificate_number rows are never updated'); END;
CREATE TRIGGER certificate_number_no_delete BEFORE DELETE ON certificate_number BEGIN SELECT RAISE(ABORT, 'append-only: certificate_number rows are never deleted'); END;
