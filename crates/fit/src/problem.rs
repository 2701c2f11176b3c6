//! The training rows of one fit as triangles: one pass over the rows steps the real-time
//! feature banks ([`crate::features::Cursor`]) and fills, per segment of the inner folds
//! ([`crate::inner_cv`]), the QR triangle of [1 | every candidate feature | every target]
//! ([`crate::least_squares`]). Every design (a family on a sensor set, a difference against a
//! reference sensor), every fold's fit, every held-out error and the stacking's held-out
//! predictions then come from these triangles, never from the rows again: a triangle R of rows
//! Z stands for them exactly (Zᵀ·Z = Rᵀ·R, and Z·u, Z·v have the dot product of R·u, R·v). A
//! month of logs at 1 s costs one pass and a few megabytes, not a copy of a hundred feature
//! columns.

#![allow(clippy::needless_range_loop)] // index loops mirror the matrix formulas

use faer::Mat;
use truepos_model::FeatureKind;

use crate::dataset::Dataset;
use crate::features::{Candidates, Extended, Family};
use crate::inner_cv::{decorrelation_time, Folds, Row};
use crate::least_squares::{Accumulator, SolveOptions, Triangle};
use crate::settings::{Selection, Settings};
use crate::transfer::TransferTaus;

/// The regressors of one candidate: feature columns, each minus an optional reference column (the
/// reference-sensor regression: t_i − t_r is rise_i − rise_r, the rises being taken from the same
/// first sample).
#[derive(Debug, Clone)]
pub(crate) struct Design {
    pub cols: Vec<usize>,
    pub minus: Option<usize>,
    /// The design's columns (intercept 0) that share one ridge scale: per unit with the blend
    /// ([`unit_groups`]), per sensor with the paired selection ([`sensor_groups`]), none for the
    /// baseline.
    pub shared_scale: Vec<Vec<usize>>,
}

impl Design {
    /// How to solve the design at `ridge`: the intercept unpenalised, the ridge on the
    /// coefficients with the design's scales (see [`SolveOptions::shared_scale`]).
    pub fn solve_options(&self, ridge: f64) -> SolveOptions {
        SolveOptions {
            ridge,
            unpenalized: vec![0],
            rcond: None,
            shared_scale: self.shared_scale.clone(),
        }
    }
}

/// The shared-scale groups of a design's columns `cols` with the blend: every temperature term
/// (rises, their low-passes, rises while running) in kelvin shares one scale, so that a gain
/// costs the same µm/K on every sensor; every rate (K/s) another; an operating input keeps its
/// own.
fn unit_groups(cand: &Candidates, cols: &[usize]) -> Vec<Vec<usize>> {
    let unit = |kind: FeatureKind| match kind {
        FeatureKind::Rise | FeatureKind::LowPass { .. } | FeatureKind::RiseWhileRunning { .. } => {
            Some(0)
        }
        FeatureKind::Rate { .. } => Some(1),
        FeatureKind::Operating { .. } | FeatureKind::OperatingSquared { .. } => None,
    };
    (0..2)
        .map(|u| {
            (0..cols.len())
                .filter(|&j| unit(cand.features[cols[j]].kind) == Some(u))
                .map(|j| 1 + j)
                .collect()
        })
        .collect()
}

/// The shared-scale groups of a design's columns `cols` with the paired selection: one per
/// temperature sensor, over every term made from it — its rise, its low-passes, its rates and
/// its rises while running. A sensor's terms are one temperature seen with different delays, so
/// they share its scale and the ridge cannot favour one delay for being louder; sensors keep
/// their own scales, because how far a sensor moved in training says nothing about how much of
/// the error it explains (a well-placed sensor on a massive casting barely moves). An operating
/// input's unit is its own, and so is its scale.
fn sensor_groups(cand: &Candidates, cols: &[usize]) -> Vec<Vec<usize>> {
    let mut groups: Vec<(usize, Vec<usize>)> = Vec::new();
    for (j, &c) in cols.iter().enumerate() {
        let f = cand.features[c];
        if matches!(
            f.kind,
            FeatureKind::Operating { .. } | FeatureKind::OperatingSquared { .. }
        ) {
            continue;
        }
        match groups.iter_mut().find(|(input, _)| *input == f.input) {
            Some((_, members)) => members.push(1 + j),
            None => groups.push((f.input, vec![1 + j])),
        }
    }
    groups
        .into_iter()
        .map(|(_, members)| members)
        .filter(|m| m.len() > 1)
        .collect()
}

