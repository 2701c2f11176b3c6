//! Training: choose family, sensors and ridge by blocked time-series cross-validation inside the
//! training rows only, then fit and export a [`DynamicModel`].
//!
//! Blocked CV: the training rows (in time order, run after run) are cut into k contiguous blocks;
//! each block is predicted by a model fitted on the other blocks. Contiguous blocks keep
//! neighbouring, nearly identical samples on the same side, which a random split would not.
//! Every block's QR factor is computed once; a fold's factor is the merge of the others'.
//! [`InnerCv::Rolling`] is the forecaster's variant (rolling origin, forward chaining): each block
//! from the third on is predicted by a model fitted on the blocks before it only, as the model
//! will be used — it never learns from the future it is scored on.

#![allow(clippy::needless_range_loop)] // index loops mirror the matrix formulas

use faer::Mat;
use truepos_model::{DynamicModel, FeatureBank, FeatureKind};

use crate::dataset::{Dataset, InputKind};
use crate::features::{bank_for, Candidates, Family};
use crate::least_squares::{Accumulator, SolveOptions};
use crate::settings::{InnerCv, Rule, Settings, ROLLING_FIRST_HELD_OUT};

/// What was chosen for one target.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Choice {
    /// Target name.
    pub target: String,
    /// Family.
    pub family: Family,
    /// Ridge parameter.
    pub ridge: f64,
    /// Inner-CV RMSE of the choice (µm).
    pub cv_rmse_um: f64,
}

/// A trained model with what was chosen.
#[derive(Debug, Clone)]
pub struct Trained {
    /// The real-time model.
    pub model: DynamicModel,
    /// Dataset input index of each model input.
    pub inputs: Vec<usize>,
    /// Temperature sensors used (dataset input indices).
    pub sensors: Vec<usize>,
    /// One per target.
    pub choices: Vec<Choice>,
    /// Warnings (rank deficiency with culprit columns).
    pub warnings: Vec<String>,
    /// Every family tried, with its inner-CV figures per target.
    pub scores: Vec<FamilyScore>,
}

/// The inner-CV figures of one family: per target, its lowest CV RMSE over the ridges tried
/// and that ridge.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct FamilyScore {
    /// The family.
    pub family: Family,
    /// Per target: (CV RMSE µm, ridge).
    pub per_target: Vec<(f64, f64)>,
}

/// Training rows: (run, row) pairs in time order.
pub type Rows = Vec<(usize, usize)>;

/// The regressors of one candidate: feature columns, each minus an optional reference column
/// (seed C: t_i − t_r is rise_i − rise_r, the rises being taken from the same first sample).
#[derive(Debug, Clone)]
struct Design {
    cols: Vec<usize>,
    minus: Option<usize>,
}

struct Problem<'a> {
    cand: &'a Candidates,
    x: Mat<f64>,
    y: Mat<f64>,
    means: Vec<f64>,
    blocks: Vec<std::ops::Range<usize>>,
    inner: InnerCv,
}

impl<'a> Problem<'a> {
    fn new(
        dataset: &Dataset,
        cand: &'a Candidates,
        rows: &[(usize, usize)],
        folds: usize,
        inner: InnerCv,
        absolute: bool,
    ) -> Self {
        let nf = cand.features.len();
        let nt = dataset.target_names.len();
        let mut x = Mat::<f64>::zeros(rows.len(), nf);
        let mut y = Mat::<f64>::zeros(rows.len(), nt);
        let rel: Vec<Vec<Vec<f64>>> = dataset
            .runs
            .iter()
            .map(|r| (0..nt).map(|k| r.target(k, absolute)).collect())
            .collect();
        for (i, &(run, row)) in rows.iter().enumerate() {
            for j in 0..nf {
                x[(i, j)] = cand.runs[run][(row, j)];
            }
            for k in 0..nt {
                y[(i, k)] = rel[run][k][row];
            }
        }
        let mut means = vec![0.0; nf];
        for (j, mean) in means.iter_mut().enumerate() {
            *mean = (0..rows.len()).map(|i| x[(i, j)]).sum::<f64>() / rows.len().max(1) as f64;
            for i in 0..rows.len() {
                x[(i, j)] -= *mean;
            }
        }
        let min_folds = match inner {
            InnerCv::Blocked => 2,
            InnerCv::Rolling => ROLLING_FIRST_HELD_OUT + 1,
        };
        let folds = folds.clamp(min_folds, rows.len().max(min_folds));
        let blocks = (0..folds)
            .map(|b| b * rows.len() / folds..(b + 1) * rows.len() / folds)
            .collect();
        Self {
            cand,
            x,
            y,
            means,
            blocks,
            inner,
        }
    }

