//! The host of a source whose values a thread of its own reads from the network (SHDR,
//! Modbus and OPC UA, in `truepos-protocols`): it starts the thread, hands the cycle the latest
//! values with their stamps (atomics only, no allocation, no lock), reports an outage once, and
//! stops the thread when it is dropped. What differs between protocols is only the thread's body.

use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::Duration;

use truepos_files::InputError;

use super::{stop_thread, LinkSnapshot, LinkStatus, OutageReporter, Target};
use crate::frame::Frame;
use crate::io_traits::{LinkError, SharedChannels, Source};

/// What a source's thread publishes into and watches: one slot per target, the link's state,
/// and the flag that asks it to stop.
#[derive(Debug, Clone)]
pub struct Link {
    /// The latest value and stamp per target, in target order.
    pub channels: Arc<SharedChannels>,
    /// The connection's state and events.
    pub status: Arc<LinkStatus>,
    /// Set when the source is dropped: the thread ends within its stop limit.
    pub stop: Arc<AtomicBool>,
}

/// A source fed by a thread of its own.
#[derive(Debug)]
pub struct PolledSource {
    name: String,
    targets: Vec<Target>,
    link: Link,
    outage: OutageReporter,
    thread: Option<JoinHandle<()>>,
    stop_limit: Duration,
}

impl PolledSource {
    /// Starts `body` on a thread named `name`, publishing into a [`Link`] with one slot per
    /// target. `stop_limit`: how long a drop waits for the thread to notice the stop flag.
    pub fn start(
        name: String,
        targets: Vec<Target>,
        stop_limit: Duration,
        body: impl FnOnce(Link) + Send + 'static,
    ) -> Result<Self, InputError> {
        let link = Link {
            channels: SharedChannels::new(targets.len()),
            status: Arc::new(LinkStatus::default()),
            stop: Arc::new(AtomicBool::new(false)),
        };
        let theirs = link.clone();
        let thread = std::thread::Builder::new()
            .name(name.clone())
            .spawn(move || body(theirs))
            .map_err(|e| {
                let what = name.split(' ').next().unwrap_or("source").to_string();
                InputError::at_key(what, format!("cannot start the reading thread: {e}"))
            })?;
        Ok(Self {
            name,
            targets,
            link,
            outage: OutageReporter::default(),
            thread: Some(thread),
            stop_limit,
        })
    }

    /// The link's state for the status line.
    pub fn status(&self) -> LinkSnapshot {
        self.link.status.snapshot()
    }

    /// The link's state, including its events to drain (off the cycle).
    pub fn link(&self) -> &LinkStatus {
        &self.link.status
    }

    /// The machine channels this source feeds, in configuration order.
    pub fn targets(&self) -> &[Target] {
        &self.targets
    }
}

impl Source for PolledSource {
    fn name(&self) -> &str {
        &self.name
    }

    /// Copies the latest values with the time they were read. A value that arrived after the
    /// frame's clock reading is stamped with the frame's time: stamps never lie after
    /// `frame.time_s`.
    fn read(&mut self, frame: &mut Frame) -> Result<(), LinkError> {
        for (k, target) in self.targets.iter().enumerate() {
            let (value, stamp) = self.link.channels.get(k);
            target.write(frame, value, stamp.min(frame.time_s));
        }
        self.outage.check(&self.link.status)
    }
}

impl Drop for PolledSource {
    fn drop(&mut self) {
        if let Some(t) = self.thread.take() {
            stop_thread(&self.link.stop, t, self.stop_limit);
        }
    }
}
