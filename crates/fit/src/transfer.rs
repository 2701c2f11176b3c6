//! First-order transfer functions from the temperatures to the error, with their time constant
//! identified from the data ([`Family::Transfer`](crate::features::Family::Transfer)):
//!
//! y(t) = c + Σ_i [a_i·ΔT_i(t) + b_i·LPF_τ(ΔT_i)(t)]
//!
//! — each sensor's rise acts on the error directly (a_i) and through a first-order lag of time
//! constant τ (b_i): the steady-state gain per kelvin is a_i + b_i, the part b_i arrives with the
//! structure's delay. τ is not taken from a fixed grid but identified by variable projection
//! (Golub & Pereyra, *SIAM J. Numer. Anal.* 10, 1973): for a given τ the coefficients are linear
//! and are eliminated by least squares, leaving the residual as a function of τ alone, which is
//! minimised over log τ (a coarse scan, then golden-section search around the best point). One τ
//! serves every target and sensor: one more parameter, not one per sensor, keeps the family
//! from chasing noise. The filter steps with the real-time bank's own gain ([`lag_gain`]) and
//! arithmetic, so the τ found is the τ the control runs.

use truepos_model::lag_gain;

use crate::dataset::{Dataset, InputKind};
use crate::least_squares::{Accumulator, SolveOptions};

/// The range searched (s): 5 min to 8 h, the span of machine-tool thermal time constants.
pub const TAU_RANGE_S: (f64, f64) = (300.0, 8.0 * 3600.0);

/// Ridge of the reduced problem: a whisper, only so that collinear sensors stay solvable.
const RIDGE: f64 = 1e-6;

/// Training rows the reduced residual is summed over at most: one τ is a smooth function of
/// thousands of rows, and a month of logs at 1 s must not cost 25 passes of a full QR. Every row
/// still steps the filter; beyond this count every k-th training row enters the sum.
const MAX_ROWS: usize = 20_000;

/// The τ (s) that minimises the training residual of the first-order transfer family, summed
/// over the targets (each relative to its own spread), on `rows` (training rows, in time order).
/// `None` when there is no temperature input or no row.
pub fn identify_tau(dataset: &Dataset, rows: &[(usize, usize)], absolute: bool) -> Option<f64> {
    let temps: Vec<usize> = (0..dataset.input_names.len())
        .filter(|&i| dataset.input_kinds[i] == InputKind::Temperature)
        .collect();
    if temps.is_empty() || rows.is_empty() {
        return None;
    }
    let stretches = stretches(dataset, rows, absolute);
    let cost = |log_tau: f64| reduced_residual(&stretches, &temps, log_tau.exp());
    let (lo, hi) = (TAU_RANGE_S.0.ln(), TAU_RANGE_S.1.ln());
    // Coarse scan: the residual of a sum of lags can have more than one dip.
    let steps = 12;
    let at = |s: usize| lo + (hi - lo) * s as f64 / steps as f64;
    // The scan's points are independent: half of them on a second core.
    let grid: Vec<(f64, f64)> = std::thread::scope(|scope| {
        let cost = &cost;
        let odd = scope.spawn(move || {
            (1..=steps)
                .step_by(2)
                .map(|s| (at(s), cost(at(s))))
                .collect::<Vec<_>>()
        });
        let even: Vec<(f64, f64)> = (0..=steps)
            .step_by(2)
            .map(|s| (at(s), cost(at(s))))
            .collect();
        let odd = match odd.join() {
            Ok(v) => v,
            Err(panic) => std::panic::resume_unwind(panic),
        };
        let mut all: Vec<(f64, f64)> = even.into_iter().chain(odd).collect();
        all.sort_by(|x, y| x.0.total_cmp(&y.0));
        all
    });
    let best = (0..grid.len()).min_by(|&a, &b| grid[a].1.total_cmp(&grid[b].1))?;
    if !grid[best].1.is_finite() {
        return None;
    }
    let (mut a, mut b) = (
        grid[best.saturating_sub(1)].0,
        grid[(best + 1).min(steps)].0,
    );
    let phi = (5f64.sqrt() - 1.0) / 2.0;
    let (mut c, mut d) = (b - phi * (b - a), a + phi * (b - a));
    let (mut fc, mut fd) = (cost(c), cost(d));
    for _ in 0..20 {
        if fc < fd {
            b = d;
            d = c;
            fd = fc;
            c = b - phi * (b - a);
            fc = cost(c);
        } else {
            a = c;
            c = d;
            fc = fd;
            d = a + phi * (b - a);
            fd = cost(d);
        }
    }
    let u = if fc < fd { c } else { d };
    let found = if cost(u) <= grid[best].1 {
        u
    } else {
        grid[best].0
    };
    // Rounded to 1 s: the τ is written into the model file and named in reports.
    Some(found.exp().round())
}

/// The training rows of one run: the run, its last training row, and the rows that enter the
/// sum with their targets (every `stride`-th training row, see [`MAX_ROWS`]).
struct Stretch<'d> {
    run: &'d crate::dataset::Run,
    last: usize,
    used: Vec<(usize, Vec<f64>)>,
}

