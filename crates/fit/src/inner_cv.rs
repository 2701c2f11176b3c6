//! The inner validation's folds: which training rows fit the model that predicts each held-out
//! block.
//!
//! The training rows (in time order, run after run) are cut into contiguous blocks. A model that
//! predicts block f must not learn from rows whose errors are the same excursion as block f's:
//! thermal errors and every filtered feature carry hours of memory, so a row just before or after
//! the block tells the fit what the block holds, and the score comes out below the error on
//! really unseen data. Each held-out block is therefore separated from its training rows by a
//! **gap** on both sides (within the same run; another run is another excursion) at least as long
//! as the slowest filter or lag of the candidate and the decorrelation time of its residual,
//! capped at one block length per side so that most rows still train. Filter states are those of
//! the whole run from its first sample, as on the control: a held-out row's features see the
//! inputs before it, never a carried-over fit.
//!
//! ```
//! use truepos_fit::inner_cv::{Folds, Row};
//! // One run, 10 rows 60 s apart, 2 blocks of 5; a 150 s gap keeps rows 3, 4 out of the fit
//! // that predicts block 1 and rows 5, 6 out of the one that predicts block 0.
//! let rows: Vec<Row> = (0..10).map(|i| Row { run: 0, time_s: 60.0 * i as f64 }).collect();
//! let folds = Folds::new(&rows, 2, truepos_fit::settings::InnerCv::Blocked, 150.0);
//! assert_eq!(folds.training_rows(1), vec![0..3]);
//! assert_eq!(folds.training_rows(0), vec![7..10]);
//! ```

use std::ops::Range;

use crate::settings::{InnerCv, ROLLING_FIRST_HELD_OUT};

/// Where a training row sits in time.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Row {
    /// Index of its run.
    pub run: usize,
    /// Time within the run (s).
    pub time_s: f64,
}

/// One held-out block and the segments whose rows fit the model that predicts it.
#[derive(Debug, Clone, PartialEq)]
pub struct Fold {
    /// The held-out rows.
    pub held: Range<usize>,
    /// Indices into [`Folds::segments`] of the rows that train its model.
    pub train: Vec<usize>,
}

/// The folds of one inner validation at one gap.
#[derive(Debug, Clone, PartialEq)]
pub struct Folds {
    /// Contiguous row ranges cut at every block edge and every gap edge: each fold trains on a
    /// union of whole segments, so one accumulator per segment serves every fold.
    pub segments: Vec<Range<usize>>,
    /// The held-out blocks, in order.
    pub folds: Vec<Fold>,
    /// The gap applied (s), after the cap.
    pub gap_s: f64,
    /// Whether every block is a set of whole runs.
    pub whole_runs: bool,
}

impl Folds {
    /// `blocks` contiguous blocks of `rows` (at least 2, 3 with rolling origin; at most one per
    /// row); with [`InnerCv::Rolling`] only blocks from the third on are held out, each predicted
    /// from the rows before it.
    pub fn new(rows: &[Row], blocks: usize, inner: InnerCv, gap_s: f64) -> Self {
        let n = rows.len();
        // Never fewer blocks than leave a fold to score (`--folds 2` with rolling origin).
        let k = blocks.max(inner.min_blocks()).clamp(1, n.max(1));
        let (ranges, whole_runs) = block_ranges(rows, k, inner.min_blocks());
        let mut cuts = vec![0, n];
        let mut zones = Vec::new();
        for (f, held) in ranges.iter().enumerate() {
            if !inner.holds_out(f) || held.is_empty() {
                continue;
            }
            let zone = exclusion(rows, held.clone(), gap_s);
            cuts.extend([held.start, held.end, zone.start, zone.end]);
            zones.push((held.clone(), zone));
        }
        cuts.sort_unstable();
        cuts.dedup();
        let segments: Vec<Range<usize>> = cuts.windows(2).map(|w| w[0]..w[1]).collect();
        let folds = zones
            .into_iter()
            .map(|(held, zone)| Fold {
                train: (0..segments.len())
                    .filter(|&s| {
                        let seg = &segments[s];
                        seg.end <= zone.start
                            || (inner == InnerCv::Blocked && seg.start >= zone.end)
                    })
                    .collect(),
                held,
            })
            .collect();
        Self {
            segments,
            folds,
            gap_s,
            whole_runs,
        }
    }

