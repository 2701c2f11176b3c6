//! `--after-write`: a command run after each model file the follower wrote, bounded in time.

use std::path::Path;
use std::time::{Duration, Instant};

/// Runs `--after-write`, bounded: what it did, in words. The command runs in a process group
/// of its own, killed whole when it overruns (not only `sh`: what it started too).
pub(super) fn after_write(cmd: &str, model: &Path, version: i32) -> String {
    after_write_within(cmd, model, version, Duration::from_secs(30))
}

fn after_write_within(cmd: &str, model: &Path, version: i32, limit: Duration) -> String {
    use std::os::unix::process::CommandExt;
    let child = std::process::Command::new("sh")
        .process_group(0)
        .arg("-c")
        .arg(cmd)
        .env("TRUEPOS_MODEL", model)
        .env("TRUEPOS_MODEL_VERSION", version.to_string())
        .stdin(std::process::Stdio::null())
        .spawn();
    let mut child = match child {
        Ok(c) => c,
        Err(e) => return format!("--after-write: cannot start `sh`: {e}"),
    };
    let start = Instant::now();
    loop {
        match child.try_wait() {
            Ok(Some(status)) if status.success() => return "--after-write: done".into(),
            Ok(Some(status)) => return format!("--after-write: failed ({status})"),
            Ok(None) if start.elapsed() > limit => {
                // The group's id is `sh`'s pid (`process_group(0)`).
                let group = format!("-{}", child.id());
                let _ = std::process::Command::new("kill")
                    .args(["-KILL", "--", &group])
                    .stdout(std::process::Stdio::null())
                    .stderr(std::process::Stdio::null())
                    .status();
                let _ = child.kill();
                let _ = child.wait();
                return format!(
                    "--after-write: still running after {} s, killed with its process group",
                    limit.as_secs_f64()
                );
            }
            Ok(None) => std::thread::sleep(Duration::from_millis(20)),
            Err(e) => return format!("--after-write: {e}"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_after_write_that_overruns_is_killed_with_what_it_started() {
        let dir = std::env::temp_dir().join(format!("truepos-after-write-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let pid_file = dir.join("sleeper.pid");
        // `sh` starts a sleeper in the background and waits on it: the limit kills both.
        let cmd = format!("sleep 30 & echo $! > {}; wait", pid_file.display());
        let said = after_write_within(&cmd, &dir, 3, Duration::from_millis(300));
        assert!(said.contains("killed with its process group"), "{said}");
        let pid = std::fs::read_to_string(&pid_file).unwrap();
        let pid = pid.trim();
        // The sleeper is gone, or a zombie no one reaped yet (killed; its parent `sh` is dead).
        let mut gone = false;
        for _ in 0..100 {
            let status = std::fs::read_to_string(format!("/proc/{pid}/status")).unwrap_or_default();
            let alive = status
                .lines()
                .find(|l| l.starts_with("State:"))
                .is_some_and(|l| !l.contains('Z'));
            if !alive {
                gone = true;
                break;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        assert!(gone, "the sleeper {pid} still runs");
        assert_eq!(
            after_write_within("exit 0", &dir, 3, Duration::from_secs(5)),
            "--after-write: done"
        );
        let _ = std::fs::remove_dir_all(&dir);
    }
}
