//! The cycle's work over the last minute (`cycle_work` in `/api/state`,
//! `truepos_cycle_work_window_seconds` in `/metrics`): made on the sampler's thread from copies
//! of the board's histogram taken a second apart, the newest less the one a minute older, so
//! that the cycle's side stays a few atomic additions.

use std::collections::VecDeque;
use std::time::{Duration, Instant};

use truepos_runtime::live::{quantile_us, WorkStats};

/// The window the percentiles cover.
pub const WINDOW: Duration = Duration::from_secs(60);
/// How often a copy of the histogram is kept.
const COPY_EVERY: Duration = Duration::from_secs(1);

/// The cycle's work figures as served.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WorkFigures {
    /// Seconds the window covers (up to [`WINDOW`] plus a second; less just after start).
    pub window_s: f64,
    /// Cycles in the window.
    pub cycles: u64,
    /// Median work in the window, µs (upper edge of its histogram bucket: at most 9 % above).
    pub p50_us: f64,
    /// 99th percentile, µs (the same resolution).
    pub p99_us: f64,
    /// Largest work in the window, µs (exact, by second of real time).
    pub max_us: f64,
    /// Cycles since start.
    pub total_cycles: u64,
    /// Work since start, µs.
    pub total_us: f64,
}

impl Default for WorkFigures {
    fn default() -> Self {
        Self {
            window_s: 0.0,
            cycles: 0,
            p50_us: f64::NAN,
            p99_us: f64::NAN,
            max_us: f64::NAN,
            total_cycles: 0,
            total_us: 0.0,
        }
    }
}

/// The copies of the histogram the window is made from.
#[derive(Debug)]
pub struct WorkWindow {
    copies: VecDeque<(Instant, Vec<u64>)>,
}

impl WorkWindow {
    /// A window that starts now, from nothing recorded.
    pub fn new(now: Instant, buckets: usize) -> Self {
        let mut copies = VecDeque::new();
        copies.push_back((now, vec![0; buckets]));
        Self { copies }
    }

    /// Takes a copy if a second has passed and answers the figures of the last minute.
    pub fn update(&mut self, stats: &WorkStats, now: Instant) -> WorkFigures {
        let counts = stats.counts();
        if self
            .copies
            .back()
            .is_none_or(|(t, _)| now.saturating_duration_since(*t) >= COPY_EVERY)
        {
            self.copies.push_back((now, counts.clone()));
        }
        // The oldest copy kept is the newest one at least a window old.
        while self.copies.len() >= 2
            && self
                .copies
                .get(1)
                .is_some_and(|(t, _)| now.saturating_duration_since(*t) >= WINDOW)
        {
            self.copies.pop_front();
        }
        let Some((since, base)) = self.copies.front() else {
            return WorkFigures::default();
        };
        let delta: Vec<u64> = counts
            .iter()
            .zip(base)
            .map(|(n, b)| n.saturating_sub(*b))
            .collect();
        let window = now.saturating_duration_since(*since);
        let (total_cycles, total_us) = stats.total();
        WorkFigures {
            window_s: window.as_secs_f64(),
            cycles: delta.iter().sum(),
            p50_us: quantile_us(&delta, 0.5),
            p99_us: quantile_us(&delta, 0.99),
            max_us: stats.max_us(now, window.as_secs().max(1)),
            total_cycles,
            total_us,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use truepos_runtime::live::WORK_BUCKETS;

    #[test]
    fn the_window_forgets_cycles_older_than_a_minute() {
        let stats = WorkStats::new();
        let t0 = Instant::now();
        let mut w = WorkWindow::new(t0, WORK_BUCKETS);
        for _ in 0..100 {
            stats.record(1000.0, t0);
        }
        let f = w.update(&stats, t0 + Duration::from_millis(200));
        assert_eq!(f.cycles, 100);
        assert!((1000.0..1091.0).contains(&f.p50_us), "{f:?}");
        // A copy every second for two minutes, slow cycles only at the start.
        let mut last = f;
        for s in 1..=120 {
            let at = t0 + Duration::from_secs(s);
            stats.record(10.0, at);
            last = w.update(&stats, at);
        }
        assert!(last.cycles <= 61 && last.cycles >= 59, "{last:?}");
        assert!(last.p99_us < 11.0, "{last:?}");
        assert_eq!(last.max_us, 10.0, "{last:?}");
        assert_eq!(last.total_cycles, 220);
        assert!((60.0..=62.0).contains(&last.window_s), "{last:?}");
    }
}
