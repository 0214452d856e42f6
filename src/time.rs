//! Time stamps as text: parsing the formats logs and command lines use (ISO 8601 with or without
//! an offset, Unix seconds, Unix milliseconds) to Unix epoch milliseconds, and formatting epoch
//! milliseconds back as UTC text for messages, exports, charts and reports; and (`zone`) local
//! wall-clock stamps of an IANA time zone to UTC instants.
//!
//! The one place for this: every other module (replay, acquisition messages, charts, reports,
//! the commands) calls it rather than keeping a copy. Foundation floor: depends on no other
//! module of the crate. Must not read or stamp the wall clock's time into data, do I/O, or know
//! about CSV columns, the store or the daemon.

use ::time::format_description::well_known::Rfc3339;
use serde::{Deserialize, Serialize};

mod zone;
pub use zone::{zone_problem, LocalClock, StampError};

/// How the time column is written.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum TimeFormat {
    #[default]
    Iso8601,
    EpochS,
    EpochMs,
}

/// Formats epoch ms as ISO 8601 UTC (for messages and exports).
pub fn fmt_ms(t_ms: i64) -> String {
    let fmt = ::time::macros::format_description!(
        "[year]-[month]-[day]T[hour]:[minute]:[second].[subsecond digits:3]Z"
    );
    ::time::OffsetDateTime::from_unix_timestamp_nanos(i128::from(t_ms) * 1_000_000)
        .ok()
        .and_then(|t| t.format(&fmt).ok())
        .unwrap_or_else(|| format!("{t_ms} ms"))
}

/// Formats epoch ms as RFC 3339 UTC (`2024-03-01T12:00:00Z`, sub-second digits only where there
/// are any), as the `wash` commands print their times.
pub fn fmt_ms_rfc3339(ms: i64) -> String {
    ::time::OffsetDateTime::from_unix_timestamp_nanos(i128::from(ms) * 1_000_000)
        .ok()
        .and_then(|t| t.format(&Rfc3339).ok())
        .unwrap_or_else(|| format!("{ms} ms"))
}

/// Formats a date-time as RFC 3339 (`?` if it cannot be written), e.g. a file header's
/// "generated at".
pub fn fmt_rfc3339(t: ::time::OffsetDateTime) -> String {
    t.format(&Rfc3339).unwrap_or_else(|_| "?".into())
}

/// Parses a time stamp to Unix epoch ms. ISO 8601 without an offset is UTC.
pub fn parse_time(raw: &[u8], fmt: TimeFormat) -> Result<i64, String> {
    let s = std::str::from_utf8(raw.trim_ascii()).map_err(|_| "not UTF-8".to_string())?;
    if s.is_empty() {
        return Err("empty".into());
    }
    match fmt {
        TimeFormat::EpochMs => {
            if let Ok(v) = s.parse::<i64>() {
                return Ok(v);
            }
            let v: f64 = s.parse().map_err(|_| "not a number".to_string())?;
            finite_ms(v)
        }
        TimeFormat::EpochS => {
            if let Ok(v) = s.parse::<i64>() {
                return v.checked_mul(1000).ok_or_else(|| "out of range".into());
            }
            let v: f64 = s.parse().map_err(|_| "not a number".to_string())?;
            finite_ms(v * 1000.0)
        }
        TimeFormat::Iso8601 => parse_iso8601_ms(s),
    }
}

fn finite_ms(v: f64) -> Result<i64, String> {
    if v.is_finite() && v.abs() < 1e17 {
        Ok(v.round() as i64)
    } else {
        Err("out of range".into())
    }
}

/// ISO 8601 date-time to epoch ms; `T` or a space between date and time; no offset = UTC.
/// A bare date (`2024-03-01`) is midnight UTC.
pub fn parse_iso8601_ms(s: &str) -> Result<i64, String> {
    Ok(match parse_iso8601_stamp(s)? {
        Stamp::Instant(t) => t,
        Stamp::Local(dt) => local_as_utc_ms(dt),
    })
}

/// An ISO 8601 text as written: an instant (it carried `Z` or an offset) or a local date-time
/// without an offset, which only a time zone can place.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stamp {
    /// Unix epoch ms.
    Instant(i64),
    /// Wall-clock date and time, no offset (a bare date is its midnight).
    Local(::time::PrimitiveDateTime),
}

