//! Clock times on a time axis: UTC, as the run's date-times are read (a date-time without an
//! offset is taken as written). A calendar date from a day count is a few lines of arithmetic,
//! so the report links no date library for it.

/// Year, month, day of the day `days` after 1970-01-01 (the proleptic Gregorian calendar,
/// H. Hinnant's `civil_from_days`).
fn civil_from_days(days: i64) -> (i64, i64, i64) {
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z.rem_euclid(146_097);
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = doy - (153 * mp + 2) / 5 + 1;
    let month = if mp < 10 { mp + 3 } else { mp - 9 };
    let year = yoe + era * 400 + i64::from(month <= 2);
    (year, month, day)
}

/// Date and time to the minute, `2024-03-04 06:00`, of seconds since 1970-01-01 UTC.
pub(crate) fn date_time(unix_s: f64) -> String {
    let s = unix_s.round() as i64;
    let (y, m, d) = civil_from_days(s.div_euclid(86_400));
    format!("{y:04}-{m:02}-{d:02} {}", time_of_day(unix_s))
}

/// `HH:MM` of seconds since 1970-01-01 UTC.
pub(crate) fn time_of_day(unix_s: f64) -> String {
    let s = (unix_s.round() as i64).rem_euclid(86_400);
    format!("{:02}:{:02}", s / 3600, s % 3600 / 60)
}

/// A tick label: the time of day, with the day of the month in front when the axis spans
/// more than one day (`04. 18:00`).
pub(crate) fn tick(unix_s: f64, several_days: bool) -> String {
    if several_days {
        let (_, _, d) = civil_from_days((unix_s.round() as i64).div_euclid(86_400));
        format!("{d:02}. {}", time_of_day(unix_s))
    } else {
        time_of_day(unix_s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The same instants `truepos_io::timestamp` reads and prints.
    #[test]
    fn dates_and_times_of_known_instants() {
        assert_eq!(date_time(1_795_896_303.7), "2026-11-28 20:05");
        assert_eq!(date_time(0.0), "1970-01-01 00:00");
        // 2024-02-29 (a leap day) 23:59:30 rounds to the minute it shows: seconds are dropped.
        assert_eq!(date_time(1_709_251_170.0), "2024-02-29 23:59");
        assert_eq!(date_time(951_782_400.0), "2000-02-29 00:00");
        assert_eq!(tick(1_709_510_400.0 + 6.5 * 3600.0, true), "04. 06:30");
        assert_eq!(tick(1_709_510_400.0 + 6.5 * 3600.0, false), "06:30");
    }
}
