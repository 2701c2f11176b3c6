//! Every model family of a machine in one selection: the dynamic families over the dataset's
//! columns ([`crate::train`]) and, next to them, the position-dependent families and the
//! reference-sensor regression ([`crate::position_model`]) over the machine's temperature
//! channels, differences, lags and axis positions — each scored by the same inner
//! cross-validation inside the training rows (the same contiguous blocks, blocked or rolling,
//! the same ridge candidates and rule), and validated by the same outer protocol
//! ([`crate::validate::Split`]). The chosen model is of one form: a fitted dynamic model, or a
//! position-dependent [`Model`] for the model file `truepos_io::model_file::position` writes.
//!
//! Within the position-dependent form each target axis gets its own family, input set and ridge (an
//! axis' summands never touch another axis' coefficients, so the choices are independent and one
//! [`Model`] holds them all). The form is chosen by the pooled inner-CV RMSE over the targets.

use truepos_files::InputError;
use truepos_io::run::RunTable;
use truepos_io::units::{find_channel, Role};
use truepos_model::{CycleInput, LagSource, Machine, Model, Part, RecordedRun, Reference};

use crate::dataset::Dataset;
use crate::features::Candidates;
use crate::out_of_fold::{cross_validate, Procedure};
use crate::position_model::{
    fit_blocks, input_sets, CvOptions, Fitted, InputSet, Observation, PositionDesign, Shape,
};
use crate::settings::{InnerCv, Settings};
use crate::train::{train, Trained};
use crate::validate::{
    per_run, predict, worse_than_uncompensated, Metrics, Predictions, Split, Validation,
};

/// The runs of a [`Dataset`] as the machine sees them, and which axis each target is the error
/// of.
#[derive(Debug, Clone)]
pub struct MachineData {
    /// The machine.
    pub machine: Machine,
    /// One per run of the dataset, row for row.
    pub runs: Vec<RecordedRun>,
    /// Per dataset target, the machine axis whose error it is.
    pub target_axes: Vec<usize>,
    /// The reference sensor of the reference-sensor regression
    /// ([`crate::position_model::reference_sensor`] or a given one).
    pub reference: Option<usize>,
    /// The machine's differences every run holds the channels of.
    pub differences: Vec<usize>,
    /// Per machine difference, the axis whose part it measures, if known (the own-axis
    /// and serial families need it; without any, those families are no candidates).
    pub owners: Vec<Option<usize>>,
}

/// Axis `a`'s positions from column `name` of `t`, in mm (or degrees), converted by the unit the
/// column states. Without `--positions` the machine's own column is found by the axis name and
/// any unit (`X_mm`, `X [mm]`, `X (in)`).
fn position_column(
    machine: &Machine,
    t: &RunTable,
    a: usize,
    name: &str,
    given: bool,
) -> Result<Vec<f64>, InputError> {
    let axis = &machine.axes[a];
    let role = match axis.kind {
        truepos_model::AxisKind::Linear => Role::Position,
        truepos_model::AxisKind::Rotary => Role::Angle,
    };
    let found = (!given)
        .then(|| find_channel(&t.columns, name).or_else(|| find_channel(&t.columns, &axis.name)))
        .flatten();
    let col = match found {
        Some(c) => c,
        None => t.select(&[name])?[0],
    };
    t.numbers_as(col, role)
}

