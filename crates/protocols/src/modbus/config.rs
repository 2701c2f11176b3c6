//! The Modbus source's TOML configuration and its resolution against the machine.

use serde::Deserialize;
use truepos_model::Machine;

use super::codec::{Encoding, RegisterKind, WordOrder};
use super::plan::RegisterSpan;
use crate::channel::channel_config;
use truepos_files::InputError;
use truepos_runtime::sources::{check_source_config, check_unique_targets, BackoffConfig, Target};
use truepos_runtime::sources::{from_toml_text, load_toml_file};

/// How the configured register numbers count.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
pub enum Addressing {
    /// Register numbers are protocol addresses (`0-based`).
    #[default]
    #[serde(rename = "0-based")]
    ZeroBased,
    /// Register numbers start at 1 as in many manuals (`1-based`): protocol address = n − 1.
    #[serde(rename = "1-based")]
    OneBased,
}

channel_config! {
/// One Modbus register feeding one machine channel (configuration, TOML). Give exactly one of
/// `temperature`, `axis` or `operating`.
pub struct ModbusChannelConfig {
    ..feeds,
    /// Unit identifier (default 1).
    #[serde(default = "default_unit")]
    pub unit: u8,
    /// `holding` (function 03, default) or `input` (function 04).
    #[serde(default = "default_function")]
    pub function: RegisterKind,
    /// Register number, counted as `addressing` says.
    pub register: u32,
    /// `int16-x0.1`, `int16-x0.01`, `uint16` or `float32`.
    pub encoding: Encoding,
    /// For `float32`: `high-first` (default) or `low-first`.
    #[serde(default)]
    pub word_order: WordOrder,
}
}

fn default_unit() -> u8 {
    1
}
fn default_function() -> RegisterKind {
    RegisterKind::Holding
}

/// A Modbus TCP source (configuration, TOML).
///
/// ```toml
/// address = "192.168.0.20:502"
/// poll_ms = 100
/// addressing = "1-based"
/// [[channel]]
/// temperature = "x_slide_bottom"
/// function = "input"
/// register = 1
/// encoding = "int16-x0.1"
/// ```
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ModbusConfig {
    /// The server's `host:port` (Modbus TCP's port is 502).
    pub address: String,
    /// Poll period in ms (default 100).
    #[serde(default = "default_poll_ms")]
    pub poll_ms: u64,
    /// Longest wait for a connection or an answer in ms (default 500).
    #[serde(default = "default_timeout_ms")]
    pub timeout_ms: u64,
    /// `0-based` (default) or `1-based` register numbers.
    #[serde(default)]
    pub addressing: Addressing,
    /// Reconnection waits.
    #[serde(default)]
    pub backoff: BackoffConfig,
    /// Which register feeds which machine channel.
    #[serde(rename = "channel")]
    pub channels: Vec<ModbusChannelConfig>,
}

fn default_poll_ms() -> u64 {
    100
}
fn default_timeout_ms() -> u64 {
    500
}

impl ModbusConfig {
    /// Reads the configuration from TOML text (a table with the fields above).
    pub fn from_toml(text: &str) -> Result<Self, InputError> {
        from_toml_text(text, "modbus")
    }

    /// Reads the configuration from a TOML file; errors name the file (and, for TOML mistakes,
    /// the line and column).
    pub fn load(path: &std::path::Path) -> Result<Self, InputError> {
        load_toml_file(path, "Modbus source")
    }

    /// Checks the bounds and resolves the channels against the machine: their targets and
    /// register spans (protocol addresses).
    pub fn resolve(
        &self,
        machine: &Machine,
    ) -> Result<(Vec<Target>, Vec<RegisterSpan>), InputError> {
        let keys = check_source_config(
            "modbus",
            &self.address,
            &[("poll_ms", self.poll_ms), ("timeout_ms", self.timeout_ms)],
            &self.backoff,
            self.channels.len(),
            "a register",
        )?;
        let mut targets = Vec::with_capacity(self.channels.len());
        let mut spans = Vec::with_capacity(self.channels.len());
        for (c, key) in self.channels.iter().zip(&keys) {
            targets.push(c.target(machine, key)?);
            let n = c.encoding.registers();
            let address = match self.addressing {
                Addressing::ZeroBased => Some(c.register),
                Addressing::OneBased => c.register.checked_sub(1),
            };
            let last = 0xFFFF - u32::from(n - 1);
            let address = address.filter(|&a| a <= last).ok_or_else(|| {
                let (lo, hi, how) = match self.addressing {
                    Addressing::ZeroBased => (0, last, "0-based"),
                    Addressing::OneBased => (1, last + 1, "1-based"),
                };
                InputError::at_key(
                    format!("{key}.register"),
                    format!(
                        "expected a register number from {lo} to {hi} ({how} addressing, {n} register(s)), found {}",
                        c.register
                    ),
                )
            })?;
            spans.push((c.unit, c.function, address as u16, n));
        }
        check_unique_targets(&targets, &keys)?;
        Ok((targets, spans))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn config_reads_toml() {
        let c = ModbusConfig::from_toml(
            "address = \"127.0.0.1:502\"\naddressing = \"1-based\"\n[[channel]]\ntemperature = \"t\"\n\
             function = \"input\"\nregister = 1\nencoding = \"float32\"\nword_order = \"low-first\"\n",
        )
        .unwrap();
        assert_eq!(c.addressing, Addressing::OneBased);
        assert_eq!((c.poll_ms, c.timeout_ms), (100, 500));
        let ch = &c.channels[0];
        assert_eq!(
            (ch.unit, ch.function, ch.encoding, ch.word_order),
            (
                1,
                RegisterKind::Input,
                Encoding::Float32,
                WordOrder::LowFirst
            )
        );
        let e = ModbusConfig::from_toml(
            "address = \"a\"\n[[channel]]\nregister = 1\nencoding = \"int32\"\n",
        )
        .unwrap_err();
        assert!(e.message.contains("int16-x0.1"), "{e}");
    }
}
