//! The cycle's work times for the live view's percentiles: the host records every cycle's work
//! into a fixed histogram of atomics and a maximum per second of real time ([`WorkStats::record`],
//! one writer, no allocation, no lock, no wait); readers on other threads take copies and make
//! percentiles over a window from two copies apart ([`WorkStats::counts`], [`WorkStats::max_us`]).

use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

/// Buckets per doubling of the work time: a percentile read from the histogram is at most
/// 2^(1/8) − 1 ≈ 9 % above the true one.
pub const PER_DOUBLING: f64 = 8.0;
/// Buckets: from 1 µs (the first also holds everything below) to 2^20 µs ≈ 1 s (the last also
/// holds everything above).
pub const WORK_BUCKETS: usize = 160;
/// Seconds of maxima kept: a window of up to `MAX_SLOTS − 1` seconds can be asked.
pub const MAX_SLOTS: usize = 64;

/// The upper edge of bucket `k` in µs (the last: infinite).
pub fn bucket_edge_us(k: usize) -> f64 {
    if k + 1 >= WORK_BUCKETS {
        f64::INFINITY
    } else {
        ((k + 1) as f64 / PER_DOUBLING).exp2()
    }
}

fn bucket_of(work_us: f64) -> usize {
    if work_us < 1.0 {
        0
    } else {
        ((work_us.log2() * PER_DOUBLING) as usize).min(WORK_BUCKETS - 1)
    }
}

/// One second's largest work: the second's number since the board was made, and the work's bits.
#[derive(Debug)]
struct Slot {
    second: AtomicU64,
    max_bits: AtomicU64,
}

/// Work times of the cycles since start: counts per bucket, their number and sum, and the
/// largest of each of the last [`MAX_SLOTS`] seconds.
#[derive(Debug)]
pub struct WorkStats {
    born: Instant,
    counts: Vec<AtomicU64>,
    cycles: AtomicU64,
    sum_bits: AtomicU64,
    slots: Vec<Slot>,
}

impl WorkStats {
    /// Nothing recorded yet; seconds count from now.
    pub fn new() -> Self {
        Self {
            born: Instant::now(),
            counts: (0..WORK_BUCKETS).map(|_| AtomicU64::new(0)).collect(),
            cycles: AtomicU64::new(0),
            sum_bits: AtomicU64::new(0.0f64.to_bits()),
            slots: (0..MAX_SLOTS)
                .map(|_| Slot {
                    // No second is this one: every slot starts empty.
                    second: AtomicU64::new(u64::MAX),
                    max_bits: AtomicU64::new(0),
                })
                .collect(),
        }
    }

    fn second(&self, at: Instant) -> u64 {
        at.saturating_duration_since(self.born).as_secs()
    }

    /// Records one cycle's work (µs; not finite or negative: ignored) done at `at` (the
    /// writer's clock read). One writer only: the host's loop.
    pub fn record(&self, work_us: f64, at: Instant) {
        if !(work_us.is_finite() && work_us >= 0.0) {
            return;
        }
        self.counts[bucket_of(work_us)].fetch_add(1, Ordering::Relaxed);
        self.cycles.fetch_add(1, Ordering::Relaxed);
        let sum = f64::from_bits(self.sum_bits.load(Ordering::Relaxed)) + work_us;
        self.sum_bits.store(sum.to_bits(), Ordering::Relaxed);
        let second = self.second(at);
        let slot = &self.slots[(second % MAX_SLOTS as u64) as usize];
        // A positive f64's bits order as the number does.
        if slot.second.load(Ordering::Relaxed) != second {
            // The slot's old maximum goes first, so that a reader never takes it for this
            // second's (it may briefly miss this second's instead).
            slot.max_bits.store(work_us.to_bits(), Ordering::Relaxed);
            slot.second.store(second, Ordering::Release);
        } else if work_us.to_bits() > slot.max_bits.load(Ordering::Relaxed) {
            slot.max_bits.store(work_us.to_bits(), Ordering::Relaxed);
        }
    }

    /// The counts per bucket since start (a reader's copy).
    pub fn counts(&self) -> Vec<u64> {
        self.counts
            .iter()
            .map(|c| c.load(Ordering::Relaxed))
            .collect()
    }

    /// Cycles recorded since start and the sum of their work in µs.
    pub fn total(&self) -> (u64, f64) {
        (
            self.cycles.load(Ordering::Relaxed),
            f64::from_bits(self.sum_bits.load(Ordering::Relaxed)),
        )
    }

    /// The largest work (µs) of the seconds within the last `window_s` seconds before `now`
    /// (at most [`MAX_SLOTS`] − 1); NaN when none was recorded there.
    pub fn max_us(&self, now: Instant, window_s: u64) -> f64 {
        let now_s = self.second(now);
        let from = now_s.saturating_sub(window_s.min(MAX_SLOTS as u64 - 1));
        let mut max = f64::NAN;
        for slot in &self.slots {
            let s = slot.second.load(Ordering::Acquire);
            if s == u64::MAX || s < from || s > now_s {
                continue;
            }
            let v = f64::from_bits(slot.max_bits.load(Ordering::Relaxed));
            if slot.second.load(Ordering::Acquire) == s && (max.is_nan() || v > max) {
                max = v;
            }
        }
        max
    }
}

impl Default for WorkStats {
    fn default() -> Self {
        Self::new()
    }
}

/// The `q` quantile (0–1) of the cycles counted in `counts`, as the upper edge of its bucket
/// (µs); NaN when there are none.
pub fn quantile_us(counts: &[u64], q: f64) -> f64 {
    let n: u64 = counts.iter().sum();
    if n == 0 {
        return f64::NAN;
    }
    let rank = ((q.clamp(0.0, 1.0) * n as f64).ceil() as u64).max(1);
    let mut seen = 0;
    for (k, c) in counts.iter().enumerate() {
        seen += c;
        if seen >= rank {
            return bucket_edge_us(k);
        }
    }
    bucket_edge_us(counts.len() - 1)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;

    #[test]
    fn quantiles_are_the_upper_edge_of_their_bucket_within_nine_percent() {
        let w = WorkStats::new();
        let t = Instant::now();
        for i in 1..=1000 {
            w.record(f64::from(i), t);
        }
        let c = w.counts();
        let p50 = quantile_us(&c, 0.5);
        let p99 = quantile_us(&c, 0.99);
        assert!((500.0..=500.0 * 1.091).contains(&p50), "{p50}");
        assert!((990.0..=990.0 * 1.091).contains(&p99), "{p99}");
        assert_eq!(w.max_us(t, 10), 1000.0);
        assert_eq!(w.total(), (1000, 500_500.0));
        assert!(quantile_us(&[0; WORK_BUCKETS], 0.5).is_nan());
        w.record(f64::NAN, t);
        w.record(-1.0, t);
        assert_eq!(w.total().0, 1000, "not finite or negative: not counted");
    }

    #[test]
    fn the_maximum_forgets_seconds_beyond_its_window() {
        let w = WorkStats::new();
        let t0 = w.born;
        w.record(900.0, t0);
        w.record(20.0, t0 + Duration::from_secs(30));
        let later = t0 + Duration::from_secs(30);
        assert_eq!(w.max_us(later, 60), 900.0);
        assert_eq!(w.max_us(later, 10), 20.0);
        // The slot of second 0 is taken again 64 s later: its old maximum is gone.
        w.record(5.0, t0 + Duration::from_secs(64));
        assert_eq!(w.max_us(t0 + Duration::from_secs(64), 63), 20.0);
        assert!(w.max_us(t0 + Duration::from_secs(200), 10).is_nan());
    }
}
