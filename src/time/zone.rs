//! Local wall-clock time stamps of one IANA time zone (`Europe/Berlin`) to UTC instants, one
//! row after another, as a historian export writes them.
//!
//! A local time is placed by the zone's rules (the IANA database through `jiff`): an ordinary
//! time has one offset; a time inside the spring gap (02:00–03:00 on the last Sunday of March in
//! Europe/Berlin) does not exist and is refused ([`StampError::Nonexistent`]); a time inside the
//! repeated autumn hour exists twice and is resolved by row order: while the rows go forward in
//! local time the earlier (summer) offset holds; when the local clock steps back by at least
//! half the repeated span inside it, the rows are in the second pass and take the later (winter)
//! offset until the next unambiguous time. A stamp that carries `Z` or an offset is an instant
//! already and always wins over the zone; epoch formats are UTC by definition.
//!
//! Must not know about CSV, columns, the store or the wall clock: it only turns text into
//! epoch milliseconds, keeping the little state the row order needs.

use super::{local_as_utc_ms, parse_iso8601_stamp, parse_time, Stamp, TimeFormat};
use jiff::tz::{AmbiguousOffset, Offset, TimeZone};

/// Why a time stamp could not be placed.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum StampError {
    /// Not a time stamp of the expected format.
    Unreadable(String),
    /// A local time the zone skips (the spring gap): no instant has it.
    Nonexistent(String),
}

/// Reads time stamps in one zone, remembering where the last local time fell (for the
/// repeated autumn hour). One clock per sequence of rows that goes forward in time: one per
/// file for a wide CSV, one per tag for a long one.
#[derive(Debug, Clone)]
pub struct LocalClock {
    /// `None`: UTC, the old rule (no offset = UTC) without a zone lookup.
    tz: Option<TimeZone>,
    name: String,
    /// The previous local time placed by the zone, read as if UTC (ms).
    prev_local_ms: Option<i64>,
    /// Inside a repeated hour, after the clock stepped back: the later offset applies.
    second_pass: bool,
}

/// Whether `name` is a time zone [`LocalClock::new`] accepts; `None` if it is.
pub fn zone_problem(name: &str) -> Option<String> {
    LocalClock::new(name).err()
}

impl LocalClock {
    /// A clock for the IANA zone `name` (`UTC`, `Europe/Berlin`, `America/Chicago`, …).
    pub fn new(name: &str) -> Result<LocalClock, String> {
        let trimmed = name.trim();
        let tz = if trimmed == "UTC" {
            None
        } else if trimmed.is_empty() {
            return Err("must name an IANA time zone such as \"UTC\" or \"Europe/Berlin\"".into());
        } else {
            Some(TimeZone::get(trimmed).map_err(|_| {
                format!(
                    "'{trimmed}' is not an IANA time zone (examples: \"UTC\", \"Europe/Berlin\", \
                     \"America/Chicago\"; names are case-sensitive)"
                )
            })?)
        };
        Ok(LocalClock {
            tz,
            name: trimmed.to_string(),
            prev_local_ms: None,
            second_pass: false,
        })
    }

    /// The zone's name as configured.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Reads one time stamp to Unix epoch ms. Without a zone (UTC) this is [`parse_time`].
    pub fn read(&mut self, raw: &[u8], fmt: TimeFormat) -> Result<i64, StampError> {
        if self.tz.is_none() || fmt != TimeFormat::Iso8601 {
            return parse_time(raw, fmt).map_err(StampError::Unreadable);
        }
        let s = std::str::from_utf8(raw.trim_ascii())
            .map_err(|_| StampError::Unreadable("not UTF-8".into()))?;
        if s.is_empty() {
            return Err(StampError::Unreadable("empty".into()));
        }
        match parse_iso8601_stamp(s).map_err(StampError::Unreadable)? {
            Stamp::Instant(t) => Ok(t),
            Stamp::Local(dt) => self.place(dt, s),
        }
    }

    /// Places a local date-time by the zone's rules and the row order.
    fn place(&mut self, dt: ::time::PrimitiveDateTime, text: &str) -> Result<i64, StampError> {
        let local_ms = local_as_utc_ms(dt);
        let Some(tz) = &self.tz else {
            return Ok(local_ms);
        };
        let unreadable = |e: String| StampError::Unreadable(e);
        let civil = jiff::civil::DateTime::new(
            i16::try_from(dt.year()).map_err(|e| unreadable(e.to_string()))?,
            dt.month() as i8,
            dt.day() as i8,
            dt.hour() as i8,
            dt.minute() as i8,
            dt.second() as i8,
            dt.nanosecond() as i32,
        )
        .map_err(|e| unreadable(e.to_string()))?;
        let offset = match tz.to_ambiguous_timestamp(civil).offset() {
            AmbiguousOffset::Unambiguous { offset } => {
                self.second_pass = false;
                offset
            }
            AmbiguousOffset::Gap { before, after } => {
                return Err(StampError::Nonexistent(format!(
                    "local time {text} does not exist in {}: the clocks jumped from UTC{} to \
                     UTC{} (spring gap)",
                    self.name,
                    fmt_offset(before),
                    fmt_offset(after)
                )));
            }
            AmbiguousOffset::Fold { before, after } => {
                let span_ms = i64::from(before.seconds() - after.seconds()) * 1000;
                if let Some(prev) = self.prev_local_ms {
                    if !self.second_pass && prev - local_ms >= span_ms / 2 {
                        self.second_pass = true;
                    }
                }
                if self.second_pass {
                    after
                } else {
                    before
                }
            }
        };
        self.prev_local_ms = Some(local_ms);
        Ok(local_ms - i64::from(offset.seconds()) * 1000)
    }
}

