//! Numbers checked at the door: every number a person types (a command-line option, a replay
//! speed) is finite and inside a documented range before anything uses it, so that no NaN,
//! infinity or absurd magnitude reaches a `Duration`, an allocation or a loop bound.
//!
//! The parsers plug into clap as value parsers (`#[arg(value_parser = finite_in(0.1, 1e4))]`);
//! clap then names the option in its error. This crate stays free of clap: a value parser is
//! any `Fn(&str) -> Result<T, String>`.
//!
//! ```
//! use truepos_io::limits::{finite_in, int_in};
//! assert_eq!(finite_in(0.1, 10.0)("2.5"), Ok(2.5));
//! assert!(finite_in(0.1, 10.0)("nan").unwrap_err().contains("[0.1, 10]"));
//! assert!(int_in(1usize, 20)("0").unwrap_err().contains("1 to 20"));
//! ```

use std::fmt::Display;
use std::str::FromStr;

/// A parser of a finite number in `[lo, hi]`; the error states the range and what was given.
pub fn finite_in(lo: f64, hi: f64) -> impl Fn(&str) -> Result<f64, String> + Clone + Send + Sync {
    move |text: &str| match text.trim().parse::<f64>() {
        Ok(v) if v.is_finite() && v >= lo && v <= hi => Ok(v),
        _ => Err(format!(
            "expected a finite number in [{lo}, {hi}], got `{text}`"
        )),
    }
}

/// `v` if it is finite and in `[lo, hi]`, else an error stating the range.
pub fn check_in(v: f64, lo: f64, hi: f64) -> Result<f64, String> {
    if v.is_finite() && v >= lo && v <= hi {
        Ok(v)
    } else {
        // Debug shows 1e300 as such, where Display would print 301 digits.
        Err(format!(
            "expected a finite number in [{lo}, {hi}], got {v:?}"
        ))
    }
}

/// A parser of an integer in `lo..=hi`; the error states the range and what was given.
pub fn int_in<T>(lo: T, hi: T) -> impl Fn(&str) -> Result<T, String> + Clone + Send + Sync
where
    T: FromStr + PartialOrd + Display + Copy + Send + Sync,
{
    move |text: &str| match text.trim().parse::<T>() {
        Ok(v) if v >= lo && v <= hi => Ok(v),
        _ => Err(format!(
            "expected a whole number from {lo} to {hi}, got `{text}`"
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bounds_are_inclusive_and_non_finite_is_refused() {
        let p = finite_in(0.1, 10_000.0);
        assert_eq!(p("0.1"), Ok(0.1));
        assert_eq!(p("10000"), Ok(10_000.0));
        for bad in [
            "1e300", "1e-7", "nan", "NaN", "inf", "-inf", "", "x", "0.09",
        ] {
            let e = p(bad).unwrap_err();
            assert!(e.contains("[0.1, 10000]"), "{bad}: {e}");
        }
        let n = int_in(1usize, 20);
        assert_eq!(n("20"), Ok(20));
        for bad in ["0", "21", "-1", "1.5", "99999999999999999999999"] {
            assert!(n(bad).unwrap_err().contains("from 1 to 20"), "{bad}");
        }
    }
}
