//! The defaults the documentation states are the defaults the code applies: every
//! `(default N …)` of the source configurations in docs/network_sources.md is compared with what
//! an empty setting gives.

use std::path::{Path, PathBuf};

use truepos_protocols::modbus::ModbusConfig;
use truepos_protocols::shdr::ShdrConfig;

fn doc(name: &str) -> String {
    let path: PathBuf = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../docs")
        .join(name);
    std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// The number after `(default ` on the first line of `section` (the text after its heading)
/// that sets `key`.
fn documented(text: &str, section: &str, key: &str) -> f64 {
    let start = text
        .find(section)
        .unwrap_or_else(|| panic!("no section `{section}`"));
    let line = text[start..]
        .lines()
        .find(|l| l.trim_start().starts_with(&format!("{key} =")))
        .unwrap_or_else(|| panic!("`{key}` is not documented under `{section}`"));
    let after = line
        .split("(default ")
        .nth(1)
        .unwrap_or_else(|| panic!("no `(default …)` on `{line}`"));
    let number: String = after
        .chars()
        .take_while(|c| c.is_ascii_digit() || *c == '.' || *c == ' ')
        .filter(|c| *c != ' ')
        .collect();
    number.parse().unwrap_or_else(|e| panic!("`{line}`: {e}"))
}

#[test]
fn shdr_defaults_are_as_documented() {
    let text = doc("network_sources.md");
    let c = ShdrConfig::from_toml(
        "address = \"127.0.0.1:7878\"\n[[channel]]\ndata_item = \"T\"\ntemperature = \"ambient\"\n",
    )
    .unwrap();
    let s = "### MTConnect SHDR";
    for (key, value) in [
        ("connect_timeout_ms", c.connect_timeout_ms),
        ("ping_ms", c.ping_ms),
        ("first_pong_timeout_ms", c.first_pong_timeout_ms),
        ("line_timeout_ms", c.line_timeout_ms),
        ("data_timeout_ms", c.data_timeout_ms),
    ] {
        assert_eq!(documented(&text, s, key), value as f64, "{key}");
    }
}

#[test]
fn modbus_defaults_are_as_documented() {
    let text = doc("network_sources.md");
    let c = ModbusConfig::from_toml(
        "address = \"127.0.0.1:5020\"\n[[channel]]\ntemperature = \"ambient\"\nregister = 1\nencoding = \"int16-x0.1\"\n",
    )
    .unwrap();
    let s = "### Modbus TCP";
    assert_eq!(documented(&text, s, "poll_ms"), c.poll_ms as f64);
    assert_eq!(documented(&text, s, "timeout_ms"), c.timeout_ms as f64);
}
