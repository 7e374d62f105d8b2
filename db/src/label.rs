//! Which serial number a device carries, and the refusals that keep the two tied one to one.
//!
//! A device's label is the serial of its latest labelling: a run begun with a serial (a voided
//! run does not count) or a relabel row, whichever is later (a relabel at the same second
//! wins). A new run is refused when its serial is another device's label, or when its device is
//! labelled with another serial, unless the operator relabels on purpose: then one relabel row
//! per device changed is appended with the reason (the serial moves to this device; a device
//! that carried it is left without one, found by its device id), in the run's own transaction.

use serde::Serialize;

use super::chain::{self, relabel_content};
use super::engine::{Tx, Val};
use super::{now_unix_s, sha256_hex, DbError};

/// A device's current serial and where it comes from.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Label {
    /// The device id.
    pub device_id: String,
    /// Its serial (empty: the label was taken off).
    pub serial: String,
    /// Since when, Unix seconds.
    pub since_unix_s: i64,
    /// What labelled it: `run RUN_ID` or `relabel: REASON`.
    pub by: String,
}

/// A relabel to store with a new run.
#[derive(Clone, Debug, PartialEq)]
pub struct Relabel {
    /// Why (stored with the row).
    pub reason: String,
    /// Who.
    pub operator: String,
}

/// Why a new run's serial or device was refused.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum LabelClash {
    /// The serial is another device's.
    #[error(
        "serial {serial} is device {other} in the database (since {}, {}), not this node's device {device}: check the unit's label; to move the serial to this device on purpose, relabel it with a reason (--relabel REASON)",
        utc(other_label.since_unix_s), other_label.by
    )]
    SerialOfAnother {
        /// The serial given.
        serial: String,
        /// This run's device.
        device: String,
        /// The device that carries the serial.
        other: String,
        /// Its label.
        other_label: Label,
    },
    /// The device carries another serial.
    #[error(
        "device {device} is unit {} in the database (since {}, {}), not {serial}: give its serial, or relabel it on purpose with a reason (--relabel REASON)",
        label.serial, utc(label.since_unix_s), label.by
    )]
    DeviceIsAnother {
        /// The device.
        device: String,
        /// The serial given.
        serial: String,
        /// Its label.
        label: Label,
    },
    /// A relabel was asked for where nothing clashes.
    #[error("nothing to relabel: device {device} is unit {serial} already and no other device carries that serial")]
    NothingToRelabel {
        /// The device.
        device: String,
        /// Its serial.
        serial: String,
    },
}

impl accelcal_core::error::Classify for LabelClash {
    fn kind(&self) -> accelcal_core::error::Kind {
        accelcal_core::error::Kind::BadInput
    }
}

/// A time for messages, UTC.
fn utc(unix_s: i64) -> String {
    accelcal_core::output::utc_date_time(unix_s)
}

/// The label of `device`, if it ever had one.
pub fn current(tx: &mut Tx<'_>, device: &str) -> Result<Option<Label>, DbError> {
    let d = Val::from(device.to_string());
    let run = tx.query(
        "SELECT serial, started_unix_s, run_id FROM run WHERE device_id = $1 AND serial <> '' \
         AND run_id NOT IN (SELECT run_id FROM void) ORDER BY started_unix_s DESC, run_id DESC LIMIT 1",
        std::slice::from_ref(&d),
    )?;
    let relabel = tx.query(
        "SELECT new_serial, relabelled_unix_s, reason FROM relabel WHERE device_id = $1 \
         ORDER BY relabelled_unix_s DESC, relabel_id DESC LIMIT 1",
        std::slice::from_ref(&d),
    )?;
    let run = run.first().map(|r| -> Result<Label, DbError> {
        Ok(Label {
            device_id: device.into(),
            serial: r[0].text()?,
            since_unix_s: r[1].int()?,
            by: format!("run {}", r[2].text()?),
        })
    });
    let relabel = relabel.first().map(|r| -> Result<Label, DbError> {
        Ok(Label {
            device_id: device.into(),
            serial: r[0].text()?,
            since_unix_s: r[1].int()?,
            by: format!("relabelled: {}", r[2].text()?),
        })
    });
    Ok(match (run.transpose()?, relabel.transpose()?) {
        (Some(a), Some(b)) => Some(if b.since_unix_s >= a.since_unix_s { b } else { a }),
        (a, b) => a.or(b),
    })
}