pub(crate) struct Problem<'a> {
    pub cand: &'a Candidates,
    /// The transfer families' identified time constants.
    pub transfer: TransferTaus,
    /// The fixed grid of temperature low-pass time constants the other families use.
    pub grid_taus: Vec<f64>,
    /// The operating time constant of the baseline: the shortest of the grid.
    pub baseline_operating_tau: Option<f64>,
    /// One ridge scale per sensor (the paired selection) rather than per unit.
    pub per_sensor: bool,
    /// Per candidate feature, its mean over the training rows (the columns are centred).
    pub means: Vec<f64>,
    pub folds: Folds,
    /// Number of targets.
    pub nt: usize,
    /// Number of training rows.
    pub n: usize,
    /// Per fold, the triangle of [1 | x − mean | y] (every candidate feature, every target) over
    /// the rows that train its model, and over its held-out rows.
    train_tri: Vec<Triangle>,
    held_tri: Vec<Triangle>,
    /// Per segment of the folds, its centred triangle.
    segs: Vec<Triangle>,
    /// The same over every training row.
    all: Triangle,
}

impl<'a> Problem<'a> {
    /// The problem of `rows` with the folds of [`inner_folds`].
    pub(crate) fn new(
        dataset: &Dataset,
        source: &'a Extended<'_>,
        rows: &[(usize, usize)],
        settings: &Settings,
        transfer: TransferTaus,
    ) -> Result<Self, String> {
        Self::build(dataset, source, rows, settings, transfer, None)
    }

    /// One pass over the training rows fills one triangle per segment of the folds (`folds`,
    /// or those of [`inner_folds`]); every design, fold and score is then computed from
    /// these triangles, never from the rows again.
    pub(crate) fn build(
        dataset: &Dataset,
        source: &'a Extended<'_>,
        rows: &[(usize, usize)],
        settings: &Settings,
        transfer: TransferTaus,
        folds: Option<Folds>,
    ) -> Result<Self, String> {
        let cand = &source.meta;
        let nf = cand.features.len();
        let nt = dataset.target_names.len();
        let rel: Vec<Vec<Vec<f64>>> = dataset.targets(settings.absolute_targets);
        let at: Vec<Row> = rows
            .iter()
            .map(|&(run, row)| Row {
                run,
                time_s: dataset.runs[run].time_s[row],
            })
            .collect();
        let folds = folds.unwrap_or_else(|| inner_folds(source, rows, &rel, &at, settings));
        let mut segs = segment_triangles(source, rows, &rel, &folds.segments, nt)?;
        let all = Triangle::stack(&segs).unwrap_or_else(|| Accumulator::new(nf + 1, nt).finish());
        let n = rows.len();
        let means: Vec<f64> = (0..nf)
            .map(|j| all.gram(0, j + 1) / n.max(1) as f64)
            .collect();
        for t in &mut segs {
            for (j, &m) in means.iter().enumerate() {
                t.subtract_first_column(j + 1, m);
            }
        }
        let mut p = Self {
            cand,
            transfer,
            grid_taus: settings.taus.temperature_s.clone(),
            baseline_operating_tau: settings
                .taus
                .operating_s
                .iter()
                .copied()
                .min_by(f64::total_cmp),
            per_sensor: settings.selection == Selection::Paired,
            means,
            folds,
            nt,
            n,
            segs,
            train_tri: Vec::new(),
            held_tri: Vec::new(),
            all: Accumulator::new(nf + 1, nt).finish(),
        };
        let folds = &p.folds.folds;
        p.train_tri = folds.iter().map(|f| p.stack(&f.train)).collect();
        p.held_tri = folds.iter().map(|f| p.stack_rows(f.held.clone())).collect();
        p.all = p.stack_rows(0..n);
        Ok(p)
    }

