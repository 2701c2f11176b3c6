//! Writing a file: whole or not at all, never over an input, a device, a FIFO, a socket, a
//! directory or a symbolic link.
//!
//! [`Pending::create`] checks the output and creates an exclusive temporary file beside it;
//! the caller writes into it (it is a [`Write`]) and [`Pending::commit`] syncs it and renames
//! it over the output. Dropped without a commit, the temporary file is removed and the output
//! is untouched. [`write_whole`] and [`write_all_whole`] do the three steps for bytes in
//! memory.

use std::fs::File;
use std::io::Write;
use std::os::unix::fs::MetadataExt;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use crate::{describe, FileError};

/// The inputs of the command that writes, each with the option that named it (`--model`), so
/// that an output that is one of them is refused by name.
pub type Inputs<'a> = &'a [(&'a str, &'a Path)];

/// Checks that `path` may be written by a command whose inputs are `inputs`: its directory
/// exists, and it is either missing or a regular file that is none of the inputs (same device
/// and inode, so a hard link or another spelling of an input is caught too).
pub fn check_output(path: &Path, inputs: Inputs<'_>) -> Result<(), FileError> {
    let dir = directory(path);
    match std::fs::metadata(&dir) {
        Ok(m) if m.is_dir() => {}
        Ok(m) => {
            return Err(FileError::new(
                path,
                format!(
                    "cannot write: {} is {}, not a directory",
                    dir.display(),
                    describe(m.file_type())
                ),
            ))
        }
        Err(e) => {
            return Err(FileError::io(
                path,
                &format!("cannot write: directory {}", dir.display()),
                e,
            ))
        }
    }
    let meta = match std::fs::symlink_metadata(path) {
        Ok(m) => m,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(()),
        Err(e) => return Err(FileError::io(path, "cannot write", e)),
    };
    check_existing(path, &meta, inputs, false)
}

/// The rules for an output that exists: no link, no input, a regular file (or, for a stream
/// when `char_device` is set, a character device).
fn check_existing(
    path: &Path,
    meta: &std::fs::Metadata,
    inputs: Inputs<'_>,
    char_device: bool,
) -> Result<(), FileError> {
    use std::os::unix::fs::FileTypeExt;
    let ft = meta.file_type();
    if ft.is_symlink() {
        let to = std::fs::read_link(path)
            .map(|t| t.display().to_string())
            .unwrap_or_else(|_| "?".into());
        return Err(FileError::new(
            path,
            format!(
                "cannot write: is a symbolic link (to {to}); truepos neither writes through \
                 nor replaces a link: give the file itself as the output"
            ),
        ));
    }
    let writable = ft.is_file() || (char_device && ft.is_char_device());
    if !writable {
        return Err(FileError::new(
            path,
            format!(
                "cannot write: is {}; an output must be a regular file or a new name",
                describe(ft)
            ),
        ));
    }
    for (option, input) in inputs {
        let Ok(m) = std::fs::metadata(input) else {
            continue;
        };
        if m.dev() == meta.dev() && m.ino() == meta.ino() {
            return Err(FileError::new(
                path,
                format!(
                    "cannot write: is also this command's input {option} ({}); writing it would \
                     destroy the input: choose another output",
                    input.display()
                ),
            ));
        }
    }
    Ok(())
}

/// Opens `path` as a stream that is written while the command runs (the CSV sink's
/// recording, which a monitor follows and which keeps what was recorded before a crash): the
/// rules of [`check_output`], except that a character device (`/dev/null`, a serial line) is
/// written into — never replaced. The file is opened without following a link and without
/// blocking (a FIFO swapped in since the check fails instead of waiting for a reader), checked
/// again once open, and only then truncated.
pub fn open_stream(path: &Path, inputs: Inputs<'_>) -> Result<File, FileError> {
    use std::os::unix::fs::OpenOptionsExt;
    if let Ok(meta) = std::fs::symlink_metadata(path) {
        check_existing(path, &meta, inputs, true)?;
    } else {
        check_output(path, inputs)?;
    }
    let file = std::fs::OpenOptions::new()
        .write(true)
        .create(true)
        .custom_flags(libc::O_NOFOLLOW | libc::O_NONBLOCK | libc::O_NOCTTY)
        .open(path)
        .map_err(|e| FileError::io(path, "cannot write", e))?;
    let meta = file
        .metadata()
        .map_err(|e| FileError::io(path, "cannot write", e))?;
    check_existing(path, &meta, inputs, true)?;
    if meta.file_type().is_file() {
        file.set_len(0)
            .map_err(|e| FileError::io(path, "cannot write", e))?;
    }
    Ok(file)
}

/// The directory an output is renamed into (`.` for a bare file name).
fn directory(path: &Path) -> PathBuf {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

/// A name no other writer chose: the process, a counter and the clock hashed with a key the
/// standard library draws from the system's randomness for every `RandomState`.
fn random_name(path: &Path) -> PathBuf {
    use std::hash::{BuildHasher, Hasher};
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    let mut h = std::collections::hash_map::RandomState::new().build_hasher();
    h.write_u64(COUNTER.fetch_add(1, Ordering::Relaxed));
    h.write_u32(std::process::id());
    let now = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos());
    h.write_u128(now);
    let stem = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    directory(path).join(format!(".{stem}.{:016x}.tmp", h.finish()))
}

/// An output being written: an exclusive temporary file beside it, renamed over it by
/// [`Pending::commit`].
#[derive(Debug)]
pub struct Pending {
    path: PathBuf,
    tmp: PathBuf,
    inputs: Vec<(String, PathBuf)>,
    file: Option<File>,
}

