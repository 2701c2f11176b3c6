//! What every network source's configuration shares: the error naming a key, the common checks
//! (address, times, backoff, at least one channel) and address resolution.

use std::net::{SocketAddr, ToSocketAddrs};
use std::path::Path;

use truepos_files::toml_place;

use crate::sources::BackoffConfig;

/// A configuration mistake, naming the file, line and column (once known), the key and what was
/// expected — as every file the project reads names its mistakes.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ConfigError {
    /// The configuration file; empty for a configuration given as text.
    pub file: String,
    /// 1-based line and column of the key in the file; 0 when not known.
    pub line: usize,
    /// See [`ConfigError::line`].
    pub column: usize,
    /// The key, e.g. `modbus.channel[2].register` (the section, then the path in the file).
    pub key: String,
    /// What is wrong and what was expected.
    pub message: String,
}

impl ConfigError {
    /// An error about `key`, its place not yet known ([`ConfigError::in_file`]).
    pub fn new(key: impl Into<String>, message: impl Into<String>) -> Self {
        Self {
            file: String::new(),
            line: 0,
            column: 0,
            key: key.into(),
            message: message.into(),
        }
    }

    /// The error placed in the file it came from: its name, and the line and column of the key
    /// (the key without its `section.` is looked up in the file's text; a key the file does
    /// not hold is named at the deepest table that does). An error placed already is kept.
    pub fn in_file(self, path: &Path, section: &str) -> Self {
        if !self.file.is_empty() {
            return self;
        }
        let text = truepos_files::read::read_text(path, truepos_files::CONFIG).unwrap_or_default();
        let in_text = self
            .key
            .strip_prefix(section)
            .and_then(|k| k.strip_prefix('.'))
            .unwrap_or(&self.key);
        let (line, column) =
            toml_place::place(&text, &toml_place::steps(in_text)).unwrap_or((0, 0));
        Self {
            file: path.display().to_string(),
            line,
            column,
            ..self
        }
    }
}

impl std::fmt::Display for ConfigError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if !self.file.is_empty() {
            write!(f, "{}:", self.file)?;
            if self.line > 0 {
                write!(f, "{}:{}:", self.line, self.column)?;
            }
            f.write_str(" ")?;
        }
        if !self.key.is_empty() {
            write!(f, "{}: ", self.key)?;
        }
        f.write_str(&self.message)
    }
}

impl std::error::Error for ConfigError {}

/// Reads a source configuration from TOML text; a TOML mistake is named by `section` (the
/// table's name, `modbus` or `shdr`), the key at its place and toml's words.
pub fn from_toml_text<T: serde::de::DeserializeOwned>(
    text: &str,
    section: &str,
) -> Result<T, ConfigError> {
    toml::from_str(text).map_err(|e| {
        let start = e.span().map(|s| s.start);
        let (line, column) = start.map_or((0, 0), |s| truepos_files::line_column(text, s));
        let key = start.map(|s| toml_place::key_on_line(text, s));
        let key = match (section, key) {
            (_, None) => section.to_string(),
            ("", Some(k)) => k,
            (_, Some(k)) if k.is_empty() => section.to_string(),
            (_, Some(k)) => format!("{section}.{k}"),
        };
        ConfigError {
            line,
            column,
            ..ConfigError::new(key, e.message().trim())
        }
    })
}

/// Reads a source configuration from a TOML file; errors name the file, and a TOML mistake its
/// line and column. `what` names the configuration in the read error (`Modbus source`).
pub fn load_toml_file<T: serde::de::DeserializeOwned>(
    path: &Path,
    what: &str,
) -> Result<T, ConfigError> {
    let file = path.display().to_string();
    let text =
        truepos_files::read::read_text(path, truepos_files::CONFIG).map_err(|e| ConfigError {
            file: file.clone(),
            ..ConfigError::new(
                "",
                format!("cannot read the {what} configuration: {}", e.message),
            )
        })?;
    from_toml_text(&text, "").map_err(|e| ConfigError { file, ..e })
}

/// The checks every network source's configuration shares, for its TOML `section`
/// (`modbus`, `shdr`): the address resolves, every time in `times_ms` (key, value) is at least
/// 1 ms, the backoff is sound and there is at least one of `channels` channels, each mapping
/// `what` to a machine channel. Returns the keys of the channels (`section.channel[1]`, …) for
/// their own errors.
pub fn check_source_config(
    section: &str,
    address: &str,
    times_ms: &[(&str, u64)],
    backoff: &BackoffConfig,
    channels: usize,
    what: &str,
) -> Result<Vec<String>, ConfigError> {
    resolve_address(address, &format!("{section}.address"))?;
    if let Some((key, _)) = times_ms.iter().find(|(_, v)| *v == 0) {
        return Err(ConfigError::new(
            format!("{section}.{key}"),
            "expected a time of at least 1 ms, found 0",
        ));
    }
    backoff.check(&format!("{section}.backoff"))?;
    if channels == 0 {
        return Err(ConfigError::new(
            format!("{section}.channel"),
            format!("expected at least one [[channel]] mapping {what} to a machine channel"),
        ));
    }
    Ok((1..=channels)
        .map(|i| format!("{section}.channel[{i}]"))
        .collect())
}

/// Resolves `host:port` to a socket address; `key` names the setting in errors.
pub fn resolve_address(address: &str, key: &str) -> Result<SocketAddr, ConfigError> {
    address
        .to_socket_addrs()
        .ok()
        .and_then(|mut a| a.next())
        .ok_or_else(|| ConfigError::new(key, format!("expected host:port, found `{address}`")))
}
