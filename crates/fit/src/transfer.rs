//! First-order transfer functions from the temperatures to the error, with their time constant
//! identified from the data ([`Family::Transfer`]):
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
//!
//! The second-order family ([`Family::Transfer2`]) adds a second lag: y = c + Σ_i [a_i·ΔT_i +
//! b_i·LPF_τ1(ΔT_i) + d_i·LPF_τ2(ΔT_i)], τ1 < τ2 — a second-order transfer function with two
//! real poles (a structure whose parts respond with two delays), both time constants identified
//! by the same variable projection over pairs ([`identify_tau_pair`]). It is not among the
//! default families: on the twin population it helps, on FL_THERMAL it costs a channel its bar
//! (docs/fitting.md).

use truepos_model::lag_gain;

use crate::dataset::{Dataset, InputKind};
use crate::features::Family;
use crate::least_squares::{Accumulator, SolveOptions};
use crate::settings::{Selection, Settings};

/// The range searched (s): 5 min to 8 h, the span of machine-tool thermal time constants.
pub const TAU_RANGE_S: (f64, f64) = (300.0, 8.0 * 3600.0);

/// Ridge of the reduced problem: a whisper, only so that collinear sensors stay solvable (on the
/// kelvin columns' shared scale, as in the fit: a sensor a thousand times quieter than the others
/// would be shrunk by about half here).
const RIDGE: f64 = 1e-6;

/// Training rows the reduced residual is summed over at most: one τ is a smooth function of
/// thousands of rows, and a month of logs at 1 s must not cost 25 passes of a full QR. Every row
/// still steps the filter; beyond this count every k-th training row enters the sum.
const MAX_ROWS: usize = 20_000;

/// The second-order family's τ2 is at least this many times τ1.
pub const MIN_RATIO: f64 = 1.5;

/// The time constants the transfer families identified on one training part (s).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct TransferTaus {
    /// [`Family::Transfer`]'s τ.
    pub first: Option<f64>,
    /// [`Family::Transfer2`]'s τ1 < τ2.
    pub second: Option<[f64; 2]>,
}

impl TransferTaus {
    /// Identifies the time constants of the transfer families among `settings.families`, on
    /// `rows` (training rows only).
    pub fn identify(dataset: &Dataset, rows: &[(usize, usize)], settings: &Settings) -> Self {
        let wanted = |f: Family| settings.families.contains(&f);
        let absolute = settings.absolute_targets;
        let kept = |tau: &f64| settings.selection == Selection::Blend || interior(*tau);
        Self {
            first: wanted(Family::Transfer)
                .then(|| identify_tau(dataset, rows, absolute))
                .flatten()
                .filter(kept),
            second: wanted(Family::Transfer2)
                .then(|| identify_tau_pair(dataset, rows, absolute))
                .flatten()
                .filter(|(a, b)| kept(a) && kept(b))
                .map(|(a, b)| [a, b]),
        }
    }

    /// The low-pass time constants of `family`'s features (none for a family not identified).
    pub fn of(&self, family: Family) -> Vec<f64> {
        match family {
            Family::Transfer => self.first.into_iter().collect(),
            Family::Transfer2 => self.second.map_or(Vec::new(), |p| p.to_vec()),
            _ => Vec::new(),
        }
    }

    /// Every identified time constant, ascending, each once.
    pub fn all(&self) -> Vec<f64> {
        let mut all: Vec<f64> = self
            .first
            .into_iter()
            .chain(self.of(Family::Transfer2))
            .collect();
        all.sort_by(f64::total_cmp);
        all.dedup();
        all
    }
}

/// `cost` at every point, the points split between this thread and a second one (the points of
/// a scan are independent, and a fit has the machine's two cores).
fn scan<P: Sync>(points: &[P], cost: &(dyn Fn(&P) -> f64 + Sync)) -> Vec<f64> {
    let (left, right) = points.split_at(points.len() / 2);
    std::thread::scope(|scope| {
        let other = scope.spawn(move || right.iter().map(cost).collect::<Vec<_>>());
        let mut out: Vec<f64> = left.iter().map(cost).collect();
        match other.join() {
            Ok(v) => out.extend(v),
            Err(panic) => std::panic::resume_unwind(panic),
        }
        out
    })
}