/// A local date-time read as if it were UTC, in epoch ms (the "no offset = UTC" rule).
pub fn local_as_utc_ms(dt: ::time::PrimitiveDateTime) -> i64 {
    (dt.assume_utc().unix_timestamp_nanos() / 1_000_000) as i64
}

/// ISO 8601 text to a [`Stamp`]; `T` or a space between date and time.
pub fn parse_iso8601_stamp(s: &str) -> Result<Stamp, String> {
    use ::time::format_description::well_known::Iso8601;
    let s = s.trim();
    let owned;
    let s = if s.len() > 10 && s.as_bytes()[10] == b' ' {
        owned = format!("{}T{}", &s[..10], &s[11..]);
        owned.as_str()
    } else {
        s
    };
    if let Ok(t) = ::time::OffsetDateTime::parse(s, &Iso8601::DEFAULT) {
        return Ok(Stamp::Instant(
            (t.unix_timestamp_nanos() / 1_000_000) as i64,
        ));
    }
    if let Ok(t) = ::time::PrimitiveDateTime::parse(s, &Iso8601::DEFAULT) {
        return Ok(Stamp::Local(t));
    }
    match ::time::Date::parse(s, &Iso8601::DEFAULT) {
        Ok(d) => Ok(Stamp::Local(d.midnight())),
        Err(e) => Err(date_problem(s).unwrap_or_else(|| e.to_string())),
    }
}

/// For a `YYYY-MM-DD…` text whose date part is out of range, says which part (the `time`
/// parser only says "unexpected trailing characters" for `2024-13-01`).
fn date_problem(s: &str) -> Option<String> {
    let b = s.as_bytes();
    if b.len() < 10 || b[4] != b'-' || b[7] != b'-' {
        return None;
    }
    let year: i32 = s.get(0..4)?.parse().ok()?;
    let month: u8 = s.get(5..7)?.parse().ok()?;
    let day: u8 = s.get(8..10)?.parse().ok()?;
    let month = match ::time::Month::try_from(month) {
        Ok(m) => m,
        Err(_) => return Some(format!("month {month} is not 1 … 12")),
    };
    match ::time::Date::from_calendar_date(year, month, day) {
        Ok(_) => None,
        Err(_) => Some(format!("day {day} does not exist in {month} {year}")),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn time_formats() {
        let ms = |s: &str, f| parse_time(s.as_bytes(), f);
        assert_eq!(
            ms("2024-03-01T00:00:00Z", TimeFormat::Iso8601),
            Ok(1_709_251_200_000)
        );
        assert_eq!(
            ms("2024-03-01T01:00:00+01:00", TimeFormat::Iso8601),
            Ok(1_709_251_200_000)
        );
        // No offset = UTC; a space instead of T; fractions.
        assert_eq!(
            ms("2024-03-01 00:00:00.250", TimeFormat::Iso8601),
            Ok(1_709_251_200_250)
        );
        assert_eq!(ms("2024-03-01", TimeFormat::Iso8601), Ok(1_709_251_200_000));
        assert_eq!(ms("1709251200", TimeFormat::EpochS), Ok(1_709_251_200_000));
        assert_eq!(
            ms("1709251200.5", TimeFormat::EpochS),
            Ok(1_709_251_200_500)
        );
        assert_eq!(
            ms("1709251200500", TimeFormat::EpochMs),
            Ok(1_709_251_200_500)
        );
        assert!(ms("yesterday", TimeFormat::Iso8601).is_err());
        assert!(ms("12:00", TimeFormat::EpochS).is_err());
        assert_eq!(fmt_ms(1_709_251_200_250), "2024-03-01T00:00:00.250Z");
    }

    #[test]
    fn out_of_range_dates_say_which_part() {
        // Regression (issue 12 #9): `segments --since 2024-13-01` said only "unexpected trailing
        // characters".
        let e = parse_iso8601_ms("2024-13-01").expect_err("month 13");
        assert!(e.contains("month 13"), "{e}");
        let e = parse_iso8601_ms("2023-02-29").expect_err("no leap day");
        assert!(e.contains("day 29"), "{e}");
        assert!(parse_iso8601_ms("2024-02-29").is_ok());
    }
}