    /// The triangle of segments `ids` together (of no row if none).
    pub fn stack(&self, ids: &[usize]) -> Triangle {
        Triangle::stack(ids.iter().map(|&s| &self.segs[s]))
            .unwrap_or_else(|| Accumulator::new(self.cand.features.len() + 1, self.nt).finish())
    }

    /// The triangle of the segments within rows `range` (a held-out block is a union of them).
    pub fn stack_rows(&self, range: std::ops::Range<usize>) -> Triangle {
        let ids: Vec<usize> = (0..self.segs.len())
            .filter(|&s| self.folds.segments[s].start >= range.start)
            .filter(|&s| self.folds.segments[s].end <= range.end)
            .collect();
        self.stack(&ids)
    }

    /// A design's triangle from a triangle of [1 | every feature | targets].
    pub fn design_on(&self, t: &Triangle, d: &Design) -> Triangle {
        t.transformed(self.map(d).as_ref(), 1 + d.cols.len(), self.nt)
    }

    /// The columns of a design as a map from [1 | every feature | targets] to
    /// [1 | the design's regressors | targets].
    fn map(&self, d: &Design) -> Mat<f64> {
        let (nf, nd, nt) = (self.cand.features.len(), d.cols.len(), self.nt);
        let mut m = Mat::<f64>::zeros(1 + nf + nt, 1 + nd + nt);
        m[(0, 0)] = 1.0;
        for (j, &c) in d.cols.iter().enumerate() {
            m[(1 + c, 1 + j)] = 1.0;
            if let Some(r) = d.minus {
                m[(1 + r, 1 + j)] = -1.0;
            }
        }
        for k in 0..nt {
            m[(1 + nf + k, 1 + nd + k)] = 1.0;
        }
        m
    }

    /// The triangle of a design over fold `f`'s training rows (`None`: every training row).
    pub fn design_triangle(&self, d: &Design, f: Option<usize>) -> Triangle {
        self.design_on(f.map_or(&self.all, |f| &self.train_tri[f]), d)
    }

    /// The combination of [1 | features | targets] that a design's coefficients `coef`
    /// (intercept first) predict, minus target `k` if given (the residual's negative).
    pub fn combination(&self, d: &Design, coef: &[f64], k: Option<usize>) -> Vec<f64> {
        let nf = self.cand.features.len();
        let mut u = vec![0.0; 1 + nf + self.nt];
        u[0] = coef[0];
        for (j, &c) in d.cols.iter().enumerate() {
            u[1 + c] += coef[1 + j];
            if let Some(r) = d.minus {
                u[1 + r] -= coef[1 + j];
            }
        }
        if let Some(k) = k {
            u[1 + nf + k] = -1.0;
        }
        u
    }

    /// Sum of squared errors of `coef` on fold `f`'s held-out rows for target `k`.
    pub fn held_sse(&self, f: usize, d: &Design, coef: &[f64], k: usize) -> f64 {
        let e = self.held_tri[f].apply(&self.combination(d, coef, Some(k)));
        e.iter().map(|v| v * v).sum()
    }

    /// Fold `f`'s held-out predictions of `coef`, in the held triangle's coordinates: vectors
    /// whose dot products (over the folds concatenated) are those of the predictions themselves.
    pub fn held_prediction(&self, f: usize, d: &Design, coef: &[f64]) -> Vec<f64> {
        self.held_tri[f].apply(&self.combination(d, coef, None))
    }

    /// Length of one fold's vector in [`Problem::held_prediction`].
    pub fn held_width(&self) -> usize {
        1 + self.cand.features.len() + self.nt
    }

