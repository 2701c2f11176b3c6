//! The one-slot hand-over from the cycle to the sink's network thread: the latest cycle's
//! values, latest wins. A sequence lock over atomics, so the cycle (the only writer) neither
//! allocates, locks nor waits, and the reader never sees a mix of two cycles.

use std::sync::atomic::{fence, AtomicU64, Ordering};

/// The latest values of a fixed number of f64 cells.
#[derive(Debug)]
pub struct Latest {
    seq: AtomicU64,
    cells: Vec<AtomicU64>,
}

impl Latest {
    /// `n` cells, never published.
    pub fn new(n: usize) -> Self {
        Self {
            seq: AtomicU64::new(0),
            cells: (0..n).map(|_| AtomicU64::new(f64::NAN.to_bits())).collect(),
        }
    }

    /// Publishes the values (one writer only). Extra values are ignored.
    pub fn publish(&self, values: impl Iterator<Item = f64>) {
        let s = self.seq.load(Ordering::Relaxed);
        self.seq.store(s.wrapping_add(1), Ordering::Relaxed);
        fence(Ordering::Release);
        for (c, v) in self.cells.iter().zip(values) {
            c.store(v.to_bits(), Ordering::Relaxed);
        }
        self.seq.store(s.wrapping_add(2), Ordering::Release);
    }

    /// Copies a consistent set of values into `out` and returns its sequence number (0: never
    /// published), or `None` if the writer kept overwriting it (the reader tries again later).
    pub fn read(&self, out: &mut [f64]) -> Option<u64> {
        for _ in 0..64 {
            let s1 = self.seq.load(Ordering::Acquire);
            if s1 % 2 == 1 {
                std::hint::spin_loop();
                continue;
            }
            for (o, c) in out.iter_mut().zip(&self.cells) {
                *o = f64::from_bits(c.load(Ordering::Relaxed));
            }
            fence(Ordering::Acquire);
            if self.seq.load(Ordering::Relaxed) == s1 {
                return Some(s1 / 2);
            }
        }
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::Arc;

    #[test]
    fn a_reader_never_sees_two_cycles_mixed() {
        let l = Arc::new(Latest::new(8));
        let w = Arc::clone(&l);
        let writer = std::thread::spawn(move || {
            for k in 0..200_000u32 {
                w.publish((0..8).map(|_| f64::from(k)));
            }
        });
        let mut out = [0.0; 8];
        let mut seen = 0;
        while !writer.is_finished() {
            if let Some(seq) = l.read(&mut out) {
                if seq > 0 {
                    assert!(out.iter().all(|&v| v == out[0]), "mixed: {out:?}");
                    seen += 1;
                }
            }
        }
        writer.join().unwrap();
        assert_eq!(l.read(&mut out), Some(200_000));
        assert!(out.iter().all(|&v| v == 199_999.0));
        assert!(seen > 0);
    }
}
