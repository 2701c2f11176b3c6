//! Training: choose family, sensors and ridge by cross-validation inside the training rows only,
//! then fit and export a [`DynamicModel`].
//!
//! The training rows (in time order, run after run) are cut into k contiguous blocks; each block
//! is predicted by a model fitted on the rows outside it and outside a gap around it
//! ([`crate::inner_cv`]): contiguous blocks keep neighbouring, nearly identical samples on the same
//! side, which a random split would not, and the gap keeps the rows that share the block's
//! thermal excursion out of its fit. [`InnerCv::Rolling`](crate::settings::InnerCv::Rolling)
//! is the forecaster's variant (rolling origin): each block from the third on is predicted from
//! the rows before it only. Every
//! family's out-of-fold predictions are then combined ([`crate::selection`]).

#![allow(clippy::needless_range_loop)] // index loops mirror the matrix formulas

use truepos_model::{DynamicModel, FeatureBank, FeatureKind};

use crate::dataset::{Dataset, InputKind};
use crate::features::{bank_for, Candidates, Extended, Family};
use crate::problem::{Design, Problem};
use crate::selection::{fit_all, select, Member, Paired, Pick, BASELINE_RIDGE};
use crate::settings::Settings;
use crate::transfer::TransferTaus;

/// What was chosen for one target.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Choice {
    /// Target name.
    pub target: String,
    /// The heaviest member's family; `None` when no compensation was chosen (empty blend).
    pub family: Option<Family>,
    /// The heaviest member's ridge parameter (0 with no compensation).
    pub ridge: f64,
    /// Inner estimate of the choice's error (µm): the blend as chosen, evaluated forward in
    /// time — each late inner block predicted by the members refitted on the rows before it,
    /// beyond the gap (the `forward` module; docs/fitting.md).
    pub cv_rmse_um: f64,
    /// The blend written: members with their weights (empty: no compensation). `family` and
    /// `ridge` above are its heaviest member's.
    #[serde(default)]
    pub blend: Vec<Member>,
    /// Inner estimate of no compensation's error (µm), on the same rows.
    #[serde(default)]
    pub uncompensated_cv_rmse_um: f64,
    /// The blocked inner-validation RMSE the choice was made by (µm): what other forms fitted on
    /// the same blocked folds (the position-dependent ones in `machine_fit`) are compared with.
    #[serde(default)]
    pub selection_cv_rmse_um: f64,
    /// Why nothing is compensated, if so.
    #[serde(default)]
    pub fallback: Option<String>,
    /// The baseline's inner estimate (µm), evaluated as `cv_rmse_um` is: what the simple
    /// reference model would have scored.
    #[serde(default)]
    pub baseline_cv_rmse_um: Option<f64>,
    /// The paired comparison that decided between the baseline and the best richer family.
    #[serde(default)]
    pub paired: Option<Paired>,
}

impl Choice {
    /// Short: the family, the members' families joined by `+` for a blend, or `no compensation`.
    pub fn label(&self) -> String {
        if self.blend.is_empty() {
            return "no compensation".into();
        }
        let names: Vec<&str> = self.blend.iter().map(|m| m.family.name()).collect();
        names.join("+")
    }

    /// In words: `dynamic-running τ… λ=3e-2`, or `no compensation`.
    pub fn describe(&self) -> String {
        if self.blend.is_empty() {
            return "no compensation".into();
        }
        let parts: Vec<String> = self
            .blend
            .iter()
            .map(|m| {
                let tau = match (m.tau_s, m.tau2_s) {
                    (Some(t), Some(t2)) => format!(" τ={t:.0}/{t2:.0} s"),
                    (Some(t), None) => format!(" τ={t:.0} s"),
                    _ => String::new(),
                };
                if self.blend.len() == 1 {
                    format!("{}{tau} λ={:e}", m.family.name(), m.ridge)
                } else {
                    format!("{} {:.2}{tau} λ={:e}", m.family.name(), m.weight, m.ridge)
                }
            })
            .collect();
        parts.join(" + ")
    }
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
    /// The baseline fitted on the same rows, to be judged beside the choice on held-out data
    /// (`None` when it cannot be built).
    pub baseline: Option<Box<Exported>>,
}

