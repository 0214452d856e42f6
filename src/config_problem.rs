//! One problem found while checking a configuration: the key path it concerns and why.
//!
//! Shared by every config section's `validate`/`check`. Holds data only; no I/O.

use std::fmt;

/// A problem in a configuration, named by its key path (e.g. `modbus.request[2].field[3].address`).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ConfigProblem {
    pub key: String,
    pub message: String,
}

impl ConfigProblem {
    pub fn new(key: impl Into<String>, message: impl Into<String>) -> Self {
        ConfigProblem {
            key: key.into(),
            message: message.into(),
        }
    }
}

impl fmt::Display for ConfigProblem {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: {}", self.key, self.message)
    }
}
