-- The calibration database, version 11 (SQLite): a reference's own value (issue 59, "g is a
-- reference like the head"). The same columns as ../postgres/V11__asset_value.sql.
--
-- A gravity asset's certificate (a survey of the site) states the value of g there and its
-- standard uncertainty, in SI units (m/s²): `value_si` and `value_u_si`. Other kinds, and every
-- row registered before this version, hold NULL; a row's `content_sha256` covers the two only
-- when they are stated, so the rows before keep their hashes.

ALTER TABLE asset ADD COLUMN value_si DOUBLE PRECISION;
ALTER TABLE asset ADD COLUMN value_u_si DOUBLE PRECISION;