/// A model exported from the candidate features: the real-time model and the dataset input
/// index of each of its inputs.
#[derive(Debug, Clone)]
pub struct Exported {
    /// The real-time model.
    pub model: DynamicModel,
    /// Dataset input index of each model input.
    pub inputs: Vec<usize>,
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

/// Chooses by inner CV on `rows` (training rows only; blocked or rolling origin, see
/// [`InnerCv`](crate::settings::InnerCv)) and fits on all of them.
pub fn train(
    dataset: &Dataset,
    cand: &Candidates,
    rows: &[(usize, usize)],
    settings: &Settings,
) -> Result<Trained, String> {
    // Every factorisation after the segment pass is of a few hundred columns at most: faer's
    // thread pool costs more than it saves there, and the segments already use every core.
    // Restored on the way out, so that the caller's own large solves keep their threads.
    let _sequential = Sequential::new();
    if rows.len() < 4 * settings.folds.max(2) {
        return Err(format!(
            "only {} training samples: too few for {}-fold cross-validation",
            rows.len(),
            settings.folds
        ));
    }
    // The transfer families' τ, identified on the training rows only, join the bank.
    let transfer = TransferTaus::identify(dataset, rows, settings);
    let mut taus = settings.taus.clone();
    let added: Vec<f64> = transfer
        .all()
        .into_iter()
        .filter(|tau| !taus.temperature_s.contains(tau))
        .collect();
    taus.temperature_s.extend_from_slice(&added);
    let ext = Extended::new(dataset, cand, &added).map_err(|e| e.to_string())?;
    let cand = &ext.meta;
    let p = Problem::new(dataset, &ext, rows, settings, transfer)?;
    let all_sensors: Vec<usize> = (0..cand.spec.temperatures).collect();
    let mut sensors = match settings.max_sensors {
        Some(max) if max < all_sensors.len() => {
            stable_sensors(dataset, &ext, rows, settings, transfer, max)?
        }
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
            "no candidate family can be built: the family reference needs a reference sensor (--reference)"
                .into(),
        );
    }
    let (mut picks, scores) = select(&p, settings, &sensors);
    let blocked: Vec<f64> = picks.iter().map(|p| p.cv_rmse_um).collect();
    let mut baseline_picks = baseline_picks(&picks);
    report_forward(&p, &mut picks, &sensors, reference);
    report_forward(&p, &mut baseline_picks, &sensors, reference);
    let Blended {
        coef,
        intercepts,
        warnings,
        mut choices,
    } = blend(dataset, &p, &picks, &sensors, reference)?;
    for ((c, b), base) in choices.iter_mut().zip(blocked).zip(&baseline_picks) {
        c.selection_cv_rmse_um = b;
        c.baseline_cv_rmse_um = (!base.members.is_empty()).then_some(base.cv_rmse_um);
    }
    let exported = export(dataset, &ext, &taus, &sensors, &coef, intercepts)?;
    let baseline = if baseline_picks.iter().all(|b| b.members.is_empty()) {
        None
    } else {
        let b = blend(dataset, &p, &baseline_picks, &sensors, None)?;
        Some(Box::new(export(
            dataset,
            &ext,
            &taus,
            &sensors,
            &b.coef,
            b.intercepts,
        )?))
    };
    Ok(Trained {
        model: exported.model,
        inputs: exported.inputs,
        sensors: sensors.iter().map(|&s| cand.bank_inputs[s]).collect(),
        choices,
        warnings,
        scores,
        baseline,
    })
}