impl MachineData {
    /// The machine's channels of every table (the dataset's runs, in order): its measured
    /// temperature channels and operating channels by id, the lagged channels computed from
    /// them (`truepos_io::cycles`), and the positions from `positions` (one column per axis,
    /// e.g. a probe's coordinates) or else the machine's own position columns (`X_mm`, …).
    /// A channel a table lacks reads NaN, and the differences that read it are left out.
    pub fn from_tables(
        machine: &Machine,
        tables: &[RunTable],
        dataset: &Dataset,
        positions: Option<&[String]>,
        target_axes: Vec<usize>,
        reference: Option<usize>,
    ) -> Result<Self, InputError> {
        let position_names: Vec<String> = match positions {
            Some(p) => p.to_vec(),
            None => machine.axes.iter().map(|a| a.position_column()).collect(),
        };
        let measured: Vec<usize> = (0..machine.temperatures.len())
            .filter(|&c| machine.temperatures[c].lag.is_none())
            .collect();
        let ids: Vec<String> = measured
            .iter()
            .map(|&c| machine.temperatures[c].id.clone())
            .collect();
        let mut present_t = vec![true; machine.temperatures.len()];
        let mut present_o = vec![true; machine.operating.len()];
        let mut runs = Vec::new();
        for (t, run) in tables.iter().zip(&dataset.runs) {
            // A channel's column by its id with or without a unit (`t1`, `t1 [°F]`);
            // temperatures in °C, operating state as written.
            let read = |name: &str, role: Option<Role>, present: &mut bool| match find_channel(
                &t.columns, name,
            ) {
                Some(c) => match role {
                    Some(role) => t.numbers_as(c, role),
                    None => t.numbers(c),
                },
                None => {
                    *present = false;
                    Ok(vec![f64::NAN; t.rows()])
                }
            };
            let mut pos_cols = Vec::new();
            for (a, name) in position_names.iter().enumerate() {
                pos_cols.push(position_column(machine, t, a, name, positions.is_some())?);
            }
            let mut temp_cols = Vec::new();
            for &c in &measured {
                temp_cols.push(read(
                    &machine.temperatures[c].id,
                    Some(Role::Temperature),
                    &mut present_t[c],
                )?);
            }
            let mut op_cols = Vec::new();
            for (o, present) in machine.operating.iter().zip(present_o.iter_mut()) {
                op_cols.push(read(&o.id, None, present)?);
            }
            let rows = t.rows();
            let by_row = |cols: &[Vec<f64>]| -> Vec<Vec<f64>> {
                (0..rows)
                    .map(|i| cols.iter().map(|c| c[i]).collect())
                    .collect()
            };
            let operating = by_row(&op_cols);
            let temp_rows = by_row(&temp_cols);
            let temperatures_c = truepos_io::cycles::machine_temperatures(
                machine,
                &ids,
                &run.time_s,
                temp_rows.iter().map(Vec::as_slice),
                &operating,
            );
            runs.push(RecordedRun {
                time_s: run.time_s.clone(),
                temperatures_c,
                positions: by_row(&pos_cols),
                operating,
            });
        }
        // A lagged channel is there when its source is.
        for c in 0..machine.temperatures.len() {
            if let Some(lag) = machine.temperatures[c].lag {
                present_t[c] = match lag.source {
                    LagSource::Temperature(s) => present_t[s],
                    LagSource::Operating { channel, .. } => present_o[channel],
                };
            }
        }
        let differences = (0..machine.differences.len())
            .filter(|&d| {
                let diff = &machine.differences[d];
                present_t[diff.plus]
                    && match diff.minus {
                        Reference::Sensor(m) => present_t[m],
                        Reference::Fixed(_) => true,
                    }
            })
            .collect();
        Ok(Self {
            machine: machine.clone(),
            runs,
            target_axes,
            reference,
            differences,
            owners: Vec::new(),
        })
    }

    fn input(&self, r: usize, i: usize) -> CycleInput<'_> {
        let run = &self.runs[r];
        CycleInput {
            temperatures_c: &run.temperatures_c[i],
            positions: &run.positions[i],
            operating: &run.operating[i],
        }
    }
}

/// The inner-CV figure of one candidate for one target.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct TargetScore {
    /// The target.
    pub target: String,
    /// Inner-CV RMSE, µm (of the ridge chosen for a position-dependent candidate; the lowest over
    /// the ridges for a dynamic family).
    pub cv_rmse_um: f64,
    /// That ridge.
    pub ridge: f64,
}

/// One candidate of the selection and its inner-CV figures.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct CandidateFigures {
    /// `dynamic` or `position-dependent`.
    pub form: &'static str,
    /// The family's name on the command line.
    pub family: String,
    /// The inputs it read.
    pub inputs: String,
    /// Per target.
    pub targets: Vec<TargetScore>,
}

/// A position-dependent model and what was chosen for each target.
#[derive(Debug, Clone)]
pub struct StaticModel {
    /// The model, every target axis' summands in it.
    pub model: Model,
    /// Per target, what was chosen.
    pub choices: Vec<PositionChoice>,
}

/// What the selection chose for one target of a position model.
#[derive(Debug, Clone)]
pub struct PositionChoice {
    /// The family's name on the command line ([`PositionDesign::key`]).
    pub family: &'static str,
    /// Its name in reports ([`PositionDesign::name`]).
    pub family_name: &'static str,
    /// The input set's label.
    pub inputs: &'static str,
    /// The fitted candidate.
    pub fitted: Fitted,
}

