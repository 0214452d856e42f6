//! One problem found while checking a configuration: which key, and why it is wrong.
//!
//! Shared by every config section's `validate()` so `gtwatch check-config` can list all
//! problems at once. Data only: no parsing, no I/O.

use std::fmt;

/// A configuration problem, e.g. `storage.batch_size: must be at least 1`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ConfigProblem {
    /// Dotted key path, e.g. `replay.time_column`.
    pub key: String,
    /// What is wrong and, where possible, what would be right.
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
