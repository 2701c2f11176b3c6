//! [`Episodes`] groups the cycles of the timing benchmark that finished late into stalls,
//! without allocating.

/// A stall: late cycles whose windows (deadline to finish) overlap.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Episode {
    /// Earliest deadline of its cycles, ns.
    pub start_ns: u64,
    /// Latest finish of its cycles, ns.
    pub end_ns: u64,
    /// Cycles in it.
    pub cycles: u64,
    /// The largest lateness of its cycles, ns.
    pub worst_ns: u64,
}

/// The late cycles of a run, merged into [`Episode`]s in preallocated room.
#[derive(Debug, Clone)]
pub struct Episodes {
    list: Vec<Episode>,
    /// Late cycles that found no room (counted, not kept).
    pub overflow_cycles: u64,
}

impl Episodes {
    /// Room for `capacity` episodes.
    pub fn with_capacity(capacity: usize) -> Self {
        Self {
            list: Vec::with_capacity(capacity),
            overflow_cycles: 0,
        }
    }

    /// Adds a late cycle (deadline, finish); cycles arrive in deadline order. Never allocates.
    pub fn push(&mut self, deadline_ns: u64, finish_ns: u64) {
        let late = finish_ns.saturating_sub(deadline_ns);
        if let Some(last) = self.list.last_mut() {
            if deadline_ns <= last.end_ns {
                last.end_ns = last.end_ns.max(finish_ns);
                last.cycles += 1;
                last.worst_ns = last.worst_ns.max(late);
                return;
            }
        }
        if self.list.len() < self.list.capacity() {
            self.list.push(Episode {
                start_ns: deadline_ns,
                end_ns: finish_ns,
                cycles: 1,
                worst_ns: late,
            });
        } else {
            self.overflow_cycles += 1;
        }
    }

    /// The episodes in time order.
    pub fn list(&self) -> &[Episode] {
        &self.list
    }

    /// Late cycles in all episodes (and in the overflow).
    pub fn cycles(&self) -> u64 {
        self.list.iter().map(|e| e.cycles).sum::<u64>() + self.overflow_cycles
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_stall_is_one_episode() {
        let ms = 1_000_000;
        let mut e = Episodes::with_capacity(2);
        // A 10 ms stall: the cycles of deadlines 0…7 ms all finish at 10 ms.
        for k in 0..8 {
            e.push(k * ms, 10 * ms);
        }
        e.push(50 * ms, 53 * ms);
        e.push(90 * ms, 93 * ms); // no room left
        assert_eq!(e.list().len(), 2);
        assert_eq!(
            e.list()[0],
            Episode {
                start_ns: 0,
                end_ns: 10 * ms,
                cycles: 8,
                worst_ns: 10 * ms
            }
        );
        assert_eq!(e.overflow_cycles, 1);
        assert_eq!(e.cycles(), 10);
    }
}