    /// The training rows of fold `f` as ranges (adjacent segments joined).
    pub fn training_rows(&self, f: usize) -> Vec<Range<usize>> {
        let mut out: Vec<Range<usize>> = Vec::new();
        for &s in &self.folds[f].train {
            let seg = self.segments[s].clone();
            match out.last_mut() {
                Some(last) if last.end == seg.start => last.end = seg.end,
                _ => out.push(seg),
            }
        }
        out
    }

    /// The forward-chaining (rolling-origin) view of these folds: the same held-out blocks, each
    /// trained only on the segments that end before its exclusion zone — the past beyond the
    /// gap. The model is then used as it will be, on rows later than all it learnt from; the
    /// blocked folds let a block be predicted by the rows after it, which hides how a model
    /// extrapolates (docs/fitting.md, "How the selection chooses"). A fold is kept when its
    /// past holds at least [`ROLLING_FIRST_HELD_OUT`] blocks' worth of rows (the mean block):
    /// a fit on less than that is no model of anything the user would deploy, and its error
    /// would say more about the lack of data than about extrapolation. The gap, up to a block,
    /// comes out of that past, so with a long gap the first scored block is the fourth.
    pub fn forward(&self) -> Self {
        let past = |fold: &Fold| -> Vec<usize> {
            fold.train
                .iter()
                .copied()
                .filter(|&s| self.segments[s].end <= fold.held.start)
                .collect()
        };
        let mean_block = self.held_rows() as f64 / self.folds.len().max(1) as f64;
        let enough = ROLLING_FIRST_HELD_OUT as f64 * mean_block;
        let folds = self
            .folds
            .iter()
            .map(|fold| Fold {
                held: fold.held.clone(),
                train: past(fold),
            })
            .filter(|fold| {
                let rows: usize = fold.train.iter().map(|&s| self.segments[s].len()).sum();
                // Block edges round to whole rows: a row per block of slack.
                (rows + ROLLING_FIRST_HELD_OUT) as f64 >= enough
            })
            .collect();
        Self {
            segments: self.segments.clone(),
            folds,
            gap_s: self.gap_s,
            whole_runs: self.whole_runs,
        }
    }

    /// Rows held out over all folds.
    pub fn held_rows(&self) -> usize {
        self.folds.iter().map(|f| f.held.len()).sum()
    }
}

/// `k` contiguous blocks of about equal size. With `min_runs` runs or more (the blocks a fold
/// needs: two, or three for rolling origin) the blocks hold whole runs (as many blocks as runs
/// at most): a run is one thermal excursion, and a block that cut one would be predicted from
/// the rest of the same excursion — the inner validation then mirrors leave-one-run-out. With two runs each fold trains on the other run alone: a thinner fit, but
/// the only one that shows whether a family carries from one run to another.
fn block_ranges(rows: &[Row], k: usize, min_runs: usize) -> (Vec<Range<usize>>, bool) {
    let n = rows.len();
    let starts: Vec<usize> = (0..n)
        .filter(|&i| i == 0 || rows[i].run != rows[i - 1].run)
        .collect();
    if starts.len() < min_runs {
        return ((0..k).map(|b| b * n / k..(b + 1) * n / k).collect(), false);
    }
    let k = k.min(starts.len());
    let mut ranges: Vec<Range<usize>> = Vec::new();
    for (r, &start) in starts.iter().enumerate() {
        let end = starts.get(r + 1).copied().unwrap_or(n);
        // The block of a run: where its middle row falls among k equal shares of the rows.
        let b = ((start + end) / 2 * k / n).min(k - 1);
        if ranges.len() > b {
            if let Some(last) = ranges.last_mut() {
                last.end = end;
            }
        } else {
            ranges.push(start..end);
        }
    }
    (ranges, true)
}

/// The rows a held-out block excludes from its training: the block, and on each side the rows
/// of the same run closer than `gap_s` to it, at most one block length per side.
fn exclusion(rows: &[Row], held: Range<usize>, gap_s: f64) -> Range<usize> {
    let len = held.len();
    let (first, last) = (rows[held.start], rows[held.end - 1]);
    let mut lo = held.start;
    while lo > 0
        && held.start - lo < len
        && rows[lo - 1].run == first.run
        && first.time_s - rows[lo - 1].time_s < gap_s
    {
        lo -= 1;
    }
    let mut hi = held.end;
    while hi < rows.len()
        && hi - held.end < len
        && rows[hi].run == last.run
        && rows[hi].time_s - last.time_s < gap_s
    {
        hi += 1;
    }
    lo..hi
}