    /// Per target, the held-out targets in the held triangles' coordinates, folds concatenated:
    /// vectors whose sum of squares is that of the held-out targets themselves.
    pub fn held_targets(&self) -> Vec<Vec<f64>> {
        let nf = self.cand.features.len();
        (0..self.nt)
            .map(|k| {
                let mut e = vec![0.0; self.held_width()];
                e[1 + nf + k] = 1.0;
                self.held_tri.iter().flat_map(|t| t.apply(&e)).collect()
            })
            .collect()
    }

    /// Sum over the training rows of column i times column j of [1 | x − mean | y].
    pub fn gram(&self, i: usize, j: usize) -> f64 {
        self.all.gram(i, j)
    }

    /// The design of a family on a sensor set; `None` when the family cannot be built (the
    /// reference-sensor regression without a reference, or with nothing left to regress on).
    pub fn design(
        &self,
        family: Family,
        sensors: &[usize],
        reference: Option<usize>,
    ) -> Option<Design> {
        let rise = |s: usize| {
            (0..self.cand.features.len()).find(|&j| {
                self.cand.features[j].input == s && self.cand.features[j].kind == FeatureKind::Rise
            })
        };
        let minus = match family {
            Family::Reference => Some(rise(reference?)?),
            _ => None,
        };
        let transfer_taus = self.transfer.of(family);
        let cols: Vec<usize> = (0..self.cand.features.len())
            .filter(|&j| {
                let f = self.cand.features[j];
                let is_temp = f.input < self.cand.spec.temperatures;
                let tau_ok = match (f.kind, family) {
                    (FeatureKind::LowPass { tau_s }, Family::Transfer | Family::Transfer2) => {
                        transfer_taus.contains(&tau_s)
                    }
                    (FeatureKind::LowPass { tau_s }, _) => self.grid_taus.contains(&tau_s),
                    (FeatureKind::Operating { tau_s }, Family::Baseline) => {
                        self.baseline_operating_tau == Some(tau_s)
                    }
                    _ => true,
                };
                family.includes(f.kind)
                    && tau_ok
                    && (!is_temp || sensors.contains(&f.input))
                    && Some(j) != minus
            })
            .collect();
        // The baseline is defined with one scale per column: each of its columns is a
        // different sensor or input already.
        let shared_scale = match family {
            Family::Baseline => Vec::new(),
            _ if self.per_sensor => sensor_groups(self.cand, &cols),
            _ => unit_groups(self.cand, &cols),
        };
        (!cols.is_empty()).then_some(Design {
            cols,
            minus,
            shared_scale,
        })
    }
}

/// The folds of the inner validation. The gap is the slowest time constant of any candidate
/// feature and the decorrelation time of the static model's residual, whichever is longer
/// (capped at a block per side by [`Folds::new`]); without any row left to train a fold, no
/// gap. With the paired selection a time constant identified from the data (the transfer
/// families') does not set it: it can land anywhere up to its scan bound, and would then set the
/// gap of every other candidate.
fn inner_folds(
    source: &Extended<'_>,
    rows: &[(usize, usize)],
    rel: &[Vec<Vec<f64>>],
    at: &[Row],
    settings: &Settings,
) -> Folds {
    let features = match settings.selection {
        Selection::Paired => &source.base.features,
        Selection::Blend => &source.meta.features,
    };
    let slowest = features
        .iter()
        .filter(|f| settings.families.iter().any(|fam| fam.includes(f.kind)))
        .filter_map(|f| f.kind.tau_s())
        .fold(0.0, f64::max);
    let residual = static_residuals(source, rows, rel)
        .map(|series| decorrelation_time(at, &series))
        .unwrap_or(0.0);
    let folds = Folds::new(at, settings.folds, settings.inner, slowest.max(residual));
    if folds.folds.iter().any(|f| f.train.is_empty()) {
        Folds::new(at, settings.folds, settings.inner, 0.0)
    } else {
        folds
    }
}

