//! What every network source's configuration shares: the error naming a key, the common checks
//! (address, times, backoff, at least one channel) and address resolution.

use std::net::{SocketAddr, ToSocketAddrs};

use crate::sources::BackoffConfig;

/// A configuration mistake, naming the key and what was expected.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ConfigError {
    /// The key, e.g. `channel[2].register`.
    pub key: String,
    /// What is wrong and what was expected.
    pub message: String,
}

impl ConfigError {
    /// An error about `key`.
    pub fn new(key: impl Into<String>, message: impl Into<String>) -> Self {
        Self {
            key: key.into(),
            message: message.into(),
        }
    }
}

impl std::fmt::Display for ConfigError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}: {}", self.key, self.message)
    }
}

impl std::error::Error for ConfigError {}

/// Reads a source configuration from TOML text; TOML mistakes are named by `section` (the
/// table's name, `modbus` or `shdr`) with toml's line and column.
pub fn from_toml_text<T: serde::de::DeserializeOwned>(
    text: &str,
    section: &str,
) -> Result<T, ConfigError> {
    toml::from_str(text).map_err(|e| ConfigError::new(section, e.to_string()))
}

/// Reads a source configuration from a TOML file; errors name the file (and, for TOML
/// mistakes, the line and column). `what` names the configuration in the read error
/// (`Modbus source`).
pub fn load_toml_file<T: serde::de::DeserializeOwned>(
    path: &std::path::Path,
    what: &str,
) -> Result<T, ConfigError> {
    let file = path.display().to_string();
    let text = truepos_files::read::read_text(path, truepos_files::CONFIG).map_err(|e| {
        ConfigError::new(
            &file,
            format!("cannot read the {what} configuration: {}", e.message),
        )
    })?;
    from_toml_text(&text, &file)
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
