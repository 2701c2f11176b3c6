//! The fleet store: Sparkplug B telemetry of truepos services (`truepos_fleet`'s publisher)
//! taken from an MQTT broker into PostgreSQL (docs/fleet.md).
//!
//! [`ingest::run`] subscribes with a persistent session, writes each node's birth, each second
//! of aggregates and each event, and acknowledges a message only after its row is committed;
//! rows are keyed by machine and data time, so a message sent twice is written once. The
//! schema is versioned in `migrations/` ([`schema::MIGRATIONS`]), applied once each; the time
//! tables are partitioned by day.
//!
//! [`models`] keeps every generation of a machine's model — signed bytes, provenance and
//! validation figures, state (candidate, shadow, active, retired) — and moves them: register,
//! activate, roll back, each with a history row. [`shadow`] is the rule a model in shadow is
//! activated by and a new active model rolled back by (pure, on probe residuals that
//! [`shadow_probes`] keeps). [`status`] reads the fleet at a glance per
//! machine: online, last message, model generation, compensating, faults in the last hour.
//!
//! An NDATA message as rows, without a broker or a database:
//!
//! ```
//! use std::collections::HashMap;
//! use truepos_fleet::sparkplug::{Metric, Payload, Value};
//! use truepos_fleet_store::ingest::{parse_topic, rows, Row};
//!
//! assert_eq!(
//!     parse_topic("spBv1.0/truepos/NDATA/vmc3"),
//!     Some(("truepos", "NDATA", "vmc3"))
//! );
//! // The node's birth named alias 4 `Cycles` and alias 6 `Offsets/X_offset_um/mean`.
//! let names = HashMap::from([(4, "Cycles".to_string()), (6, "Offsets/X_offset_um/mean".to_string())]);
//! let by_alias = |alias, value| Metric {
//!     alias: Some(alias),
//!     timestamp_ms: Some(1_764_000_000_000),
//!     ..Metric::new("", value)
//! };
//! let ndata = Payload {
//!     timestamp_ms: 1_764_000_000_500,
//!     seq: Some(1),
//!     metrics: vec![by_alias(4, Value::UInt32(10)), by_alias(6, Value::Double(-3.5))],
//! };
//! let Row::Second { t_ms, cycles, stats, .. } = rows(&ndata, &names).unwrap() else {
//!     panic!("a second")
//! };
//! assert_eq!((t_ms, cycles), (1_764_000_000_000, Some(10)));
//! assert_eq!(stats["Offsets/X_offset_um"][1], -3.5);
//! ```

#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub mod ingest;
pub mod models;
pub mod schema;
pub mod shadow;
pub mod shadow_probes;
pub mod status;

/// The PostgreSQL client the store's functions take, for callers that connect themselves.
pub use postgres;