/// The model the selection chose: one form.
#[derive(Debug, Clone)]
pub enum Chosen {
    /// A fitted filtered (dynamic) model: its filters carry history from cycle to cycle.
    Filtered(Trained),
    /// A position-dependent or reference-sensor model: a function of this cycle's values.
    Position(StaticModel),
}

/// The selection on one training part.
#[derive(Debug, Clone)]
pub struct Selection {
    /// The model.
    pub chosen: Chosen,
    /// Every candidate with its inner-CV figures.
    pub candidates: Vec<CandidateFigures>,
    /// Per target, what was chosen, in words (`all-axes-squared on + lagged sensors, λ=1e-3`).
    pub labels: Vec<String>,
    /// Per target, the inner-CV RMSE of what was chosen, µm.
    pub cv_rmse_um: Vec<f64>,
    /// Solver warnings.
    pub warnings: Vec<String>,
}

/// The contiguous blocks of the inner CV over `rows`, as `train` cuts them.
fn blocks(rows: &[(usize, usize)], folds: usize, inner: InnerCv) -> Vec<&[(usize, usize)]> {
    let min = inner.min_blocks();
    let k = folds.clamp(min, rows.len().max(min));
    (0..k)
        .map(|b| &rows[b * rows.len() / k..(b + 1) * rows.len() / k])
        .collect()
}

fn pooled(scores: &[f64]) -> f64 {
    (scores.iter().map(|s| s * s).sum::<f64>() / scores.len().max(1) as f64).sqrt()
}

/// The position-dependent candidates on `rows`: every family on every input set, per target; the
/// best per target, assembled into one model. `None` when no candidate can be fitted.
fn static_selection(
    ds: &Dataset,
    data: &MachineData,
    targets: &[Vec<Vec<f64>>],
    rows: &[(usize, usize)],
    settings: &Settings,
    families: &[&dyn PositionDesign],
    candidates: &mut Vec<CandidateFigures>,
) -> Result<Option<StaticModel>, String> {
    let machine = &data.machine;
    let nt = ds.target_names.len();
    let blocks = blocks(rows, settings.folds, settings.inner);
    let options = CvOptions {
        inner: settings.inner,
        ridges: &settings.position_ridges,
        rule: settings.position_rule,
    };
    let sets = usable_input_sets(data);
    let mut best: Vec<Option<PositionChoice>> = vec![None; nt];
    for &family in families {
        let owned = data.owners.iter().any(Option::is_some);
        if family.needs_owners() && !owned {
            continue;
        }
        let mut seen: Vec<Vec<usize>> = Vec::new();
        for set in &sets {
            let diffs = family.differences(machine, &set.differences, data.reference);
            // The reference-sensor regression reads only sensor-minus-reference differences: two
            // input sets can leave it the same, and an empty one is no candidate.
            if diffs.is_empty() || seen.contains(&diffs) {
                continue;
            }
            seen.push(diffs.clone());
            let mut scores = Vec::new();
            for (k, best_k) in best.iter_mut().enumerate() {
                let axis = data.target_axes[k];
                let shape = Shape {
                    name: "fit",
                    machine,
                    differences: &diffs,
                    targets: &[axis],
                    constant: true,
                    owners: &data.owners,
                };
                let s = family.structure(&shape).map_err(|e| e.to_string())?;
                let obs = observations(data, &blocks, targets, k);
                let Ok(fitted) = fit_blocks(&s, machine, &obs, &options) else {
                    continue;
                };
                scores.push(TargetScore {
                    target: ds.target_names[k].clone(),
                    cv_rmse_um: fitted.score_um,
                    ridge: fitted.ridge,
                });
                if best_k
                    .as_ref()
                    .is_none_or(|b| fitted.score_um < b.fitted.score_um)
                {
                    *best_k = Some(PositionChoice {
                        family: family.key(),
                        family_name: family.name(),
                        inputs: set.label,
                        fitted,
                    });
                }
            }
            candidates.push(CandidateFigures {
                form: "position-dependent",
                family: family.key().into(),
                inputs: set.label.into(),
                targets: scores,
            });
        }
    }
    let Some(choices) = best.into_iter().collect::<Option<Vec<_>>>() else {
        return Ok(None);
    };
    let model = one_model(data, &choices)?;
    Ok(Some(StaticModel { model, choices }))
}

