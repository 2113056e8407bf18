//! JSON records that carry a CRC-32 of their own content (the field `crc32`).
//!
//! The segments are MCAP with checked chunks, but the small records beside them
//! (spectrum.json, backward.json) are plain JSON a person may open, and one damaged digit in
//! them would otherwise flow on without a word: into a resumed backward sweep (its C and its
//! sums), into the GS spectrum the report prints. With the checksum they are refused instead.
//!
//! The checksum is over the compact serialization of the record without the field, so it
//! does not depend on how the file is indented, and f64 values survive it exactly (shortest
//! round-trip formatting). Records written before the field existed read as before, unless
//! the run.json beside them has one: then the field was removed.

use crate::error::{Error, Result};
use serde::de::DeserializeOwned;
use serde::Serialize;
use std::path::Path;

const FIELD: &str = "crc32";

fn crc_of(record: &serde_json::Map<String, serde_json::Value>) -> Result<u32> {
    let bytes = serde_json::to_vec(record).map_err(|e| Error::Other(e.to_string()))?;
    Ok(crc32fast::hash(&bytes))
}

/// `value` as pretty JSON with its checksum; `value` must serialize to a JSON object.
pub fn to_vec<T: Serialize>(value: &T) -> Result<Vec<u8>> {
    let serde_json::Value::Object(mut record) = serde_json::to_value(value).map_err(|e| Error::Other(e.to_string()))? else {
        return Err(Error::Other("a checked JSON record must be an object (a bug: please report it)".into()));
    };
    record.remove(FIELD);
    let crc = crc_of(&record)?;
    record.insert(FIELD.into(), crc.into());
    serde_json::to_vec_pretty(&record).map_err(|e| Error::Other(e.to_string()))
}

/// Whether a record read by [`from_slice`] carried its checksum.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Seal {
    Checked,
    /// Written by a build before records carried one.
    Absent,
}

/// The record in `bytes` (read from `path`, named in errors), its checksum verified.
pub fn from_slice<T: DeserializeOwned>(path: &Path, bytes: &[u8]) -> Result<(T, Seal)> {
    let value: serde_json::Value = serde_json::from_slice(bytes).map_err(|e| Error::corrupt(path, format!("not valid JSON: {e}")))?;
    let serde_json::Value::Object(mut record) = value else {
        return Err(Error::corrupt(path, "not a JSON object"));
    };
    let seal = match record.remove(FIELD) {
        None if beside_a_sealed_run(path) => {
            return Err(Error::corrupt(path, format!("it carries no checksum ({FIELD}), while the run.json beside it does: the field was removed by an edit")));
        }
        None => Seal::Absent,
        Some(stored) => {
            let crc = crc_of(&record)?;
            if stored.as_u64() != Some(crc as u64) {
                return Err(Error::corrupt(path, format!("its checksum ({FIELD} = {stored}) does not match its content ({crc}): the file was edited or damaged")));
            }
            Seal::Checked
        }
    };
    let value = serde_json::from_value(serde_json::Value::Object(record)).map_err(|e| Error::corrupt(path, e.to_string()))?;
    Ok((value, seal))
}

/// Whether `path` is a record beside a run.json that carries a checksum: a run written by a
/// build that seals its records, so that a record of it without one was edited.
fn beside_a_sealed_run(path: &Path) -> bool {
    let run_json = path.with_file_name("run.json");
    path.file_name().is_some_and(|n| n != "run.json")
        && std::fs::read(&run_json).ok().and_then(|b| serde_json::from_slice::<serde_json::Value>(&b).ok()).is_some_and(|v| v.get(FIELD).is_some())
}

/// [`from_slice`] of the file at `path`.
pub fn read<T: DeserializeOwned>(path: &Path) -> Result<(T, Seal)> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    from_slice(path, &bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Serialize, serde::Deserialize, Debug, PartialEq)]
    struct Record {
        at: u64,
        sums: Vec<f64>,
        name: String,
    }

    fn record() -> Record {
        Record { at: 960, sums: vec![0.1, -2.5e-300, 1.0 / 3.0, 5.036636095], name: "a".into() }
    }

    #[test]
    fn a_record_reads_back_exactly_and_whatever_its_indentation() {
        let bytes = to_vec(&record()).unwrap();
        assert_eq!(from_slice::<Record>(Path::new("r.json"), &bytes).unwrap(), (record(), Seal::Checked));
        let compact = serde_json::to_vec(&serde_json::from_slice::<serde_json::Value>(&bytes).unwrap()).unwrap();
        assert_eq!(from_slice::<Record>(Path::new("r.json"), &compact).unwrap().0, record());
    }

    /// Every one-digit change of a number is refused, with the file named.
    #[test]
    fn a_changed_digit_is_refused() {
        let text = String::from_utf8(to_vec(&record()).unwrap()).unwrap();
        for (from, to) in [("960", "940"), ("5.036636095", "4.036636095"), ("0.1", "0.2")] {
            let damaged = text.replacen(from, to, 1);
            assert_ne!(damaged, text);
            let err = from_slice::<Record>(Path::new("backward.json"), damaged.as_bytes()).unwrap_err().to_string();
            assert!(err.contains("backward.json") && err.contains("edited or damaged"), "{err}");
        }
    }

    #[test]
    fn a_record_of_an_older_build_without_checksum_still_reads() {
        let bytes = serde_json::to_vec(&record()).unwrap();
        assert_eq!(from_slice::<Record>(Path::new("r.json"), &bytes).unwrap(), (record(), Seal::Absent));
    }
}
