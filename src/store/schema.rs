//! The schemas of `schemas/`, embedded in the binary and in every MCAP file, and checked
//! against every message written and read: the schema files are the single source of truth
//! for field names, types, units and orderings.

use super::cbor::{self, MapWriter, Value};
use std::collections::BTreeMap;
use std::sync::OnceLock;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FieldType {
    U64,
    F64,
    F64s,
    Text,
}

pub struct Schema {
    /// MCAP topic of the channel.
    pub topic: &'static str,
    /// Schema name (the JSON schema's title).
    pub name: &'static str,
    /// The schema file, verbatim.
    pub text: &'static str,
    fields: OnceLock<Vec<Field>>,
}

/// One declared field of a schema.
pub struct Field {
    pub name: String,
    pub t: FieldType,
    /// Listed in the schema's `required`. A field added to a schema after files were
    /// written with it is optional, so that those files still read; writers always write it.
    pub required: bool,
}

impl Schema {
    const fn new(topic: &'static str, name: &'static str, text: &'static str) -> Self {
        Schema { topic, name, text, fields: OnceLock::new() }
    }

    /// The declared fields.
    pub fn fields(&self) -> &[Field] {
        self.fields.get_or_init(|| {
            let v: serde_json::Value = serde_json::from_str(self.text).expect("embedded schema is valid JSON");
            let props = v["properties"].as_object().expect("schema has properties");
            let required: Vec<&str> = v["required"].as_array().expect("schema has required").iter().filter_map(|r| r.as_str()).collect();
            props
                .iter()
                .map(|(name, p)| {
                    let t = match p["x-type"].as_str() {
                        Some("u64") => FieldType::U64,
                        Some("f64") => FieldType::F64,
                        Some("f64[]") => FieldType::F64s,
                        Some("text") => FieldType::Text,
                        other => panic!("schema {}: field {name} has unknown x-type {other:?}", self.name),
                    };
                    Field { name: name.clone(), t, required: required.contains(&name.as_str()) }
                })
                .collect()
        })
    }

    fn field(&self, name: &str) -> Option<FieldType> {
        self.fields().iter().find(|f| f.name == name).map(|f| f.t)
    }

    /// Start a message of this schema.
    pub fn encoder(&'static self, capacity: usize) -> Encoder {
        Encoder { schema: self, map: MapWriter::new(self.fields().len(), capacity), written: 0 }
    }

    /// Decode and check a message of this schema.
    pub fn decode(&'static self, bytes: &[u8]) -> Result<Decoded, String> {
        let map = cbor::decode_map(bytes).map_err(|e| format!("{} message: {e}", self.name))?;
        for Field { name, t, required } in self.fields() {
            match (map.get(name), t) {
                (Some(Value::U64(_)), FieldType::U64)
                | (Some(Value::F64(_)), FieldType::F64)
                | (Some(Value::F64s(_)), FieldType::F64s)
                | (Some(Value::Text(_)), FieldType::Text) => {}
                (None, _) if !required => {}
                (None, _) => return Err(format!("{} message lacks field {name:?}", self.name)),
                (Some(v), _) => return Err(format!("{} message: field {name:?} should be {t:?}, found {v:?}", self.name)),
            }
        }
        Ok(Decoded { schema: self, map })
    }
}

pub static CHECKPOINT: Schema = Schema::new("checkpoint", "clv.Checkpoint", include_str!("../../schemas/checkpoint.json"));
pub static R: Schema = Schema::new("r", "clv.R", include_str!("../../schemas/r.json"));
pub static STATS: Schema = Schema::new("stats", "clv.Stats", include_str!("../../schemas/stats.json"));

pub static FRAME: Schema = Schema::new("frame", "clv.Frame", include_str!("../../schemas/frame.json"));

/// Every schema a run directory uses.
pub static RUN_SCHEMAS: [&Schema; 3] = [&CHECKPOINT, &R, &STATS];

/// Writes one message, refusing (by panic: a programming error, not user input) any field
/// the schema does not declare or with another type, and any message missing a field.
pub struct Encoder {
    schema: &'static Schema,
    map: MapWriter,
    written: usize,
}