/// Golden-section search for the minimum of `f` on [a, b] (`steps` reductions); the point and
/// its value.
fn golden(f: &dyn Fn(f64) -> f64, (mut a, mut b): (f64, f64), steps: usize) -> (f64, f64) {
    let phi = (5f64.sqrt() - 1.0) / 2.0;
    let (mut c, mut d) = (b - phi * (b - a), a + phi * (b - a));
    let (mut fc, mut fd) = (f(c), f(d));
    for _ in 0..steps {
        if fc < fd {
            b = d;
            d = c;
            fd = fc;
            c = b - phi * (b - a);
            fc = f(c);
        } else {
            a = c;
            c = d;
            fc = fd;
            d = a + phi * (b - a);
            fd = f(d);
        }
    }
    if fc < fd {
        (c, fc)
    } else {
        (d, fd)
    }
}

/// The temperature inputs of a dataset.
fn temperatures(dataset: &Dataset) -> Vec<usize> {
    (0..dataset.input_names.len())
        .filter(|&i| dataset.input_kinds[i] == InputKind::Temperature)
        .collect()
}

/// The τ (s) that minimises the training residual of the first-order transfer family, summed
/// over the targets (each relative to its own spread), on `rows` (training rows, in time order).
/// `None` when there is no temperature input or no row.
pub fn identify_tau(dataset: &Dataset, rows: &[(usize, usize)], absolute: bool) -> Option<f64> {
    let temps = temperatures(dataset);
    if temps.is_empty() || rows.is_empty() {
        return None;
    }
    let stretches = stretches(dataset, rows, absolute);
    let cost = |log_tau: f64| reduced_residual(&stretches, &temps, &[log_tau.exp()]);
    let (lo, hi) = (TAU_RANGE_S.0.ln(), TAU_RANGE_S.1.ln());
    // Coarse scan: the residual of a sum of lags can have more than one dip.
    let steps = 12;
    let grid: Vec<f64> = (0..=steps)
        .map(|s| lo + (hi - lo) * s as f64 / steps as f64)
        .collect();
    let costs = scan(&grid, &|&x| cost(x));
    let best = (0..grid.len()).min_by(|&a, &b| costs[a].total_cmp(&costs[b]))?;
    if !costs[best].is_finite() {
        return None;
    }
    let around = (grid[best.saturating_sub(1)], grid[(best + 1).min(steps)]);
    let (u, fu) = golden(&cost, around, 20);
    let found = if fu <= costs[best] { u } else { grid[best] };
    // Rounded to 1 s: the τ is written into the model file and named in reports.
    Some(found.exp().round())
}

/// How close (in ln τ) to a bound of [`TAU_RANGE_S`] a time constant counts as on it: 5 %.
const ON_BOUND: f64 = 0.05;

/// Whether τ (s) lies inside the range searched, not on a bound. A τ on its bound was not
/// identified — the data's best lag lies outside the range, or the family does not fit at
/// all — and the paired selection leaves the family out rather than fit it at an arbitrary
/// edge.
pub fn interior(tau_s: f64) -> bool {
    let (lo, hi) = (TAU_RANGE_S.0.ln(), TAU_RANGE_S.1.ln());
    tau_s.ln() > lo + ON_BOUND && tau_s.ln() < hi - ON_BOUND
}