/// Per target, the baseline alone as a pick (no member where it could not be built).
fn baseline_picks(picks: &[Pick]) -> Vec<Pick> {
    picks
        .iter()
        .map(|p| Pick {
            members: p
                .baseline_cv_rmse_um
                .map(|rmse| Member {
                    family: Family::Baseline,
                    ridge: BASELINE_RIDGE,
                    weight: 1.0,
                    cv_rmse_um: rmse,
                    tau_s: None,
                    tau2_s: None,
                })
                .into_iter()
                .collect(),
            cv_rmse_um: p.baseline_cv_rmse_um.unwrap_or(p.uncompensated_um),
            uncompensated_um: p.uncompensated_um,
            baseline_cv_rmse_um: p.baseline_cv_rmse_um,
            paired: None,
            fallback: None,
        })
        .collect()
}

/// The real-time model of per-target coefficients over the candidate features: its inputs are
/// the chosen sensors, plus the operating inputs if any target reads them.
fn export(
    dataset: &Dataset,
    ext: &Extended<'_>,
    taus: &crate::features::TimeConstants,
    sensors: &[usize],
    coef: &[Vec<f64>],
    intercepts: Vec<f64>,
) -> Result<Exported, String> {
    let cand = &ext.meta;
    let nf = cand.features.len();
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
    let (spec, order) = bank_for(dataset, &inputs, taus, uses_running);
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
    for c in coef {
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
    Ok(Exported {
        model,
        inputs: order,
    })
}

/// The inner estimate reported for each pick is its forward evaluation ([`crate::forward`]):
/// the blocked score chose it, the forward one says what to expect on later data or another
/// run (on the twin population the blocked figure was 0.42 × the test error on the median, the
/// forward one 0.91). Without a forward fold the blocked figure stays.
fn report_forward(
    p: &Problem<'_>,
    picks: &mut [crate::selection::Pick],
    sensors: &[usize],
    reference: Option<usize>,
) {
    let Some(fwd) = crate::forward::evaluate(p, picks, sensors, reference) else {
        return;
    };
    for (k, pick) in picks.iter_mut().enumerate() {
        (pick.cv_rmse_um, pick.uncompensated_um) = fwd[k];
    }
}

/// faer's global parallelism set to sequential while it lives, the caller's restored after.
struct Sequential(faer::Par);

impl Sequential {
    fn new() -> Self {
        let before = faer::get_global_parallelism();
        faer::set_global_parallelism(faer::Par::Seq);
        Self(before)
    }
}

impl Drop for Sequential {
    fn drop(&mut self) {
        faer::set_global_parallelism(self.0);
    }
}

/// The blends fitted: per target, coefficients over the candidate features and an intercept.
struct Blended {
    coef: Vec<Vec<f64>>,
    intercepts: Vec<f64>,
    warnings: Vec<String>,
    choices: Vec<Choice>,
}

/// Fits every member of every target's blend on all training rows (each family and ridge once)
/// and sums them with their weights; a fallback becomes a warning naming the target.
fn blend(
    dataset: &Dataset,
    p: &Problem<'_>,
    picks: &[crate::selection::Pick],
    sensors: &[usize],
    reference: Option<usize>,
) -> Result<Blended, String> {
    let cand = p.cand;
    let nt = picks.len();
    let nf = cand.features.len();
    let mut coef = vec![vec![0.0; nf]; nt];
    let mut intercepts = vec![0.0; nt];
    let mut warnings = Vec::new();
    let mut choices = Vec::new();
    let mut fitted: Vec<(Family, f64, Design, crate::least_squares::Solution)> = Vec::new();
    for k in 0..nt {
        let pick = &picks[k];
        for m in &pick.members {
            let at = match fitted
                .iter()
                .position(|f| f.0 == m.family && f.1 == m.ridge)
            {
                Some(at) => at,
                None => {
                    let design = p
                        .design(m.family, sensors, reference)
                        .ok_or("internal: the chosen family has no design")?;
                    let sol = fit_all(p, &design, m.ridge)?;
                    fitted.push((m.family, m.ridge, design, sol));
                    fitted.len() - 1
                }
            };
            let (_, _, design, sol) = &fitted[at];
            let names: Vec<String> = std::iter::once("intercept".to_string())
                .chain(design.cols.iter().map(|&c| match design.minus {
                    Some(r) => format!("{} − {}", cand.names[c], cand.names[r]),
                    None => cand.names[c].clone(),
                }))
                .collect();
            for d in &sol.rank_deficiencies {
                let w = format!("{}: {}", dataset.target_names[k], d.describe(&names));
                if !warnings.contains(&w) {
                    warnings.push(w);
                }
            }
            let c = &sol.coefficients[k];
            let mut b0 = c[0];
            for (cj, &col) in c[1..].iter().zip(&design.cols) {
                coef[k][col] += m.weight * cj;
                b0 -= cj * p.means[col];
                // k·(x_i − x_r) = k·x_i − k·x_r: the reference's rise carries −Σk.
                if let Some(r) = design.minus {
                    coef[k][r] -= m.weight * cj;
                    b0 += cj * p.means[r];
                }
            }
            intercepts[k] += m.weight * b0;
        }
        if let Some(why) = &pick.fallback {
            warnings.push(format!("{}: {why}", dataset.target_names[k]));
        }
        let head = pick
            .members
            .iter()
            .max_by(|a, b| a.weight.total_cmp(&b.weight))
            .copied();
        choices.push(Choice {
            target: dataset.target_names[k].clone(),
            family: head.map(|m| m.family),
            ridge: head.map_or(0.0, |m| m.ridge),
            cv_rmse_um: pick.cv_rmse_um,
            blend: pick.members.clone(),
            uncompensated_cv_rmse_um: pick.uncompensated_um,
            selection_cv_rmse_um: pick.cv_rmse_um,
            fallback: pick.fallback.clone(),
            baseline_cv_rmse_um: pick.baseline_cv_rmse_um,
            paired: pick.paired,
        });
    }
    Ok(Blended {
        coef,
        intercepts,
        warnings,
        choices,
    })
}

/// The bank index of the reference sensor, if one is set and is a temperature input.
fn reference_input(p: &Problem<'_>, settings: &Settings) -> Option<usize> {
    p.reference(settings)
}

/// Sub-samples of the stability selection.
const STABILITY_DRAWS: usize = 4;

/// Stability selection (Meinshausen & Bühlmann, *J. R. Stat. Soc. B* 72, 2010): the greedy search
/// runs on [`STABILITY_DRAWS`] sub-samples — the training rows without one contiguous share of
/// them — and the sensors chosen in at least half of them are kept (most often chosen first, at
/// most `max`). A sensor that one stretch of data happens to favour does not make it, so the set
/// changes less from one outer fold to the next than a single greedy search's.
fn stable_sensors(
    dataset: &Dataset,
    cand: &Extended<'_>,
    rows: &[(usize, usize)],
    settings: &Settings,
    transfer: TransferTaus,
    max: usize,
) -> Result<Vec<usize>, String> {
    let mut count = vec![0usize; cand.meta.spec.temperatures];
    for d in 0..STABILITY_DRAWS {
        let sub: Vec<(usize, usize)> = rows
            .iter()
            .enumerate()
            .filter(|(i, _)| i * STABILITY_DRAWS / rows.len() != d)
            .map(|(_, r)| *r)
            .collect();
        let p = Problem::new(dataset, cand, &sub, settings, transfer)?;
        for s in greedy_sensors(&p, settings, max) {
            count[s] += 1;
        }
    }
    let mut kept: Vec<usize> = (0..count.len())
        .filter(|&s| 2 * count[s] >= STABILITY_DRAWS)
        .collect();
    kept.sort_by(|a, b| count[*b].cmp(&count[*a]).then(a.cmp(b)));
    kept.truncate(max);
    if kept.is_empty() {
        let p = Problem::new(dataset, cand, rows, settings, transfer)?;
        return Ok(greedy_sensors(&p, settings, max));
    }
    kept.sort_unstable();
    Ok(kept)
}

/// Correlation ranking, then greedy forward selection by CV score (mean over targets of the
/// CV RMSE relative to the target's spread), among the best-ranked candidates.
fn greedy_sensors(p: &Problem<'_>, settings: &Settings, max: usize) -> Vec<usize> {
    let nt = p.nt;
    let temps = p.cand.spec.temperatures;
    let rise_col = |s: usize| {
        (0..p.cand.features.len()).find(|&j| {
            p.cand.features[j].input == s && p.cand.features[j].kind == FeatureKind::Rise
        })
    };
    let nf = p.cand.features.len();
    let n = p.n.max(1) as f64;
    // From the Gram matrix of [1 | x − mean | y]: the columns x are centred, so Σx·(y − ȳ) = Σx·y.
    let spread: Vec<f64> = (0..nt)
        .map(|k| {
            let (sy, syy) = (p.gram(0, 1 + nf + k), p.gram(1 + nf + k, 1 + nf + k));
            ((syy - sy * sy / n).max(0.0) / n).sqrt().max(1e-12)
        })
        .collect();
    // |Pearson correlation| of each sensor's rise with each target, averaged over targets.
    let mut ranked: Vec<(f64, usize)> = (0..temps)
        .filter_map(|s| {
            let j = rise_col(s)?;
            let sx = p.gram(1 + j, 1 + j).max(0.0).sqrt();
            let r = (0..nt)
                .map(|k| {
                    let sxy = p.gram(1 + j, 1 + nf + k);
                    let sy = spread[k] * n.sqrt();
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
        select(p, settings, sensors)
            .0
            .iter()
            .zip(&spread)
            .map(|(b, s)| b.cv_rmse_um / s)
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
    use crate::inner_cv::{Folds, Row};
    use crate::settings::InnerCv;
    use crate::validate::predict;

    /// Three runs of a machine whose growth lags the spindle and one of two sensors.
    fn twin_like() -> Dataset {
        let mut runs = Vec::new();
        for (r, level) in [(0, 3000.0), (1, 4500.0), (2, 3750.0)] {
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
        // The second-order transfer family: both identified time constants join the bank.
        offline_equals_online(Settings {
            families: vec![Family::Transfer2],
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
        // Offline: intercept + Σ coefficient · candidate feature column of the same name (the
        // candidates at the model's own time constants: the transfer family adds its τ).
        let model = &trained.model;
        let taus = TimeConstants {
            temperature_s: model.bank().spec().temperature_taus_s.clone(),
            ..settings.taus.clone()
        };
        let cand = candidates(&ds, &taus).unwrap();
        let n = model.bank().features().len();
        let names: Vec<String> = model
            .bank()
            .features()
            .iter()
            .map(|f| f.name(|i| &ds.input_names[trained.inputs[i]]))
            .collect();
        let ext = Extended::new(&ds, &cand, &[]).unwrap();
        let mut cursor = ext.cursor().unwrap();
        let mut nonzero = 0;
        for (r, run) in ds.runs.iter().enumerate() {
            for i in 0..run.len() {
                let values = cursor.at(r, i).unwrap().to_vec();
                let mut p = model.intercepts()[0];
                for (j, name) in names.iter().enumerate() {
                    let c = model.coefficients()[j];
                    if c != 0.0 {
                        nonzero += 1;
                    }
                    let col = cand.names.iter().position(|x| x == name).unwrap();
                    p += c * values[col];
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
        // And the model is good: the data are exactly representable by lags of the inputs, the
        // spindle's among them (so only for families that read it).
        let operating = FeatureKind::Operating { tau_s: 1.0 };
        if !settings.families.iter().any(|f| f.includes(operating)) {
            return;
        }
        let rel = ds.runs[1].relative_target(0);
        let rms = (rel
            .iter()
            .zip(&online[1][0])
            .map(|(a, b)| (a - b).powi(2))
            .sum::<f64>()
            / rel.len() as f64)
            .sqrt();
        assert!(rms < 0.5, "{rms} {:?}", trained.choices);
    }

    /// The reference-sensor regression Y = Σ k_i·(t_i − t_r) + c. Data made exactly so, with
    /// k = (2, 0.5) against a drifting reference t3 and c = 1 µm (relative targets remove c, the
    /// model's intercept puts the start value back): the fit recovers k, and the reference's rise
    /// carries −(2 + 0.5) = −2.5.
    #[test]
    fn the_reference_sensor_regression_recovers_its_coefficients() {
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
            families: vec![Family::Reference],
            ridges: vec![0.0],
            reference: Some(2),
            ..Settings::default()
        };
        let cand = candidates(&ds, &settings.taus).unwrap();
        let rows: Rows = (0..n).map(|i| (0, i)).collect();
        let trained = train(&ds, &cand, &rows, &settings).unwrap();
        assert_eq!(trained.choices[0].family, Some(Family::Reference));
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
        // Nothing but rises: the reference-sensor regression has no dynamics.
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

    /// Three runs whose errors contradict each other (c moves −1 µm/K where a and b move
    /// +2): whole runs held out in the inner validation show that no family predicts a run from
    /// the others, and the automatic selection writes no compensation, saying why (and names no
    /// family for it: `family` is null in `--json`); the same
    /// data with the static family named alone is fitted as asked.
    #[test]
    fn contradicting_runs_get_no_compensation_from_the_automatic_selection() {
        let ds = crate::validate::tests::three_runs();
        let cand = candidates(&ds, &TimeConstants::default()).unwrap();
        let rows: Rows = (0..ds.runs.len())
            .flat_map(|r| (0..ds.runs[r].len()).map(move |i| (r, i)))
            .collect();
        let trained = train(&ds, &cand, &rows, &Settings::default()).unwrap();
        let c = &trained.choices[0];
        assert!(c.blend.is_empty(), "{c:?}");
        assert_eq!((c.family, c.label().as_str()), (None, "no compensation"));
        assert_eq!(
            serde_json::to_value(c).unwrap()["family"],
            serde_json::Value::Null
        );
        assert!(c
            .fallback
            .as_deref()
            .unwrap()
            .starts_with("no compensation"));
        assert!(trained.model.coefficients().iter().all(|v| *v == 0.0));
        assert!(trained
            .warnings
            .iter()
            .any(|w| w.starts_with("dz_um: no compensation")));
        let named = crate::validate::tests::static_settings();
        let trained = train(&ds, &cand, &rows, &named).unwrap();
        assert_eq!(trained.choices[0].blend.len(), 1);
        assert_eq!(trained.choices[0].fallback, None);
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
        let ds = crate::dataset::one_sensor(t, temp, y);
        let cand = candidates(&ds, &TimeConstants::default()).unwrap();
        let rows: Rows = (0..n).map(|i| (0, i)).collect();
        let score = |inner| {
            let settings = Settings {
                inner,
                ..Settings::default()
            };
            let ext = Extended::new(&ds, &cand, &[]).unwrap();
            let at: Vec<Row> = rows
                .iter()
                .map(|&(run, row)| Row {
                    run,
                    time_s: ds.runs[run].time_s[row],
                })
                .collect();
            let folds = Folds::new(&at, 8, inner, 0.0);
            let p = Problem::build(
                &ds,
                &ext,
                &rows,
                &settings,
                TransferTaus::default(),
                Some(folds),
            )
            .unwrap();
            let d = p.design(Family::Static, &[0], None).unwrap();
            crate::selection::cv(&p, &d, &[0.0]).scores[0][0].0
        };
        let rolling = score(InnerCv::Rolling);
        assert!((rolling - 5.0 / 6f64.sqrt()).abs() < 1e-9, "{rolling}");
        let blocked = score(InnerCv::Blocked);
        assert!((blocked - rolling).abs() > 0.1, "{blocked}");
    }
}
