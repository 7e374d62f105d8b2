//! The documents the tool writes and reads back, typed once: each is a serde type that its writer
//! fills and every reader parses, so a field's name and meaning are stated in one place.
//!
//! - [`FitDoc`]: `fit --json`, read by `verify --fit`, `report --fit`, `record show --fit`, the
//!   database's `store_fit`, `history` and `fleet`.
//! - [`SelectDoc`]: `select --json`, read by the station (whether the node can apply the
//!   selection).
//! - [`InfoDoc`]: `info --json`, read by the station (the node's device, firmware and record in
//!   force).
//! - [`verify::VerifyReport`]: `verify --json`, read by `report --verify`, the station and the
//!   database.
//!
//! A reader is lenient where older writers were: a field a reader does not need may be missing
//! (serde defaults), and a fit written before fits carried the unit's identity reads with
//! `identity: None` ([`FitDoc::identity`]; [`crate::campaign::identity::Identity::of_fit_json`]
//! refuses it where the identity is needed).
//!
//! Each document carries a `version` ([`FIT_VERSION`], [`SELECT_VERSION`], [`INFO_VERSION`],
//! [`VERIFY_VERSION`]); every reader goes through its type's `parse` (or
//! [`verify::VerifyReport::read`]), which takes 0 (written before versions) up to its own and
//! refuses a later one ([`check_version`]). The station's journal is typed in
//! `accelcal_line::station` and read at its own version only.

pub mod verify;

use serde::{Deserialize, Serialize};

use crate::campaign::identity::Identity;
use crate::uncertainty::UncertaintyJson;

/// The version of `fit --json` this build writes. Every document carries its `version`; a reader
/// takes each version up to the one it writes (0: a document written before documents carried
/// one) and refuses a later one, which a newer accelcal wrote.
pub const FIT_VERSION: u32 = 1;
/// The version of `select --json` this build writes (see [`FIT_VERSION`]).
pub const SELECT_VERSION: u32 = 1;
/// The version of `info --json` this build writes (see [`FIT_VERSION`]).
pub const INFO_VERSION: u32 = 1;
/// The version of `verify --json` this build writes (see [`FIT_VERSION`];
/// [`verify::VerifyReport`]).
pub const VERIFY_VERSION: u32 = 1;

/// Refuses a document of a later version than this build reads.
pub fn check_version(what: &str, version: u32, known: u32) -> Result<(), serde_json::Error> {
    if version > known {
        return Err(<serde_json::Error as serde::de::Error>::custom(format!(
            "{what}'s JSON document is version {version}, written by a newer accelcal (this one reads versions up to {known})"
        )));
    }
    Ok(())
}

/// One channel of a fit: its terms, their coefficients and the coefficients' statistics.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FitChannelDoc {
    /// The channel's name (the campaign's column).
    pub channel: String,
    /// The terms of its model, in order (`1`, `ax`, …, `t`).
    pub terms: Vec<String>,
    /// The coefficient of each term (codes per the term's unit).
    pub coefficients: Vec<f64>,
    /// The standard error of each coefficient (`null`: not finite).
    #[serde(default)]
    pub std_errors: Vec<Option<f64>>,
    /// The coefficients' covariance matrix, row by row in term order (codes² per units of the two
    /// terms); `verify --fit` propagates it.
    #[serde(default)]
    pub covariance: Vec<Vec<Option<f64>>>,
    /// The condition number of the least-squares problem (`null` for test turns).
    #[serde(default)]
    pub condition: Option<f64>,
    /// The residual RMS of the dwell means, codes.
    #[serde(default)]
    pub rms_codes: Option<f64>,
}

impl FitChannelDoc {
    /// The index of `term` among the channel's terms.
    pub fn term_index(&self, term: &str) -> Option<usize> {
        self.terms.iter().position(|t| t == term)
    }

    /// The coefficient of `term`.
    pub fn coefficient(&self, term: &str) -> Option<f64> {
        self.coefficients.get(self.term_index(term)?).copied()
    }

    /// The standard error of `term`'s coefficient, when finite.
    pub fn std_error(&self, term: &str) -> Option<f64> {
        self.std_errors.get(self.term_index(term)?).copied().flatten().filter(|v| v.is_finite())
    }

    /// The variance of `term`'s coefficient from the covariance's diagonal, when stated.
    pub fn variance(&self, term: &str) -> Option<f64> {
        let i = self.term_index(term)?;
        self.covariance.get(i)?.get(i).copied().flatten()
    }
}