/// The machine's input sets restricted to the differences the data holds; a set left without
/// any is no candidate.
fn usable_input_sets(data: &MachineData) -> Vec<InputSet> {
    input_sets(&data.machine)
        .into_iter()
        .map(|mut s| {
            s.differences.retain(|d| data.differences.contains(d));
            s
        })
        .filter(|s| !s.differences.is_empty())
        .collect()
}

/// Target `k`'s observations on the training rows, block by block of the inner CV.
fn observations<'d>(
    data: &'d MachineData,
    blocks: &[&[(usize, usize)]],
    targets: &[Vec<Vec<f64>>],
    k: usize,
) -> Vec<Vec<Observation<'d>>> {
    let axis = data.target_axes[k];
    blocks
        .iter()
        .map(|b| {
            b.iter()
                .map(|&(r, i)| Observation {
                    input: data.input(r, i),
                    axis,
                    error_um: targets[r][k][i],
                })
                .collect()
        })
        .collect()
}

/// One model of the targets' choices: every target's parts, named by their axis so that they
/// stay apart (a part already named after its axis, as the reference-sensor regression's,
/// keeps its name).
fn one_model(data: &MachineData, choices: &[PositionChoice]) -> Result<Model, String> {
    let machine = &data.machine;
    let mut parts: Vec<Part> = Vec::new();
    for (k, choice) in choices.iter().enumerate() {
        let axis = &machine.axes[data.target_axes[k]].name;
        for p in choice.fitted.model.parts() {
            let mut p = p.clone();
            if !p.name.ends_with(&format!("-{axis}")) {
                p.name = format!("{}-{axis}", p.name);
            }
            parts.push(p);
        }
    }
    Model::new(format!("{}-fit", machine.name), machine, parts)
        .map_err(|e| format!("the chosen position-dependent model: {e}"))
}

/// Chooses among every family on the training `rows` by inner CV and fits the choice on them:
/// the dynamic `settings.families` (none when empty or without `cand`, their candidate
/// features) and the position-dependent `families` (the shipped [`crate::family::PositionFamily`]
/// or any other [`PositionDesign`]).
pub fn select(
    ds: &Dataset,
    data: &MachineData,
    cand: Option<&Candidates>,
    rows: &[(usize, usize)],
    settings: &Settings,
    families: &[&dyn PositionDesign],
) -> Result<Selection, String> {
    if rows.len() < 4 * settings.folds.max(2) {
        return Err(format!(
            "only {} training samples: too few for {}-fold cross-validation",
            rows.len(),
            settings.folds
        ));
    }
    let targets: Vec<Vec<Vec<f64>>> = ds.targets(settings.absolute_targets);
    let mut candidates = Vec::new();
    let dynamic = if let Some(cand) = cand.filter(|_| !settings.families.is_empty()) {
        let trained = train(ds, cand, rows, settings)?;
        candidates.extend(filtered_figures(ds, &trained));
        Some(trained)
    } else {
        None
    };
    let fixed = static_selection(
        ds,
        data,
        &targets,
        rows,
        settings,
        families,
        &mut candidates,
    )?;
    let dynamic_score = dynamic.as_ref().map(|t| {
        // The position-dependent scores come from the same blocked folds: compare like with like.
        pooled(
            &t.choices
                .iter()
                .map(|c| c.selection_cv_rmse_um)
                .collect::<Vec<_>>(),
        )
    });
    let static_score = fixed.as_ref().map(|s| {
        pooled(
            &s.choices
                .iter()
                .map(|c| c.fitted.score_um)
                .collect::<Vec<_>>(),
        )
    });
    let take_static = match (dynamic_score, static_score) {
        (Some(d), Some(s)) => s <= d,
        (None, Some(_)) => true,
        (Some(_), None) => false,
        (None, None) => return Err("no candidate family could be fitted".into()),
    };
    let (chosen, labels, cv_rmse_um, warnings) = match (take_static, dynamic, fixed) {
        (true, _, Some(s)) => {
            let labels = s
                .choices
                .iter()
                .map(|c| format!("{} on {}, λ={:e}", c.family, c.inputs, c.fitted.ridge))
                .collect();
            let cv = s.choices.iter().map(|c| c.fitted.score_um).collect();
            let warnings = skipped_warnings(ds, &s);
            (Chosen::Position(s), labels, cv, warnings)
        }
        (_, Some(t), _) => {
            let labels = t.choices.iter().map(|c| c.describe()).collect();
            let cv = t.choices.iter().map(|c| c.cv_rmse_um).collect();
            let warnings = t.warnings.clone();
            (Chosen::Filtered(t), labels, cv, warnings)
        }
        _ => return Err("internal: no chosen form".into()),
    };
    Ok(Selection {
        chosen,
        candidates,
        labels,
        cv_rmse_um,
        warnings,
    })
}

