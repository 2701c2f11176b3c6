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
//! from chasing noise. The filter is the real-time crate's own [`FeatureBank`], so the τ found
//! is the τ the control runs.

use truepos_model::{FeatureBank, FeatureSpec};

use crate::dataset::{Dataset, InputKind};
use crate::least_squares::{Accumulator, SolveOptions};

/// The range searched (s): 5 min to 8 h, the span of machine-tool thermal time constants.
pub const TAU_RANGE_S: (f64, f64) = (300.0, 8.0 * 3600.0);

/// Ridge of the reduced problem: a whisper, only so that collinear sensors stay solvable.
const RIDGE: f64 = 1e-6;

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
    let cost = |log_tau: f64| reduced_residual(dataset, rows, &temps, log_tau.exp(), absolute);
    let (lo, hi) = (TAU_RANGE_S.0.ln(), TAU_RANGE_S.1.ln());
    // Coarse scan: the residual of a sum of lags can have more than one dip.
    let steps = 12;
    let grid: Vec<(f64, f64)> = (0..=steps)
        .map(|s| {
            let u = lo + (hi - lo) * s as f64 / steps as f64;
            (u, cost(u))
        })
        .collect();
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

/// Σ_k RSS_k / TSS_k of the least-squares fit of [1, ΔT_i, LPF_τ(ΔT_i)] to every target.
fn reduced_residual(
    dataset: &Dataset,
    rows: &[(usize, usize)],
    temps: &[usize],
    tau: f64,
    absolute: bool,
) -> f64 {
    let spec = FeatureSpec {
        temperatures: temps.len(),
        operating: 0,
        temperature_rise: true,
        temperature_taus_s: vec![tau],
        rate_taus_s: Vec::new(),
        operating_taus_s: Vec::new(),
        operating_square: false,
        rise_while_running: false,
    };
    let Ok(mut bank) = FeatureBank::new(spec) else {
        return f64::INFINITY;
    };
    let nt = dataset.target_names.len();
    let nf = bank.features().len();
    let mut acc = Accumulator::new(nf + 1, nt);
    let (mut a, mut b, mut inputs) = (vec![1.0; nf + 1], vec![0.0; nt], vec![0.0; temps.len()]);
    let (mut sum, mut sum2) = (vec![0.0; nt], vec![0.0; nt]);
    let mut i = 0;
    while i < rows.len() {
        let run_index = rows[i].0;
        let run = &dataset.runs[run_index];
        let targets: Vec<Vec<f64>> = (0..nt).map(|k| run.target(k, absolute)).collect();
        let end = rows[i..]
            .iter()
            .position(|r| r.0 != run_index)
            .map_or(rows.len(), |p| i + p);
        let last = rows[end - 1].1;
        bank.reset();
        let mut next = i;
        for row in 0..=last {
            for (slot, &d) in inputs.iter_mut().zip(temps) {
                *slot = run.inputs[d][row];
            }
            let dt = if row == 0 {
                0.0
            } else {
                run.time_s[row] - run.time_s[row - 1]
            };
            let Ok(values) = bank.step(dt, &inputs) else {
                return f64::INFINITY;
            };
            if next < end && rows[next].1 == row {
                a[1..].copy_from_slice(values);
                for (k, target) in targets.iter().enumerate() {
                    b[k] = target[row];
                    sum[k] += b[k];
                    sum2[k] += b[k] * b[k];
                }
                let _ = acc.push_row(&a, &b, 1.0);
                next += 1;
            }
        }
        i = end;
    }
    let n = rows.len() as f64;
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