/// `fit --json`: the method, the unit's identity, each channel's fit and, for a model-4 triad
/// fitted by least squares, the uncertainty budget. The field order is the document's.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FitDoc {
    /// [`FIT_VERSION`] (0: written before documents carried a version).
    #[serde(default)]
    pub version: u32,
    /// `lsq` or `test-turns`.
    pub method: String,
    /// Whose fit it is: device id, serial, g, the campaign's hash, the record's CRC (`None` in a
    /// fit written before fits carried it).
    #[serde(flatten)]
    pub identity: Option<Identity>,
    /// The reference temperature of the terms in `t` (°C), when a fit has one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub t_ref_c: Option<f64>,
    /// Each channel's fit.
    pub channels: Vec<FitChannelDoc>,
    /// The uncertainty budget of a model-4 triad fitted by least squares.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub uncertainty: Option<UncertaintyJson>,
}

impl FitDoc {
    /// Parses a fit document; the error is serde's, which names the field and its place.
    pub fn parse(text: &str) -> Result<FitDoc, serde_json::Error> {
        let doc: FitDoc = serde_json::from_str(text)?;
        check_version("fit", doc.version, FIT_VERSION)?;
        Ok(doc)
    }

    /// The channel named `name`.
    pub fn channel(&self, name: &str) -> Option<&FitChannelDoc> {
        self.channels.iter().find(|c| c.channel == name)
    }
}

/// One candidate model of a selection.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CandidateDoc {
    /// Its terms.
    pub terms: Vec<String>,
    /// Its criterion, codes (`null`: not identifiable, or not finite).
    pub criterion: Option<f64>,
    /// Whether the plan and split identify it.
    pub identifiable: bool,
}

/// The model a selection chose.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SelectedDoc {
    /// Its terms.
    pub terms: Vec<String>,
    /// Its coefficients fitted on all positions.
    pub coefficients: Vec<f64>,
    /// Its criterion, codes.
    pub criterion: f64,
}

/// One channel's selection.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SelectChannelDoc {
    /// The channel.
    pub channel: String,
    /// The model chosen.
    pub selected: SelectedDoc,
    /// The best criterion of any candidate, codes.
    pub best_criterion: f64,
    /// How many candidates were searched.
    pub candidates_total: usize,
    /// How long the search took, s.
    pub search_seconds: f64,
    /// Candidates per second.
    pub models_per_second: f64,
    /// How many candidates the plan and split do not identify.
    pub unidentifiable: usize,
    /// The candidates listed (all, or the best `--top`).
    pub candidates: Vec<CandidateDoc>,
}

/// `select --json`: the basis, criterion, split and tolerance of the selection, and each
/// channel's.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SelectDoc {
    /// [`SELECT_VERSION`] (0: written before documents carried a version).
    #[serde(default)]
    pub version: u32,
    /// The candidate basis (`paper`, `linear`, …).
    pub basis: String,
    /// The external criterion.
    pub criterion: crate::gmdh::Criterion,
    /// The split (`null` for leave-one-out, which has none).
    pub split: Option<String>,
    /// The tolerance of "simplest within", codes.
    pub tolerance: f64,
    /// Each channel's selection.
    pub channels: Vec<SelectChannelDoc>,
}

/// The record a node runs, as `info --json` (and a verification's `record`) states it (the fields
/// in the order of their names).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RecordInForceDoc {
    /// The record's creation time, seconds since the Unix epoch.
    pub created_unix_s: u64,
    /// Its CRC-32, 8 lower-case hex digits.
    pub crc: String,
    /// The slot's write sequence number.
    pub sequence: u32,
    /// The record slot it was read from (0 or 1).
    pub slot: u8,
}

impl RecordInForceDoc {
    /// The record `r` a node reports, or `None` when it runs none.
    pub fn of(r: accelcal_shared::wire::RecordStatus) -> Option<RecordInForceDoc> {
        match r {
            accelcal_shared::wire::RecordStatus::InUse { slot, sequence, created_unix_s, crc } => {
                Some(RecordInForceDoc { slot, sequence, created_unix_s, crc: format!("{crc:08x}") })
            }
            accelcal_shared::wire::RecordStatus::Missing(_) => None,
        }
    }
}

/// `info --json`: who the node is and what it runs (the field names are an interface; the
/// fields in the order of their names, as the document has always been written).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct InfoDoc {
    /// [`INFO_VERSION`] (0: written before documents carried a version).
    #[serde(default)]
    pub version: u32,
    /// The MCU's unique id, 24 lower-case hex digits.
    pub device_id: String,
    /// The firmware's version, `major.minor.patch`.
    pub firmware: String,
    /// Sample sets lost since boot.
    pub overruns: u32,
    /// The sampling rate, Hz per channel.
    pub rate_hz: u32,
    /// The record in force (`null`: none).
    pub record: Option<RecordInForceDoc>,
    /// The cause of the last reset (`PowerOn`, `IndependentWatchdog`, …).
    pub reset_cause: String,
}

