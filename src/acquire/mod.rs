//! Live acquisition from the plant's control system.
//!
//! `register_map` says where each tag lives in the Modbus address space and how to decode it
//! (pure functions); `clock` stamps samples; `gate` applies the bad-value policy; `modbus` is
//! the read-only poll loop. Nothing in this module may write to the control system: the only
//! Modbus client type it exposes can issue read function codes (3 and 4) and nothing else.

pub(crate) mod clock;
pub(crate) mod gate;
pub mod modbus;
pub mod register_map;
#[cfg(test)]
pub(crate) mod test_support;