/// The filtered families' inner-CV figures, per target, as candidates beside the
/// position-dependent ones.
fn filtered_figures(ds: &Dataset, trained: &Trained) -> Vec<CandidateFigures> {
    trained
        .scores
        .iter()
        .map(|s| CandidateFigures {
            form: "dynamic",
            family: s.family.name().into(),
            inputs: "dataset inputs".into(),
            targets: s
                .per_target
                .iter()
                .zip(&ds.target_names)
                .map(|(&(cv_rmse_um, ridge), t)| TargetScore {
                    target: t.clone(),
                    cv_rmse_um,
                    ridge,
                })
                .collect(),
        })
        .collect()
}

/// A warning per target whose position-dependent fit left training samples out (an input
/// invalid or outside its range), so that a user sees the fit saw fewer rows than given.
fn skipped_warnings(ds: &Dataset, s: &StaticModel) -> Vec<String> {
    s.choices
        .iter()
        .zip(&ds.target_names)
        .filter(|(c, _)| c.fitted.skipped > 0)
        .map(|(c, t)| {
            format!(
                "{t}: {} of {} training samples left out of the position-dependent fit (an input invalid or outside its range)",
                c.fitted.skipped,
                c.fitted.skipped + c.fitted.observations
            )
        })
        .collect()
}

/// The predictions of a chosen model over every row of every run: a dynamic model stepped through
/// each run, a position-dependent model evaluated at each row (NaN where it refuses an input).
pub fn predict_chosen(
    ds: &Dataset,
    data: &MachineData,
    chosen: &Chosen,
) -> Result<Predictions, String> {
    match chosen {
        Chosen::Filtered(t) => predict(ds, t),
        Chosen::Position(s) => Ok(ds
            .runs
            .iter()
            .enumerate()
            .map(|(r, run)| {
                let rows: Vec<Option<Vec<f64>>> = (0..run.len())
                    .map(|i| {
                        s.model
                            .evaluate(&data.input(r, i))
                            .ok()
                            .map(|c| c.error_um().to_vec())
                    })
                    .collect();
                data.target_axes
                    .iter()
                    .map(|&a| {
                        rows.iter()
                            .map(|e| e.as_ref().map_or(f64::NAN, |e| e[a]))
                            .collect()
                    })
                    .collect()
            })
            .collect()),
    }
}

/// What one outer fold chose.
#[derive(Debug, Clone, serde::Serialize)]
pub struct FoldSelection {
    /// Every candidate's inner-CV figures.
    pub candidates: Vec<CandidateFigures>,
    /// Per target, what was chosen.
    pub chosen: Vec<String>,
    /// Per target, its inner-CV RMSE, µm.
    pub cv_rmse_um: Vec<f64>,
}

/// A fit over every family: figures, the model to write, and the predictions behind them.
#[derive(Debug, Clone)]
pub struct MachineOutcome {
    /// Figures pooled over the outer folds, and per run (`choices` holds a fold's dynamic
    /// choices when it chose the dynamic form).
    pub validation: Validation,
    /// What each outer fold chose, with every candidate's inner figures.
    pub folds: Vec<FoldSelection>,
    /// The model to write (as [`crate::validate::Outcome::trained`]) and its selection.
    pub selection: Selection,
    /// Out-of-fold predictions (as [`crate::validate::Outcome::predictions`]).
    pub predictions: Predictions,
    /// Per run and row, whether a fold held it out.
    pub held_out: Vec<Vec<bool>>,
    /// The final model's predictions over every row.
    pub fitted: Predictions,
    /// The rows the final model was fitted on.
    pub training_rows: Vec<(usize, usize)>,
}

fn figures(target: &str, measured: &[f64], predicted: &[f64]) -> (Metrics, usize) {
    let (m, p): (Vec<f64>, Vec<f64>) = measured
        .iter()
        .zip(predicted)
        .filter(|(_, p)| p.is_finite())
        .map(|(m, p)| (*m, *p))
        .unzip();
    (Metrics::new(target, &m, &p), measured.len() - m.len())
}

/// The machine fit as the outer loop's procedure: [`select`] on the rows, [`predict_chosen`].
struct MachineFit<'a> {
    ds: &'a Dataset,
    data: &'a MachineData,
    cand: Option<&'a Candidates>,
    settings: &'a Settings,
    families: &'a [&'a dyn PositionDesign],
}

