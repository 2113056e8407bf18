//! The message encoding: one CBOR map per message (RFC 8949), text keys, with f64 arrays
//! carried as a single little-endian byte string.
//!
//! Why CBOR: every language has a standard decoder (Python: `cbor2.loads`, then
//! `numpy.frombuffer(value, "<f8")` for an array), and it is MCAP's well-known `cbor`
//! message encoding. Why byte strings for arrays: an array of CBOR floats is an order of
//! magnitude slower to encode and larger; a byte string is one memcpy.
//! Only the subset the schemas use is implemented: unsigned integers, f64, byte and text
//! strings, and the top-level map.

use std::collections::BTreeMap;

#[derive(Clone, Debug, PartialEq)]
pub enum Value {
    U64(u64),
    F64(f64),
    /// An array of f64, little-endian.
    F64s(Vec<f64>),
    Text(String),
}

/// Builds one CBOR map of `len` entries.
pub struct MapWriter {
    buf: Vec<u8>,
}

fn head(buf: &mut Vec<u8>, major: u8, n: u64) {
    let m = major << 5;
    if n < 24 {
        buf.push(m | n as u8);
    } else if n <= u8::MAX as u64 {
        buf.extend_from_slice(&[m | 24, n as u8]);
    } else if n <= u16::MAX as u64 {
        buf.push(m | 25);
        buf.extend_from_slice(&(n as u16).to_be_bytes());
    } else if n <= u32::MAX as u64 {
        buf.push(m | 26);
        buf.extend_from_slice(&(n as u32).to_be_bytes());
    } else {
        buf.push(m | 27);
        buf.extend_from_slice(&n.to_be_bytes());
    }
}

impl MapWriter {
    pub fn new(len: usize, capacity: usize) -> Self {
        let mut buf = Vec::with_capacity(capacity + 16 * len);
        head(&mut buf, 5, len as u64);
        MapWriter { buf }
    }

    fn key(&mut self, k: &str) {
        head(&mut self.buf, 3, k.len() as u64);
        self.buf.extend_from_slice(k.as_bytes());
    }

    pub fn u64(&mut self, k: &str, v: u64) {
        self.key(k);
        head(&mut self.buf, 0, v);
    }

    pub fn f64(&mut self, k: &str, v: f64) {
        self.key(k);
        self.buf.push(0xfb);
        self.buf.extend_from_slice(&v.to_bits().to_be_bytes());
    }

    pub fn f64s(&mut self, k: &str, v: &[f64]) {
        self.f64s_of(k, v.len(), v.iter().copied());
    }

    /// [`MapWriter::f64s`] of `len` values drawn from `v`, without a slice of them in memory.
    pub fn f64s_of(&mut self, k: &str, len: usize, v: impl Iterator<Item = f64>) {
        self.key(k);
        head(&mut self.buf, 2, 8 * len as u64);
        let start = self.buf.len();
        for x in v {
            self.buf.extend_from_slice(&x.to_le_bytes());
        }
        assert_eq!(self.buf.len() - start, 8 * len, "f64s_of: the values must number len");
    }

    pub fn text(&mut self, k: &str, v: &str) {
        self.key(k);
        head(&mut self.buf, 3, v.len() as u64);
        self.buf.extend_from_slice(v.as_bytes());
    }

    pub fn value(&mut self, k: &str, v: &Value) {
        match v {
            Value::U64(x) => self.u64(k, *x),
            Value::F64(x) => self.f64(k, *x),
            Value::F64s(x) => self.f64s(k, x),
            Value::Text(x) => self.text(k, x),
        }
    }

    pub fn finish(self) -> Vec<u8> {
        self.buf
    }
}

struct Cursor<'a> {
    b: &'a [u8],
    at: usize,
}

