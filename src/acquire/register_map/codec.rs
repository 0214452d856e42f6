//! Decoding registers into values and encoding values into registers (the plant simulator's
//! inverse), for every data type and byte order in the module docs. Pure functions: no I/O,
//! and a short read is an error value, never a panic.

use super::types::{ByteOrder, DataType, FieldSpec};

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ReadingStatus {
    /// Finite and inside the plausible range.
    Good,
    /// Finite but outside the configured plausible range.
    OutOfRange,
    /// NaN or infinite (a float register holding garbage); never usable.
    NotFinite,
}

/// A decoded, scaled field value and its status.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Reading {
    pub value: f64,
    pub status: ReadingStatus,
}

/// Reorders the field's registers into the value's big-endian bytes (first `2 × words` valid).
fn canonical_bytes(words: &[u16], order: ByteOrder) -> [u8; 8] {
    let mut out = [0u8; 8];
    let n = words.len().min(4);
    for i in 0..n {
        let w = if order.words_reversed() {
            words[n - 1 - i]
        } else {
            words[i]
        };
        let [hi, lo] = w.to_be_bytes();
        let (a, b) = if order.bytes_swapped() {
            (lo, hi)
        } else {
            (hi, lo)
        };
        out[2 * i] = a;
        out[2 * i + 1] = b;
    }
    out
}

/// Inverse of [`canonical_bytes`]: big-endian value bytes to registers in wire order.
fn words_from_canonical(bytes: &[u8], order: ByteOrder) -> Vec<u16> {
    let n = bytes.len() / 2;
    let mut words = vec![0u16; n];
    for i in 0..n {
        let (a, b) = (bytes[2 * i], bytes[2 * i + 1]);
        let w = if order.bytes_swapped() {
            u16::from_be_bytes([b, a])
        } else {
            u16::from_be_bytes([a, b])
        };
        let slot = if order.words_reversed() { n - 1 - i } else { i };
        words[slot] = w;
    }
    words
}

/// Error decoding registers: fewer words than the type needs.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{data_type} needs {needed} registers, got {got}")]
pub struct ShortRead {
    pub data_type: DataType,
    pub needed: usize,
    pub got: usize,
}

/// Decodes the raw (unscaled) value of `ty` from its registers in wire order.
pub fn decode_raw(words: &[u16], ty: DataType, order: ByteOrder) -> Result<f64, ShortRead> {
    let needed = ty.words() as usize;
    if words.len() < needed {
        return Err(ShortRead {
            data_type: ty,
            needed,
            got: words.len(),
        });
    }
    let b = canonical_bytes(&words[..needed], order);
    Ok(match ty {
        DataType::U16 => f64::from(u16::from_be_bytes([b[0], b[1]])),
        DataType::I16 => f64::from(i16::from_be_bytes([b[0], b[1]])),
        DataType::U32 => f64::from(u32::from_be_bytes([b[0], b[1], b[2], b[3]])),
        DataType::I32 => f64::from(i32::from_be_bytes([b[0], b[1], b[2], b[3]])),
        DataType::F32 => f64::from(f32::from_be_bytes([b[0], b[1], b[2], b[3]])),
        DataType::F64 => f64::from_be_bytes(b),
    })
}

/// Encodes a raw (unscaled) value into registers in wire order. Integers are rounded and
/// saturated to the type's range (NaN becomes 0).
pub fn encode_raw(raw: f64, ty: DataType, order: ByteOrder) -> Vec<u16> {
    let bytes: Vec<u8> = match ty {
        DataType::U16 => (raw.round() as u16).to_be_bytes().to_vec(),
        DataType::I16 => (raw.round() as i16).to_be_bytes().to_vec(),
        DataType::U32 => (raw.round() as u32).to_be_bytes().to_vec(),
        DataType::I32 => (raw.round() as i32).to_be_bytes().to_vec(),
        DataType::F32 => (raw as f32).to_be_bytes().to_vec(),
        DataType::F64 => raw.to_be_bytes().to_vec(),
    };
    words_from_canonical(&bytes, order)
}

/// Scales a raw value and classifies it against the field's plausible range.
pub fn scale_and_classify(field: &FieldSpec, raw: f64) -> Reading {
    let value = raw * field.scale + field.offset;
    let status = if !value.is_finite() {
        ReadingStatus::NotFinite
    } else if field.min.is_some_and(|lo| value < lo) || field.max.is_some_and(|hi| value > hi) {
        ReadingStatus::OutOfRange
    } else {
        ReadingStatus::Good
    };
    Reading { value, status }
}

/// Decodes one field from the registers of its request (`block` starts at `start_address`).
pub fn decode_field(
    field: &FieldSpec,
    start_address: u32,
    block: &[u16],
) -> Result<Reading, ShortRead> {
    let from = field.address.saturating_sub(start_address) as usize;
    let words = block.get(from..).unwrap_or(&[]);
    let raw = decode_raw(words, field.data_type, field.byte_order)?;
    Ok(scale_and_classify(field, raw))
}

/// Encodes an engineering value into the field's registers (inverse of [`decode_field`]).
pub fn encode_field(field: &FieldSpec, value: f64) -> Vec<u16> {
    let raw = (value - field.offset) / field.scale;
    encode_raw(raw, field.data_type, field.byte_order)
}
