//! Several runs in one report (`truepos report --all-runs`): the runs of a file one after the
//! other on one time axis — on the shop's clock when every run has one and they follow each
//! other in time (the gaps between days then show as gaps), else laid end to end — with where
//! each starts, for the drift plots' run boundaries.

use truepos_io::cycles::Cycles;
use truepos_model::RecordedRun;

/// The runs on one time axis.
pub(super) struct Combined {
    /// Every run's cycles, in order, timed on the common axis.
    pub cycles: Cycles,
    /// Where each run starts (index of its first row) and its name.
    pub starts: Vec<(usize, String)>,
    /// The clock time of the axis' zero, when the axis is the clock.
    pub clock_start_s: Option<f64>,
}

/// The median step of a run's time, 1 s for a run of one row.
fn median_step(time_s: &[f64]) -> f64 {
    let mut steps: Vec<f64> = time_s.windows(2).map(|w| w[1] - w[0]).collect();
    steps.sort_by(f64::total_cmp);
    steps.get(steps.len() / 2).copied().unwrap_or(1.0)
}

/// What to add to each run's own times: the clock offsets from the first run when every run
/// has a clock and each starts after the one before ends, else end to end, each run one median
/// step after the one before (as `truepos fit --report` lays them).
fn offsets(runs: &[(String, Option<f64>, Cycles)]) -> (Vec<f64>, Option<f64>) {
    let first = |c: &Cycles| c.run.time_s.first().copied().unwrap_or(0.0);
    let last = |c: &Cycles| c.run.time_s.last().copied().unwrap_or(0.0);
    let clocks: Option<Vec<f64>> = runs.iter().map(|r| r.1).collect();
    if let Some(clocks) = clocks {
        let zero = clocks[0];
        let shift: Vec<f64> = clocks.iter().map(|c| c - zero).collect();
        let in_order = runs
            .windows(2)
            .zip(shift.windows(2))
            .all(|(r, s)| s[1] + first(&r[1].2) > s[0] + last(&r[0].2));
        if in_order {
            return (shift, Some(zero));
        }
    }
    let mut out = Vec::new();
    let mut end: Option<f64> = None;
    for (_, _, c) in runs {
        let offset = end.map_or(0.0, |e| e - first(c));
        out.push(offset);
        end = Some(offset + last(c) + median_step(&c.run.time_s));
    }
    (out, None)
}

/// The runs (name, clock of its first row, cycles) on one time axis.
pub(super) fn combine(runs: Vec<(String, Option<f64>, Cycles)>) -> Combined {
    let (shift, clock_start_s) = offsets(&runs);
    let mut cycles = Cycles {
        run: RecordedRun::default(),
        line: Vec::new(),
    };
    let mut starts = Vec::new();
    for ((name, _, c), s) in runs.into_iter().zip(shift) {
        starts.push((cycles.run.time_s.len(), name));
        let mut run = c.run;
        run.time_s.iter_mut().for_each(|t| *t += s);
        cycles.run.extend(run);
        cycles.line.extend(c.line);
    }
    Combined {
        cycles,
        starts,
        clock_start_s,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cycles(time_s: &[f64]) -> Cycles {
        Cycles {
            run: RecordedRun {
                time_s: time_s.to_vec(),
                temperatures_c: vec![Vec::new(); time_s.len()],
                positions: vec![Vec::new(); time_s.len()],
                operating: vec![Vec::new(); time_s.len()],
            },
            line: vec![0; time_s.len()],
        }
    }

    /// Two days on the clock keep the night between them; without clocks, or with a day that
    /// starts before the one before it ends, they are laid end to end one step apart.
    #[test]
    fn runs_on_the_clock_or_end_to_end() {
        let day = [0.0, 60.0, 120.0];
        let monday = 1_709_539_200.0;
        let two = |a: Option<f64>, b: Option<f64>| {
            vec![
                ("mon".to_string(), a, cycles(&day)),
                ("tue".to_string(), b, cycles(&day)),
            ]
        };
        let c = combine(two(Some(monday), Some(monday + 86_400.0)));
        assert_eq!(c.clock_start_s, Some(monday));
        assert_eq!(c.cycles.run.time_s[3], 86_400.0);
        assert_eq!(c.starts, [(0, "mon".to_string()), (3, "tue".to_string())]);
        let c = combine(two(Some(monday), None));
        assert_eq!(c.clock_start_s, None);
        assert_eq!(c.cycles.run.time_s, [0.0, 60.0, 120.0, 180.0, 240.0, 300.0]);
        let c = combine(two(Some(monday), Some(monday + 60.0)));
        assert_eq!(
            c.clock_start_s, None,
            "overlapping runs are not on one clock"
        );
        assert_eq!(c.cycles.run.time_s[3], 180.0);
    }
}