impl<'a> Cursor<'a> {
    fn take(&mut self, n: usize) -> Result<&'a [u8], String> {
        let end = self.at.checked_add(n).filter(|&e| e <= self.b.len());
        let end = end.ok_or_else(|| format!("message ends early at byte {} (wanted {n} more)", self.at))?;
        let s = &self.b[self.at..end];
        self.at = end;
        Ok(s)
    }

    /// The next N bytes as an array.
    fn take_array<const N: usize>(&mut self) -> Result<[u8; N], String> {
        let mut out = [0; N];
        out.copy_from_slice(self.take(N)?);
        Ok(out)
    }

    fn head(&mut self) -> Result<(u8, u8, u64), String> {
        let first = self.take(1)?[0];
        let (major, add) = (first >> 5, first & 31);
        let n = match add {
            0..=23 => add as u64,
            24 => self.take(1)?[0] as u64,
            25 => u16::from_be_bytes(self.take_array()?) as u64,
            26 => u32::from_be_bytes(self.take_array()?) as u64,
            27 => u64::from_be_bytes(self.take_array()?),
            _ => return Err(format!("unsupported CBOR item 0x{first:02x} at byte {}", self.at - 1)),
        };
        Ok((major, add, n))
    }

    fn len(&mut self, n: u64) -> Result<usize, String> {
        usize::try_from(n).ok().filter(|&n| n <= self.b.len()).ok_or_else(|| format!("length {n} at byte {} exceeds the message", self.at))
    }
}

/// f64 values from their little-endian bytes (a trailing partial value is ignored; callers
/// check the length).
pub fn f64s_from_le_bytes(raw: &[u8]) -> Vec<f64> {
    raw.chunks_exact(8)
        .map(|b| {
            let mut le = [0; 8];
            le.copy_from_slice(b);
            f64::from_le_bytes(le)
        })
        .collect()
}

/// Decode a top-level CBOR map of the supported subset.
pub fn decode_map(bytes: &[u8]) -> Result<BTreeMap<String, Value>, String> {
    let mut c = Cursor { b: bytes, at: 0 };
    let (major, _, n) = c.head()?;
    if major != 5 {
        return Err("message is not a CBOR map".into());
    }
    let mut out = BTreeMap::new();
    for _ in 0..n {
        let (major, _, len) = c.head()?;
        if major != 3 {
            return Err(format!("map key at byte {} is not text", c.at));
        }
        let len = c.len(len)?;
        let key = std::str::from_utf8(c.take(len)?).map_err(|e| e.to_string())?.to_string();
        let (major, add, n) = c.head()?;
        let value = match (major, add) {
            (0, _) => Value::U64(n),
            (7, 27) => Value::F64(f64::from_bits(n)),
            (2, _) => {
                let len = c.len(n)?;
                if len % 8 != 0 {
                    return Err(format!("field {key:?}: byte string of {len} bytes is not an f64 array"));
                }
                let raw = c.take(len)?;
                Value::F64s(f64s_from_le_bytes(raw))
            }
            (3, _) => {
                let len = c.len(n)?;
                Value::Text(std::str::from_utf8(c.take(len)?).map_err(|e| e.to_string())?.to_string())
            }
            _ => return Err(format!("field {key:?}: unsupported CBOR type {major}")),
        };
        out.insert(key, value);
    }
    if c.at != bytes.len() {
        return Err(format!("{} trailing bytes after the message", bytes.len() - c.at));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_and_known_encodings() {
        let mut w = MapWriter::new(4, 0);
        w.u64("n", 1_000_000_000_000);
        w.f64("t", -0.6);
        w.f64s("x", &[1.5, f64::MIN_POSITIVE, -0.0]);
        w.text("s", "disks");
        let b = w.finish();
        let m = decode_map(&b).unwrap();
        assert_eq!(m["n"], Value::U64(1_000_000_000_000));
        assert_eq!(m["t"], Value::F64(-0.6));
        assert_eq!(m["x"], Value::F64s(vec![1.5, f64::MIN_POSITIVE, -0.0]));
        assert_eq!(m["s"], Value::Text("disks".into()));
        // RFC 8949 Appendix A: 1000000 is 0x1a000f4240, and a map of one entry starts 0xa1.
        let mut w = MapWriter::new(1, 0);
        w.u64("a", 1_000_000);
        assert_eq!(w.finish(), vec![0xa1, 0x61, b'a', 0x1a, 0x00, 0x0f, 0x42, 0x40]);
    }

    #[test]
    fn damaged_messages_are_errors_not_panics() {
        let mut w = MapWriter::new(2, 0);
        w.f64s("x", &[1.0; 40]);
        w.u64("n", 7);
        let b = w.finish();
        for cut in 0..b.len() {
            assert!(decode_map(&b[..cut]).is_err());
        }
        let mut bad = b.clone();
        bad[0] = 0x82;
        assert!(decode_map(&bad).is_err());
    }
}
