//! The worker protocol's frames (version 1, documented in `python/bfqi_gym_worker.py`): a u32
//! header length and a u64 payload length (little-endian), a JSON header whose `arrays` lists
//! `[name, dtype, shape]`, and the arrays' little-endian bytes in that order.

use serde_json::{Map, Value};
use std::io::{self, Read};

/// The protocol version this build speaks.
pub const PROTOCOL: u64 = 1;

/// Headers above this are refused (a header is a few hundred bytes).
const MAX_HEADER: usize = 16 << 20;
/// Payloads above this are refused (a batch of episodes is a few MB).
const MAX_PAYLOAD: u64 = 8 << 30;

/// The values of one array.
#[derive(Debug, Clone, PartialEq)]
pub enum Data {
    /// `f8`: float64.
    F8(Vec<f64>),
    /// `u8`: uint64.
    U8(Vec<u64>),
    /// `u1`: uint8 (flags, pixels).
    U1(Vec<u8>),
}

impl Data {
    fn code(&self) -> &'static str {
        match self {
            Data::F8(_) => "f8",
            Data::U8(_) => "u8",
            Data::U1(_) => "u1",
        }
    }

    fn len(&self) -> usize {
        match self {
            Data::F8(v) => v.len(),
            Data::U8(v) => v.len(),
            Data::U1(v) => v.len(),
        }
    }
}

/// A named array with its shape.
#[derive(Debug, Clone, PartialEq)]
pub struct Array {
    /// Its name in the header.
    pub name: String,
    /// Its shape (C order).
    pub shape: Vec<usize>,
    /// Its values.
    pub data: Data,
}

/// One message.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Frame {
    /// The JSON header, without `arrays`.
    pub header: Map<String, Value>,
    /// The arrays, in order.
    pub arrays: Vec<Array>,
}

impl Frame {
    /// A request `op` with header fields `fields` (an object) and no arrays yet.
    pub fn request(op: &str, fields: Value) -> Frame {
        let mut header = match fields {
            Value::Object(m) => m,
            _ => Map::new(),
        };
        header.insert("op".into(), Value::String(op.into()));
        Frame { header, arrays: Vec::new() }
    }

    /// Adds an array.
    pub fn with(mut self, name: &str, shape: &[usize], data: Data) -> Frame {
        self.arrays.push(Array { name: name.into(), shape: shape.to_vec(), data });
        self
    }

    /// The array called `name`.
    pub fn array(&self, name: &str) -> Option<&Array> {
        self.arrays.iter().find(|a| a.name == name)
    }

    /// The bytes of the frame.
    pub fn encode(&self) -> Vec<u8> {
        let mut header = self.header.clone();
        let listed: Vec<Value> =
            self.arrays.iter().map(|a| serde_json::json!([a.name, a.data.code(), a.shape])).collect();
        header.insert("arrays".into(), Value::Array(listed));
        let h = serde_json::to_vec(&Value::Object(header)).expect("a header serialises");
        let payload: usize = self.arrays.iter().map(|a| a.data.len() * width(a.data.code())).sum();
        let mut out = Vec::with_capacity(12 + h.len() + payload);
        out.extend_from_slice(&(h.len() as u32).to_le_bytes());
        out.extend_from_slice(&(payload as u64).to_le_bytes());
        out.extend_from_slice(&h);
        for a in &self.arrays {
            match &a.data {
                Data::F8(v) => v.iter().for_each(|x| out.extend_from_slice(&x.to_le_bytes())),
                Data::U8(v) => v.iter().for_each(|x| out.extend_from_slice(&x.to_le_bytes())),
                Data::U1(v) => out.extend_from_slice(v),
            }
        }
        out
    }

