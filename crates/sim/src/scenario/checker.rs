//! Errors that name their place in a TOML text: file, line, column, key path and what was
//! expected. Scenarios and twin descriptions (`crate::params`) check their values with it.

use std::ops::Range;

use super::ScenarioError;

/// A TOML syntax or type error as a [`ScenarioError`].
pub(crate) fn toml_error(src: &str, file: &str, e: &toml::de::Error) -> ScenarioError {
    let (line, column) = e
        .span()
        .map_or((0, 0), |s| truepos_files::line_column(src, s.start));
    ScenarioError {
        file: file.into(),
        line,
        column,
        key: e.span().map(|s| key_at(src, s)).unwrap_or_default(),
        expected: e.message().trim().to_string(),
    }
}

/// The key written on the line of a span (`key = …`), or the table header.
fn key_at(src: &str, span: Range<usize>) -> String {
    let start = src[..span.start.min(src.len())]
        .rfind('\n')
        .map_or(0, |i| i + 1);
    let end = src[start..].find('\n').map_or(src.len(), |i| start + i);
    let line = src[start..end].trim();
    if let Some((k, _)) = line.split_once('=') {
        k.trim().to_string()
    } else {
        line.trim_matches(|c| c == '[' || c == ']').to_string()
    }
}

/// One step of a key path.
pub(crate) enum Seg<'a> {
    Key(&'a str),
    Index(usize),
}

pub(crate) struct Checker<'a> {
    src: &'a str,
    file: &'a str,
    doc: Option<toml_edit::ImDocument<&'a str>>,
}

impl<'a> Checker<'a> {
    /// A checker for the TOML text `src` of `file`.
    pub(crate) fn new(src: &'a str, file: &'a str) -> Self {
        Self {
            src,
            file,
            doc: toml_edit::ImDocument::parse(src).ok(),
        }
    }

    fn span(&self, path: &[Seg]) -> Option<Range<usize>> {
        let doc = self.doc.as_ref()?;
        self.span_in_table(doc.as_table(), path, None)
    }

    fn span_in_table(
        &self,
        t: &toml_edit::Table,
        rest: &[Seg],
        mut span: Option<Range<usize>>,
    ) -> Option<Range<usize>> {
        let mut tl: &dyn toml_edit::TableLike = t;
        for (n, seg) in rest.iter().enumerate() {
            match seg {
                Seg::Key(k) => {
                    let Some((key, next)) = tl.get_key_value(k) else {
                        return span;
                    };
                    span = key.span().or(span);
                    if n + 1 == rest.len() {
                        return span;
                    }
                    if let Some(aot) = next.as_array_of_tables() {
                        if let Some(Seg::Index(i)) = rest.get(n + 1) {
                            let Some(t2) = aot.get(*i) else { return span };
                            return self.span_in_table(t2, &rest[n + 2..], t2.span().or(span));
                        }
                    }
                    if let Some(arr) = next.as_array() {
                        if let Some(Seg::Index(i)) = rest.get(n + 1) {
                            return arr.get(*i).and_then(|v| v.span()).or(span);
                        }
                    }
                    match next.as_table_like() {
                        Some(inner) => tl = inner,
                        None => return span,
                    }
                }
                Seg::Index(_) => return span,
            }
        }
        span
    }

    pub(crate) fn err(&self, path: &[Seg], expected: impl Into<String>) -> ScenarioError {
        let (line, column) = self
            .span(path)
            .map_or((0, 0), |s| truepos_files::line_column(self.src, s.start));
        let mut key = String::new();
        for seg in path {
            match seg {
                Seg::Key(k) => {
                    if !key.is_empty() {
                        key.push('.');
                    }
                    key.push_str(k);
                }
                Seg::Index(i) => key.push_str(&format!("[{i}]")),
            }
        }
        ScenarioError {
            file: self.file.into(),
            line,
            column,
            key,
            expected: format!("expected {}", expected.into()),
        }
    }

    pub(super) fn positive(&self, path: &[Seg], v: f64) -> Result<f64, ScenarioError> {
        if v.is_finite() && v > 0.0 {
            Ok(v)
        } else {
            Err(self.err(path, format!("a positive number, got {v}")))
        }
    }

    pub(super) fn non_negative(&self, path: &[Seg], v: f64) -> Result<f64, ScenarioError> {
        if v.is_finite() && v >= 0.0 {
            Ok(v)
        } else {
            Err(self.err(path, format!("a number ≥ 0, got {v}")))
        }
    }

    pub(crate) fn within(
        &self,
        path: &[Seg],
        v: f64,
        lo: f64,
        hi: f64,
        what: &str,
    ) -> Result<f64, ScenarioError> {
        if v.is_finite() && v >= lo && v <= hi {
            Ok(v)
        } else {
            Err(self.err(path, format!("{what} between {lo} and {hi}, got {v}")))
        }
    }
}
