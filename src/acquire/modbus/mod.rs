//! The Modbus TCP poll loop: read the register map every period, decode, send samples to the
//! writer, and turn outages into recorded gaps.
//!
//! Read-only by construction: the only client type here is [`ReadOnlyClient`], whose private
//! tokio-modbus context is reachable only through `read_holding_registers` (function 3) and
//! `read_input_registers` (function 4). Nothing in this module may write to the control system.
//!
//! Every connect and request is wrapped in a timeout. After any error or timeout the connection
//! is dropped and re-made (with capped exponential backoff): a reply that arrives after its
//! timeout then lands on a closed socket and can never be taken for the answer to the next
//! request. An outage is recorded as a [`Gap`] from the last good poll to the first good poll
//! after it, with the reason of the first failure. The loop never panics on plant input.
//!
//! Split by concern: `config` (the `[acquisition]` section), `client` (the read-only Modbus
//! client and its errors), `plan` (what to read and how registers become samples), `progress`
//! (counters and backoff), `poll_loop` (the loop itself, outages and gaps). Everything is
//! re-exported here, so callers keep using `acquire::modbus::…`.

mod client;
mod config;
mod plan;
mod poll_loop;
mod progress;

pub use client::{ReadError, ReadOnlyClient};
pub use config::{AcquisitionConfig, SourceKind};
pub use plan::{decode_request, PlannedRequest, PollPlan};
pub use poll_loop::{poll_loop, poll_loop_with_clock, CLOCK_GAP_SOURCE, GAP_SOURCE};
pub use progress::{Backoff, PollProgress, PollStats};

#[cfg(test)]
mod tests;
