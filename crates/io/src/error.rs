//! The one error type of every parser: it names the file, the line and column, the key and what
//! was expected, so that a person can fix the file without reading code.

use std::path::Path;

pub use truepos_files::line_column;
use truepos_files::InputError;

/// Reads a whole text file of one kind through the one door ([`truepos_files::read`]: a
/// regular file only, within the kind's size limit, opened without blocking), naming it in the
/// error.
pub fn read_text(path: &Path, limit: truepos_files::Limit) -> Result<String, InputError> {
    truepos_files::read::read_text(path, limit).map_err(InputError::from)
}

/// Deserialises TOML text, turning syntax and type errors into an [`InputError`] that names the
/// line, column and key path.
pub(crate) fn parse_toml<T: serde::de::DeserializeOwned>(
    path: &Path,
    text: &str,
) -> Result<T, InputError> {
    let de = toml::Deserializer::new(text);
    serde_path_to_error::deserialize(de).map_err(|e| {
        // Spanned<T> wraps its value in a private field; the user's key ends before it.
        let key = e
            .path()
            .to_string()
            .replace(".$__serde_spanned_private_value", "");
        let key = if key == "." { String::new() } else { key };
        let inner = e.into_inner();
        let message = inner.message().trim().to_string();
        match inner.span() {
            Some(span) => InputError::at_span(path, text, span, key, message),
            None => InputError {
                file: path.to_path_buf(),
                position: None,
                key: Some(key).filter(|k| !k.is_empty()),
                message,
            },
        }
    })
}

/// Deserialises JSON text, turning syntax and type errors into an [`InputError`] that names the
/// line, column (in characters) and key path.
pub(crate) fn parse_json<T: serde::de::DeserializeOwned>(
    path: &Path,
    text: &str,
) -> Result<T, InputError> {
    let mut de = serde_json::Deserializer::from_str(text);
    serde_path_to_error::deserialize(&mut de).map_err(|e| {
        // `?` stands for a key a syntax error came before; the key is the part before it.
        let key = e.path().to_string();
        let key = key.split('?').next().unwrap_or("");
        let key = key
            .trim_start_matches('.')
            .trim_end_matches('.')
            .to_string();
        let inner = e.into_inner();
        // serde_json appends " at line L column C" (column in bytes); the position goes in front.
        let message = inner.to_string();
        let message = message
            .rsplit_once(" at line ")
            .map_or(message.as_str(), |(m, _)| m)
            .to_string();
        let line_start = if inner.line() <= 1 {
            0
        } else {
            text.match_indices('\n')
                .nth(inner.line() - 2)
                .map_or(text.len(), |(i, _)| i + 1)
        };
        // serde_json places a type error at the end of the value; the value's start is where
        // a person looks.
        let offset = if inner.classify() == serde_json::error::Category::Data && !key.is_empty() {
            json_key_offset(text, &key)
        } else {
            line_start + inner.column().saturating_sub(1)
        };
        InputError::at_span(path, text, offset..offset, key, message)
    })
}

/// The byte offset of the value at `key` (`outputs[0].coefficients`, `""` for the whole
/// document) in valid JSON text; for a key that is not there, the offset of the deepest part of
/// it that is (so an error about a missing key points at the object that lacks it).
pub(crate) fn json_key_offset(text: &str, key: &str) -> usize {
    let b = text.as_bytes();
    let mut at = skip_ws(b, 0);
    for segment in key.split('.').filter(|s| !s.is_empty()) {
        let (name, indices) = segment
            .split_once('[')
            .map_or((segment, ""), |(n, i)| (n, i));
        if !name.is_empty() {
            match json_member(b, at, name) {
                Some(i) => at = i,
                None => return at,
            }
        }
        for index in indices.split('[') {
            let Ok(index) = index.trim_end_matches(']').parse::<usize>() else {
                continue;
            };
            match json_element(b, at, index) {
                Some(i) => at = i,
                None => return at,
            }
        }
    }
    at
}