/// The two time constants (s), τ1 < τ2, that minimise the training residual of the second-order
/// transfer family ([1, ΔT_i, LPF_τ1(ΔT_i), LPF_τ2(ΔT_i)], summed over the targets as in
/// [`identify_tau`]): every pair of a coarse grid over log τ, then golden-section search along
/// one time constant and then the other, twice, each within a grid step of where it stands and
/// τ2 kept at least [`MIN_RATIO`] × τ1 (two lags closer than that are one lag twice, and their
/// coefficients would not be identifiable). `None` as for [`identify_tau`].
pub fn identify_tau_pair(
    dataset: &Dataset,
    rows: &[(usize, usize)],
    absolute: bool,
) -> Option<(f64, f64)> {
    let temps = temperatures(dataset);
    if temps.is_empty() || rows.is_empty() {
        return None;
    }
    let stretches = stretches(dataset, rows, absolute);
    let cost = |a: f64, b: f64| reduced_residual(&stretches, &temps, &[a.exp(), b.exp()]);
    let (lo, hi) = (TAU_RANGE_S.0.ln(), TAU_RANGE_S.1.ln());
    let steps = 8;
    let h = (hi - lo) / steps as f64;
    let at = |s: usize| lo + h * s as f64;
    let pairs: Vec<(f64, f64)> = (0..steps)
        .flat_map(|i| (i + 1..=steps).map(move |j| (at(i), at(j))))
        .collect();
    let costs = scan(&pairs, &|&(a, b)| cost(a, b));
    let best = (0..pairs.len()).min_by(|&a, &b| costs[a].total_cmp(&costs[b]))?;
    if !costs[best].is_finite() {
        return None;
    }
    let ((mut x, mut y), mut f_best) = (pairs[best], costs[best]);
    let gap = MIN_RATIO.ln();
    for round in 0..4 {
        let (v, fv) = if round % 2 == 0 {
            let range = ((x - h).max(lo), (x + h).min(hi).min(y - gap));
            if range.1 <= range.0 {
                continue;
            }
            golden(&|v| cost(v, y), range, 12)
        } else {
            let range = ((y - h).max(lo).max(x + gap), (y + h).min(hi));
            if range.1 <= range.0 {
                continue;
            }
            golden(&|v| cost(x, v), range, 12)
        };
        if fv < f_best {
            f_best = fv;
            if round % 2 == 0 {
                x = v;
            } else {
                y = v;
            }
        }
    }
    Some((x.exp().round(), y.exp().round()))
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

/// Σ_k RSS_k / TSS_k of the least-squares fit of [1, ΔT_i, LPF_τ(ΔT_i) for each τ of `taus`]
/// to every target. The filters are the bank's own first-order lag ([`lag_gain`], state from
/// the run's first sample), stepped over every row of the run and read at the rows of the sum.
fn reduced_residual(stretches: &[Stretch<'_>], temps: &[usize], taus: &[f64]) -> f64 {
    let nt = stretches
        .first()
        .and_then(|s| s.used.first())
        .map_or(0, |u| u.1.len());
    let nl = taus.len();
    // Per sensor: its rise, then its low-pass at each τ.
    let width = 1 + nl;
    let mut acc = Accumulator::new(width * temps.len() + 1, nt);
    let mut a = vec![1.0; width * temps.len() + 1];
    let (mut sum, mut sum2) = (vec![0.0; nt], vec![0.0; nt]);
    let mut used = 0usize;
    let mut state = vec![0.0; temps.len() * nl];
    let mut gains = vec![0.0; nl];
    for s in stretches {
        let (run, mut next) = (s.run, 0);
        let initial: Vec<f64> = temps.iter().map(|&d| run.inputs[d][0]).collect();
        state.fill(0.0);
        let mut gain_dt = 0.0;
        for row in 0..=s.last {
            if row > 0 {
                let dt = run.time_s[row] - run.time_s[row - 1];
                if !(dt.is_finite() && dt > 0.0) {
                    return f64::INFINITY;
                }
                if dt != gain_dt {
                    for (g, &tau) in gains.iter_mut().zip(taus) {
                        *g = lag_gain(dt, tau);
                    }
                    gain_dt = dt;
                }
                for (i, &d) in temps.iter().enumerate() {
                    let rise = run.inputs[d][row] - initial[i];
                    for (l, g) in gains.iter().enumerate() {
                        state[i * nl + l] += g * (rise - state[i * nl + l]);
                    }
                }
            }
            let Some((_, b)) = s.used.get(next).filter(|u| u.0 == row) else {
                continue;
            };
            next += 1;
            used += 1;
            for (i, &d) in temps.iter().enumerate() {
                a[1 + width * i] = run.inputs[d][row] - initial[i];
                a[2 + width * i..1 + width * (i + 1)].copy_from_slice(&state[i * nl..(i + 1) * nl]);
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
        // Every column is in kelvin, as in the fit the identified τ serves.
        shared_scale: vec![(1..=width * temps.len()).collect()],
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
        let ds = crate::dataset::one_sensor(t, temp, y);
        let rows: Vec<(usize, usize)> = (0..2400).step_by(2).map(|i| (0, i)).collect();
        let tau = identify_tau(&ds, &rows, false).unwrap();
        assert!((tau - 2400.0).abs() < 0.05 * 2400.0, "{tau}");
    }

    /// A structure lagging its sensor by 100 h, far beyond the 8 h searched: the best τ lies on
    /// the range's bound, which identifies nothing, and the paired selection leaves the family
    /// out.
    #[test]
    fn a_time_constant_on_its_bound_is_not_identified() {
        let (mut t, mut temp, mut y) = (vec![], vec![], vec![]);
        let (mut lag, dt) = (0.0, 30.0);
        for i in 0..3000 {
            let heat = if (i / 400) % 2 == 0 { 0.0 } else { 4.0 };
            let temp_now = 20.0 + heat + 0.5 * (i as f64 / 50.0).sin();
            lag += (1.0 - (-dt / 360_000.0f64).exp()) * (temp_now - 20.0 - lag);
            t.push(dt * i as f64);
            temp.push(temp_now);
            y.push(200.0 * lag + 0.1 * (temp_now - 20.0));
        }
        let ds = crate::dataset::one_sensor(t, temp, y);
        let rows: Vec<(usize, usize)> = (0..3000).map(|i| (0, i)).collect();
        let found = identify_tau(&ds, &rows, false).unwrap();
        assert!(!interior(found), "{found}");
        let settings = Settings {
            families: vec![Family::Transfer],
            ..Settings::paired()
        };
        assert_eq!(TransferTaus::identify(&ds, &rows, &settings).first, None);
        assert!(interior(3600.0) && !interior(TAU_RANGE_S.1));
    }

    /// A structure with two parts lagging the sensor by 1200 s and 9000 s: both time constants
    /// are found within a few percent.
    #[test]
    fn the_time_constants_of_two_lags_are_found() {
        let (mut t, mut temp, mut y) = (vec![], vec![], vec![]);
        let (mut fast, mut slow, dt) = (0.0, 0.0, 30.0);
        for i in 0..4000 {
            let heat = if (i / 500) % 2 == 0 { 0.0 } else { 4.0 };
            let rise = heat + 0.5 * (i as f64 / 70.0).sin();
            fast += (1.0 - (-dt / 1200.0f64).exp()) * (rise - fast);
            slow += (1.0 - (-dt / 9000.0f64).exp()) * (rise - slow);
            t.push(dt * i as f64);
            temp.push(20.0 + rise);
            y.push(2.0 * fast - 1.2 * slow + 0.2 * rise);
        }
        let ds = crate::dataset::one_sensor(t, temp, y);
        let rows: Vec<(usize, usize)> = (0..3600).map(|i| (0, i)).collect();
        let (a, b) = identify_tau_pair(&ds, &rows, false).unwrap();
        assert!((a - 1200.0).abs() < 0.05 * 1200.0, "{a}");
        assert!((b - 9000.0).abs() < 0.05 * 9000.0, "{b}");
        let settings = Settings {
            families: vec![Family::Transfer, Family::Transfer2],
            ..Settings::default()
        };
        let taus = TransferTaus::identify(&ds, &rows, &settings);
        assert_eq!(taus.second, Some([a, b]));
        assert_eq!(taus.of(Family::Static), Vec::<f64>::new());
        assert_eq!(taus.all().len(), 3);
    }
}