/// The devices whose label is `serial` now.
pub fn devices_labelled(tx: &mut Tx<'_>, serial: &str) -> Result<Vec<Label>, DbError> {
    let s = Val::from(serial.to_string());
    let mut ever: Vec<String> = tx
        .query(
            "SELECT DISTINCT device_id FROM run WHERE serial = $1 \
             UNION SELECT DISTINCT device_id FROM relabel WHERE new_serial = $1",
            std::slice::from_ref(&s),
        )?
        .iter()
        .map(|r| r[0].text())
        .collect::<Result<_, _>>()?;
    ever.sort();
    let mut out = Vec::new();
    for d in ever {
        if let Some(l) = current(tx, &d)? {
            if l.serial == serial {
                out.push(l);
            }
        }
    }
    Ok(out)
}

/// The devices that ever carried `serial` (runs voided or not, relabels).
pub fn devices_ever(tx: &mut Tx<'_>, serial: &str) -> Result<Vec<String>, DbError> {
    let mut v: Vec<String> = tx
        .query(
            "SELECT DISTINCT device_id FROM run WHERE serial = $1 \
             UNION SELECT DISTINCT device_id FROM relabel WHERE new_serial = $1 OR old_serial = $1",
            &[serial.to_string().into()],
        )?
        .iter()
        .map(|r| r[0].text())
        .collect::<Result<_, _>>()?;
    v.sort();
    Ok(v)
}

/// Checks a new run's device and serial against the labels (in the run's transaction) and, when
/// `relabel` says so, appends the relabel rows.
pub fn check_new_run(
    tx: &mut Tx<'_>,
    device: &str,
    serial: &str,
    relabel: Option<&Relabel>,
) -> Result<(), DbError> {
    if serial.is_empty() {
        return Ok(());
    }
    let label = current(tx, device)?;
    let own = label.clone().filter(|l| l.serial != serial && !l.serial.is_empty());
    let others: Vec<Label> =
        devices_labelled(tx, serial)?.into_iter().filter(|l| l.device_id != device).collect();
    let Some(r) = relabel else {
        if let Some(o) = others.into_iter().next() {
            return Err(DbError::Label(Box::new(LabelClash::SerialOfAnother {
                serial: serial.into(),
                device: device.into(),
                other: o.device_id.clone(),
                other_label: o,
            })));
        }
        if let Some(l) = own {
            return Err(DbError::Label(Box::new(LabelClash::DeviceIsAnother {
                device: device.into(),
                serial: serial.into(),
                label: l,
            })));
        }
        return Ok(());
    };
    if own.is_none() && others.is_empty() {
        return Err(DbError::Label(Box::new(LabelClash::NothingToRelabel {
            device: device.into(),
            serial: serial.into(),
        })));
    }
    let old = label.map(|l| l.serial).unwrap_or_default();
    insert(tx, device, &old, serial, r)?;
    for o in others {
        insert(tx, &o.device_id, serial, "", r)?;
    }
    Ok(())
}

/// Appends one relabel row and its ledger entry.
fn insert(tx: &mut Tx<'_>, device: &str, old: &str, new: &str, r: &Relabel) -> Result<(), DbError> {
    let row: Vec<Val> = vec![
        uuid::Uuid::new_v4().hyphenated().to_string().into(),
        device.to_string().into(),
        old.to_string().into(),
        new.to_string().into(),
        r.reason.clone().into(),
        r.operator.clone().into(),
        now_unix_s().into(),
        sha256_hex(relabel_content(device, old, new, &r.reason).as_bytes()).into(),
    ];
    super::insert_row(tx, chain::table("relabel"), &row)
}