/// The training rows by run, with the targets of the rows the sum uses (read once, not per τ).
fn stretches<'d>(
    dataset: &'d Dataset,
    rows: &[(usize, usize)],
    absolute: bool,
) -> Vec<Stretch<'d>> {
    let nt = dataset.target_names.len();
    let stride = rows.len().div_ceil(MAX_ROWS).max(1);
    let mut out: Vec<Stretch<'d>> = Vec::new();
    let mut i = 0;
    while i < rows.len() {
        let run_index = rows[i].0;
        let run = &dataset.runs[run_index];
        let end = rows[i..]
            .iter()
            .position(|r| r.0 != run_index)
            .map_or(rows.len(), |p| i + p);
        let targets: Vec<Vec<f64>> = (0..nt).map(|k| run.target(k, absolute)).collect();
        let used = (i..end)
            .filter(|n| n % stride == 0)
            .map(|n| {
                let row = rows[n].1;
                (row, targets.iter().map(|t| t[row]).collect())
            })
            .collect();
        out.push(Stretch {
            run,
            last: rows[end - 1].1,
            used,
        });
        i = end;
    }
    out
}

/// Σ_k RSS_k / TSS_k of the least-squares fit of [1, ΔT_i, LPF_τ(ΔT_i)] to every target. The
/// filter is the bank's own first-order lag ([`lag_gain`], state from the run's first sample),
/// stepped over every row of the run and read at the rows of the sum.
fn reduced_residual(stretches: &[Stretch<'_>], temps: &[usize], tau: f64) -> f64 {
    let nt = stretches
        .first()
        .and_then(|s| s.used.first())
        .map_or(0, |u| u.1.len());
    let nf = 2 * temps.len();
    let mut acc = Accumulator::new(nf + 1, nt);
    let mut a = vec![1.0; nf + 1];
    let (mut sum, mut sum2) = (vec![0.0; nt], vec![0.0; nt]);
    let mut used = 0usize;
    let mut state = vec![0.0; temps.len()];
    for s in stretches {
        let (run, mut next) = (s.run, 0);
        let initial: Vec<f64> = temps.iter().map(|&d| run.inputs[d][0]).collect();
        state.fill(0.0);
        let (mut gain, mut gain_dt) = (0.0, 0.0);
        for row in 0..=s.last {
            if row > 0 {
                let dt = run.time_s[row] - run.time_s[row - 1];
                if !(dt.is_finite() && dt > 0.0) {
                    return f64::INFINITY;
                }
                if dt != gain_dt {
                    (gain, gain_dt) = (lag_gain(dt, tau), dt);
                }
                for (i, &d) in temps.iter().enumerate() {
                    state[i] += gain * (run.inputs[d][row] - initial[i] - state[i]);
                }
            }
            let Some((_, b)) = s.used.get(next).filter(|u| u.0 == row) else {
                continue;
            };
            next += 1;
            used += 1;
            for (i, &d) in temps.iter().enumerate() {
                a[1 + 2 * i] = run.inputs[d][row] - initial[i];
                a[2 + 2 * i] = state[i];
            }
            for k in 0..nt {
                sum[k] += b[k];
                sum2[k] += b[k] * b[k];
            }
            if acc.push_row(&a, b, 1.0).is_err() {
                return f64::INFINITY;
            }
        }
    }
    let n = used as f64;
    let Ok(sol) = acc.finish().solve(&SolveOptions {
        ridge: RIDGE,
        unpenalized: vec![0],
        rcond: None,
    }) else {
        return f64::INFINITY;
    };
    (0..nt)
        .map(|k| sol.rss[k] / (sum2[k] - sum[k] * sum[k] / n).max(1e-300))
        .sum()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dataset::Run;

    /// A structure lagging its sensor by τ = 2400 s: the identified τ is within a few percent,
    /// from training rows that skip every other sample and leave out the run's end.
    #[test]
    fn the_time_constant_of_a_first_order_lag_is_found() {
        let (mut t, mut temp, mut y) = (vec![], vec![], vec![]);
        let (mut lag, dt) = (0.0, 30.0);
        for i in 0..3000 {
            let heat = if (i / 400) % 2 == 0 { 0.0 } else { 4.0 };
            let temp_now = 20.0 + heat + 0.5 * (i as f64 / 50.0).sin();
            lag += (1.0 - (-dt / 2400.0f64).exp()) * (temp_now - 20.0 - lag);
            t.push(dt * i as f64);
            temp.push(temp_now);
            y.push(1.5 * lag - 0.3 * (temp_now - 20.0));
        }
        let ds = Dataset {
            input_names: vec!["t1_c".into()],
            input_kinds: vec![InputKind::Temperature],
            target_names: vec!["dz_um".into()],
            runs: vec![Run {
                name: "r".into(),
                time_s: t,
                inputs: vec![temp],
                targets: vec![y],
            }],
        };
        let rows: Vec<(usize, usize)> = (0..2400).step_by(2).map(|i| (0, i)).collect();
        let tau = identify_tau(&ds, &rows, false).unwrap();
        assert!((tau - 2400.0).abs() < 0.05 * 2400.0, "{tau}");
    }
}