impl SelectDoc {
    /// Parses a selection document (see [`FitDoc::parse`]).
    pub fn parse(text: &str) -> Result<SelectDoc, serde_json::Error> {
        let doc: SelectDoc = serde_json::from_str(text)?;
        check_version("select", doc.version, SELECT_VERSION)?;
        Ok(doc)
    }
}

impl InfoDoc {
    /// Parses a node's `info --json` (see [`FitDoc::parse`]).
    pub fn parse(text: &str) -> Result<InfoDoc, serde_json::Error> {
        let doc: InfoDoc = serde_json::from_str(text)?;
        check_version("info", doc.version, INFO_VERSION)?;
        Ok(doc)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn doc() -> serde_json::Value {
        serde_json::json!({
            "version": 1,
            "method": "lsq",
            "device_id": "51454d552d422d4c34373545",
            "serial": "A-1",
            "g_m_s2": 9.81,
            "campaign_sha256": "ab",
            "record_crc": null,
            "channels": [{
                "channel": "x",
                "terms": ["1", "ax", "ay", "az"],
                "coefficients": [32768.0, 1670.0, 1.0, -2.0],
                "std_errors": [0.5, null, 0.1, 0.1],
                "covariance": [[0.25, 0.0, 0.0, 0.0], [0.0, null, 0.0, 0.0], [0.0, 0.0, 0.01, 0.0], [0.0, 0.0, 0.0, 0.01]],
                "condition": 1.5,
                "rms_codes": 2.0
            }]
        })
    }

    #[test]
    fn a_fit_document_reads_and_writes_back_the_same() {
        let v = doc();
        let d = FitDoc::parse(&v.to_string()).unwrap();
        assert_eq!(d.identity.as_ref().unwrap().serial.as_deref(), Some("A-1"));
        let x = d.channel("x").unwrap();
        assert_eq!(x.coefficient("ax"), Some(1670.0));
        assert_eq!(x.std_error("1"), Some(0.5));
        assert_eq!(x.std_error("ax"), None);
        assert_eq!(x.variance("ay"), Some(0.01));
        assert_eq!(x.variance("ax"), None);
        assert_eq!(serde_json::to_value(&d).unwrap(), v);
    }

    #[test]
    fn a_fit_without_identity_reads_and_one_without_channels_does_not() {
        let mut v = doc();
        for k in ["device_id", "serial", "g_m_s2", "campaign_sha256", "record_crc"] {
            v.as_object_mut().unwrap().remove(k);
        }
        assert_eq!(FitDoc::parse(&v.to_string()).unwrap().identity, None);
        v.as_object_mut().unwrap().remove("channels");
        let e = FitDoc::parse(&v.to_string()).unwrap_err().to_string();
        assert!(e.contains("missing field `channels`"), "{e}");
    }

    /// A document without a version was written before documents carried one: it reads as 0. A
    /// later version than this build writes is refused, by each document's reader.
    #[test]
    fn a_document_of_a_later_version_is_refused_and_one_without_reads() {
        let mut v = doc();
        v.as_object_mut().unwrap().remove("version");
        assert_eq!(FitDoc::parse(&v.to_string()).unwrap().version, 0);
        v["version"] = (FIT_VERSION + 1).into();
        let e = FitDoc::parse(&v.to_string()).unwrap_err().to_string();
        assert!(
            e.contains(
                "fit's JSON document is version 2, written by a newer accelcal (this one reads versions up to 1)"
            ),
            "{e}"
        );
        let select = serde_json::json!({
            "version": SELECT_VERSION + 1, "basis": "paper", "criterion": "regularity",
            "split": "alternate", "tolerance": 1.0, "channels": []
        });
        let e = SelectDoc::parse(&select.to_string()).unwrap_err().to_string();
        assert!(e.contains("select's JSON document is version 2"), "{e}");
        let info = serde_json::json!({
            "version": INFO_VERSION + 1, "device_id": "51454d552d422d4c34373545", "firmware": "0.1.0",
            "overruns": 0, "rate_hz": 1000, "record": null, "reset_cause": "power-on"
        });
        let e = InfoDoc::parse(&info.to_string()).unwrap_err().to_string();
        assert!(e.contains("info's JSON document is version 2"), "{e}");
    }
}
