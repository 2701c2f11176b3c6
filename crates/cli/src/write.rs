//! Output files are written whole or not at all: a reader (a control loading a table, the
//! service reloading a model) never sees half a file, and a refused or failed write leaves no
//! file behind. The one place the CLI writes its outputs.

use std::io::Write as _;
use std::path::{Path, PathBuf};

use crate::error::CliError;

/// The temporary file beside `path` that becomes it by a rename (same directory, so the
/// rename is atomic on one file system): `path` with `.partial` appended.
fn temporary(path: &Path) -> PathBuf {
    let mut tmp = path.as_os_str().to_owned();
    tmp.push(".partial");
    PathBuf::from(tmp)
}

fn write_synced(tmp: &Path, bytes: &[u8]) -> std::io::Result<()> {
    let mut f = std::fs::File::create(tmp)?;
    f.write_all(bytes)?;
    f.sync_all()
}

/// Writes `bytes` to a temporary file beside `path`, syncs it and renames it over `path`; on
/// any failure the temporary file is removed and `path` is untouched.
pub fn write_whole(path: &Path, bytes: impl AsRef<[u8]>) -> Result<(), CliError> {
    write_all_whole(&[(path, bytes.as_ref())])
}

/// Writes several files that belong together (a HEIDENHAIN `.COM` table and the `.CMA` that
/// selects it): every file is first written and synced to its temporary file, and only when
/// all are complete are they renamed into place. If a rename fails, the files already renamed
/// by this call are removed again, so a reader finds all of them or none of this call's.
pub fn write_all_whole(files: &[(&Path, &[u8])]) -> Result<(), CliError> {
    let tmps: Vec<PathBuf> = files.iter().map(|(p, _)| temporary(p)).collect();
    let clean = |tmps: &[PathBuf]| {
        for t in tmps {
            let _ = std::fs::remove_file(t);
        }
    };
    for ((path, bytes), tmp) in files.iter().zip(&tmps) {
        if let Err(e) = write_synced(tmp, bytes) {
            clean(&tmps);
            return Err(CliError::file(path, Some("cannot write"))(e));
        }
    }
    for (i, ((path, _), tmp)) in files.iter().zip(&tmps).enumerate() {
        if let Err(e) = std::fs::rename(tmp, path) {
            clean(&tmps[i..]);
            for (done, _) in &files[..i] {
                let _ = std::fs::remove_file(done);
            }
            return Err(CliError::file(path, Some("cannot write"))(e));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_failed_write_leaves_no_file() {
        let d = std::env::temp_dir().join(format!("truepos-write-{}", std::process::id()));
        std::fs::create_dir_all(&d).unwrap();
        let (a, b) = (d.join("a.txt"), d.join("b.txt"));
        write_all_whole(&[(&a, b"one".as_slice()), (&b, b"two".as_slice())]).unwrap();
        assert_eq!(std::fs::read_to_string(&a).unwrap(), "one");
        assert_eq!(std::fs::read_to_string(&b).unwrap(), "two");
        // The second target is a directory: the rename fails, the first file is removed again
        // and no temporary file stays behind.
        let (c, dir) = (d.join("c.txt"), d.join("sub"));
        std::fs::create_dir_all(dir.join("x")).unwrap();
        assert!(write_all_whole(&[(&c, b"1".as_slice()), (&dir, b"2".as_slice())]).is_err());
        assert!(!c.exists());
        let left: Vec<_> = std::fs::read_dir(&d)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .filter(|n| n.ends_with(".partial"))
            .collect();
        assert!(left.is_empty(), "{left:?}");
        let _ = std::fs::remove_dir_all(&d);
    }
}