impl Encoder {
    fn check(&mut self, name: &str, t: FieldType) {
        assert_eq!(self.schema.field(name), Some(t), "schema {} does not declare field {name} as {t:?}", self.schema.name);
        self.written += 1;
    }
    pub fn u64(mut self, name: &str, v: u64) -> Self {
        self.check(name, FieldType::U64);
        self.map.u64(name, v);
        self
    }
    pub fn f64(mut self, name: &str, v: f64) -> Self {
        self.check(name, FieldType::F64);
        self.map.f64(name, v);
        self
    }
    pub fn f64s(mut self, name: &str, v: &[f64]) -> Self {
        self.check(name, FieldType::F64s);
        self.map.f64s(name, v);
        self
    }
    /// [`Encoder::f64s`] of `len` values drawn from `v`.
    pub fn f64s_of(mut self, name: &str, len: usize, v: impl Iterator<Item = f64>) -> Self {
        self.check(name, FieldType::F64s);
        self.map.f64s_of(name, len, v);
        self
    }
    pub fn text(mut self, name: &str, v: &str) -> Self {
        self.check(name, FieldType::Text);
        self.map.text(name, v);
        self
    }
    pub fn finish(self) -> Vec<u8> {
        assert_eq!(self.written, self.schema.fields().len(), "message of {} misses fields", self.schema.name);
        self.map.finish()
    }
}

/// A decoded message whose fields have been checked against its schema.
pub struct Decoded {
    schema: &'static Schema,
    map: BTreeMap<String, Value>,
}

impl Decoded {
    pub fn u64(&self, name: &str) -> u64 {
        match self.map.get(name) {
            Some(Value::U64(x)) => *x,
            _ => panic!("{}: {name} is not a declared u64 field", self.schema.name),
        }
    }
    pub fn f64(&self, name: &str) -> f64 {
        match self.map.get(name) {
            Some(Value::F64(x)) => *x,
            _ => panic!("{}: {name} is not a declared f64 field", self.schema.name),
        }
    }
    pub fn take_f64s(&mut self, name: &str) -> Vec<f64> {
        match self.map.remove(name) {
            Some(Value::F64s(x)) => x,
            _ => panic!("{}: {name} is not a declared f64[] field (or was taken)", self.schema.name),
        }
    }
    /// An optional f64[] field: empty where the message (written before the field was added)
    /// lacks it.
    pub fn take_optional_f64s(&mut self, name: &str) -> Vec<f64> {
        assert!(self.schema.fields().iter().any(|f| f.name == name && f.t == FieldType::F64s && !f.required), "{}: {name} is not a declared optional f64[] field", self.schema.name);
        match self.map.remove(name) {
            Some(Value::F64s(x)) => x,
            _ => Vec::new(),
        }
    }
    pub fn text(&self, name: &str) -> &str {
        match self.map.get(name) {
            Some(Value::Text(x)) => x,
            _ => panic!("{}: {name} is not a declared text field", self.schema.name),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn schema_files_parse_and_describe_every_field() {
        for s in RUN_SCHEMAS.iter().chain([&&FRAME]) {
            let v: serde_json::Value = serde_json::from_str(s.text).unwrap();
            assert_eq!(v["title"], s.name);
            assert_eq!(v["x-topic"], s.topic);
            let required: Vec<String> = serde_json::from_value(v["required"].clone()).unwrap();
            for r in &required {
                assert!(s.fields().iter().any(|f| &f.name == r), "{}: required field {r} is not declared", s.name);
            }
            for f in s.fields() {
                let desc = v["properties"][&f.name]["description"].as_str().unwrap_or("");
                assert!(desc.len() > 3, "{}: field {} has no description", s.name, f.name);
                // An optional field exists only for files written before it: say since when.
                assert!(f.required || desc.to_lowercase().contains("absent"), "{}: optional field {} does not say when it is absent", s.name, f.name);
            }
        }
    }

    #[test]
    fn a_message_missing_a_field_is_refused_on_decode() {
        let mut w = MapWriter::new(2, 0);
        w.u64("step", 3);
        w.u64("k", 1);
        let err = R.decode(&w.finish()).err().unwrap();
        assert!(err.contains("\"r\""), "{err}");
    }
}