    /// Reads the next frame; `None` at a clean end of input (before its first byte).
    pub fn read(r: &mut impl Read) -> io::Result<Option<Frame>> {
        let mut prefix = [0u8; 12];
        let mut got = 0;
        while got < prefix.len() {
            match r.read(&mut prefix[got..])? {
                0 if got == 0 => return Ok(None),
                0 => return Err(bad(format!("input ended inside a frame prefix ({got} of 12 bytes)"))),
                n => got += n,
            }
        }
        let hlen = u32::from_le_bytes(prefix[..4].try_into().expect("4 bytes")) as usize;
        let plen = u64::from_le_bytes(prefix[4..].try_into().expect("8 bytes"));
        if hlen > MAX_HEADER || plen > MAX_PAYLOAD {
            return Err(bad(format!("a frame of {hlen} header and {plen} payload bytes (not the protocol?)")));
        }
        let mut h = vec![0u8; hlen];
        r.read_exact(&mut h)?;
        let mut header: Map<String, Value> = match serde_json::from_slice(&h) {
            Ok(Value::Object(m)) => m,
            _ => return Err(bad("a frame header that is not a JSON object (not the protocol?)".into())),
        };
        let mut payload = vec![0u8; plen as usize];
        r.read_exact(&mut payload)?;
        let listed = header.remove("arrays").unwrap_or(Value::Array(vec![]));
        let mut arrays = Vec::new();
        let mut at = 0usize;
        for entry in listed.as_array().into_iter().flatten() {
            let (name, code, shape) = parse_entry(entry).ok_or_else(|| bad(format!("a bad array entry {entry}")))?;
            let count: usize = shape.iter().product();
            let bytes = count.checked_mul(width(&code)).ok_or_else(|| bad("an array too large".into()))?;
            let chunk =
                payload.get(at..at + bytes).ok_or_else(|| bad(format!("array {name} runs past the payload")))?;
            at += bytes;
            let data = match code.as_str() {
                "f8" => Data::F8(chunk.chunks_exact(8).map(|b| f64::from_le_bytes(b.try_into().expect("8"))).collect()),
                "u8" => Data::U8(chunk.chunks_exact(8).map(|b| u64::from_le_bytes(b.try_into().expect("8"))).collect()),
                "u1" | "b1" => Data::U1(chunk.to_vec()),
                other => return Err(bad(format!("array {name} of unsupported dtype {other}"))),
            };
            arrays.push(Array { name, shape, data });
        }
        if at != payload.len() {
            return Err(bad(format!("a payload of {} bytes for arrays of {at}", payload.len())));
        }
        Ok(Some(Frame { header, arrays }))
    }
}

fn parse_entry(v: &Value) -> Option<(String, String, Vec<usize>)> {
    let a = v.as_array()?;
    let name = a.first()?.as_str()?.to_string();
    let code = a.get(1)?.as_str()?.to_string();
    let shape = a.get(2)?.as_array()?.iter().map(|s| s.as_u64().map(|x| x as usize)).collect::<Option<Vec<_>>>()?;
    Some((name, code, shape))
}

fn width(code: &str) -> usize {
    match code {
        "f8" | "u8" => 8,
        _ => 1,
    }
}

fn bad(message: String) -> io::Error {
    io::Error::new(io::ErrorKind::InvalidData, message)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frames_round_trip_bit_for_bit() {
        let f = Frame::request("collect", serde_json::json!({"horizon": 3}))
            .with("seeds", &[2], Data::U8(vec![7, u64::MAX]))
            .with("actions", &[2, 3, 1], Data::F8(vec![0.1, -0.0, f64::MIN_POSITIVE, 1e308, 2.0, 3.0]))
            .with("flags", &[0], Data::U1(vec![]));
        let bytes = f.encode();
        let back = Frame::read(&mut bytes.as_slice()).unwrap().unwrap();
        assert_eq!(back, f);
        assert!(Frame::read(&mut &bytes[..0]).unwrap().is_none(), "a clean end");
        assert!(Frame::read(&mut &bytes[..bytes.len() - 1]).is_err(), "a cut frame");
    }

    #[test]
    fn garbage_is_an_error_not_an_allocation() {
        let junk = b"Traceback (most recent call last):\n  File ...".to_vec();
        assert!(Frame::read(&mut junk.as_slice()).is_err());
    }
}
