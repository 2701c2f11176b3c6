//! Reading a file: a regular file only, opened without blocking, no larger than its kind's
//! [`Limit`].

use std::fs::File;
use std::io::Read;
use std::os::unix::fs::OpenOptionsExt;
use std::path::Path;

use crate::{describe, FileError, Limit};

/// Opens `path` for reading after checking that it is a regular file within `limit`; returns
/// the file and its size. A FIFO, device, socket or directory is refused by name; the check
/// is made on the path before opening (so a device is never opened) and again on the opened
/// file (so one swapped in between is refused too). `O_NONBLOCK` makes opening a FIFO return
/// at once instead of waiting for a writer.
pub fn open(path: &Path, limit: Limit) -> Result<(File, u64), FileError> {
    let max = limit.effective().map_err(|m| FileError::new(path, m))?;
    let before = std::fs::metadata(path).map_err(|e| FileError::io(path, "cannot read", e))?;
    check(path, &before, limit, max)?;
    let file = std::fs::OpenOptions::new()
        .read(true)
        .custom_flags(libc::O_NONBLOCK | libc::O_NOCTTY)
        .open(path)
        .map_err(|e| FileError::io(path, "cannot read", e))?;
    let meta = file
        .metadata()
        .map_err(|e| FileError::io(path, "cannot read", e))?;
    check(path, &meta, limit, max)?;
    Ok((file, meta.len()))
}

fn check(path: &Path, meta: &std::fs::Metadata, limit: Limit, max: u64) -> Result<(), FileError> {
    if !meta.file_type().is_file() {
        return Err(FileError::new(
            path,
            format!(
                "is {}, not a regular file: a {} file must be a regular file",
                describe(meta.file_type()),
                limit.kind
            ),
        ));
    }
    if meta.len() > max {
        return Err(too_large(path, meta.len(), limit, max));
    }
    Ok(())
}

fn too_large(path: &Path, size: u64, limit: Limit, max: u64) -> FileError {
    FileError::new(
        path,
        format!(
            "is {size} bytes, more than the {max} bytes a {} file may have{}",
            limit.kind,
            limit.how_to_raise()
        ),
    )
}

/// The whole content of a regular file within `limit`. A file that grows beyond the limit
/// while it is read is refused as well.
pub fn read(path: &Path, limit: Limit) -> Result<Vec<u8>, FileError> {
    let (file, size) = open(path, limit)?;
    let max = limit.effective().map_err(|m| FileError::new(path, m))?;
    let mut bytes = Vec::with_capacity(usize::try_from(size).unwrap_or(0));
    file.take(max.saturating_add(1))
        .read_to_end(&mut bytes)
        .map_err(|e| FileError::io(path, "cannot read", e))?;
    if bytes.len() as u64 > max {
        return Err(too_large(path, bytes.len() as u64, limit, max));
    }
    Ok(bytes)
}

/// The whole content of a regular UTF-8 text file within `limit`.
pub fn read_text(path: &Path, limit: Limit) -> Result<String, FileError> {
    String::from_utf8(read(path, limit)?).map_err(|e| {
        let at = e.utf8_error().valid_up_to();
        FileError::new(
            path,
            format!("cannot read: not UTF-8 text (byte {at} starts an invalid sequence)"),
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_dir;

    #[test]
    fn a_device_is_refused_by_name_and_kind() {
        let e = read(Path::new("/dev/zero"), crate::MODEL).unwrap_err();
        assert_eq!(
            e.to_string(),
            "/dev/zero: is a character device, not a regular file: a model file must be a \
             regular file"
        );
    }

    #[test]
    fn a_fifo_never_blocks_and_is_refused() {
        let d = test_dir("fifo-read");
        let fifo = d.join("model.toml");
        let made = std::process::Command::new("mkfifo")
            .arg(&fifo)
            .status()
            .unwrap();
        assert!(made.success());
        let t = std::time::Instant::now();
        let e = read(&fifo, crate::MODEL).unwrap_err();
        assert!(t.elapsed() < std::time::Duration::from_secs(2));
        assert!(e.to_string().contains("is a FIFO (named pipe)"), "{e}");
    }

    #[test]
    fn a_directory_is_refused() {
        let d = test_dir("dir-read");
        let e = read(&d, crate::RUN).unwrap_err();
        assert!(
            e.to_string().contains("is a directory, not a regular file"),
            "{e}"
        );
    }

    #[test]
    fn a_file_beyond_its_limit_names_size_and_limit() {
        let d = test_dir("large-read");
        let f = d.join("m.toml");
        std::fs::write(&f, vec![b'#'; 100]).unwrap();
        let small = Limit {
            kind: "model",
            bytes: 99,
            env: None,
        };
        let e = read(&f, small).unwrap_err();
        assert!(
            e.to_string()
                .ends_with("is 100 bytes, more than the 99 bytes a model file may have"),
            "{e}"
        );
        assert_eq!(read(&f, crate::MODEL).unwrap().len(), 100);
    }

    #[test]
    fn text_that_is_not_utf8_names_the_byte() {
        let d = test_dir("utf8-read");
        let f = d.join("m.toml");
        std::fs::write(&f, b"ab\xffcd").unwrap();
        let e = read_text(&f, crate::MODEL).unwrap_err();
        assert!(e.to_string().contains("byte 2"), "{e}");
    }
}

#[cfg(test)]
mod limit_tests {
    use super::*;
    use crate::test_dir;

    /// A variable of this test alone, so no other test sees it change.
    const RAISED: Limit = Limit {
        kind: "run",
        bytes: 10,
        env: Some("TRUEPOS_TEST_ONLY_MAX_MB"),
    };

    #[test]
    fn a_limit_is_raised_by_its_variable_and_a_bad_value_is_an_error() {
        let d = test_dir("raised");
        let f = d.join("run.csv");
        std::fs::write(&f, vec![b'1'; 100]).unwrap();
        let e = read(&f, RAISED).unwrap_err();
        assert!(
            e.to_string().ends_with(
                "is 100 bytes, more than the 10 bytes a run file may have (raise it with \
                 TRUEPOS_TEST_ONLY_MAX_MB=MiB)"
            ),
            "{e}"
        );
        std::env::set_var("TRUEPOS_TEST_ONLY_MAX_MB", "1");
        assert_eq!(read(&f, RAISED).unwrap().len(), 100);
        std::env::set_var("TRUEPOS_TEST_ONLY_MAX_MB", "lots");
        let e = read(&f, RAISED).unwrap_err();
        assert!(
            e.to_string().contains("expected a whole number of MiB"),
            "{e}"
        );
        std::env::remove_var("TRUEPOS_TEST_ONLY_MAX_MB");
    }
}
