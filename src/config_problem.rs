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

/// A numeric key's allowed range: `lo..=hi` in `unit` (`""` or e.g. `" ms"`), and why the
/// upper bound exists (what a larger value would break).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Bounds<'a> {
    pub(crate) lo: u64,
    pub(crate) hi: u64,
    pub(crate) unit: &'a str,
    pub(crate) why: &'a str,
}

/// Adds a problem if `value` is outside `b`, naming the key, the value and the bound.
pub(crate) fn check_range(problems: &mut Vec<ConfigProblem>, key: &str, value: u64, b: Bounds<'_>) {
    let Bounds { lo, hi, unit, why } = b;
    if value < lo {
        problems.push(ConfigProblem::new(
            key,
            format!("must be at least {lo}{unit}"),
        ));
    } else if value > hi {
        problems.push(ConfigProblem::new(
            key,
            format!("{value}{unit} is above the maximum {hi}{unit} ({why})"),
        ));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn check_range_names_key_value_and_bounds() {
        let mut p = Vec::new();
        let b = Bounds {
            lo: 1,
            hi: 10,
            unit: " ms",
            why: "why",
        };
        check_range(&mut p, "a.b", 5, b);
        assert!(p.is_empty());
        check_range(&mut p, "a.b", 0, b);
        check_range(&mut p, "a.c", u64::MAX, b);
        assert_eq!(p.len(), 2);
        assert_eq!(p[0].to_string(), "a.b: must be at least 1 ms");
        assert_eq!(
            p[1].to_string(),
            "a.c: 18446744073709551615 ms is above the maximum 10 ms (why)"
        );
    }
}
