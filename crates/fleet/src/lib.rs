//! Telemetry out of a truepos service: the service's SQLite log forwarded to an MQTT broker as
//! Sparkplug B 3.0, store-and-forward (docs/fleet.md).
//!
//! [`Publisher`] is a thread beside the service. It reads the log with a read-only connection
//! after a cursor kept per broker ([`cursor`]), sends one NDATA per second of cycles (min, mean
//! and max of every input and axis offset), one per event and one per accepted probe event at
//! MQTT QoS 1, and advances the
//! cursor only over what the broker acknowledged. After an outage it replays the rest, marked
//! historical and bounded in rate. Nothing on the cycle's path touches the network: the only
//! link between the cycle and this crate is the log file.
//!
//! Its MQTT client ([`mqtt`]) and Sparkplug codec ([`sparkplug`]) are also what the fleet
//! store (`truepos-fleet-store`, `truepos fleet ingest`) subscribes and decodes with; this
//! crate links no database client.
//!
//! The messages, without a broker:
//!
//! ```
//! use truepos_fleet::sparkplug::{topic, MessageType, Metric, Payload, Value};
//!
//! let ndata = Payload {
//!     timestamp_ms: 1_764_000_000_000,
//!     seq: Some(1),
//!     metrics: vec![Metric::new("Offsets/X_offset_um/mean", Value::Double(-3.25))],
//! };
//! assert_eq!(topic("truepos", MessageType::NData, "vmc3"), "spBv1.0/truepos/NDATA/vmc3");
//! // Protobuf: the timestamp (field 1), one metric (field 2), seq = 1 (field 3) last.
//! let bytes = ndata.encode();
//! assert_eq!(bytes[0], 0x08);
//! assert_eq!(&bytes[bytes.len() - 2..], &[0x18, 0x01]);
//! ```
//!
//! Forwarding a log (a broker must listen; `truepos run --mqtt` does this beside the service):
//!
//! ```no_run
//! use std::time::Duration;
//! use truepos_fleet::{BrokerUrl, Config, Publisher};
//!
//! let broker = BrokerUrl::parse("mqtt://127.0.0.1:1883")?;
//! let publisher = Publisher::start(Config::new(broker, "run.sqlite".into()))?;
//! // … the service runs and logs …
//! let summary = publisher.stop(Duration::from_secs(10));
//! println!("{} messages acknowledged", summary.acknowledged);
//! # Ok::<(), String>(())
//! ```

#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub mod cursor;
pub mod mqtt;
pub mod publisher;
pub mod sparkplug;
pub mod store;

pub use mqtt::BrokerUrl;
#[cfg(feature = "clap")]
pub use publisher::MqttOptions;
pub use publisher::{Config, Publisher, Summary};
pub use store::{last_rows, Rows};
