//! The defaults the documentation states are the defaults the code applies: every
//! `(default N …)` of the source configurations in docs/network_sources.md is compared with what
//! an empty setting gives.

#[path = "../../runtime/tests/support/mod.rs"]
mod support;

use support::{doc, documented};
use truepos_protocols::modbus::ModbusConfig;
use truepos_protocols::shdr::ShdrConfig;

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