/// The time after which a residual series has forgotten itself: the smallest lag at which its
/// autocorrelation falls below 1/e, in seconds (each run on its own; the longest over `series`).
/// `series[k][i]` belongs to `rows[i]`.
pub fn decorrelation_time(rows: &[Row], series: &[Vec<f64>]) -> f64 {
    let mut runs: Vec<Range<usize>> = Vec::new();
    for (i, r) in rows.iter().enumerate() {
        match runs.last_mut() {
            Some(last) if rows[last.start].run == r.run => last.end = i + 1,
            _ => runs.push(i..i + 1),
        }
    }
    let mut longest: f64 = 0.0;
    for s in series {
        for run in &runs {
            let x = &s[run.clone()];
            let m = x.iter().sum::<f64>() / x.len().max(1) as f64;
            let c0: f64 = x.iter().map(|v| (v - m).powi(2)).sum();
            if c0 <= 0.0 || x.len() < 3 {
                continue;
            }
            // Lags in doubling steps, then bisection: the sums are O(n) each, O(n log n) in all.
            let acf = |lag: usize| {
                x.iter()
                    .zip(&x[lag..])
                    .map(|(a, b)| (a - m) * (b - m))
                    .sum::<f64>()
                    / c0
            };
            let limit = (-1.0f64).exp();
            let mut hi = 1;
            while hi < x.len() && acf(hi) >= limit {
                hi *= 2;
            }
            let hi = hi.min(x.len() - 1);
            let mut lo = hi / 2;
            let mut hi = hi;
            while hi - lo > 1 {
                let mid = (lo + hi) / 2;
                if acf(mid) >= limit {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            let t = rows[run.start + hi].time_s - rows[run.start].time_s;
            longest = longest.max(t);
        }
    }
    longest
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn rows(runs: &[usize], dt: f64) -> Vec<Row> {
        runs.iter()
            .enumerate()
            .flat_map(|(r, &n)| {
                (0..n).map(move |i| Row {
                    run: r,
                    time_s: dt * i as f64,
                })
            })
            .collect()
    }

    #[test]
    fn no_gap_is_the_plain_blocked_validation() {
        let r = rows(&[12], 1.0);
        let f = Folds::new(&r, 3, InnerCv::Blocked, 0.0);
        assert_eq!(f.training_rows(0), vec![4..12]);
        assert_eq!(f.training_rows(1), vec![0..4, 8..12]);
        assert_eq!(f.training_rows(2), vec![0..8]);
    }

    #[test]
    fn two_runs_or_more_are_held_out_whole() {
        let r = rows(&[5, 30, 4, 6, 5], 1.0);
        let f = Folds::new(&r, 3, InnerCv::Blocked, 1e9);
        let held: Vec<Range<usize>> = f.folds.iter().map(|f| f.held.clone()).collect();
        assert_eq!(held, vec![0..5, 5..35, 35..50]);
        // Whole runs: the gap never reaches into another run, so nothing else is excluded.
        assert_eq!(f.training_rows(1), vec![0..5, 35..50]);
        let f = Folds::new(&r, 8, InnerCv::Blocked, 0.0);
        assert_eq!(f.folds.len(), 5);
        // Two runs: each is predicted from the other alone, never from the rest of itself.
        let f = Folds::new(&rows(&[6, 6], 10.0), 3, InnerCv::Blocked, 1e9);
        let held: Vec<Range<usize>> = f.folds.iter().map(|f| f.held.clone()).collect();
        assert_eq!(held, vec![0..6, 6..12]);
        assert_eq!(f.training_rows(0), vec![6..12]);
        assert_eq!(f.training_rows(1), vec![0..6]);
        // Rolling origin scores from the third block on: two runs are cut in time instead,
        // or nothing would be scored.
        let f = Folds::new(&rows(&[6, 6], 10.0), 4, InnerCv::Rolling, 0.0);
        assert!(!f.whole_runs);
        assert_eq!(f.folds.len(), 2);
        // Two blocks asked for with rolling origin: three, so that one is scored.
        let f = Folds::new(&rows(&[12], 1.0), 2, InnerCv::Rolling, 0.0);
        assert_eq!(f.folds.len(), 1);
    }

    #[test]
    fn the_gap_stops_at_one_block() {
        // One run of 12 rows, 10 s apart; blocks of 4.
        let r = rows(&[12], 10.0);
        let f = Folds::new(&r, 3, InnerCv::Blocked, 1e9);
        // Block 1 (rows 4..8): an endless gap takes one block on each side, and no more.
        assert_eq!(f.training_rows(1), Vec::<Range<usize>>::new());
        assert_eq!(f.training_rows(0), vec![8..12]);
        let f = Folds::new(&r, 3, InnerCv::Blocked, 15.0);
        assert_eq!(f.training_rows(1), vec![0..3, 9..12]);
    }

    #[test]
    fn rolling_trains_on_the_past_beyond_the_gap() {
        let r = rows(&[16], 1.0);
        let f = Folds::new(&r, 4, InnerCv::Rolling, 2.5);
        assert_eq!(f.folds.len(), 2);
        assert_eq!(f.folds[0].held, 8..12);
        assert_eq!(f.training_rows(0), vec![0..6]);
        assert_eq!(f.training_rows(1), vec![0..10]);
    }

    #[test]
    fn forward_folds_train_on_at_least_two_blocks_of_the_past() {
        // 8 blocks of 10 rows. A gap of 15 s (capped at one block) takes a block out of each
        // past: blocks 3… are scored, block 3 from rows 0..20.
        let r = rows(&[80], 1.0);
        let f = Folds::new(&r, 8, InnerCv::Blocked, 15.0).forward();
        let held: Vec<Range<usize>> = f.folds.iter().map(|f| f.held.clone()).collect();
        assert_eq!(held, vec![30..40, 40..50, 50..60, 60..70, 70..80]);
        assert_eq!(f.training_rows(0), vec![0..20]);
        assert_eq!(f.training_rows(4), vec![0..60]);
        // Without a gap, from block 2 on; a rolling validation is forward already.
        let f = Folds::new(&r, 8, InnerCv::Blocked, 0.0).forward();
        assert_eq!(f.folds[0].held, 20..30);
        assert_eq!(f.training_rows(0), vec![0..20]);
        let rolling = Folds::new(&r, 8, InnerCv::Rolling, 0.0);
        assert_eq!(rolling.forward().folds, rolling.folds);
    }

    #[test]
    fn decorrelation_of_a_first_order_process() {
        // AR(1) with φ = e^(−1/50): the autocorrelation falls below 1/e at lag 50.
        let phi = (-1.0f64 / 50.0).exp();
        let mut x = vec![0.0; 20_000];
        let mut state = 12345u64;
        for i in 1..x.len() {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            let u = ((state >> 11) as f64 / (1u64 << 53) as f64) - 0.5;
            x[i] = phi * x[i - 1] + u;
        }
        let r = rows(&[x.len()], 2.0);
        let t = decorrelation_time(&r, &[x]);
        assert!((80.0..=120.0).contains(&t), "{t}");
    }

    proptest! {
        /// No training row of a fold lies in its block or within the gap of it in the same run,
        /// and a blocked fold trains on every row outside its exclusion zone.
        #[test]
        fn folds_never_train_on_or_near_the_held_block(
            lens in proptest::collection::vec(1usize..40, 1..4),
            blocks in 2usize..10,
            gap in 0.0f64..30.0,
            rolling in any::<bool>(),
        ) {
            let r = rows(&lens, 1.0);
            let inner = if rolling { InnerCv::Rolling } else { InnerCv::Blocked };
            let f = Folds::new(&r, blocks, inner, gap);
            for (k, fold) in f.folds.iter().enumerate() {
                let len = fold.held.len();
                for range in f.training_rows(k) {
                    for i in range {
                        prop_assert!(!fold.held.contains(&i));
                        if rolling { prop_assert!(i < fold.held.start); }
                        for h in fold.held.clone() {
                            let near = r[i].run == r[h].run && (r[i].time_s - r[h].time_s).abs() < gap;
                            let within_cap = i + len >= fold.held.start && i < fold.held.end + len;
                            prop_assert!(!(near && within_cap), "row {i} near held {h}");
                        }
                    }
                }
            }
        }
    }
}
