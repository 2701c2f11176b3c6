//! What every network source's configuration shares: reading its TOML, the common checks
//! (address, times, backoff, at least one channel) and address resolution. A mistake is the
//! files' one [`InputError`]: a check names the key ([`InputError::at_key`]) and the caller that
//! knows the file places it there ([`InputError::in_file`]).

use std::net::{SocketAddr, ToSocketAddrs};
use std::path::Path;

use truepos_files::{toml_place, InputError};

use crate::sources::BackoffConfig;

/// Reads a source configuration from TOML text; a TOML mistake is named by `section` (the
/// table's name, `modbus` or `shdr`), the key at its place and toml's words.
pub fn from_toml_text<T: serde::de::DeserializeOwned>(
    text: &str,
    section: &str,
) -> Result<T, InputError> {
    toml::from_str(text).map_err(|e| {
        let start = e.span().map(|s| s.start);
        let key = start.map(|s| toml_place::key_on_line(text, s));
        let key = match (section, key) {
            (_, None) => section.to_string(),
            ("", Some(k)) => k,
            (_, Some(k)) if k.is_empty() => section.to_string(),
            (_, Some(k)) => format!("{section}.{k}"),
        };
        InputError {
            position: start.map(|s| truepos_files::line_column(text, s)),
            ..InputError::at_key(key, e.message().trim())
        }
    })
}

/// Reads a source configuration from a TOML file; errors name the file, and a TOML mistake its
/// line and column. `what` names the configuration in the read error (`Modbus source`).
pub fn load_toml_file<T: serde::de::DeserializeOwned>(
    path: &Path,
    what: &str,
) -> Result<T, InputError> {
    let text = truepos_files::read::read_text(path, truepos_files::CONFIG).map_err(|e| {
        InputError::file(
            path,
            format!("cannot read the {what} configuration: {}", e.message),
        )
    })?;
    from_toml_text(&text, "").map_err(|e| InputError {
        file: path.to_path_buf(),
        ..e
    })
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
) -> Result<Vec<String>, InputError> {
    resolve_address(address, &format!("{section}.address"))?;
    if let Some((key, _)) = times_ms.iter().find(|(_, v)| *v == 0) {
        return Err(InputError::at_key(
            format!("{section}.{key}"),
            "expected a time of at least 1 ms, found 0",
        ));
    }
    backoff.check(&format!("{section}.backoff"))?;
    if channels == 0 {
        return Err(InputError::at_key(
            format!("{section}.channel"),
            format!("expected at least one [[channel]] mapping {what} to a machine channel"),
        ));
    }
    Ok((1..=channels)
        .map(|i| format!("{section}.channel[{i}]"))
        .collect())
}

/// Resolves `host:port` to a socket address; `key` names the setting in errors.
pub fn resolve_address(address: &str, key: &str) -> Result<SocketAddr, InputError> {
    address
        .to_socket_addrs()
        .ok()
        .and_then(|mut a| a.next())
        .ok_or_else(|| InputError::at_key(key, format!("expected host:port, found `{address}`")))
}
