//! # truepos-hal — truepos beside LinuxCNC
//!
//! A userspace HAL component, `truepos`, for LinuxCNC 2.9 (Debian `linuxcnc-uspace`). Every
//! cycle it reads the nominal axis positions (`axis.L.pos-cmd`) and temperature pins, evaluates
//! the compensation model and drives LinuxCNC's external offsets (`axis.L.eoffset-counts`,
//! `-scale`, `-enable`), which LinuxCNC adds to the joint commands. The binary `truepos-hal`
//! is what `loadusr -W` starts: it runs the runtime's [`Service`](truepos_runtime::Service)
//! (validation, model set, envelope, bumpless switching, log) with this crate's source and sink.
//! [`pins`] lists the pins and `docs/linuxcnc.md` the HAL lines.
//!
//! - [`ffi`]: the C interface of `liblinuxcnchal` — the only `unsafe` code of truepos.
//! - [`source::HalSource`] / [`sink::HalSink`]: the component as the runtime's
//!   [`Source`](truepos_runtime::Source) and [`Sink`](truepos_runtime::Sink).
//! - [`eoffset`]: offsets in µm ↔ LinuxCNC counts.
//! - [`Error`]: why the component could not start or stop cleanly.
//! - [`pacer`]: the periodic cycle (absolute deadlines, `SCHED_FIFO`, locked memory, one CPU).
//!
//! The judge of the LinuxCNC end-to-end test and the timing benchmark of the cycle are
//! development tools, not part of the component: `truepos-hal-check` (`crates/hal-check`).
//!
//! Sign: the model predicts the error (actual − nominal); the offset sent is −error.
//!
//! ## Example: the offset a LinuxCNC axis receives
//! The model of `examples/vmc3` predicts, for X at 800 mm with the X table 5 K warmer underneath
//! than on top, a Z error of 5 K × (2 + 4·1) µm/K = 30 µm; the component sends −30 µm, which is
//! −3000 counts at 0.01 µm per count.
//!
//! ```
//! use truepos_hal::eoffset::{counts_for, SCALE_MM_PER_COUNT};
//! let error_um = 5.0 * (2.0 + 4.0 * 1.0);
//! let counts = counts_for(-error_um);
//! assert_eq!(counts, -3000);
//! assert!((f64::from(counts) * SCALE_MM_PER_COUNT + 0.030).abs() < 1e-12); // mm LinuxCNC applies
//! ```
#![deny(unsafe_code)]
#![warn(missing_docs)]

pub mod eoffset;
pub mod error;
#[allow(unsafe_code)]
pub mod ffi;
pub mod pacer;
pub mod pins;
pub mod sink;
pub mod source;

pub use error::Error;
pub use sink::HalSink;
pub use source::HalSource;
