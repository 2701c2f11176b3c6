//! ISO 8601 date-times in a run's time column, read with `jiff` (no time-zone database: the
//! crate built with `std` only, one small dependency).
//!
//! Accepted: a date and a time separated by `T` or a space, seconds optional, fractional
//! seconds (`.` or `,`), and optionally `Z` or an offset (`+02:00`). Also the day-first form
//! of German-speaking shops and their exports, `dd.mm.yyyy HH:MM[:SS[,fff]]` (the dots make it
//! day-first; a slash form like `03/04/2024` is ambiguous between day- and month-first and is
//! refused). A date-time without an
//! offset is taken as written, as if in UTC: without a zone a local clock's daylight-saving
//! jump cannot be known, so it shows as an hour's gap or as time going backwards (refused).
//!
//! ```
//! use truepos_io::timestamp::parse;
//! let a = parse("2024-03-01T08:00:00").unwrap();
//! let b = parse("2024-03-01 08:00:01.5").unwrap();
//! assert_eq!(b - a, 1_500_000_000);
//! assert_eq!(parse("2024-03-01T10:00:00+02:00"), Ok(a));
//! assert_eq!(parse("01.03.2024 08:00"), Ok(a));
//! assert!(parse("yesterday").is_err());
//! ```

/// Nanoseconds since 1970-01-01T00:00:00Z of an ISO 8601 date-time; the error sentence says
/// what was expected.
pub fn parse(text: &str) -> Result<i128, String> {
    let text = text.trim();
    // Only text that starts like a date is tried: `jiff` would take a bare number for nothing
    // useful, and a message about a number belongs to the number syntax.
    let date_like = text.len() >= 10
        && text.as_bytes()[..4].iter().all(u8::is_ascii_digit)
        && text.as_bytes()[4] == b'-';
    if date_like {
        if let Ok(ts) = text.parse::<jiff::Timestamp>() {
            return Ok(ts.as_nanosecond());
        }
        if let Ok(dt) = text.parse::<jiff::civil::DateTime>() {
            if let Ok(ts) = jiff::tz::Offset::UTC.to_timestamp(dt) {
                return Ok(ts.as_nanosecond());
            }
        }
    }
    if let Some(ns) = day_first(text) {
        return Ok(ns);
    }
    Err(format!(
        "expected seconds (a number), an ISO 8601 date-time like 2024-03-01T08:00:00 or a \
         day-first one like 01.03.2024 08:00:00, got `{text}`"
    ))
}

/// Nanoseconds since 1970-01-01T00:00:00Z of `text` read by a `strftime`-style `format`
/// (`%m/%d/%Y %I:%M %p`; `%z` for an offset, else taken as UTC like every date-time without
/// one); the error sentence names the format.
pub fn parse_with(format: &str, text: &str) -> Result<i128, String> {
    let text = text.trim();
    let bad = |why: String| {
        format!("expected a date-time in the form `{format}` (--time-format), got `{text}`: {why}")
    };
    let parsed = jiff::fmt::strtime::parse(format, text).map_err(|e| bad(e.to_string()))?;
    if let Ok(ts) = parsed.to_timestamp() {
        return Ok(ts.as_nanosecond());
    }
    let dt = parsed.to_datetime().map_err(|e| bad(e.to_string()))?;
    jiff::tz::Offset::UTC
        .to_timestamp(dt)
        .map(|ts| ts.as_nanosecond())
        .map_err(|e| bad(e.to_string()))
}

/// A day-first date-time, `dd.mm.yyyy HH:MM[:SS[.fff]]` (a decimal comma read as a point).
fn day_first(text: &str) -> Option<i128> {
    let (day, month, rest) = {
        let mut parts = text.splitn(3, '.');
        (parts.next()?, parts.next()?, parts.next()?)
    };
    let (year, time) = rest.split_once([' ', 'T'])?;
    let digits = |s: &str, n: std::ops::RangeInclusive<usize>| {
        n.contains(&s.len()) && s.bytes().all(|b| b.is_ascii_digit())
    };
    if !(digits(day, 1..=2) && digits(month, 1..=2) && digits(year, 4..=4)) {
        return None;
    }
    let iso = format!(
        "{year}-{month:0>2}-{day:0>2}T{}",
        time.trim().replace(',', ".")
    );
    let dt = iso.parse::<jiff::civil::DateTime>().ok()?;
    Some(jiff::tz::Offset::UTC.to_timestamp(dt).ok()?.as_nanosecond())
}

