//! What a source thread does besides talking to its peer: waiting while staying stoppable (sleeps
//! and socket reads in short slices), being stopped within a bounded time, and reading the
//! service clock.

use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// Sleeps `duration` in short slices, returning early (with `false`) once `stop` is set, so a
/// source thread always ends within about 20 ms of being asked to.
pub fn sleep_unless_stopped(duration: Duration, stop: &AtomicBool) -> bool {
    const SLICE: Duration = Duration::from_millis(20);
    let end = Instant::now() + duration;
    loop {
        if stop.load(Ordering::Acquire) {
            return false;
        }
        let now = Instant::now();
        if now >= end {
            return true;
        }
        std::thread::sleep((end - now).min(SLICE));
    }
}

/// Asks a source thread to stop and waits for it at most `limit`. A thread still busy after that
/// (inside a connection attempt, which std cannot interrupt) is left to end by itself: it holds
/// only shared state, checks `stop` as soon as the attempt returns, and nobody reads what it
/// publishes any more. So dropping a source never takes much longer than `limit`, whatever the
/// peer does. Returns whether the thread ended within the limit.
pub fn stop_thread(stop: &AtomicBool, thread: JoinHandle<()>, limit: Duration) -> bool {
    stop.store(true, Ordering::Release);
    let end = Instant::now() + limit;
    while !thread.is_finished() {
        if Instant::now() >= end {
            return false;
        }
        std::thread::sleep(Duration::from_millis(2));
    }
    let _ = thread.join();
    true
}

/// How long dropping a network source waits for its thread (see [`stop_thread`]).
pub const STOP_LIMIT: Duration = Duration::from_millis(500);

/// Reads from `stream` until `buf` is full or `deadline` passes: the deadline covers the whole
/// answer, however the peer spreads its bytes. Waits in slices of at most 20 ms and gives up
/// with `Interrupted` once `stop` is set, so that a source thread stops promptly even while a
/// peer drips bytes. On a timeout the error is `TimedOut` and `filled` tells how many bytes came.
pub fn read_exact_until(
    stream: &mut std::net::TcpStream,
    buf: &mut [u8],
    deadline: Instant,
    stop: &AtomicBool,
    filled: &mut usize,
) -> std::io::Result<()> {
    use std::io::{Error, ErrorKind, Read};
    const SLICE: Duration = Duration::from_millis(20);
    *filled = 0;
    while *filled < buf.len() {
        if stop.load(Ordering::Acquire) {
            return Err(Error::new(ErrorKind::Interrupted, "stopped"));
        }
        let now = Instant::now();
        if now >= deadline {
            return Err(Error::new(ErrorKind::TimedOut, "timed out"));
        }
        stream.set_read_timeout(Some(
            (deadline - now).clamp(Duration::from_millis(1), SLICE),
        ))?;
        match stream.read(&mut buf[*filled..]) {
            Ok(0) => return Err(Error::new(ErrorKind::UnexpectedEof, "closed")),
            Ok(n) => *filled += n,
            Err(e)
                if matches!(
                    e.kind(),
                    ErrorKind::WouldBlock | ErrorKind::TimedOut | ErrorKind::Interrupted
                ) => {}
            Err(e) => return Err(e),
        }
    }
    Ok(())
}

/// Seconds since `epoch` (the service clock when `epoch` is the service's start).
pub fn seconds_since(epoch: Instant) -> f64 {
    epoch.elapsed().as_secs_f64()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sleep_stops_early_when_asked() {
        let stop = AtomicBool::new(true);
        let t = Instant::now();
        assert!(!sleep_unless_stopped(Duration::from_secs(10), &stop));
        assert!(t.elapsed() < Duration::from_secs(1));
        let go = AtomicBool::new(false);
        assert!(sleep_unless_stopped(Duration::from_millis(30), &go));
    }
}