    /// Value of design column j at row i.
    #[inline]
    fn value(&self, d: &Design, i: usize, j: usize) -> f64 {
        self.x[(i, d.cols[j])] - d.minus.map_or(0.0, |m| self.x[(i, m)])
    }

    fn accumulate(&self, d: &Design, range: std::ops::Range<usize>) -> Accumulator {
        let n = d.cols.len() + 1;
        let nt = self.y.ncols();
        let mut acc = Accumulator::new(n, nt);
        let mut a = vec![0.0; n];
        let mut b = vec![0.0; nt];
        a[0] = 1.0;
        for i in range {
            for (j, slot) in a[1..].iter_mut().enumerate() {
                *slot = self.value(d, i, j);
            }
            for (k, slot) in b.iter_mut().enumerate() {
                *slot = self.y[(i, k)];
            }
            // Finite by construction (checked dataset, checked filters).
            let _ = acc.push_row(&a, &b, 1.0);
        }
        acc
    }

    /// Per ridge, per target: (CV RMSE over all held-out rows, standard error of the per-fold
    /// RMSEs of the held-out blocks).
    fn cv(&self, d: &Design, ridges: &[f64]) -> Vec<Vec<(f64, f64)>> {
        let nt = self.y.ncols();
        let folds = self.blocks.len();
        let parts: Vec<Accumulator> = self
            .blocks
            .iter()
            .map(|r| self.accumulate(d, r.clone()))
            .collect();
        // sse[ridge][target][fold]
        let mut sse = vec![vec![vec![0.0; folds]; nt]; ridges.len()];
        let held: Vec<usize> = (0..folds).filter(|&f| self.inner.holds_out(f)).collect();
        for &f in &held {
            let block = &self.blocks[f];
            let mut acc = Accumulator::new(d.cols.len() + 1, nt);
            for (g, p) in parts.iter().enumerate() {
                if self.inner.trains(g, f) {
                    let _ = acc.merge(p.clone());
                }
            }
            let tri = acc.finish();
            for (ri, &ridge) in ridges.iter().enumerate() {
                let opts = SolveOptions {
                    ridge,
                    unpenalized: vec![0],
                    rcond: None,
                };
                let Ok(sol) = tri.solve(&opts) else {
                    sse[ri].iter_mut().for_each(|s| s[f] = f64::INFINITY);
                    continue;
                };
                for i in block.clone() {
                    for k in 0..nt {
                        let c = &sol.coefficients[k];
                        let mut p = c[0];
                        for (j, cj) in c[1..].iter().enumerate() {
                            p += cj * self.value(d, i, j);
                        }
                        let e = self.y[(i, k)] - p;
                        sse[ri][k][f] += e * e;
                    }
                }
            }
        }
        let n = held
            .iter()
            .map(|&f| self.blocks[f].len())
            .sum::<usize>()
            .max(1) as f64;
        let used = held.len() as f64;
        sse.into_iter()
            .map(|per_target| {
                per_target
                    .into_iter()
                    .map(|per_fold| {
                        let total: f64 = held.iter().map(|&f| per_fold[f]).sum();
                        let rmse: Vec<f64> = held
                            .iter()
                            .map(|&f| (per_fold[f] / self.blocks[f].len().max(1) as f64).sqrt())
                            .collect();
                        let m = rmse.iter().sum::<f64>() / used;
                        let var = rmse.iter().map(|r| (r - m).powi(2)).sum::<f64>()
                            / (used - 1.0).max(1.0);
                        ((total / n).sqrt(), (var / used).sqrt())
                    })
                    .collect()
            })
            .collect()
    }