/// Per target, the residual on every training row of the static model (every temperature
/// rise, centred, ridge 1e-3) fitted on all of them; `None` if it cannot be fitted.
fn static_residuals(
    source: &Extended<'_>,
    rows: &[(usize, usize)],
    rel: &[Vec<Vec<f64>>],
) -> Option<Vec<Vec<f64>>> {
    // The rise of a temperature is its value minus the run's first (as the bank computes it).
    let cand = &source.meta;
    let cols: Vec<usize> = (0..cand.spec.temperatures)
        .filter(|&s| {
            cand.features
                .iter()
                .any(|f| f.input == s && f.kind == FeatureKind::Rise)
        })
        .map(|s| cand.bank_inputs[s])
        .collect();
    if cols.is_empty() || rows.is_empty() {
        return None;
    }
    let runs = &source.dataset.runs;
    let rise = |r: usize, i: usize, d: usize| runs[r].inputs[d][i] - runs[r].inputs[d][0];
    let nt = rel.first().map_or(0, Vec::len);
    let n = rows.len() as f64;
    let means: Vec<f64> = cols
        .iter()
        .map(|&d| rows.iter().map(|&(r, i)| rise(r, i, d)).sum::<f64>() / n)
        .collect();
    let x = |&(r, i): &(usize, usize), c: usize| rise(r, i, cols[c]) - means[c];
    let mut acc = Accumulator::new(cols.len() + 1, nt);
    let mut a = vec![1.0; cols.len() + 1];
    let mut b = vec![0.0; nt];
    for at in rows {
        for c in 0..cols.len() {
            a[1 + c] = x(at, c);
        }
        for (k, slot) in b.iter_mut().enumerate() {
            *slot = rel[at.0][k][at.1];
        }
        acc.push_row(&a, &b, 1.0).ok()?;
    }
    let sol = acc
        .finish()
        .solve(&SolveOptions {
            ridge: 1e-3,
            unpenalized: vec![0],
            rcond: None,
            shared_scale: vec![(1..=cols.len()).collect()],
        })
        .ok()?;
    Some(
        (0..nt)
            .map(|k| {
                let coef = &sol.coefficients[k];
                rows.iter()
                    .map(|at| {
                        let p: f64 =
                            coef[0] + (0..cols.len()).map(|c| coef[1 + c] * x(at, c)).sum::<f64>();
                        rel[at.0][k][at.1] - p
                    })
                    .collect()
            })
            .collect(),
    )
}

/// One triangle of [1 | every candidate feature | every target] per segment of training rows,
/// uncentred; the segments are shared among the cores.
fn segment_triangles(
    source: &Extended<'_>,
    rows: &[(usize, usize)],
    rel: &[Vec<Vec<f64>>],
    segments: &[std::ops::Range<usize>],
    nt: usize,
) -> Result<Vec<Triangle>, String> {
    let nf = source.meta.features.len();
    // Each core steps its own banks from the start of every run it needs.
    let fill = |group: &[usize]| -> Result<Vec<(usize, Triangle)>, String> {
        let mut cursor = source.cursor().map_err(|e| e.to_string())?;
        let mut a = vec![1.0; nf + 1];
        let mut b = vec![0.0; nt];
        let mut out = Vec::with_capacity(group.len());
        for &s in group {
            let mut acc = Accumulator::new(nf + 1, nt);
            for &(run, row) in &rows[segments[s].clone()] {
                let values = cursor.at(run, row).map_err(|e| {
                    format!("{}, row {}: {e}", source.dataset.runs[run].name, row + 1)
                })?;
                a[1..].copy_from_slice(values);
                for (k, slot) in b.iter_mut().enumerate() {
                    *slot = rel[run][k][row];
                }
                acc.push_row(&a, &b, 1.0).map_err(|e| e.to_string())?;
            }
            out.push((s, acc.finish()));
        }
        Ok(out)
    };
    let threads = std::thread::available_parallelism()
        .map_or(1, |n| n.get())
        .min(segments.len())
        .max(1);
    // Contiguous groups of segments with about equal numbers of rows, one per core. Each core's
    // cursor steps the banks from its runs' first samples, so with one long run the later
    // group also steps the filters over the rows before its own (cheap beside the QR).
    let per = rows.len().div_ceil(threads).max(1);
    let mut groups: Vec<Vec<usize>> = vec![Vec::new(); threads];
    for (s, seg) in segments.iter().enumerate() {
        groups[(seg.start / per).min(threads - 1)].push(s);
    }
    let mut out: Vec<Option<Triangle>> = vec![None; segments.len()];
    std::thread::scope(|scope| {
        let handles: Vec<_> = groups
            .iter()
            .map(|g| {
                let fill = &fill;
                scope.spawn(move || fill(g))
            })
            .collect();
        for h in handles {
            match h.join() {
                Ok(done) => {
                    for (s, t) in done? {
                        out[s] = Some(t);
                    }
                }
                Err(panic) => std::panic::resume_unwind(panic),
            }
        }
        Ok::<(), String>(())
    })?;
    Ok(out
        .into_iter()
        .map(|t| t.unwrap_or_else(|| Accumulator::new(nf + 1, nt).finish()))
        .collect())
}

