//! The register map's types as read from the `[modbus]` section (serde), with the small
//! arithmetic on them (word counts, address spans). No validation (that is `check`) and no
//! decoding (that is `codec`). Must not talk to Modbus.

use crate::signals::Signal;
use serde::{Deserialize, Deserializer, Serialize};
use std::fmt;

/// Which Modbus table a request reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum RegisterKind {
    /// Holding registers, function code 3 (the 4xxxx table in 1-based notation).
    Holding,
    /// Input registers, function code 4 (the 3xxxx table in 1-based notation).
    Input,
}

impl RegisterKind {
    /// First address of this table in the 1-based Modicon notation (40001 / 30001).
    pub fn modicon_base(self) -> u32 {
        match self {
            RegisterKind::Holding => 40001,
            RegisterKind::Input => 30001,
        }
    }
}

impl fmt::Display for RegisterKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            RegisterKind::Holding => "holding",
            RegisterKind::Input => "input",
        })
    }
}

/// Data type of a field; decides how many registers it occupies.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum DataType {
    U16,
    I16,
    U32,
    I32,
    F32,
    F64,
}

impl DataType {
    /// Number of 16-bit registers the type occupies.
    pub fn words(self) -> u32 {
        match self {
            DataType::U16 | DataType::I16 => 1,
            DataType::U32 | DataType::I32 | DataType::F32 => 2,
            DataType::F64 => 4,
        }
    }
}

impl fmt::Display for DataType {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            DataType::U16 => "u16",
            DataType::I16 => "i16",
            DataType::U32 => "u32",
            DataType::I32 => "i32",
            DataType::F32 => "f32",
            DataType::F64 => "f64",
        })
    }
}

/// Byte order of a multi-byte value across registers (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub enum ByteOrder {
    #[default]
    ABCD,
    CDAB,
    BADC,
    DCBA,
}

impl ByteOrder {
    pub(super) fn words_reversed(self) -> bool {
        matches!(self, ByteOrder::CDAB | ByteOrder::DCBA)
    }
    pub(super) fn bytes_swapped(self) -> bool {
        matches!(self, ByteOrder::BADC | ByteOrder::DCBA)
    }
}

/// The `[modbus]` section: where the PLC is and what to read.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ModbusConfig {
    /// PLC or gateway as `host:port` (Modbus TCP default port 502).
    pub endpoint: String,
    /// The read requests, executed in this order every poll.
    #[serde(rename = "request", default)]
    pub requests: Vec<RequestSpec>,
}

/// One read request: a contiguous block of registers of one kind from one slave.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RequestSpec {
    /// Modbus unit / slave id, 1–255 (0 is broadcast and cannot be read).
    pub slave_id: u8,
    /// `holding` (function 3) or `input` (function 4).
    pub register: RegisterKind,
    /// First register of the block, 0-based (Modicon 40001 is holding address 0).
    pub start_address: u32,
    /// Number of registers to read; default: up to the end of the last field.
    #[serde(default)]
    pub count: Option<u32>,
    /// The tags decoded from this block.
    #[serde(rename = "field", default)]
    pub fields: Vec<FieldSpec>,
}

/// One tag inside a request.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FieldSpec {
    /// Tag name as stored in the database (unique across the map).
    pub name: String,
    /// Absolute 0-based register address of the field's first register.
    pub address: u32,
    /// Data type: u16, i16, u32, i32, f32, f64.
    #[serde(rename = "type")]
    pub data_type: DataType,
    /// ABCD (default), CDAB, BADC or DCBA.
    #[serde(default)]
    pub byte_order: ByteOrder,
    /// Engineering value = raw × scale + offset.
    #[serde(default = "one")]
    pub scale: f64,
    #[serde(default)]
    pub offset: f64,
    /// Engineering unit of the scaled value (informational; stored with the tag).
    #[serde(default)]
    pub unit: String,
    /// Engine signal this tag feeds (n1, n2, T1, P1, T2, P2, T34, P34, T4, P4, fuel_flow, power);
    /// absent for free extra tags.
    #[serde(default, deserialize_with = "de_signal")]
    pub signal: Option<Signal>,
    /// Plausible range of the scaled value; outside it the sample is flagged OutOfRange.
    #[serde(default)]
    pub min: Option<f64>,
    #[serde(default)]
    pub max: Option<f64>,
}

fn one() -> f64 {
    1.0
}

fn de_signal<'de, D: Deserializer<'de>>(d: D) -> Result<Option<Signal>, D::Error> {
    let s: Option<String> = Option::deserialize(d)?;
    s.map(|s| s.parse::<Signal>().map_err(serde::de::Error::custom))
        .transpose()
}

impl FieldSpec {
    /// Last register the field occupies (inclusive).
    pub fn last_address(&self) -> u32 {
        self.address + self.data_type.words() - 1
    }
}

impl RequestSpec {
    /// Number of registers the request reads: `count` if given, else up to the last field's end.
    pub fn register_count(&self) -> u32 {
        self.count.unwrap_or_else(|| {
            self.fields
                .iter()
                .map(|f| (f.last_address() + 1).saturating_sub(self.start_address))
                .max()
                .unwrap_or(0)
        })
    }
}

impl ModbusConfig {
    /// All fields in poll order, with the index of their request.
    pub fn fields(&self) -> impl Iterator<Item = (usize, &FieldSpec)> {
        self.requests
            .iter()
            .enumerate()
            .flat_map(|(i, r)| r.fields.iter().map(move |f| (i, f)))
    }
}
