//! What every test of the `truepos` binary needs: the repository root, a scratch directory and
//! the binary started from the root (so examples are named by their repository paths).
#![allow(dead_code)] // each test file uses a part

use std::path::{Path, PathBuf};
use std::process::Command;

/// A path in the repository.
pub fn repo(path: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../..")
        .join(path)
}

/// An empty directory of its own for one test (`truepos-NAME-PID`).
pub fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("truepos-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// The binary, started in the repository root.
pub fn command() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_truepos"));
    c.current_dir(repo(""));
    c
}

/// Runs the binary from the repository root: (success, stdout, stderr).
pub fn run(args: &[&str]) -> (bool, String, String) {
    let out = command().args(args).output().unwrap();
    (
        out.status.success(),
        String::from_utf8(out.stdout).unwrap(),
        String::from_utf8(out.stderr).unwrap(),
    )
}

/// Runs the binary from the repository root, killed after `limit` (the test then fails):
/// (success, stdout, stderr). Both outputs are read while it runs, so a long one cannot stall it.
pub fn run_within<S>(args: &[S], limit: std::time::Duration) -> (bool, String, String)
where
    S: AsRef<std::ffi::OsStr> + std::fmt::Debug,
{
    use std::io::Read;
    use std::process::Stdio;
    let mut child = command()
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let read = |mut r: Box<dyn Read + Send>| {
        std::thread::spawn(move || {
            let mut s = String::new();
            let _ = r.read_to_string(&mut s);
            s
        })
    };
    let out = read(Box::new(child.stdout.take().unwrap()));
    let err = read(Box::new(child.stderr.take().unwrap()));
    let start = std::time::Instant::now();
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        if start.elapsed() > limit {
            let _ = child.kill();
            let _ = child.wait();
            panic!("truepos {args:?} ran longer than {limit:?}");
        }
        std::thread::sleep(std::time::Duration::from_millis(20));
    };
    (status.success(), out.join().unwrap(), err.join().unwrap())
}