impl Problem<'_> {
    /// The bank index of the reference sensor, if one is set and is a temperature input.
    pub fn reference(&self, settings: &Settings) -> Option<usize> {
        let r = settings.reference?;
        self.cand
            .bank_inputs
            .iter()
            .position(|&d| d == r)
            .filter(|&b| b < self.cand.spec.temperatures)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dataset::{Dataset, InputKind, Run};
    use crate::features::{candidates, TimeConstants};

    /// Every term made from one sensor shares its scale, each sensor has its own, and an
    /// operating input's terms are scaled alone; the baseline holds the rises and the shortest
    /// operating lag only.
    #[test]
    fn one_scale_per_sensor_and_the_baseline_structure() {
        let ds = Dataset {
            input_names: vec!["t1_c".into(), "t2_c".into(), "spindle_rpm".into()],
            input_kinds: vec![
                InputKind::Temperature,
                InputKind::Temperature,
                InputKind::Operating,
            ],
            target_names: vec!["dz_um".into()],
            runs: vec![Run {
                name: "r".into(),
                time_s: vec![0.0, 60.0],
                inputs: vec![vec![20.0; 2], vec![21.0; 2], vec![0.0; 2]],
                targets: vec![vec![0.0; 2]],
            }],
        };
        let cand = candidates(&ds, &TimeConstants::default()).unwrap();
        let cols: Vec<usize> = (0..cand.features.len()).collect();
        let groups = sensor_groups(&cand, &cols);
        assert_eq!(groups.len(), 2);
        for g in &groups {
            let input = cand.features[g[0] - 1].input;
            assert!(g.iter().all(|&j| cand.features[j - 1].input == input));
            assert!(input < 2, "operating terms keep their own scale");
        }
        let grouped: usize = groups.iter().map(Vec::len).sum();
        let temperature_terms = cand.features.iter().filter(|f| f.input < 2).count();
        assert_eq!(grouped, temperature_terms);
        let ext = Extended::new(&ds, &cand, &[]).unwrap();
        let rows: Vec<(usize, usize)> = vec![(0, 0), (0, 1)];
        let settings = Settings::paired();
        let folds = Folds::new(
            &[
                Row {
                    run: 0,
                    time_s: 0.0,
                },
                Row {
                    run: 0,
                    time_s: 60.0,
                },
            ],
            2,
            settings.inner,
            0.0,
        );
        let p = Problem::build(
            &ds,
            &ext,
            &rows,
            &settings,
            TransferTaus::default(),
            Some(folds),
        )
        .unwrap();
        let d = p.design(Family::Baseline, &[0, 1], None).unwrap();
        let names: Vec<&str> = d.cols.iter().map(|&c| cand.names[c].as_str()).collect();
        assert_eq!(names, ["rise(t1_c)", "rise(t2_c)", "lp300(spindle_rpm)"]);
        assert!(d.shared_scale.is_empty());
    }
}
