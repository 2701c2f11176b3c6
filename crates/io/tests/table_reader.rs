//! The one table reader (`truepos_io::table`) on random CSV: cells with quoting, blanks, empty
//! lines and comments. It never panics, every cell keeps its text and its line and character
//! column, and every error a caller builds from a cell names that line and column.

use std::path::Path;

use proptest::prelude::*;
use truepos_io::table::{self, CsvOptions, Value};

/// A cell as written in the file and what the reader must make of it.
fn cell() -> impl Strategy<Value = (String, String)> {
    prop_oneof![
        3 => (-1e6f64..1e6).prop_map(|v| (v.to_string(), v.to_string())),
        1 => Just((String::new(), String::new())),
        1 => Just(("  ".to_string(), String::new())),
        1 => "[a-zé°]{1,5}".prop_map(|s| (s.clone(), s)),
        1 => "[a-z ,]{0,5}".prop_map(|s| (format!("\"{s}\""), s.trim().to_string())),
        1 => "[a-z]{0,3}".prop_map(|s| (format!("\"{s}\"\"x\""), format!("{s}\"x"))),
        1 => Just(("NaN".to_string(), "NaN".to_string())),
    ]
}

fn expected(text: &str) -> Value<'_> {
    if text.is_empty() {
        Value::Empty
    } else {
        match text.parse::<f64>() {
            Ok(v) if v.is_finite() => Value::Number(v),
            _ => Value::Text(text),
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(300))]

    /// Arbitrary bytes and arbitrary text: no panic, with or without comments.
    #[test]
    fn never_panics(bytes in prop::collection::vec(any::<u8>(), 0..200), text in "[a-z0-9,\"#\r\n .é-]{0,120}") {
        for comments in [false, true] {
            let o = CsvOptions {
                comments,
                ..Default::default()
            };
            if let Ok(t) = table::parse_csv(Path::new("t.csv"), &bytes, o) {
                for r in 0..t.len() {
                    let _ = t.width_error(r);
                    for c in 0..t.row(r).len() {
                        let _ = t.row(r).number(c);
                        let _ = t.at(r, c, "x").to_string();
                        let _ = t.at_character(r, c, "x").to_string();
                    }
                }
            }
            let t = table::parse_csv(Path::new("t.csv"), text.as_bytes(), o).unwrap();
            for r in t.rows() {
                prop_assert!(r.line() >= 1);
                for c in r.cells() {
                    prop_assert!(c.line >= 1 && c.column >= 1);
                }
            }
        }
    }

    /// A grid of random cells, with empty lines between rows: each cell reads as written, at
    /// its line and character column, and an error about it names both.
    #[test]
    fn cells_keep_text_and_place(
        grid in prop::collection::vec(prop::collection::vec(cell(), 3), 1..6),
        blank in prop::collection::vec(any::<bool>(), 6),
    ) {
        let mut text = String::from("a,b,c\n");
        let mut line = 2;
        let mut places = Vec::new();
        for (r, row) in grid.iter().enumerate() {
            if blank[r] {
                text.push('\n');
                line += 1;
            }
            let mut column = 1;
            let mut cols = Vec::new();
            for (c, (written, _)) in row.iter().enumerate() {
                if c > 0 {
                    text.push(',');
                    column += 1;
                }
                cols.push(column);
                text.push_str(written);
                column += written.chars().count();
            }
            text.push('\n');
            places.push((line, cols));
            line += 1;
        }
        let t = table::parse_csv(Path::new("t.csv"), text.as_bytes(), CsvOptions::default()).unwrap();
        prop_assert_eq!(&t.columns, &["a", "b", "c"]);
        prop_assert_eq!(t.len(), grid.len());
        for (r, row) in grid.iter().enumerate() {
            let got = t.row(r);
            prop_assert!(t.width_error(r).is_none());
            prop_assert_eq!(got.line(), places[r].0);
            for (c, (_, value)) in row.iter().enumerate() {
                let cell = got.cell(c).unwrap();
                prop_assert_eq!(cell.value, expected(value), "{:?}", text);
                prop_assert_eq!(cell.line as usize, places[r].0);
                prop_assert_eq!(cell.column as usize, places[r].1[c]);
                let e = t.at(r, c, "expected x").to_string();
                let want = format!("t.csv:{}:{}: `{}`: expected x", places[r].0, c + 1, t.columns[c]);
                prop_assert_eq!(e, want);
                let e = t.at_character(r, c, "expected x").to_string();
                let want = format!("t.csv:{}:{}: `{}`: expected x", places[r].0, places[r].1[c], t.columns[c]);
                prop_assert_eq!(e, want);
            }
        }
    }

    /// A row narrower or wider than the header is an error naming its line.
    #[test]
    fn width_errors_name_the_line(widths in prop::collection::vec(1usize..5, 1..6)) {
        let mut text = String::from("a,b,c\n");
        for w in &widths {
            text.push_str(&vec!["1"; *w].join(","));
            text.push('\n');
        }
        let t = table::parse_csv(Path::new("t.csv"), text.as_bytes(), CsvOptions::default()).unwrap();
        for (r, w) in widths.iter().enumerate() {
            match t.width_error(r) {
                None => prop_assert_eq!(*w, 3),
                Some(e) => prop_assert_eq!(
                    e.to_string(),
                    format!("t.csv:{}:1: expected 3 fields as in the header, found {}", r + 2, w)
                ),
            }
        }
    }
}