    /// The design of a family on a sensor set; `None` when the family cannot be built (seed C
    /// without a reference, or with nothing left to regress on).
    fn design(
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
            Family::SeedC => Some(rise(reference?)?),
            _ => None,
        };
        let cols: Vec<usize> = (0..self.cand.features.len())
            .filter(|&j| {
                let f = self.cand.features[j];
                let is_temp = f.input < self.cand.spec.temperatures;
                family.includes(f.kind)
                    && (!is_temp || sensors.contains(&f.input))
                    && Some(j) != minus
            })
            .collect();
        (!cols.is_empty()).then_some(Design { cols, minus })
    }
}

/// Best (family, ridge) per target for a sensor set: (CV RMSE, family, ridge).
///
/// With [`Rule::OneStandardError`] the choice is the largest ridge of the best family whose CV
/// RMSE lies within one standard error of the best (Hastie, Tibshirani & Friedman, *The Elements
/// of Statistical Learning*, 2nd ed., §7.10): among models the CV cannot tell apart, the most
/// regularised one, which extrapolates into unseen operating regimes more gently.
fn best_per_target(
    p: &Problem<'_>,
    settings: &Settings,
    sensors: &[usize],
) -> (Vec<(f64, Family, f64)>, Vec<FamilyScore>) {
    let nt = p.y.ncols();
    // (rmse, se, family, ridge) of every candidate, per target.
    let mut all: Vec<Vec<(f64, f64, Family, f64)>> = vec![Vec::new(); nt];
    let reference = reference_input(p, settings);
    let mut families = Vec::new();
    for &family in &settings.families {
        let Some(design) = p.design(family, sensors, reference) else {
            continue;
        };
        let scores = p.cv(&design, &settings.ridges);
        let mut per_target = vec![(f64::INFINITY, 0.0); nt];
        for (ri, row) in scores.iter().enumerate() {
            for k in 0..nt {
                all[k].push((row[k].0, row[k].1, family, settings.ridges[ri]));
                if row[k].0 < per_target[k].0 {
                    per_target[k] = (row[k].0, settings.ridges[ri]);
                }
            }
        }
        families.push(FamilyScore { family, per_target });
    }
    let picks = all
        .iter()
        .map(|cands| {
            let best = cands
                .iter()
                .copied()
                .min_by(|a, b| a.0.total_cmp(&b.0))
                .unwrap_or((f64::INFINITY, 0.0, Family::Static, 0.0));
            let pick = match settings.rule {
                Rule::MinimumCv => best,
                Rule::OneStandardError => cands
                    .iter()
                    .copied()
                    .filter(|c| c.2 == best.2 && c.0 <= best.0 + best.1)
                    .max_by(|a, b| a.3.total_cmp(&b.3))
                    .unwrap_or(best),
            };
            (pick.0, pick.2, pick.3)
        })
        .collect();
    (picks, families)
}

