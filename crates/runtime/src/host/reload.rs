//! Hot model reload: a thread of its own reads and parses model files (with a loader the
//! caller gives, since the runtime links no file format), and the caller's loop hands what it
//! loaded to the service between cycles ([`crate::Running::poll_reload`]). The cycle never
//! waits for a file, and the model a reload replaces is dropped on this thread, not the
//! cycle's.
//!
//! A reload happens on request ([`crate::Running::request_reload`]: the HAL component's
//! `truepos.model.reload` pin) or, when watching, whenever a model file's modification time,
//! size or inode changes (`truepos run --reload-on-change`, checked every [`POLL`]). Every file of the
//! set is reloaded on request; only the changed ones when watching.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, SystemTime};

use crossbeam_queue::ArrayQueue;

use crate::model_set::ModelEntry;

/// How often the thread looks for a request or a changed file.
pub const POLL: Duration = Duration::from_millis(100);

/// Reads a model file into an entry of the set, or says why it cannot (the message names the
/// file, line, column and key, as `truepos_io::model_file::load_set` does).
pub type ModelLoader = Box<dyn Fn(&Path) -> Result<ModelEntry, String> + Send>;

/// What to reload and how.
pub struct ReloadSetup {
    /// The model files of the set, in set order (file `i` replaces model `i`).
    pub files: Vec<PathBuf>,
    /// Reads one file.
    pub loader: ModelLoader,
    /// Reload a file when its modification time or size changes.
    pub watch: bool,
}

/// One file loaded (or not) by the thread.
pub(crate) struct Loaded {
    pub model: usize,
    pub file: PathBuf,
    pub entry: Result<ModelEntry, String>,
}

/// The reload thread and the queues between it and the cycle's loop.
pub(crate) struct Reloader {
    request: Arc<AtomicBool>,
    stop: Arc<AtomicBool>,
    pub results: Arc<ArrayQueue<Loaded>>,
    pub garbage: Arc<ArrayQueue<ModelEntry>>,
    handle: Option<JoinHandle<()>>,
}

/// What tells a changed file: modification time, size and (on Unix) the inode, since a file
/// replaced by a rename — how `truepos reidentify` writes — is a new inode even when its time
/// falls in the same tick of the file system's clock and its size is unchanged. The model's own
/// stamp and that of its signature beside it (`MODEL.sig`): a signed update whose signature
/// arrives after the model (rsync writes `model.toml` before `model.toml.sig`) is read again.
type Stamp = (FileStamp, FileStamp);
type FileStamp = Option<(SystemTime, u64, u64)>;

fn stamp(path: &Path) -> Stamp {
    let mut sig = path.as_os_str().to_owned();
    sig.push(".sig");
    (file_stamp(path), file_stamp(Path::new(&sig)))
}

fn file_stamp(path: &Path) -> FileStamp {
    let m = std::fs::metadata(path).ok()?;
    #[cfg(unix)]
    let inode = std::os::unix::fs::MetadataExt::ino(&m);
    #[cfg(not(unix))]
    let inode = 0;
    Some((m.modified().ok()?, m.len(), inode))
}

impl Reloader {
    pub fn start(setup: ReloadSetup) -> std::io::Result<Self> {
        // Taken here, not on the thread: a file changed before the thread first runs is a
        // change.
        let stamps: Vec<Stamp> = setup.files.iter().map(|f| stamp(f)).collect();
        let request = Arc::new(AtomicBool::new(false));
        let stop = Arc::new(AtomicBool::new(false));
        let results = Arc::new(ArrayQueue::new(64));
        let garbage = Arc::new(ArrayQueue::new(64));
        let (rq, st, res, gb) = (
            Arc::clone(&request),
            Arc::clone(&stop),
            Arc::clone(&results),
            Arc::clone(&garbage),
        );
        let handle = std::thread::Builder::new()
            .name("truepos-reload".into())
            .spawn(move || run(setup, stamps, &rq, &st, &res, &gb))?;
        Ok(Self {
            request,
            stop,
            results,
            garbage,
            handle: Some(handle),
        })
    }

    pub fn request(&self) {
        self.request.store(true, Ordering::Release);
    }
}

impl Drop for Reloader {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Release);
        if let Some(h) = self.handle.take() {
            let _ = h.join();
        }
    }
}

fn run(
    setup: ReloadSetup,
    mut stamps: Vec<Stamp>,
    request: &AtomicBool,
    stop: &AtomicBool,
    results: &ArrayQueue<Loaded>,
    garbage: &ArrayQueue<ModelEntry>,
) {
    // Loaded but not yet taken by a full queue: kept for the next round.
    let mut pending: Vec<Loaded> = Vec::new();
    while !stop.load(Ordering::Acquire) {
        while garbage.pop().is_some() {}
        let all = request.swap(false, Ordering::AcqRel);
        for (i, file) in setup.files.iter().enumerate() {
            let now = stamp(file);
            let changed = setup.watch && now != stamps[i];
            if !(all || changed) {
                continue;
            }
            stamps[i] = now;
            pending.push(Loaded {
                model: i,
                file: file.clone(),
                entry: (setup.loader)(file),
            });
        }
        while let Some(l) = pending.pop() {
            if let Err(l) = results.push(l) {
                pending.push(l);
                break;
            }
        }
        std::thread::sleep(POLL);
    }
}
