//! The defaults the documentation states are the defaults the code applies: every
//! `(default N …)` of the sensor checks in docs/formats.md is compared with what an empty
//! setting gives (the sources' defaults: `truepos-protocols`' test of the same name).

mod support;

use support::{doc, documented};
use truepos_runtime::config::{
    DEFAULT_MAX_AGE_S, DEFAULT_MAX_RATE_K_PER_MIN, DEFAULT_NOISE_K, DEFAULT_RECOVER_AFTER_S,
    DEFAULT_STUCK_AFTER_S,
};

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
