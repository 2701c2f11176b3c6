//! The coefficients as a person checks them: one table per input (a sensor and its rise, lags
//! and rates; the spindle speed; the constants), each value with its unit, and where the model
//! file keeps a unit nobody reads (µm per K/s) the value in one they do (µm per K/h) beside the
//! stored one, so the file can still be checked against the report.

use std::fmt::Write as _;

use crate::html::escape;
use crate::Coefficient;

/// A number to four significant digits without an exponent for the magnitudes coefficients
/// have (0.0001 … 10⁵), else in scientific notation.
fn number(v: f64) -> String {
    let a = v.abs();
    if a == 0.0 {
        "0".into()
    } else if !(1e-4..1e5).contains(&a) {
        format!("{v:.3e}")
    } else {
        let decimals = (3 - a.log10().floor() as i32).max(0) as usize;
        format!("{v:.decimals$}")
    }
}

/// The inputs in the order they first appear, each with its coefficients.
fn grouped(coefficients: &[Coefficient]) -> Vec<(&str, Vec<&Coefficient>)> {
    let mut groups: Vec<(&str, Vec<&Coefficient>)> = Vec::new();
    for c in coefficients {
        match groups.iter_mut().find(|(input, _)| *input == c.input) {
            Some((_, list)) => list.push(c),
            None => groups.push((c.input.as_str(), vec![c])),
        }
    }
    groups
}

/// The coefficients section: a heading, a sentence on how to read it, then a table per input.
pub(crate) fn coefficient_tables(html: &mut String, coefficients: &[Coefficient]) {
    if coefficients.is_empty() {
        return;
    }
    html.push_str(
        "<h2>Coefficients</h2><p>Grouped by the input they act on. Each value is the error it \
         adds per unit of its term; where the model file keeps another unit, its stored value \
         is given beside it.</p>",
    );
    for (input, list) in grouped(coefficients) {
        let title = if input.is_empty() { "constants" } else { input };
        let converted = list.iter().any(|c| c.readable.is_some());
        let mut meanings: Vec<&str> = Vec::new();
        for c in &list {
            if !c.meaning.is_empty() && !meanings.contains(&c.meaning.as_str()) {
                meanings.push(&c.meaning);
            }
        }
        let meanings = if meanings.is_empty() {
            String::new()
        } else {
            format!("<p>{}</p>", escape(&meanings.join("; ")))
        };
        let _ = write!(
            html,
            "<section class=\"coefficients\"><h3>{}</h3>{meanings}<table><tr><th class=\"l\">error of</th>\
             <th class=\"l\">term</th><th>value</th>{}</tr>",
            escape(title),
            if converted {
                "<th>in the model file</th>"
            } else {
                ""
            }
        );
        for c in list {
            let stored = format!("{} {}", number(c.value), escape(&c.unit));
            let (shown, file) = match &c.readable {
                Some((v, unit)) => (format!("{} {}", number(*v), escape(unit)), stored),
                None => (stored, "same".to_string()),
            };
            let _ = write!(
                html,
                "<tr><td class=\"l\">{}</td><td class=\"l\">{}</td><td>{shown}</td>{}</tr>",
                escape(&c.channel),
                escape(&c.feature),
                if converted {
                    format!("<td>{file}</td>")
                } else {
                    String::new()
                }
            );
        }
        html.push_str("</table></section>");
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn c(input: &str, feature: &str, value: f64, unit: &str) -> Coefficient {
        Coefficient {
            channel: "Z".into(),
            input: input.into(),
            feature: feature.into(),
            meaning: String::new(),
            value,
            unit: unit.into(),
            readable: None,
        }
    }

    #[test]
    fn one_table_per_input_in_order_of_appearance() {
        let mut rate = c("t_spindle", "rate of rise, τ = 10 min", 36.0, "µm/(K/s)");
        rate.readable = Some((0.01, "µm/(K/h)".into()));
        let mut lagged = c("t_spindle", "dT_lag · ratio(X)", 0.5, "µm/K");
        lagged.meaning = "dT_lag = t_spindle lagged τ = 1 h − ambient".into();
        let list = [
            c("t_spindle", "rise", 2.5, "µm/K"),
            lagged.clone(),
            lagged,
            c("spindle speed", "lagged τ = 1 h", 0.001_2, "µm per 1/min"),
            rate,
            c("", "constant", -1.25, "µm"),
        ];
        let mut html = String::new();
        coefficient_tables(&mut html, &list);
        let heads: Vec<&str> = html
            .split("<h3>")
            .skip(1)
            .map(|s| &s[..s.find("</h3>").unwrap()])
            .collect();
        assert_eq!(heads, ["t_spindle", "spindle speed", "constants"]);
        let spindle = html.split("<h3>").nth(1).unwrap();
        assert!(
            spindle.contains("<td>2.500 µm/K</td><td>same</td>"),
            "{spindle}"
        );
        // What a symbol stands for is said once under the heading.
        assert_eq!(
            spindle
                .matches("<p>dT_lag = t_spindle lagged τ = 1 h − ambient</p>")
                .count(),
            1
        );
        assert!(spindle.contains("<td>0.01000 µm/(K/h)</td><td>36.00 µm/(K/s)</td>"));
        assert!(!html
            .split("<h3>")
            .nth(3)
            .unwrap()
            .contains("in the model file"));
    }

    #[test]
    fn numbers_keep_four_significant_digits() {
        assert_eq!(number(2.91234), "2.912");
        assert_eq!(number(-0.000_123_456), "-0.0001235");
        assert_eq!(number(1234.4), "1234");
        assert_eq!(number(3.2e-7), "3.200e-7");
        assert_eq!(number(0.0), "0");
    }
}
