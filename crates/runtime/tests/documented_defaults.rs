//! The defaults the documentation states are the defaults the code applies: every
//! `(default N …)` of the sensor checks in docs/formats.md is compared with what an empty
//! setting gives (the sources' defaults: `truepos-protocols`' test of the same name).

use std::path::{Path, PathBuf};

use truepos_runtime::config::{
    DEFAULT_MAX_AGE_S, DEFAULT_MAX_RATE_K_PER_MIN, DEFAULT_NOISE_K, DEFAULT_RECOVER_AFTER_S,
    DEFAULT_STUCK_AFTER_S,
};

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
fn sensor_check_defaults_are_as_documented() {
    let text = doc("formats.md");
    let s = "[[temperature]]";
    for (key, value) in [
        ("max_rate_k_per_min", DEFAULT_MAX_RATE_K_PER_MIN),
        ("noise_k", DEFAULT_NOISE_K),
        ("max_age_s", DEFAULT_MAX_AGE_S),
        ("recover_after_s", DEFAULT_RECOVER_AFTER_S),
    ] {
        assert_eq!(documented(&text, s, key), value, "{key}");
    }
    // The stuck limit is documented in hours.
    assert_eq!(
        documented(&text, s, "stuck_after_s") * 3600.0,
        DEFAULT_STUCK_AFTER_S
    );
}
