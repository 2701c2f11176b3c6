//! # truepos-protocols — the field protocols, as sources and sinks of the service
//!
//! What a machine tool's network speaks, each as a [`truepos_runtime::Source`] (or
//! [`truepos_runtime::Sink`]) the service hosts like any other:
//!
//! - [`modbus`]: Modbus TCP temperature modules, polled (`truepos run --source modbus:FILE`);
//! - [`shdr`]: an MTConnect adapter's SHDR lines — positions and temperatures
//!   (`--source shdr:FILE`);
//! - [`opcua`]: a control's OPC UA server, read as a source (`--source opcua:FILE`) and written
//!   as a sink, the model's per-axis linear form (`--sink opcua:FILE`).
//!
//! What does not depend on the protocol stays in the runtime's [`truepos_runtime::sources`]:
//! the [`PolledSource`](truepos_runtime::sources::PolledSource) that hosts a reading thread and
//! hands the cycle its latest values, reconnection with backoff, the link's status and events,
//! the mapping of a value onto a machine channel and the checks every configuration shares. A
//! protocol here is a configuration (TOML, checked against the machine, every mistake named at
//! file:line:column:key) and a thread body. No protocol touches the network on the cycle.
//!
//! An SHDR adapter's temperature reaching the frame the cycle reads:
//!
//! ```
//! use std::io::Write;
//! use std::path::Path;
//! use std::time::{Duration, Instant};
//! use truepos_protocols::shdr::{ShdrConfig, ShdrSource};
//! use truepos_runtime::{Frame, Source};
//!
//! let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/vmc3");
//! let machine = truepos_io::machine_file::load(&root.join("machine.toml"))?.machine;
//! // An adapter: it sends one temperature and keeps the connection open.
//! let adapter = std::net::TcpListener::bind("127.0.0.1:0")?;
//! let address = adapter.local_addr()?;
//! std::thread::spawn(move || {
//!     let (mut client, _) = adapter.accept().unwrap();
//!     client.write_all(b"2024-05-01T10:00:00Z|Ttable|21.5\n").unwrap();
//!     std::thread::sleep(Duration::from_secs(5));
//! });
//! let config = ShdrConfig::from_toml(&format!(
//!     "address = \"{address}\"\n[[channel]]\ndata_item = \"Ttable\"\ntemperature = \"x_slide_top\"\n"
//! ))?;
//! let epoch = Instant::now();
//! let mut source = ShdrSource::start(&config, &machine, epoch)?;
//! let t = machine.temperature_index("x_slide_top").unwrap();
//! let mut frame = Frame::new(machine.temperatures.len(), machine.axes.len(), machine.operating.len());
//! while frame.temperatures_c[t].is_nan() && epoch.elapsed() < Duration::from_secs(4) {
//!     std::thread::sleep(Duration::from_millis(10));
//!     frame.time_s = epoch.elapsed().as_secs_f64();
//!     let _ = source.read(&mut frame); // never blocks: the values a thread received
//! }
//! assert_eq!(frame.temperatures_c[t], 21.5);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
#![forbid(unsafe_code)]

mod channel;
pub mod modbus;
pub mod opcua;
pub mod shdr;
