//! What the protocols' tests share: the repository's example machine, and reading a source into
//! a frame while polling for what a peer thread does.
#![allow(dead_code)] // each test file uses a part

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use truepos_model::Machine;
use truepos_runtime::sources::{LinkEventKind, LinkStatus};
use truepos_runtime::{Frame, LinkError, MachineConfig, Source};

/// A path in the repository.
pub fn repo(path: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../..")
        .join(path)
}

/// The example machine `examples/vmc3`, as its file describes it.
pub fn vmc() -> MachineConfig {
    truepos_io::machine_file::load(&repo("examples/vmc3/machine.toml")).expect("example machine")
}

/// The example machine's channels and axes.
pub fn machine() -> Machine {
    vmc().machine
}

/// A frame with a slot for every channel and axis of `m`.
pub fn frame_for(m: &Machine) -> Frame {
    Frame::new(m.temperatures.len(), m.axes.len(), m.operating.len())
}

/// Reads the source into the frame at service time `epoch.elapsed()`.
pub fn read(source: &mut impl Source, frame: &mut Frame, epoch: Instant) -> Result<(), LinkError> {
    frame.time_s = epoch.elapsed().as_secs_f64();
    source.read(frame)
}

/// Polls `cond` every 10 ms for at most `limit`; whether it became true.
pub fn wait_until(limit: Duration, mut cond: impl FnMut() -> bool) -> bool {
    let end = Instant::now() + limit;
    while Instant::now() < end {
        if cond() {
            return true;
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    cond()
}

/// The messages of the link's queued events of `kind`, oldest first (the queue is emptied).
pub fn messages(link: &LinkStatus, kind: LinkEventKind) -> Vec<String> {
    link.drain_events()
        .into_iter()
        .filter(|e| e.kind == kind)
        .map(|e| e.message)
        .collect()
}
