//! The read-only Modbus TCP client: connect and read with timeouts, nothing else. Its
//! tokio-modbus context is private, so no code path can reach a write function code. Read
//! errors carry a stable reason for gap records.

use crate::acquire::register_map::RegisterKind;
use std::net::SocketAddr;
use std::time::Duration;
use tokio_modbus::client::{tcp, Context, Reader};
use tokio_modbus::prelude::SlaveContext;
use tokio_modbus::Slave;

/// Why a read failed. Any of these drops the connection.
#[derive(Debug, thiserror::Error)]
pub enum ReadError {
    #[error("timed out after {0} ms")]
    Timeout(u64),
    #[error("I/O error: {0}")]
    Io(#[from] std::io::Error),
    #[error("protocol error: {0}")]
    Protocol(String),
    #[error("device answered with Modbus exception {0:?}")]
    Exception(tokio_modbus::ExceptionCode),
    #[error("device returned {got} registers, {want} requested")]
    ShortResponse { got: usize, want: usize },
}

impl ReadError {
    /// The text stored as a gap's reason: the same for the same fault on every run. An I/O
    /// error's OS text is not (tokio-modbus 0.17 maps EOF through `last_os_error`, giving
    /// `Success (os error 0)`, `Operation now in progress (os error 115)`, … for one server
    /// death), so only its kind is kept; the full text goes to the log.
    pub fn stable_reason(&self) -> String {
        match self {
            ReadError::Io(e) => {
                let what = match e.kind() {
                    std::io::ErrorKind::ConnectionRefused => "connection refused",
                    std::io::ErrorKind::TimedOut => "connection timed out",
                    std::io::ErrorKind::NotFound | std::io::ErrorKind::InvalidInput => {
                        "address not resolved"
                    }
                    _ => "connection lost",
                };
                format!("I/O error: {what}")
            }
            ReadError::Protocol(_) => "protocol error".to_string(),
            other => other.to_string(),
        }
    }
}

/// A Modbus TCP client that can only read (function codes 3 and 4). The tokio-modbus context
/// is private, so no code path can reach its `Writer` methods.
pub struct ReadOnlyClient {
    ctx: Context,
}

impl std::fmt::Debug for ReadOnlyClient {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("ReadOnlyClient")
    }
}

impl ReadOnlyClient {
    /// Connects with a timeout.
    pub async fn connect(addr: SocketAddr, timeout: Duration) -> Result<Self, ReadError> {
        match tokio::time::timeout(timeout, tcp::connect(addr)).await {
            Err(_) => Err(ReadError::Timeout(timeout.as_millis() as u64)),
            Ok(Err(e)) => Err(ReadError::Io(e)),
            Ok(Ok(ctx)) => Ok(ReadOnlyClient { ctx }),
        }
    }

    /// Reads `count` holding registers (function 3) from `slave`.
    pub async fn read_holding_registers(
        &mut self,
        slave: u8,
        addr: u16,
        count: u16,
        timeout: Duration,
    ) -> Result<Vec<u16>, ReadError> {
        self.read(RegisterKind::Holding, slave, addr, count, timeout)
            .await
    }

    /// Reads `count` input registers (function 4) from `slave`.
    pub async fn read_input_registers(
        &mut self,
        slave: u8,
        addr: u16,
        count: u16,
        timeout: Duration,
    ) -> Result<Vec<u16>, ReadError> {
        self.read(RegisterKind::Input, slave, addr, count, timeout)
            .await
    }

    async fn read(
        &mut self,
        kind: RegisterKind,
        slave: u8,
        addr: u16,
        count: u16,
        timeout: Duration,
    ) -> Result<Vec<u16>, ReadError> {
        self.ctx.set_slave(Slave(slave));
        let call = async {
            match kind {
                RegisterKind::Holding => self.ctx.read_holding_registers(addr, count).await,
                RegisterKind::Input => self.ctx.read_input_registers(addr, count).await,
            }
        };
        let words = match tokio::time::timeout(timeout, call).await {
            Err(_) => return Err(ReadError::Timeout(timeout.as_millis() as u64)),
            Ok(Err(tokio_modbus::Error::Transport(e))) => return Err(ReadError::Io(e)),
            Ok(Err(tokio_modbus::Error::Protocol(e))) => {
                return Err(ReadError::Protocol(e.to_string()))
            }
            Ok(Ok(Err(code))) => return Err(ReadError::Exception(code)),
            Ok(Ok(Ok(words))) => words,
        };
        if words.len() < count as usize {
            return Err(ReadError::ShortResponse {
                got: words.len(),
                want: count as usize,
            });
        }
        Ok(words)
    }
}

/// Resolves `host:port` (DNS names allowed) to the first address.
pub(super) async fn resolve(endpoint: &str) -> Result<SocketAddr, ReadError> {
    tokio::net::lookup_host(endpoint)
        .await?
        .next()
        .ok_or_else(|| ReadError::Protocol(format!("{endpoint} resolves to no address")))
}
