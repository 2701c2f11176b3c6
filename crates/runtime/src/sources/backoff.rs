//! Reconnection waits: exponential backoff with a cap, and its TOML configuration.

use std::time::Duration;

use serde::Deserialize;

use truepos_files::InputError;

/// How long to wait between reconnection attempts (configuration, TOML).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BackoffConfig {
    /// Wait after the first failed attempt in ms (default 100).
    #[serde(default = "default_initial_ms")]
    pub initial_ms: u64,
    /// Longest wait in ms, reached by doubling (default 5000).
    #[serde(default = "default_max_ms")]
    pub max_ms: u64,
}

fn default_initial_ms() -> u64 {
    100
}

fn default_max_ms() -> u64 {
    5000
}

impl Default for BackoffConfig {
    fn default() -> Self {
        Self {
            initial_ms: default_initial_ms(),
            max_ms: default_max_ms(),
        }
    }
}

impl BackoffConfig {
    /// Checks the bounds: `initial_ms` ≥ 1 and `max_ms` ≥ `initial_ms`.
    pub fn check(&self, key: &str) -> Result<(), InputError> {
        if self.initial_ms == 0 {
            return Err(InputError::at_key(
                format!("{key}.initial_ms"),
                "expected a wait of at least 1 ms",
            ));
        }
        if self.max_ms < self.initial_ms {
            return Err(InputError::at_key(
                format!("{key}.max_ms"),
                format!(
                    "expected at least initial_ms = {} ms, found {}",
                    self.initial_ms, self.max_ms
                ),
            ));
        }
        Ok(())
    }
}

/// Exponential backoff with a cap: the waits are `initial`, `2·initial`, `4·initial`, … up to
/// `max`, and start again at `initial` after [`Backoff::reset`].
#[derive(Debug, Clone)]
pub struct Backoff {
    config: BackoffConfig,
    next_ms: u64,
}

impl Backoff {
    /// A backoff whose next wait is `initial_ms`.
    pub fn new(config: BackoffConfig) -> Self {
        let initial = config.initial_ms.max(1);
        Self {
            config: BackoffConfig {
                initial_ms: initial,
                max_ms: config.max_ms.max(initial),
            },
            next_ms: initial,
        }
    }

    /// The wait before the next attempt; the one after it is twice as long, up to the cap.
    pub fn next_delay(&mut self) -> Duration {
        let now = self.next_ms;
        self.next_ms = now.saturating_mul(2).min(self.config.max_ms);
        Duration::from_millis(now)
    }

    /// After a successful connection: the next wait is `initial_ms` again.
    pub fn reset(&mut self) {
        self.next_ms = self.config.initial_ms;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn backoff_doubles_up_to_the_cap_and_resets() {
        let mut b = Backoff::new(BackoffConfig {
            initial_ms: 100,
            max_ms: 1000,
        });
        let waits: Vec<u64> = (0..7).map(|_| b.next_delay().as_millis() as u64).collect();
        // 100, 200, 400, 800, then capped at 1000.
        assert_eq!(waits, [100, 200, 400, 800, 1000, 1000, 1000]);
        b.reset();
        assert_eq!(b.next_delay(), Duration::from_millis(100));
    }

    #[test]
    fn backoff_config_bounds_are_checked() {
        let bad = BackoffConfig {
            initial_ms: 0,
            max_ms: 10,
        };
        assert_eq!(
            bad.check("backoff").unwrap_err().key.as_deref(),
            Some("backoff.initial_ms")
        );
        let bad = BackoffConfig {
            initial_ms: 500,
            max_ms: 10,
        };
        let e = bad.check("backoff").unwrap_err();
        assert_eq!(
            e.to_string(),
            "`backoff.max_ms`: expected at least initial_ms = 500 ms, found 10"
        );
        assert!(BackoffConfig::default().check("backoff").is_ok());
    }
}
