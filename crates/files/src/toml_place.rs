//! Where a key of a TOML text stands: a mistake found after parsing — a value out of range, a
//! channel naming no machine input — is named at its line and column like a syntax error.
//!
//! A key path is a list of [`Step`]s (`channel[2].register` is `channel`, the second table of
//! the array, `register`); [`span`] finds the deepest step the text has, so a missing key is
//! named at the table that should hold it.
//!
//! ```
//! use truepos_files::toml_place::{place, steps};
//! let text = "address = \"plc:502\"\n[[channel]]\nregister = 1\n[[channel]]\nregister = -4\n";
//! assert_eq!(place(text, &steps("channel[2].register")), Some((5, 1)));
//! ```

use std::ops::Range;

/// One step of a key path.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Step<'a> {
    /// A key of a table.
    Key(&'a str),
    /// An element of an array or an array of tables, counted from 0.
    Index(usize),
}

/// A key path as users read it, `a.b[1].c`, as steps; indices in brackets count from 1, as
/// every message of the project counts a file's tables (`channel[1]` is the first).
pub fn steps(key: &str) -> Vec<Step<'_>> {
    let mut out = Vec::new();
    for part in key.split('.').filter(|p| !p.is_empty()) {
        let (name, mut rest) = part.split_once('[').map_or((part, ""), |(n, r)| (n, r));
        if !name.is_empty() {
            out.push(Step::Key(name));
        }
        while let Some((index, after)) = rest.split_once(']') {
            if let Ok(i) = index.trim().parse::<usize>() {
                out.push(Step::Index(i.saturating_sub(1)));
            }
            rest = after.trim_start_matches('[');
        }
    }
    out
}

/// The byte range of the deepest step of `path` that `text` holds, or `None` when the text does
/// not parse or holds not even the first step.
pub fn span(text: &str, path: &[Step]) -> Option<Range<usize>> {
    let doc = toml_edit::ImDocument::parse(text).ok()?;
    in_table(doc.as_table(), path, None)
}

/// [`span`] as the 1-based line and column of its start ([`crate::line_column`]).
pub fn place(text: &str, path: &[Step]) -> Option<(usize, usize)> {
    span(text, path).map(|s| crate::line_column(text, s.start))
}

/// The key written on the line of `offset` (`key = …`), or the table a header line names
/// (`[[channel]]` → `channel`): the key of a mistake the TOML reader found, which names only
/// its place.
pub fn key_on_line(text: &str, offset: usize) -> String {
    let mut offset = offset.min(text.len());
    while !text.is_char_boundary(offset) {
        offset -= 1;
    }
    let start = text[..offset].rfind('\n').map_or(0, |i| i + 1);
    let end = text[start..].find('\n').map_or(text.len(), |i| start + i);
    let line = text[start..end].trim();
    match line.split_once('=') {
        Some((k, _)) => k.trim().to_string(),
        None => line
            .trim_matches(|c| c == '[' || c == ']')
            .trim()
            .to_string(),
    }
}

fn in_table(
    table: &toml_edit::Table,
    path: &[Step],
    mut found: Option<Range<usize>>,
) -> Option<Range<usize>> {
    let mut here: &dyn toml_edit::TableLike = table;
    for (n, step) in path.iter().enumerate() {
        let Step::Key(k) = step else { return found };
        let Some((key, item)) = here.get_key_value(k) else {
            return found;
        };
        found = key.span().or(found);
        let next = path.get(n + 1);
        if let (Some(tables), Some(Step::Index(i))) = (item.as_array_of_tables(), next) {
            let Some(t) = tables.get(*i) else {
                return found;
            };
            return in_table(t, &path[n + 2..], t.span().or(found));
        }
        if let (Some(array), Some(Step::Index(i))) = (item.as_array(), next) {
            let Some(v) = array.get(*i) else {
                return found;
            };
            return match v.as_inline_table() {
                Some(t) if n + 2 < path.len() => in_inline(t, &path[n + 2..], v.span().or(found)),
                _ => v.span().or(found),
            };
        }
        match item.as_table_like() {
            Some(inner) => here = inner,
            None => return found,
        }
    }
    found
}

fn in_inline(
    table: &toml_edit::InlineTable,
    path: &[Step],
    found: Option<Range<usize>>,
) -> Option<Range<usize>> {
    let Some(Step::Key(k)) = path.first() else {
        return found;
    };
    match table.get_key_value(k) {
        Some((key, _)) => key.span().or(found),
        None => found,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const TEXT: &str = "\
address = \"127.0.0.1:502\"
[backoff]
initial_ms = 0

[[channel]]
register = 1
temperature = \"a\"

[[channel]]
register = 2
points = [{ x = 1 }, { y = 2 }]
";

    #[test]
    fn a_key_path_is_found_at_its_line_and_column() {
        assert_eq!(place(TEXT, &steps("address")), Some((1, 1)));
        assert_eq!(place(TEXT, &steps("backoff.initial_ms")), Some((3, 1)));
        assert_eq!(place(TEXT, &steps("channel[1].temperature")), Some((7, 1)));
        assert_eq!(place(TEXT, &steps("channel[2].register")), Some((10, 1)));
        assert_eq!(
            place(TEXT, &steps("channel[2].points[2].y")),
            Some((11, 24))
        );
    }

    #[test]
    fn a_missing_key_is_named_at_the_deepest_step_the_text_holds() {
        // channel[2] has no `axis`: its table's header.
        assert_eq!(place(TEXT, &steps("channel[2].axis")), Some((9, 1)));
        assert_eq!(place(TEXT, &steps("channel[9].axis")), Some((5, 3)));
        assert_eq!(place(TEXT, &steps("nothing")), None);
        assert_eq!(place("a = [", &steps("a")), None);
    }

    #[test]
    fn the_key_on_a_line_is_its_assignment_or_its_header() {
        let at = |needle: &str| TEXT.find(needle).unwrap();
        assert_eq!(key_on_line(TEXT, at("0\n")), "initial_ms");
        assert_eq!(key_on_line(TEXT, at("[backoff]") + 2), "backoff");
        assert_eq!(key_on_line(TEXT, at("[[channel]]")), "channel");
        assert_eq!(key_on_line(TEXT, TEXT.len() + 10), "");
    }

    #[test]
    fn steps_count_brackets_from_one() {
        assert_eq!(
            steps("channel[2].points[1].y"),
            [
                Step::Key("channel"),
                Step::Index(1),
                Step::Key("points"),
                Step::Index(0),
                Step::Key("y")
            ]
        );
        assert_eq!(steps("channel[0]"), [Step::Key("channel"), Step::Index(0)]);
        assert!(steps("").is_empty());
    }
}