impl Pending {
    /// Checks `path` ([`check_output`]) and creates its temporary file: `O_CREAT | O_EXCL`
    /// (`create_new`), which never follows a link and never opens an existing file, under a
    /// random name in the output's directory (so the rename stays on one file system). An
    /// existing output's permissions are kept.
    pub fn create(path: &Path, inputs: Inputs<'_>) -> Result<Self, FileError> {
        Self::create_with_mode(path, inputs, 0o666)
    }

    /// [`Pending::create`] for a secret (a signing key): the temporary file is created readable
    /// and writable by its owner only, so no one else can open it at any moment — not even
    /// before its content is written.
    pub fn create_private(path: &Path, inputs: Inputs<'_>) -> Result<Self, FileError> {
        Self::create_with_mode(path, inputs, 0o600)
    }

    fn create_with_mode(path: &Path, inputs: Inputs<'_>, mode: u32) -> Result<Self, FileError> {
        check_output(path, inputs)?;
        let mut tries = 0;
        let (tmp, file) = loop {
            let tmp = random_name(path);
            let mut options = std::fs::OpenOptions::new();
            options.write(true).create_new(true);
            #[cfg(unix)]
            std::os::unix::fs::OpenOptionsExt::mode(&mut options, mode);
            #[cfg(not(unix))]
            let _ = mode;
            match options.open(&tmp) {
                Ok(f) => break (tmp, f),
                Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists && tries < 16 => tries += 1,
                Err(e) => {
                    return Err(FileError::io(
                        path,
                        &format!("cannot create the temporary file {}", tmp.display()),
                        e,
                    ))
                }
            }
        };
        // A secret keeps its own mode; anything else the permissions of the file it replaces.
        if mode == 0o666 {
            if let Ok(m) = std::fs::metadata(path) {
                let _ = file.set_permissions(m.permissions());
            }
        }
        Ok(Self {
            path: path.to_path_buf(),
            tmp,
            inputs: inputs
                .iter()
                .map(|(o, p)| (o.to_string(), p.to_path_buf()))
                .collect(),
            file: Some(file),
        })
    }

    /// The output this becomes.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Syncs the temporary file to disk without renaming it (all of a set first, then the
    /// renames: [`write_all_whole`]).
    fn sync(&mut self) -> Result<(), FileError> {
        let path = self.path.clone();
        let f = self
            .file
            .as_mut()
            .ok_or_else(|| FileError::new(&path, "already written"))?;
        f.flush()
            .and_then(|()| f.sync_all())
            .map_err(|e| FileError::io(&path, "cannot write", e))
    }

    /// Renames the synced temporary file over the output, after checking the output again (it
    /// may have been replaced by a link or a device since [`Pending::create`]), then syncs the
    /// directory so the rename survives a power cut.
    fn rename(&mut self) -> Result<(), FileError> {
        let inputs: Vec<(&str, &Path)> = self
            .inputs
            .iter()
            .map(|(o, p)| (o.as_str(), p.as_path()))
            .collect();
        check_output(&self.path, &inputs)?;
        std::fs::rename(&self.tmp, &self.path)
            .map_err(|e| FileError::io(&self.path, "cannot write", e))?;
        self.file = None;
        if let Ok(d) = File::open(directory(&self.path)) {
            let _ = d.sync_all();
        }
        Ok(())
    }

    /// Syncs the content and renames it over the output; on failure the temporary file is
    /// removed and the output is untouched.
    pub fn commit(mut self) -> Result<(), FileError> {
        self.sync()?;
        self.rename()
    }
}

impl Write for Pending {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        match &mut self.file {
            Some(f) => f.write(buf),
            None => Err(std::io::Error::other("the output was already renamed")),
        }
    }

    fn flush(&mut self) -> std::io::Result<()> {
        match &mut self.file {
            Some(f) => f.flush(),
            None => Ok(()),
        }
    }
}

impl Drop for Pending {
    fn drop(&mut self) {
        if self.file.take().is_some() {
            let _ = std::fs::remove_file(&self.tmp);
        }
    }
}

/// Writes `bytes` as `path`, whole or not at all ([`Pending`]).
pub fn write_whole(path: &Path, bytes: &[u8], inputs: Inputs<'_>) -> Result<(), FileError> {
    let mut p = Pending::create(path, inputs)?;
    p.write_all(bytes)
        .map_err(|e| FileError::io(path, "cannot write", e))?;
    p.commit()
}

/// Writes several files that belong together (a HEIDENHAIN `.COM` table and the `.CMA` that
/// selects it): every output is checked and every file written and synced to its temporary
/// file before the first rename; if a rename fails, the files this call already renamed are
/// removed again, so a reader finds all of them or none of this call's (the older files those
/// had already replaced are not brought back; every byte is written and synced before the
/// first rename, so a full disk refuses the call before anything is replaced).
pub fn write_all_whole(files: &[(&Path, &[u8])], inputs: Inputs<'_>) -> Result<(), FileError> {
    let mut pending = Vec::with_capacity(files.len());
    for (path, bytes) in files {
        let mut p = Pending::create(path, inputs)?;
        p.write_all(bytes)
            .map_err(|e| FileError::io(path, "cannot write", e))?;
        p.sync()?;
        pending.push(p);
    }
    for i in 0..pending.len() {
        if let Err(e) = pending[i].rename() {
            for done in &pending[..i] {
                let _ = std::fs::remove_file(done.path());
            }
            return Err(e);
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests;
