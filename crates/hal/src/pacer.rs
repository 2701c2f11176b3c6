//! A periodic cycle in userspace, as good as Linux lets one be without a realtime kernel:
//! absolute deadlines on `CLOCK_MONOTONIC` (`clock_nanosleep` with `TIMER_ABSTIME`, so that
//! neither the time to compute the next deadline nor a preemption before the sleep shifts the
//! period), `SCHED_FIFO`, memory locked, the thread bound to one CPU, no timer slack.

use crate::ffi;

/// Deadlines `start + k·period` and the sleep until each.
#[derive(Debug, Clone)]
pub struct Pacer {
    start_ns: u64,
    period_ns: u64,
    k: u64,
}

impl Pacer {
    /// A pacer whose first deadline is `start_ns` (`CLOCK_MONOTONIC`).
    pub fn new(start_ns: u64, period_ns: u64) -> Self {
        Self {
            start_ns,
            period_ns: period_ns.max(1),
            k: 0,
        }
    }

    /// The current deadline, ns.
    pub fn deadline_ns(&self) -> u64 {
        self.start_ns + self.k * self.period_ns
    }

    /// Cycles begun so far (the index of the current deadline).
    pub fn index(&self) -> u64 {
        self.k
    }

    /// Time of the current deadline after the first, s (the service clock of a cycle that
    /// keeps its schedule).
    pub fn deadline_s(&self) -> f64 {
        (self.k * self.period_ns) as f64 * 1e-9
    }

    /// Sleeps until the current deadline; returns when the thread woke (ns).
    pub fn wait(&self) -> u64 {
        ffi::sleep_until_ns(self.deadline_ns());
        ffi::monotonic_ns()
    }

    /// Moves to the next deadline. A cycle that fell behind runs the missed deadlines back to
    /// back (each is counted by its own lateness).
    pub fn advance(&mut self) {
        self.k += 1;
    }

    /// Moves to the first deadline after `now_ns`, dropping those missed; returns how many were
    /// dropped. For a control that should act on current values rather than catch up.
    pub fn skip_to(&mut self, now_ns: u64) -> u64 {
        let next = now_ns.saturating_sub(self.start_ns) / self.period_ns + 1;
        let dropped = next.saturating_sub(self.k + 1);
        self.k = self.k.max(next);
        dropped
    }
}

/// What [`realtime_setup`] achieved; the errors say what was refused (the cycle runs anyway).
#[derive(Debug, Clone, Default)]
pub struct RealtimeSetup {
    /// `SCHED_FIFO` priority in force, if any.
    pub fifo_priority: Option<i32>,
    /// Whether the process' memory is locked (`mlockall`).
    pub memory_locked: bool,
    /// The CPU the thread is bound to, if any.
    pub cpu: Option<usize>,
    /// Timer slack set to 1 ns.
    pub no_timer_slack: bool,
    /// Refusals, as "call: reason".
    pub errors: Vec<String>,
}

/// Prepares the calling thread for a periodic cycle: `SCHED_FIFO` at `priority` (if > 0) with
/// memory locked, bound to `cpu` (if given), timer slack 1 ns. Each step is tried on its own;
/// what the system refuses is reported, not fatal.
pub fn realtime_setup(priority: i32, cpu: Option<usize>) -> RealtimeSetup {
    let mut setup = RealtimeSetup::default();
    if let Some(c) = cpu {
        match ffi::pin_to_cpu(c) {
            Ok(()) => setup.cpu = Some(c),
            Err(e) => setup.errors.push(e),
        }
    }
    match ffi::set_timer_slack_ns(1) {
        Ok(()) => setup.no_timer_slack = true,
        Err(e) => setup.errors.push(e),
    }
    if priority > 0 {
        match ffi::set_realtime_priority(priority) {
            Ok(()) => {
                setup.fifo_priority = Some(priority);
                setup.memory_locked = true;
            }
            Err(e) => setup.errors.push(e),
        }
    }
    setup
}

/// Keeps the calling thread, and the threads it starts from now on (a logger, a sampler), off
/// the cycle's CPU: on a kernel without full preemption a system call of another thread (the
/// log's write and fsync) on that CPU holds a woken realtime thread up until it returns.
/// Returns the CPUs left to them (empty, and nothing changed, with a single CPU).
pub fn keep_off_cpu(cycle_cpu: usize) -> Result<Vec<usize>, String> {
    let cpus = std::thread::available_parallelism().map_or(1, |n| n.get());
    let others: Vec<usize> = (0..cpus).filter(|&c| c != cycle_cpu).collect();
    if !others.is_empty() {
        ffi::bind_to_cpus(&others)?;
    }
    Ok(others)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn deadlines_are_absolute_multiples_of_the_period() {
        let mut p = Pacer::new(1_000, 1_000_000);
        assert_eq!(p.deadline_ns(), 1_000);
        p.advance();
        p.advance();
        assert_eq!(p.deadline_ns(), 2_001_000);
        assert!((p.deadline_s() - 0.002).abs() < 1e-15);
        // Woken at 5.5 ms: deadlines 3, 4, 5 ms are dropped, the next is 6 ms.
        assert_eq!(p.skip_to(5_500_000), 3);
        assert_eq!(p.deadline_ns(), 6_001_000);
        assert_eq!(p.skip_to(6_000_000), 0);
        assert_eq!(p.index(), 6);
    }

    #[test]
    fn wait_returns_at_or_after_the_deadline() {
        let start = ffi::monotonic_ns();
        let mut p = Pacer::new(start, 200_000);
        for _ in 0..5 {
            let woke = p.wait();
            assert!(woke >= p.deadline_ns());
            p.advance();
        }
        assert!(ffi::monotonic_ns() - start >= 800_000);
    }
}
