//! What the runtime's and the protocols' tests share (`truepos-protocols` includes this file):
//! the repository's example machine, a scratch directory, reading a source into a frame while
//! polling for what a peer thread does, and the defaults the documentation states.
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

/// An empty directory of its own for one test (`truepos-NAME-PID`).
pub fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("truepos-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
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

/// The text of `docs/NAME`.
pub fn doc(name: &str) -> String {
    let path: PathBuf = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../docs")
        .join(name);
    std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// The number after `(default ` on the first line of `section` (the text after its heading)
/// that sets `key`.
pub fn documented(text: &str, section: &str, key: &str) -> f64 {
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