impl Procedure for MachineFit<'_> {
    type Model = Selection;

    fn fit(&mut self, rows: &[(usize, usize)]) -> Result<Selection, String> {
        select(
            self.ds,
            self.data,
            self.cand,
            rows,
            self.settings,
            self.families,
        )
    }

    fn predict(&self, model: &Selection) -> Result<Predictions, String> {
        predict_chosen(self.ds, self.data, &model.chosen)
    }

    fn rows_beyond(
        &self,
        model: &Selection,
        predicted: &Predictions,
        train: &[(usize, usize)],
        rows: &[(usize, usize)],
    ) -> usize {
        match &model.chosen {
            Chosen::Filtered(t) => {
                let env = crate::export::training_envelope(self.ds, &t.inputs, predicted, train);
                crate::export::rows_beyond(self.ds, &env, rows)
            }
            Chosen::Position(s) => {
                let env = crate::export::machine_envelope(&s.model, self.data, train);
                let m = &self.data.machine;
                let (mut t, mut o) = (
                    vec![0.0; m.temperatures.len()],
                    vec![0.0; m.operating.len()],
                );
                rows.iter()
                    .filter(|&&(r, i)| env.clamp(&self.data.input(r, i), &mut t, &mut o).is_some())
                    .count()
            }
        }
    }
}

/// The outer protocol (`out_of_fold::cross_validate`) over [`select`]: for each fold,
/// select and fit on its training rows, predict its test rows; then the model to write, the same
/// selection on every row.
pub fn fit_machine(
    ds: &Dataset,
    data: &MachineData,
    cand: Option<&Candidates>,
    split: Split,
    settings: &Settings,
    families: &[&dyn PositionDesign],
    progress: &mut dyn FnMut(usize, usize),
) -> Result<MachineOutcome, String> {
    let nt = ds.target_names.len();
    let rel: Vec<Vec<Vec<f64>>> = ds.targets(settings.absolute_targets);
    let mut procedure = MachineFit {
        ds,
        data,
        cand,
        settings,
        families,
    };
    let cv = cross_validate(ds, split, &rel, &mut procedure, progress)?;
    let mut warnings = Vec::new();
    let mut choices = Vec::new();
    let mut fold_selections = Vec::new();
    for fold in &cv.folds {
        let sel = &fold.model;
        choices.push(match &sel.chosen {
            Chosen::Filtered(t) => t.choices.clone(),
            Chosen::Position(_) => Vec::new(),
        });
        fold_selections.push(FoldSelection {
            candidates: sel.candidates.clone(),
            chosen: sel.labels.clone(),
            cv_rmse_um: sel.cv_rmse_um.clone(),
        });
        warnings.extend(sel.warnings.iter().cloned());
    }
    let chosen_names: Vec<Vec<String>> = fold_selections.iter().map(|f| f.chosen.clone()).collect();
    let mut metrics = Vec::new();
    for k in 0..nt {
        let (m, failed) = figures(&ds.target_names[k], &cv.measured[k], &cv.predicted[k]);
        if failed > 0 {
            warnings.push(format!(
                "{}: {failed} held-out samples could not be predicted (an input invalid or outside its range) and are not in the figures",
                ds.target_names[k]
            ));
        }
        metrics.push(m);
    }
    let done = cv.done;
    let per_run = per_run(ds, &rel, &done.predictions, &done.fold_of, &chosen_names);
    warnings.extend(worse_than_uncompensated(&per_run));
    let inner: Vec<Vec<f64>> = fold_selections
        .iter()
        .map(|f| f.cv_rmse_um.clone())
        .collect();
    let inner_vs_test = crate::validate::inner_vs_test(&metrics, &inner);
    Ok(MachineOutcome {
        validation: Validation {
            protocol: split,
            protocol_text: format!(
                "{split}; selection among every family (dynamic and position-dependent) inside each training part: {}",
                settings.describe_selection()
            ),
            metrics,
            per_run,
            choices,
            sensors: Vec::new(),
            inner_vs_test,
            baseline_metrics: None,
            held_out_rows_beyond_training: cv.held_out_beyond,
            warnings,
        },
        folds: fold_selections,
        selection: cv.model,
        predictions: done.predictions,
        held_out: done.held_out,
        fitted: cv.fitted,
        training_rows: cv.training_rows,
    })
}