/// Chooses by inner CV on `rows` (training rows only; blocked or rolling origin, see
/// [`InnerCv`]) and fits on all of them.
pub fn train(
    dataset: &Dataset,
    cand: &Candidates,
    rows: &[(usize, usize)],
    settings: &Settings,
) -> Result<Trained, String> {
    if rows.len() < 4 * settings.folds.max(2) {
        return Err(format!(
            "only {} training samples: too few for {}-fold cross-validation",
            rows.len(),
            settings.folds
        ));
    }
    let (folds, inner, absolute) = (settings.folds, settings.inner, settings.absolute_targets);
    let p = Problem::new(dataset, cand, rows, folds, inner, absolute);
    let nt = dataset.target_names.len();
    let all_sensors: Vec<usize> = (0..cand.spec.temperatures).collect();
    let mut sensors = match settings.max_sensors {
        Some(max) if max < all_sensors.len() => greedy_sensors(&p, settings, max),
        _ => all_sensors,
    };
    let reference = reference_input(&p, settings);
    if let Some(r) = reference.filter(|r| !sensors.contains(r)) {
        sensors.push(r);
        sensors.sort_unstable();
    }
    if settings
        .families
        .iter()
        .all(|&f| p.design(f, &sensors, reference).is_none())
    {
        return Err(
            "no candidate family can be built: seed-c needs a reference sensor (--reference)"
                .into(),
        );
    }
    let (best, scores) = best_per_target(&p, settings, &sensors);
    // Final fit per target on all training rows.
    let nf = cand.features.len();
    let mut coef = vec![vec![0.0; nf]; nt];
    let mut intercepts = vec![0.0; nt];
    let mut warnings = Vec::new();
    let mut choices = Vec::new();
    for k in 0..nt {
        let (score, family, ridge) = best[k];
        let design = p
            .design(family, &sensors, reference)
            .ok_or("internal: the chosen family has no design")?;
        let acc = p.accumulate(&design, 0..p.x.nrows());
        let sol = acc
            .finish()
            .solve(&SolveOptions {
                ridge,
                unpenalized: vec![0],
                rcond: None,
            })
            .map_err(|e| e.to_string())?;
        let names: Vec<String> = std::iter::once("intercept".to_string())
            .chain(design.cols.iter().map(|&c| match design.minus {
                Some(m) => format!("{} − {}", cand.names[c], cand.names[m]),
                None => cand.names[c].clone(),
            }))
            .collect();
        for d in &sol.rank_deficiencies {
            warnings.push(format!(
                "{}: {}",
                dataset.target_names[k],
                d.describe(&names)
            ));
        }
        let c = &sol.coefficients[k];
        let mut b0 = c[0];
        for (cj, &col) in c[1..].iter().zip(&design.cols) {
            coef[k][col] += *cj;
            b0 -= cj * p.means[col];
            // k·(x_i − x_r) = k·x_i − k·x_r: the reference's rise carries −Σk.
            if let Some(m) = design.minus {
                coef[k][m] -= *cj;
                b0 += cj * p.means[m];
            }
        }
        intercepts[k] = b0;
        choices.push(Choice {
            target: dataset.target_names[k].clone(),
            family,
            ridge,
            cv_rmse_um: score,
        });
    }
    // Export: inputs = the chosen sensors, plus operating inputs if any target reads them.
    let uses = |pred: &dyn Fn(FeatureKind) -> bool| {
        (0..nf).any(|j| pred(cand.features[j].kind) && coef.iter().any(|c| c[j] != 0.0))
    };
    let uses_operating = uses(&|k| {
        matches!(
            k,
            FeatureKind::Operating { .. }
                | FeatureKind::OperatingSquared { .. }
                | FeatureKind::RiseWhileRunning { .. }
        )
    });
    let uses_running = uses(&|k| matches!(k, FeatureKind::RiseWhileRunning { .. }));
    let mut inputs: Vec<usize> = sensors.iter().map(|&s| cand.bank_inputs[s]).collect();
    if uses_operating {
        inputs.extend(
            (0..dataset.input_names.len())
                .filter(|&i| dataset.input_kinds[i] == InputKind::Operating),
        );
    }
    let (spec, order) = bank_for(dataset, &inputs, &settings.taus, uses_running);
    let bank = FeatureBank::new(spec).map_err(|e| e.to_string())?;
    // The same feature in the candidate bank: same dataset input, same kind (a rise while
    // running names its operating input by bank index, which differs between the two banks).
    let dataset_kind = |kind: FeatureKind, inputs: &[usize]| match kind {
        FeatureKind::RiseWhileRunning { running } => FeatureKind::RiseWhileRunning {
            running: inputs[running],
        },
        other => other,
    };
    let mut flat = Vec::new();
    for c in &coef {
        for f in bank.features() {
            let d = order[f.input];
            let kind = dataset_kind(f.kind, &order);
            let j = cand
                .features
                .iter()
                .position(|g| {
                    cand.bank_inputs[g.input] == d
                        && dataset_kind(g.kind, &cand.bank_inputs) == kind
                })
                .ok_or("internal: feature not among the candidates")?;
            flat.push(c[j]);
        }
    }
    let model = DynamicModel::new(bank, intercepts, flat).map_err(|e| e.to_string())?;
    Ok(Trained {
        model,
        inputs: order,
        sensors: sensors.iter().map(|&s| cand.bank_inputs[s]).collect(),
        choices,
        warnings,
        scores,
    })
}

/// The bank index of the reference sensor, if one is set and is a temperature input.
fn reference_input(p: &Problem<'_>, settings: &Settings) -> Option<usize> {
    let r = settings.reference?;
    p.cand
        .bank_inputs
        .iter()
        .position(|&d| d == r)
        .filter(|&b| b < p.cand.spec.temperatures)
}

