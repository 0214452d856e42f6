//! The Modbus register map: which registers hold which tag, and how to turn words into values.
//!
//! Modelled on Telegraf's Modbus input ("request" style) so plant engineers recognise it: each
//! `[[modbus.request]]` reads one block of holding or input registers from one slave, starting
//! at a 0-based address; each `[[modbus.request.field]]` names a tag at an absolute 0-based
//! register address with a data type, byte order, scale and offset
//! (`value = raw × scale + offset`), unit, optional engine signal and optional plausible range.
//!
//! Decoding and encoding are pure functions (the plant simulator uses [`encode_field`], the
//! inverse of [`decode_field`]). Validation collects every problem instead of stopping at the
//! first. This module does no I/O and knows nothing about the network or the database.
//!
//! Byte orders (the four-letter names describe the bytes of a 32-bit value A B C D, most
//! significant first, as they appear on the wire, first register first):
//! - `ABCD`: big-endian words in big-endian order (Modbus convention). 0x12345678 → [0x1234, 0x5678]
//! - `CDAB`: word-swapped. 0x12345678 → [0x5678, 0x1234]
//! - `BADC`: byte-swapped inside each word. 0x12345678 → [0x3412, 0x7856]
//! - `DCBA`: fully little-endian. 0x12345678 → [0x7856, 0x3412]
//!
//! For 64-bit values the same rule extends to four words (`ABCD` = ABCDEFGH, `CDAB` = GHEFCDAB,
//! `BADC` = BADCFEHG, `DCBA` = HGFEDCBA); for 16-bit values `ABCD`/`CDAB` read the word as is
//! and `BADC`/`DCBA` swap its two bytes.
//!
//! Split by concern: `types` (the map's serde types), `check` (validation of a map, every
//! problem collected), `codec` (pure word ↔ value decoding and encoding). Everything is
//! re-exported here, so callers keep using `acquire::register_map::…`.

mod check;
mod codec;
mod types;

pub use codec::{
    decode_field, decode_raw, encode_field, encode_raw, scale_and_classify, Reading, ReadingStatus,
    ShortRead,
};
pub use types::{ByteOrder, DataType, FieldSpec, ModbusConfig, RegisterKind, RequestSpec};

use crate::signals::Signal;

/// Most registers one read request (function 3 or 4) may ask for (Modbus application protocol).
pub const MAX_REGISTERS_PER_REQUEST: u32 = 125;

/// Engine signals the diagnosis cannot do without (REFERENCE §3: n1, T2, P2, T34, P34 + fuel).
pub const REQUIRED_SIGNALS: [Signal; 6] = [
    Signal::N1,
    Signal::T2,
    Signal::P2,
    Signal::T34,
    Signal::P34,
    Signal::FuelFlow,
];

/// Name of the extra field through which the plant simulator publishes its true phase code.
pub const PHASE_TRUTH_FIELD: &str = "phase_truth";

/// Name of the extra field through which the plant simulator publishes its own clock (Unix epoch
/// milliseconds of the frame; use type `f64`, which holds every such millisecond exactly). A
/// daemon with `acquisition.timestamp_field` naming it stamps samples in plant time, which a
/// simulated plant running faster than real time needs (see `acquire::modbus::poll_loop`).
pub const PLANT_TIME_FIELD: &str = "plant_time_ms";

#[cfg(test)]
mod tests;