/// A clock time for a person, UTC to the second (`2026-11-28 20:05:03 UTC`), from seconds since
/// 1970-01-01T00:00:00Z; `None` for a value no clock shows.
pub fn format_utc(unix_s: f64) -> Option<String> {
    if !unix_s.is_finite() {
        return None;
    }
    let ts = jiff::Timestamp::from_second(unix_s.floor() as i64).ok()?;
    Some(ts.strftime("%Y-%m-%d %H:%M:%S UTC").to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn clock_times_for_a_person() {
        assert_eq!(
            format_utc(1_795_896_303.7).as_deref(),
            Some("2026-11-28 20:05:03 UTC")
        );
        assert_eq!(format_utc(f64::NAN), None);
        assert_eq!(format_utc(1e30), None);
    }

    #[test]
    fn forms_users_have() {
        let base = parse("2024-03-01T08:00:00").unwrap();
        let s = |t: &str| (parse(t).unwrap() - base) as f64 / 1e9;
        assert_eq!(s("2024-03-01T08:00:00Z"), 0.0);
        assert_eq!(s("2024-03-01 08:00:00"), 0.0);
        assert_eq!(s("2024-03-01T08:00"), 0.0);
        assert_eq!(s("2024-03-01T08:00:00.25"), 0.25);
        assert_eq!(s("2024-03-01T08:00:00,25"), 0.25);
        assert_eq!(s("2024-03-01T09:00:00+01:00"), 0.0);
        assert_eq!(s("2024-03-01T07:30:00-00:30"), 0.0);
        assert_eq!(s("2024-03-02T08:00:00"), 86_400.0);
        assert_eq!(s("01.03.2024 08:00:00"), 0.0);
        assert_eq!(s("1.3.2024 08:00"), 0.0);
        assert_eq!(s("01.03.2024 08:00:00,5"), 0.5);
        assert_eq!(s("02.03.2024 08:00:00"), 86_400.0);
        for bad in [
            "03/01/2024 08:00",
            "31.02.2024 08:00",
            "01.03.24 08:00",
            "01.03.2024",
            "",
            "12.5",
            "08:00:00",
            "2024-13-01T00:00:00",
            "2024-03-01T25:00",
            "x",
        ] {
            assert!(parse(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn a_stated_format_reads_the_forms_no_default_reads() {
        let base = parse("2024-03-01T20:00:00").unwrap();
        let us = "%m/%d/%Y %I:%M %p";
        assert_eq!(parse_with(us, "03/01/2024 08:00 PM"), Ok(base));
        assert_eq!(parse_with("%Y%m%d%H%M%S", "20240301200000"), Ok(base));
        assert_eq!(
            parse_with("%d/%m/%Y %H:%M %z", "01/03/2024 21:00 +0100"),
            Ok(base)
        );
        let e = parse_with(us, "13/01/2024 08:00 PM").unwrap_err();
        assert!(
            e.starts_with("expected a date-time in the form `%m/%d/%Y %I:%M %p`"),
            "{e}"
        );
        assert!(parse_with(us, "").is_err());
    }

    proptest::proptest! {
        /// Never a panic on any text.
        #[test]
        fn any_text(text in "\\PC{0,40}", format in "(%[a-zA-Z.:%]|[ /.:0-9a-z-]){0,12}") {
            let _ = parse(&text);
            let _ = parse_with(&format, &text);
        }

        /// Every date-time written the documented ways reads back to the same instant.
        #[test]
        fn written_forms_agree(
            y in 1970i32..2200, mo in 1u32..13, d in 1u32..29, h in 0u32..24, mi in 0u32..60,
            s in 0u32..60, ms in 0u32..1000, off in -12i32..15
        ) {
            let civil = format!("{y:04}-{mo:02}-{d:02}T{h:02}:{mi:02}:{s:02}.{ms:03}");
            let t = parse(&civil).unwrap();
            proptest::prop_assert_eq!(parse(&civil.replace('T', " ")), Ok(t));
            proptest::prop_assert_eq!(parse(&format!("{civil}Z")), Ok(t));
            let sign = if off < 0 { '-' } else { '+' };
            let shifted = parse(&format!("{civil}{sign}{:02}:00", off.abs())).unwrap();
            proptest::prop_assert_eq!(t - shifted, i128::from(off) * 3_600_000_000_000);
            let day = parse(&format!("{y:04}-{mo:02}-{d:02}T00:00:00")).unwrap();
            let expect = (i128::from(h) * 3600 + i128::from(mi) * 60 + i128::from(s)) * 1_000_000_000
                + i128::from(ms) * 1_000_000;
            proptest::prop_assert_eq!(t - day, expect);
            let german = format!("{d:02}.{mo:02}.{y:04} {h:02}:{mi:02}:{s:02},{ms:03}");
            proptest::prop_assert_eq!(parse(&german), Ok(t));
        }
    }
}