/// Correlation ranking, then greedy forward selection by CV score (mean over targets of the
/// CV RMSE relative to the target's spread), among the best-ranked candidates.
fn greedy_sensors(p: &Problem<'_>, settings: &Settings, max: usize) -> Vec<usize> {
    let nt = p.y.ncols();
    let temps = p.cand.spec.temperatures;
    let rise_col = |s: usize| {
        (0..p.cand.features.len()).find(|&j| {
            p.cand.features[j].input == s && p.cand.features[j].kind == FeatureKind::Rise
        })
    };
    let spread: Vec<f64> = (0..nt)
        .map(|k| {
            let n = p.y.nrows() as f64;
            let m = (0..p.y.nrows()).map(|i| p.y[(i, k)]).sum::<f64>() / n;
            ((0..p.y.nrows())
                .map(|i| (p.y[(i, k)] - m).powi(2))
                .sum::<f64>()
                / n)
                .sqrt()
                .max(1e-12)
        })
        .collect();
    // |Pearson correlation| of each sensor's rise with each target, averaged over targets.
    let mut ranked: Vec<(f64, usize)> = (0..temps)
        .filter_map(|s| {
            let j = rise_col(s)?;
            let xs = (0..p.x.nrows()).map(|i| p.x[(i, j)]);
            let sx = xs.clone().map(|v| v * v).sum::<f64>().sqrt();
            let r = (0..nt)
                .map(|k| {
                    let m = (0..p.y.nrows()).map(|i| p.y[(i, k)]).sum::<f64>() / p.y.nrows() as f64;
                    let sxy: f64 = (0..p.x.nrows())
                        .map(|i| p.x[(i, j)] * (p.y[(i, k)] - m))
                        .sum();
                    let sy = spread[k] * (p.y.nrows() as f64).sqrt();
                    if sx > 0.0 {
                        (sxy / (sx * sy)).abs()
                    } else {
                        0.0
                    }
                })
                .sum::<f64>()
                / nt as f64;
            Some((r, s))
        })
        .collect();
    ranked.sort_by(|a, b| b.0.total_cmp(&a.0));
    let pool: Vec<usize> = ranked
        .iter()
        .take((3 * max).max(8))
        .map(|&(_, s)| s)
        .collect();
    let score = |sensors: &[usize]| {
        best_per_target(p, settings, sensors)
            .0
            .iter()
            .zip(&spread)
            .map(|(b, s)| b.0 / s)
            .sum::<f64>()
            / nt as f64
    };
    let mut chosen: Vec<usize> = Vec::new();
    let mut current = score(&chosen);
    while chosen.len() < max {
        let mut best: Option<(f64, usize)> = None;
        for &s in pool.iter().filter(|s| !chosen.contains(s)) {
            let mut trial = chosen.clone();
            trial.push(s);
            let sc = score(&trial);
            if best.is_none_or(|b| sc < b.0) {
                best = Some((sc, s));
            }
        }
        match best {
            Some((sc, s)) if sc < current * 0.99 => {
                chosen.push(s);
                current = sc;
            }
            _ => break,
        }
    }
    chosen.sort_unstable();
    chosen
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dataset::Run;
    use crate::features::{candidates, TimeConstants};
    use crate::validate::predict;

    /// Two runs of a machine whose growth lags the spindle and one of two sensors.
    fn twin_like() -> Dataset {
        let mut runs = Vec::new();
        for (r, level) in [(0, 3000.0), (1, 4500.0)] {
            let (mut t, mut s, mut a, mut b, mut y) = (vec![], vec![], vec![], vec![], vec![]);
            let (mut lag, mut warm) = (0.0, 21.0);
            for i in 0..1500 {
                let rpm = if (i / 200) % 2 == 1 { level } else { 0.0 };
                lag += (1.0 - (-20.0f64 / 1200.0).exp()) * (rpm - lag);
                // The room drifts by ±1.5 K over the day: only the sensor sees that.
                let room = 21.0 + 1.5 * (i as f64 / 240.0).sin();
                warm += (1.0 - (-20.0f64 / 900.0).exp()) * (room + rpm / 400.0 - warm);
                t.push(20.0 * i as f64 + 5.0 * r as f64);
                s.push(rpm);
                a.push(warm);
                b.push(20.0 + 0.3 * (i as f64 * 0.01).sin());
                y.push(0.003 * lag + 0.8 * (warm - 21.0) + 4.0);
            }
            runs.push(Run {
                name: format!("run{r}"),
                time_s: t,
                inputs: vec![a, b, s],
                targets: vec![y],
            });
        }
        Dataset {
            input_names: vec!["t1_c".into(), "t2_c".into(), "spindle_rpm".into()],
            input_kinds: vec![
                InputKind::Temperature,
                InputKind::Temperature,
                InputKind::Operating,
            ],
            target_names: vec!["dz_um".into()],
            runs,
        }
    }

    #[test]
    fn offline_features_equal_the_online_model() {
        // Once with everything free, once with a running family on one sensor: the exported
        // bank then has one temperature, so its rise-while-running features name the spindle by
        // another index than the candidate bank does.
        offline_equals_online(Settings::default());
        offline_equals_online(Settings {
            families: vec![Family::DynamicRatesRunning],
            max_sensors: Some(1),
            ..Settings::default()
        });
    }

    fn offline_equals_online(settings: Settings) {
        let ds = twin_like();
        ds.check().unwrap();
        let cand = candidates(&ds, &settings.taus).unwrap();
        let rows: Rows = (0..ds.runs.len())
            .flat_map(|r| (0..ds.runs[r].len()).map(move |i| (r, i)))
            .collect();
        let trained = train(&ds, &cand, &rows, &settings).unwrap();
        // Online: the real-time model stepped through every run.
        let online = predict(&ds, &trained).unwrap();
        // Offline: intercept + Σ coefficient · candidate feature column of the same name.
        let model = &trained.model;
        let n = model.bank().features().len();
        let names: Vec<String> = model
            .bank()
            .features()
            .iter()
            .map(|f| f.name(|i| &ds.input_names[trained.inputs[i]]))
            .collect();
        let mut nonzero = 0;
        for (r, run) in ds.runs.iter().enumerate() {
            for i in 0..run.len() {
                let mut p = model.intercepts()[0];
                for (j, name) in names.iter().enumerate() {
                    let c = model.coefficients()[j];
                    if c != 0.0 {
                        nonzero += 1;
                    }
                    let col = cand.names.iter().position(|x| x == name).unwrap();
                    p += c * cand.runs[r][(i, col)];
                }
                let q = online[r][0][i];
                assert!(
                    (p - q).abs() <= 1e-9 * p.abs().max(1.0),
                    "run {r} row {i}: {p} vs {q}"
                );
            }
        }
        assert!(nonzero > 0 && n > 0);
        if settings.families == [Family::DynamicRatesRunning] {
            assert_eq!(trained.sensors, vec![0]);
            let running = names
                .iter()
                .zip(model.coefficients())
                .filter(|(name, c)| name.contains("running(spindle_rpm)") && **c != 0.0)
                .count();
            assert_eq!(running, 1, "{names:?}");
        }
        // And the model is good: the data are exactly representable by lags of the inputs.
        let rel = ds.runs[1].relative_target(0);
        let rms = (rel
            .iter()
            .zip(&online[1][0])
            .map(|(a, b)| (a - b).powi(2))
            .sum::<f64>()
            / rel.len() as f64)
            .sqrt();
        assert!(rms < 0.5, "{rms}");
    }

    /// Seed C: Y = Σ k_i·(t_i − t_r) + c. Data made exactly so, with k = (2, 0.5) against a
    /// drifting reference t3 and c = 1 µm (relative targets remove c, the model's intercept
    /// puts the start value back): the fit recovers k, and the reference's rise carries
    /// −(2 + 0.5) = −2.5.
    #[test]
    fn seed_c_regresses_against_the_reference_sensor() {
        let n = 600;
        let (mut t, mut a, mut b, mut r, mut y) = (vec![], vec![], vec![], vec![], vec![]);
        for i in 0..n {
            let x = i as f64;
            let (ta, tb, tr) = (
                22.0 + 3.0 * (x / 90.0).sin(),
                21.0 + 0.01 * x,
                20.0 + 1.5 * (x / 200.0).cos(),
            );
            t.push(60.0 * x);
            a.push(ta);
            b.push(tb);
            r.push(tr);
            y.push(2.0 * (ta - tr) + 0.5 * (tb - tr) + 1.0);
        }
        let ds = Dataset {
            input_names: vec!["t1_c".into(), "t2_c".into(), "t3_c".into()],
            input_kinds: vec![InputKind::Temperature; 3],
            target_names: vec!["dz_um".into()],
            runs: vec![Run {
                name: "r".into(),
                time_s: t,
                inputs: vec![a, b, r],
                targets: vec![y],
            }],
        };
        let settings = Settings {
            families: vec![Family::SeedC],
            ridges: vec![0.0],
            reference: Some(2),
            ..Settings::default()
        };
        let cand = candidates(&ds, &settings.taus).unwrap();
        let rows: Rows = (0..n).map(|i| (0, i)).collect();
        let trained = train(&ds, &cand, &rows, &settings).unwrap();
        assert_eq!(trained.choices[0].family, Family::SeedC);
        let m = &trained.model;
        let names: Vec<String> = m
            .bank()
            .features()
            .iter()
            .map(|f| f.name(|i| &ds.input_names[trained.inputs[i]]))
            .collect();
        let coef = |name: &str| m.coefficients()[names.iter().position(|x| x == name).unwrap()];
        assert!((coef("rise(t1_c)") - 2.0).abs() < 1e-9);
        assert!((coef("rise(t2_c)") - 0.5).abs() < 1e-9);
        assert!((coef("rise(t3_c)") + 2.5).abs() < 1e-9);
        // Nothing but rises: seed C's form has no dynamics.
        for (name, c) in names.iter().zip(m.coefficients()) {
            assert!(name.starts_with("rise(") || *c == 0.0, "{name}: {c}");
        }
        // Without a reference the family is no candidate at all.
        let none = Settings {
            reference: None,
            ..settings
        };
        assert!(train(&ds, &cand, &rows, &none).is_err());
    }

    #[test]
    fn sensor_selection_keeps_the_informative_sensor() {
        let ds = twin_like();
        let settings = Settings {
            max_sensors: Some(1),
            families: vec![Family::Static, Family::Operating],
            ..Settings::default()
        };
        let cand = candidates(&ds, &settings.taus).unwrap();
        let rows: Rows = (0..ds.runs[0].len()).map(|i| (0, i)).collect();
        let trained = train(&ds, &cand, &rows, &settings).unwrap();
        // t1 carries the thermal growth, including the room's drift that no lag of the spindle
        // speed can explain; t2 is an unrelated wobble.
        assert_eq!(trained.sensors, vec![0]);
        assert!(trained.inputs.contains(&0) && !trained.inputs.contains(&1));
    }

    /// Rolling origin never trains on the block it scores, nor on any later one. Data exactly
    /// y = 2·rise(t1) except the last of 8 blocks of 100 rows, which carries +5 µm more.
    /// Rolling: blocks 2…6 are predicted by fits on clean blocks, error 0; block 7 by a fit on
    /// blocks 0…6 (clean, so y = 2·rise exactly), error 5 on each of its 100 rows; over the
    /// 600 held-out rows RMSE = √(100·25 / 600) = 5/√6 = 2.0412 µm. Blocked: every fold but
    /// the last trains on the offset rows, so its error is not 0 and the figure differs.
    #[test]
    fn rolling_origin_scores_each_block_by_the_past_only() {
        let n = 800;
        let (mut t, mut temp, mut y) = (vec![], vec![], vec![]);
        for i in 0..n {
            let rise = (i as f64 / 7.0).sin();
            t.push(60.0 * i as f64);
            temp.push(20.0 + rise);
            y.push(2.0 * rise + if i >= 700 { 5.0 } else { 0.0 });
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
        let cand = candidates(&ds, &TimeConstants::default()).unwrap();
        let rows: Rows = (0..n).map(|i| (0, i)).collect();
        let score = |inner| {
            let p = Problem::new(&ds, &cand, &rows, 8, inner, false);
            let d = p.design(Family::Static, &[0], None).unwrap();
            p.cv(&d, &[0.0])[0][0].0
        };
        let rolling = score(InnerCv::Rolling);
        assert!((rolling - 5.0 / 6f64.sqrt()).abs() < 1e-9, "{rolling}");
        let blocked = score(InnerCv::Blocked);
        assert!((blocked - rolling).abs() > 0.1, "{blocked}");
    }
}