fn skip_ws(b: &[u8], mut i: usize) -> usize {
    while i < b.len() && b[i].is_ascii_whitespace() {
        i += 1;
    }
    i
}

/// The end of the JSON value starting at `i` (after leading whitespace).
fn skip_value(b: &[u8], i: usize) -> usize {
    let mut i = skip_ws(b, i);
    match b.get(i) {
        Some(b'"') => {
            i += 1;
            while i < b.len() && b[i] != b'"' {
                i += if b[i] == b'\\' { 2 } else { 1 };
            }
            (i + 1).min(b.len())
        }
        Some(b'{' | b'[') => {
            let mut depth = 0usize;
            while i < b.len() {
                match b[i] {
                    b'{' | b'[' => depth += 1,
                    b'}' | b']' => {
                        depth -= 1;
                        if depth == 0 {
                            return i + 1;
                        }
                    }
                    b'"' => {
                        i = skip_value(b, i);
                        continue;
                    }
                    _ => {}
                }
                i += 1;
            }
            i
        }
        _ => {
            while i < b.len() && !matches!(b[i], b',' | b']' | b'}') && !b[i].is_ascii_whitespace()
            {
                i += 1;
            }
            i
        }
    }
}

/// The offset of member `name`'s value in the object at `i`.
fn json_member(b: &[u8], i: usize, name: &str) -> Option<usize> {
    let mut i = skip_ws(b, i);
    if b.get(i) != Some(&b'{') {
        return None;
    }
    i += 1;
    loop {
        i = skip_ws(b, i);
        if b.get(i) != Some(&b'"') {
            return None;
        }
        let end = skip_value(b, i);
        let key: Option<String> = std::str::from_utf8(&b[i..end])
            .ok()
            .and_then(|k| serde_json::from_str(k).ok());
        i = skip_ws(b, end);
        if b.get(i) != Some(&b':') {
            return None;
        }
        let value = skip_ws(b, i + 1);
        if key.as_deref() == Some(name) {
            return Some(value);
        }
        i = skip_ws(b, skip_value(b, value));
        if b.get(i) != Some(&b',') {
            return None;
        }
        i += 1;
    }
}

/// The offset of element `index` of the array at `i`.
fn json_element(b: &[u8], i: usize, index: usize) -> Option<usize> {
    let mut i = skip_ws(b, i);
    if b.get(i) != Some(&b'[') {
        return None;
    }
    i = skip_ws(b, i + 1);
    for _ in 0..index {
        i = skip_ws(b, skip_value(b, i));
        if b.get(i) != Some(&b',') {
            return None;
        }
        i = skip_ws(b, i + 1);
    }
    (i < b.len() && b[i] != b']').then_some(i)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn line_column_counts_from_one_in_characters() {
        let text = "ab\nc°d\n";
        assert_eq!(line_column(text, 0), (1, 1));
        assert_eq!(line_column(text, 3), (2, 1));
        // `d` is byte 6 (° is two bytes) but the third character of line 2.
        assert_eq!(line_column(text, 6), (2, 3));
        assert_eq!(line_column(text, 100), (3, 1));
    }

    #[test]
    fn json_keys_are_found_at_their_values() {
        let text = "{\"a\": 1,\n \"b\": [{\"c\": \"x]\\\"\"}, {\"c\": [2, 3]}]}";
        let at = |k: &str| line_column(text, json_key_offset(text, k));
        assert_eq!(at(""), (1, 1));
        assert_eq!(at("a"), (1, 7));
        assert_eq!(at("b"), (2, 7));
        assert_eq!(at("b[1].c"), (2, 29));
        assert_eq!(at("b[1].c[1]"), (2, 33));
        // Missing keys: the deepest part that exists.
        assert_eq!(at("b[1].d"), (2, 23));
        assert_eq!(at("b[5]"), (2, 7));
    }
}