/// `+02:00`, `-05:30`.
fn fmt_offset(o: Offset) -> String {
    let s = o.seconds();
    let sign = if s < 0 { '-' } else { '+' };
    let a = s.unsigned_abs();
    format!("{sign}{:02}:{:02}", a / 3600, (a % 3600) / 60)
}

#[cfg(test)]
mod tests {
    use super::*;

    const H: i64 = 3_600_000;

    fn utc(s: &str) -> i64 {
        crate::time::parse_iso8601_ms(s).expect("utc")
    }

    #[test]
    fn utc_is_the_old_rule_and_offsets_always_win() {
        let mut c = LocalClock::new("UTC").expect("utc");
        assert_eq!(
            c.read(b"2026-10-25 02:30:00", TimeFormat::Iso8601),
            Ok(utc("2026-10-25T02:30:00Z"))
        );
        let mut b = LocalClock::new("Europe/Berlin").expect("berlin");
        assert_eq!(
            b.read(b"2026-07-01T12:00:00Z", TimeFormat::Iso8601),
            Ok(utc("2026-07-01T12:00:00Z"))
        );
        assert_eq!(
            b.read(b"2026-07-01T12:00:00+05:00", TimeFormat::Iso8601),
            Ok(utc("2026-07-01T07:00:00Z"))
        );
        assert_eq!(
            b.read(b"1782900000", TimeFormat::EpochS),
            Ok(1_782_900_000_000)
        );
    }

    #[test]
    fn berlin_summer_winter_gap_and_fold() {
        let mut b = LocalClock::new("Europe/Berlin").expect("berlin");
        let mut r = |s: &str| b.read(s.as_bytes(), TimeFormat::Iso8601);
        assert_eq!(r("2026-01-15 12:00:00"), Ok(utc("2026-01-15T11:00:00Z")));
        assert_eq!(r("2026-07-15 12:00:00"), Ok(utc("2026-07-15T10:00:00Z")));
        assert_eq!(r("2026-03-29 01:59:59"), Ok(utc("2026-03-29T00:59:59Z")));
        let gap = r("2026-03-29 02:30:00").expect_err("gap");
        assert!(
            matches!(&gap, StampError::Nonexistent(m) if m.contains("Europe/Berlin")),
            "{gap:?}"
        );
        assert_eq!(r("2026-03-29 03:00:00"), Ok(utc("2026-03-29T01:00:00Z")));
        // The repeated hour: first pass summer, after the step back winter, then unambiguous.
        assert_eq!(r("2026-10-25 01:59:59"), Ok(utc("2026-10-24T23:59:59Z")));
        assert_eq!(r("2026-10-25 02:00:00"), Ok(utc("2026-10-25T00:00:00Z")));
        assert_eq!(r("2026-10-25 02:59:59"), Ok(utc("2026-10-25T00:59:59Z")));
        assert_eq!(r("2026-10-25 02:00:00"), Ok(utc("2026-10-25T01:00:00Z")));
        assert_eq!(r("2026-10-25 02:59:59"), Ok(utc("2026-10-25T01:59:59Z")));
        assert_eq!(r("2026-10-25 03:00:00"), Ok(utc("2026-10-25T02:00:00Z")));
        assert_eq!(
            utc("2026-10-25T02:00:00Z") - utc("2026-10-25T00:00:00Z"),
            2 * H
        );
    }

    #[test]
    fn a_small_step_back_in_the_first_pass_is_not_the_second_pass() {
        let mut b = LocalClock::new("Europe/Berlin").expect("berlin");
        let mut r = |s: &str| b.read(s.as_bytes(), TimeFormat::Iso8601);
        assert_eq!(r("2026-10-25 02:30:00"), Ok(utc("2026-10-25T00:30:00Z")));
        // One second back: a glitch, left in summer time (the replay then refuses it).
        assert_eq!(r("2026-10-25 02:29:59"), Ok(utc("2026-10-25T00:29:59Z")));
        // Sparse rows: 10 minutes apart still see the step back of 50 minutes.
        assert_eq!(r("2026-10-25 02:50:00"), Ok(utc("2026-10-25T00:50:00Z")));
        assert_eq!(r("2026-10-25 02:00:00"), Ok(utc("2026-10-25T01:00:00Z")));
    }

    #[test]
    fn bad_names_are_refused() {
        assert!(zone_problem("Europe/Berlin").is_none());
        assert!(zone_problem("UTC").is_none());
        let e = zone_problem("Europe/Berlni").expect("bad");
        assert!(e.contains("Europe/Berlni"), "{e}");
        assert!(zone_problem("").is_some());
    }
}
