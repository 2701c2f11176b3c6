//! The SHDR source's TOML configuration and its resolution against the machine.

use serde::Deserialize;
use truepos_model::Machine;

use crate::channel::channel_config;

use truepos_files::InputError;
use truepos_runtime::sources::{check_source_config, check_unique_targets, BackoffConfig, Target};
use truepos_runtime::sources::{from_toml_text, load_toml_file};

channel_config! {
/// One SHDR data item feeding one machine channel (configuration, TOML). Give exactly one of
/// `temperature`, `axis` or `operating`.
pub struct ShdrChannelConfig {
    /// The adapter's dataItemId (e.g. `Xact`, `Tspindle`).
    pub data_item: String,
    ..feeds,
}
}

/// An MTConnect SHDR source (configuration, TOML).
///
/// ```toml
/// address = "127.0.0.1:7878"
/// [[channel]]
/// data_item = "Xact"
/// axis = "X"
/// [[channel]]
/// data_item = "Tspindle"
/// temperature = "spindle_front_bearing"
/// ```
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ShdrConfig {
    /// The adapter's `host:port`.
    pub address: String,
    /// Longest wait for a TCP connection in ms (default 2000).
    #[serde(default = "default_connect_timeout_ms")]
    pub connect_timeout_ms: u64,
    /// The client sends `* PING` this often in ms (default 1000), or at the adapter's announced
    /// interval if that is shorter; every answer confirms the values of the connection.
    #[serde(default = "default_ping_ms")]
    pub ping_ms: u64,
    /// Longest wait for the first `* PONG` in ms, before the adapter has announced its interval
    /// (default 5000). Afterwards the announced interval is the limit.
    #[serde(default = "default_first_pong_ms")]
    pub first_pong_timeout_ms: u64,
    /// Longest time in ms a line may take from its first byte to its end (default 1000); an
    /// adapter dripping a line more slowly loses the connection.
    #[serde(default = "default_line_timeout_ms")]
    pub line_timeout_ms: u64,
    /// Longest time in ms without a usable data line while the adapter still answers `* PING`
    /// (default 300 000, the validator's default stuck-value limit): after it, the source counts
    /// as failing and PONGs no longer confirm its values.
    #[serde(default = "default_data_timeout_ms")]
    pub data_timeout_ms: u64,
    /// Reconnection waits.
    #[serde(default)]
    pub backoff: BackoffConfig,
    /// Which data item feeds which machine channel.
    #[serde(rename = "channel")]
    pub channels: Vec<ShdrChannelConfig>,
}

fn default_connect_timeout_ms() -> u64 {
    2000
}
fn default_ping_ms() -> u64 {
    1000
}
fn default_first_pong_ms() -> u64 {
    5000
}
fn default_line_timeout_ms() -> u64 {
    1000
}
fn default_data_timeout_ms() -> u64 {
    300_000
}

impl ShdrConfig {
    /// Reads the configuration from TOML text (a table with the fields above).
    pub fn from_toml(text: &str) -> Result<Self, InputError> {
        from_toml_text(text, "shdr")
    }

    /// Reads the configuration from a TOML file; errors name the file (and, for TOML mistakes,
    /// the line and column).
    pub fn load(path: &std::path::Path) -> Result<Self, InputError> {
        load_toml_file(path, "SHDR source")
    }

    /// Checks the bounds and resolves the channels against the machine.
    pub fn resolve(&self, machine: &Machine) -> Result<Vec<Target>, InputError> {
        let keys = check_source_config(
            "shdr",
            &self.address,
            &[
                ("connect_timeout_ms", self.connect_timeout_ms),
                ("ping_ms", self.ping_ms),
                ("first_pong_timeout_ms", self.first_pong_timeout_ms),
                ("line_timeout_ms", self.line_timeout_ms),
                ("data_timeout_ms", self.data_timeout_ms),
            ],
            &self.backoff,
            self.channels.len(),
            "a data item",
        )?;
        let mut targets = Vec::with_capacity(self.channels.len());
        for (c, key) in self.channels.iter().zip(&keys) {
            if c.data_item.trim().is_empty() || c.data_item.contains('|') {
                return Err(InputError::at_key(
                    format!("{key}.data_item"),
                    format!("expected a dataItemId without `|`, found `{}`", c.data_item),
                ));
            }
            targets.push(c.target(machine, key)?);
        }
        check_unique_targets(&targets, &keys)?;
        Ok(targets)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn config_defaults_and_errors() {
        let c = ShdrConfig::from_toml(
            "address = \"127.0.0.1:7878\"\n[[channel]]\ndata_item = \"Xact\"\naxis = \"X\"\n",
        )
        .unwrap();
        assert_eq!(
            (c.connect_timeout_ms, c.ping_ms, c.first_pong_timeout_ms),
            (2000, 1000, 5000)
        );
        assert_eq!(c.backoff, BackoffConfig::default());
        let e = ShdrConfig::from_toml("address = \"a\"\nchannels = []").unwrap_err();
        assert!(e.message.contains("unknown field `channels`"), "{e}");
    }
}
