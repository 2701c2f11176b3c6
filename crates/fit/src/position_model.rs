//! Fitting the position-dependent thermal model — and its special cases, down to the
//! position-independent prior art — to measured tool-tip errors.
//!
//! A [`Family`] fixes which coefficients exist ([`structure`] builds the model with all of them
//! zero); [`fit_structure`] estimates them by least squares through the model's own regressors
//! (`Model::regressors`: error = Σ θ·φ), so the fitted model is exactly the model file the
//! control evaluates. The ridge weight is chosen by time-series cross-validation over contiguous
//! blocks of the observations given (the training part), never on data the caller holds out
//! ([`fit_blocks`] with the dynamic families' options; [`crate::machine_fit`] chooses among
//! families and input sets).

use std::fmt;

use truepos_model::{
    Carriage, CycleInput, LagSource, Machine, Model, ModelError, Part, PartForm, PositionFactor,
    PositionTerm, Reference, Summand, TemperatureDifference,
};

use crate::least_squares::{Accumulator, Solution, SolveError, SolveOptions};
use crate::settings::{InnerCv, Rule};

/// Which coefficients a position-dependent model has.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Family {
    /// The position-independent prior art: ΔA_n = Σ_m ΔT_m·K_nm, no position.
    PositionIndependent,
    /// All axes: ΔA_n = Σ_m ΔT_m·[K_nm0 + Σ_j K_nmj·g_j] over every axis j, with g_j
    /// the axis' natural factor (r for a cantilevered slide, KFA for a slide on a bed).
    AllAxes,
    /// As [`Family::AllAxes`] with r_j² terms as well (the arc is not linear).
    AllAxesSquared,
    /// The bed factor: [`Family::AllAxes`] plus, for every axis carried on a bed, each
    /// difference's summand ΔT_m·[K_nm0' + K_nmb'·KFA_b]·KFA_b — the bed bends, the error is
    /// smallest in its middle and grows towards both ends.
    BedFactor,
    /// Own axis: the summand of a difference that belongs to axis m carries that
    /// axis' position only, ΔT_m·[K_nm0 + K_nmm·g_m]; a difference of no axis stays prior art.
    /// Needs the owners ([`Shape::owners`]).
    OwnAxis,
    /// Serial, N axes resting on each other: the summand of axis m's difference carries the
    /// positions of m and of every axis resting on it (`carried_by`, transitively),
    /// ΔT_m·[K_nm0 + Σ_{j on m} K_nmj·g_j]. Needs the owners ([`Shape::owners`]).
    Serial,
    /// The reference-sensor regression Y_n = Σ_i k_ni·(t_i − t_r) + c_n: no position, only the
    /// machine's differences of a sensor against the reference sensor t_r ([`reference_sensor`]).
    ReferenceSensor,
}

impl Family {
    /// Every family, simplest first.
    pub const ALL: [Family; 7] = [
        Family::ReferenceSensor,
        Family::PositionIndependent,
        Family::OwnAxis,
        Family::Serial,
        Family::AllAxes,
        Family::AllAxesSquared,
        Family::BedFactor,
    ];

    /// The name used in reports.
    pub fn name(self) -> &'static str {
        match self {
            Self::PositionIndependent => "position-independent (prior art)",
            Self::AllAxes => "position-dependent, all axes",
            Self::AllAxesSquared => "position-dependent, all axes with squares",
            Self::BedFactor => "position-dependent with bed factor",
            Self::OwnAxis => "position-dependent, each difference its own axis",
            Self::Serial => "position-dependent, serial axes",
            Self::ReferenceSensor => "reference-sensor regression",
        }
    }

    /// The name on the command line (`truepos fit --family`).
    pub fn key(self) -> &'static str {
        match self {
            Self::PositionIndependent => "prior-art",
            Self::AllAxes => "all-axes",
            Self::AllAxesSquared => "all-axes-squared",
            Self::BedFactor => "bed-factor",
            Self::OwnAxis => "own-axis",
            Self::Serial => "serial",
            Self::ReferenceSensor => "reference-sensor",
        }
    }
}

impl fmt::Display for Family {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.key())
    }
}

impl std::str::FromStr for Family {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        Self::ALL
            .into_iter()
            .find(|f| f.key() == s.trim())
            .ok_or_else(|| {
                let keys: Vec<&str> = Self::ALL.iter().map(|f| f.key()).collect();
                format!("expected one of {}, got `{s}`", keys.join(", "))
            })
    }
}

/// The reference sensor of the reference-sensor regression on a machine: the sensor most of the
/// machine's differences are taken against (ambient, or a reference spot on the machine), the first
/// of equals; `None` when no difference is taken against a sensor.
pub fn reference_sensor(machine: &Machine) -> Option<usize> {
    let mut count = vec![0usize; machine.temperatures.len()];
    for d in &machine.differences {
        if let Reference::Sensor(m) = d.minus {
            count[m] += 1;
        }
    }
    let best = count.iter().copied().max().filter(|&c| c > 0)?;
    count.iter().position(|&c| c == best)
}

/// The differences of `differences` a family reads: the reference-sensor regression only those
/// taken against the `reference` sensor, every other family all of them.
pub fn family_differences(
    machine: &Machine,
    family: Family,
    differences: &[usize],
    reference: Option<usize>,
) -> Vec<usize> {
    match family {
        Family::ReferenceSensor => differences
            .iter()
            .copied()
            .filter(|&d| {
                matches!(machine.differences[d].minus, Reference::Sensor(m) if Some(m) == reference)
            })
            .collect(),
        _ => differences.to_vec(),
    }
}

/// What a position model is built for: its name, the machine, the differences its summands
/// read, the target axes, whether each target has a constant, and the axis each of the
/// machine's differences belongs to (by difference index; missing or `None`: no axis).
#[derive(Debug, Clone, Copy)]
pub struct Shape<'a> {
    /// The model's name.
    pub name: &'a str,
    /// The machine.
    pub machine: &'a Machine,
    /// The machine's differences the summands read.
    pub differences: &'a [usize],
    /// The axes whose errors the model predicts.
    pub targets: &'a [usize],
    /// A constant per target axis.
    pub constant: bool,
    /// The owner of each of the machine's differences ([`Family::OwnAxis`], [`Family::Serial`]).
    pub owners: &'a [Option<usize>],
}

/// What the fit needs of a position family: its names, the machine's differences it reads, and
/// its model with every coefficient zero, built of the core's parts so that the fitted model is
/// exactly the model file the control evaluates. [`Family`] is the list the project ships; a
/// caller may bring its own (docs/how-to-add-a-family.md) and hand it to
/// [`crate::machine_fit::select`] beside them.
pub trait PositionDesign: fmt::Debug + Sync {
    /// The name on the command line and in the model file's provenance (kebab-case).
    fn key(&self) -> &'static str;
    /// The name in reports.
    fn name(&self) -> &'static str;
    /// Whether its summands need the axis each difference belongs to; a machine that states
    /// none leaves such a family out.
    fn needs_owners(&self) -> bool {
        false
    }
    /// The differences of `differences` it reads (`reference`: the reference sensor).
    fn differences(
        &self,
        _machine: &Machine,
        differences: &[usize],
        _reference: Option<usize>,
    ) -> Vec<usize> {
        differences.to_vec()
    }
    /// The model of `shape` with every coefficient zero.
    fn structure(&self, shape: &Shape<'_>) -> Result<Model, ModelError>;
}

impl Family {
    /// The families of `list` as the designs [`crate::machine_fit::select`] takes.
    pub fn designs(list: &[Family]) -> Vec<&dyn PositionDesign> {
        list.iter().map(|f| f as &dyn PositionDesign).collect()
    }
}

impl PositionDesign for Family {
    fn key(&self) -> &'static str {
        Family::key(*self)
    }

    fn name(&self) -> &'static str {
        Family::name(*self)
    }

    fn needs_owners(&self) -> bool {
        matches!(self, Family::OwnAxis | Family::Serial)
    }

    fn differences(
        &self,
        machine: &Machine,
        differences: &[usize],
        reference: Option<usize>,
    ) -> Vec<usize> {
        family_differences(machine, *self, differences, reference)
    }

    fn structure(&self, shape: &Shape<'_>) -> Result<Model, ModelError> {
        if *self == Family::ReferenceSensor {
            regression_structure(shape)
        } else {
            position_structure(*self, shape)
        }
    }
}

/// The model of a family with every coefficient zero: for each target axis n and each listed
/// difference m one summand, plus a constant per target axis when `constant` is set, without
/// owners ([`Shape`] for a family that needs them). The reference-sensor regression is one
/// regression part per target axis (as its model files state it); every other family one
/// position-dependent part.
pub fn structure(
    name: &str,
    machine: &Machine,
    family: Family,
    differences: &[usize],
    targets: &[usize],
    constant: bool,
) -> Result<Model, ModelError> {
    family.structure(&Shape {
        name,
        machine,
        differences,
        targets,
        constant,
        owners: &[],
    })
}

/// The axes whose positions the summand of a difference owned by `owner` carries in
/// [`Family::OwnAxis`] (the owner) and [`Family::Serial`] (the owner and every axis resting on
/// it); none for a difference of no axis.
fn owned_axes(machine: &Machine, family: Family, owner: Option<usize>) -> Vec<usize> {
    let Some(o) = owner else {
        return Vec::new();
    };
    let rests_on = |mut j: usize| {
        // The chain is checked acyclic by the machine; the bound only guards the loop.
        for _ in 0..=machine.axes.len() {
            if j == o {
                return true;
            }
            match machine.axes[j].carried_by {
                Some(c) => j = c,
                None => return false,
            }
        }
        false
    };
    match family {
        Family::OwnAxis => vec![o],
        _ => (0..machine.axes.len()).filter(|&j| rests_on(j)).collect(),
    }
}

/// The position factor an axis' carriage gives: r for a cantilevered slide, KFA for a slide on
/// a bed.
pub fn natural_factor(machine: &Machine, axis: usize) -> PositionFactor {
    match machine.axes[axis].carriage {
        Carriage::Cantilever => PositionFactor::Ratio,
        Carriage::Bed => PositionFactor::BedFactor,
    }
}

/// A term of `axis` at its natural factor, coefficient zero.
fn natural_term(machine: &Machine, axis: usize) -> PositionTerm {
    PositionTerm {
        axis,
        factor: natural_factor(machine, axis),
        k_um_per_k: 0.0,
    }
}

/// The reference-sensor regression: one regression part per target axis.
fn regression_structure(shape: &Shape<'_>) -> Result<Model, ModelError> {
    let parts = shape
        .targets
        .iter()
        .map(|&n| Part {
            name: format!("reference-{}", shape.machine.axes[n].name),
            enabled: true,
            form: PartForm::Regression,
            summands: shape
                .differences
                .iter()
                .map(|&m| Summand {
                    axis: n,
                    difference: m,
                    k0_um_per_k: 0.0,
                    position_terms: Vec::new(),
                    bed_multiplier: None,
                })
                .collect(),
            constants_um: if shape.constant {
                vec![(n, 0.0)]
            } else {
                Vec::new()
            },
        })
        .collect();
    Model::new(shape.name, shape.machine, parts)
}

/// The position terms of one summand of difference `m` in `family`.
fn position_terms(family: Family, shape: &Shape<'_>, m: usize) -> Vec<PositionTerm> {
    let machine = shape.machine;
    let axes = 0..machine.axes.len();
    match family {
        Family::OwnAxis | Family::Serial => {
            let owner = shape.owners.get(m).copied().flatten();
            owned_axes(machine, family, owner)
                .into_iter()
                .map(|j| natural_term(machine, j))
                .collect()
        }
        Family::PositionIndependent | Family::ReferenceSensor => Vec::new(),
        Family::AllAxesSquared => axes
            .flat_map(|j| {
                let square = PositionTerm {
                    axis: j,
                    factor: PositionFactor::RatioSquared,
                    k_um_per_k: 0.0,
                };
                [natural_term(machine, j), square]
            })
            .collect(),
        Family::AllAxes | Family::BedFactor => axes.map(|j| natural_term(machine, j)).collect(),
    }
}

/// One position-dependent part: per target axis and difference a summand, and with the bed
/// factor one more per axis on a bed, multiplied by that axis' KFA.
fn position_structure(family: Family, shape: &Shape<'_>) -> Result<Model, ModelError> {
    let machine = shape.machine;
    let beds: Vec<usize> = (0..machine.axes.len())
        .filter(|&j| machine.axes[j].carriage == Carriage::Bed)
        .collect();
    let mut summands = Vec::new();
    for &n in shape.targets {
        for &m in shape.differences {
            summands.push(Summand {
                axis: n,
                difference: m,
                k0_um_per_k: 0.0,
                position_terms: position_terms(family, shape, m),
                bed_multiplier: None,
            });
            if family == Family::BedFactor {
                for &b in &beds {
                    summands.push(Summand {
                        axis: n,
                        difference: m,
                        k0_um_per_k: 0.0,
                        position_terms: vec![PositionTerm {
                            axis: b,
                            factor: PositionFactor::BedFactor,
                            k_um_per_k: 0.0,
                        }],
                        bed_multiplier: Some(b),
                    });
                }
            }
        }
    }
    let part = Part {
        name: "thermal".into(),
        enabled: true,
        form: PartForm::PositionDependent,
        summands,
        constants_um: if shape.constant {
            shape.targets.iter().map(|&n| (n, 0.0)).collect()
        } else {
            Vec::new()
        },
    };
    Model::new(shape.name, machine, vec![part])
}

/// One measured error of one axis at one instant, with what the control knew then.
#[derive(Debug, Clone, Copy)]
pub struct Observation<'a> {
    /// The inputs of that cycle.
    pub input: CycleInput<'a>,
    /// The axis whose error was measured.
    pub axis: usize,
    /// The measured error in µm (actual − nominal).
    pub error_um: f64,
}

/// A fitted model and how it was chosen.
#[derive(Debug, Clone)]
pub struct Fitted {
    /// The model with the estimated coefficients.
    pub model: Model,
    /// The solver's account (rank, condition, culprit columns).
    pub solution: Solution,
    /// The ridge weight chosen.
    pub ridge: f64,
    /// Cross-validated RMSE (µm) of each ridge weight tried, in order.
    pub cv_rmse_um: Vec<(f64, f64)>,
    /// Cross-validated RMSE (µm) of the ridge weight chosen.
    pub score_um: f64,
    /// Observations used.
    pub observations: usize,
    /// Observations skipped because an input was invalid.
    pub skipped: usize,
}

/// Ridge weights tried by the cross-validation (relative to unit-norm columns).
pub const RIDGE_GRID: [f64; 6] = [0.0, 1e-8, 1e-6, 1e-4, 1e-3, 1e-2];

/// Contiguous blocks of the cross-validation: never random rows, because neighbouring samples
/// of a thermal run are nearly identical and a random split leaks the answer.
pub const CV_BLOCKS: usize = 5;

/// How [`fit_blocks`] chooses the ridge weight: which blocks train the model scored on a
/// held-out block, the candidates, and the rule — the same choices as the dynamic families'
/// ([`crate::settings::Settings`]).
#[derive(Debug, Clone, Copy)]
pub struct CvOptions<'a> {
    /// Blocked (all other blocks) or rolling origin (the blocks before).
    pub inner: InnerCv,
    /// Candidate ridge weights.
    pub ridges: &'a [f64],
    /// Lowest CV error, or the most regularised within one standard error of it.
    pub rule: Rule,
}

/// Estimates the coefficients of `structure` from observations (in time order). The ridge
/// weight is chosen from [`RIDGE_GRID`] by blocked cross-validation over [`CV_BLOCKS`]
/// contiguous blocks of the observations, then the model is fitted on all of them.
pub fn fit_structure<'a>(
    structure: &Model,
    machine: &Machine,
    observations: impl IntoIterator<Item = Observation<'a>>,
) -> Result<Fitted, SolveError> {
    let mut rows = Vec::new();
    let mut skipped = 0;
    for o in observations {
        match regressor_row(structure, &o) {
            Some(r) => rows.push(r),
            None => skipped += 1,
        }
    }
    if rows.len() < 2 * CV_BLOCKS {
        return Err(SolveError::Empty);
    }
    let block = rows.len().div_ceil(CV_BLOCKS);
    let blocks: Vec<Vec<(Vec<f64>, f64)>> = rows.chunks(block).map(<[_]>::to_vec).collect();
    let options = CvOptions {
        inner: InnerCv::Blocked,
        ridges: &RIDGE_GRID,
        rule: Rule::MinimumCv,
    };
    let mut fitted = fit_rows(structure, machine, &blocks, &options)?;
    fitted.skipped = skipped;
    Ok(fitted)
}

/// One observation's regressors and error, `None` when an input is invalid or the error is
/// not a finite number (an observation the model cannot be fitted to).
fn regressor_row(structure: &Model, o: &Observation<'_>) -> Option<(Vec<f64>, f64)> {
    let mut phi = vec![0.0; structure.parameter_count()];
    if !o.error_um.is_finite() || structure.regressors(&o.input, o.axis, &mut phi).is_err() {
        return None;
    }
    Some((phi, o.error_um))
}

/// Estimates the coefficients of `structure` from observations already cut into contiguous
/// blocks (in time order): the ridge weight is chosen by cross-validation over the blocks as
/// `options` say, then the model is fitted on every block.
pub fn fit_blocks(
    structure: &Model,
    machine: &Machine,
    blocks: &[Vec<Observation<'_>>],
    options: &CvOptions<'_>,
) -> Result<Fitted, SolveError> {
    let mut skipped = 0;
    let rows: Vec<Vec<(Vec<f64>, f64)>> = blocks
        .iter()
        .map(|b| {
            b.iter()
                .filter_map(|o| {
                    let r = regressor_row(structure, o);
                    skipped += usize::from(r.is_none());
                    r
                })
                .collect()
        })
        .collect();
    let mut fitted = fit_rows(structure, machine, &rows, options)?;
    fitted.skipped = skipped;
    Ok(fitted)
}

/// The cross-validation and the final fit over blocks of regressor rows.
fn fit_rows(
    structure: &Model,
    machine: &Machine,
    blocks: &[Vec<(Vec<f64>, f64)>],
    options: &CvOptions<'_>,
) -> Result<Fitted, SolveError> {
    let n = structure.parameter_count();
    let observations: usize = blocks.iter().map(Vec::len).sum();
    if blocks.len() < 2 || observations < 2 * blocks.len() {
        return Err(SolveError::Empty);
    }
    // One QR accumulator per contiguous block; a fold's training triangle is the merge of the
    // training blocks, factored once and solved for every ridge weight.
    let mut accs = Vec::with_capacity(blocks.len());
    for chunk in blocks {
        let mut acc = Accumulator::new(n, 1);
        for (phi, y) in chunk {
            acc.push_row(phi, &[*y], 1.0)?;
        }
        accs.push(acc);
    }
    let solve = |ridge: f64| SolveOptions {
        ridge,
        unpenalized: Vec::new(),
        rcond: None,
        shared_scale: Vec::new(),
    };
    let ridges = options.ridges;
    let (se, held) = held_out_errors(blocks, &accs, n, options)?;
    if held.is_empty() {
        return Err(SolveError::Empty);
    }
    let scores = cv_scores(&se, &held);
    let pick = pick_ridge(ridges, &scores, options.rule)?;
    let mut all = Accumulator::new(n, 1);
    for acc in accs {
        all.merge(acc)?;
    }
    let solution = all.finish().solve(&solve(ridges[pick]))?;
    let model = structure
        .with_parameters(machine, &solution.coefficients[0])
        .map_err(|_| SolveError::NoConvergence)?;
    Ok(Fitted {
        model,
        solution,
        ridge: ridges[pick],
        cv_rmse_um: ridges.iter().zip(&scores).map(|(&r, s)| (r, s.0)).collect(),
        score_um: scores[pick].0,
        observations,
        skipped: 0,
    })
}

/// Per ridge weight, the squared errors of each held-out block, predicted by the fit on its
/// training blocks (infinite where that fit fails); and the held-out blocks' sizes. A block
/// without training blocks is not held out.
fn held_out_errors(
    blocks: &[Vec<(Vec<f64>, f64)>],
    accs: &[Accumulator],
    n: usize,
    options: &CvOptions<'_>,
) -> Result<(Vec<Vec<f64>>, Vec<usize>), SolveError> {
    let ridges = options.ridges;
    let mut se = vec![Vec::new(); ridges.len()];
    let mut held = Vec::new();
    for (b, block) in blocks.iter().enumerate() {
        if !options.inner.holds_out(b) || block.is_empty() {
            continue;
        }
        let mut train = Accumulator::new(n, 1);
        let mut any = false;
        for (k, acc) in accs.iter().enumerate() {
            if options.inner.trains(k, b) && !blocks[k].is_empty() {
                train.merge(acc.clone())?;
                any = true;
            }
        }
        if !any {
            continue;
        }
        held.push(block.len());
        let path = train.finish().ridge_path(ridges, &[]);
        for r in 0..ridges.len() {
            let sum = match &path {
                Ok(thetas) => block
                    .iter()
                    .map(|(phi, y)| {
                        let p: f64 = phi.iter().zip(&thetas[r]).map(|(a, t)| a * t).sum();
                        (y - p) * (y - p)
                    })
                    .sum(),
                Err(_) => f64::INFINITY,
            };
            se[r].push(sum);
        }
    }
    Ok((se, held))
}

/// Per ridge weight: the pooled held-out RMSE over every held-out row, and the standard error
/// of the per-block RMSEs (what the one-standard-error rule reads).
fn cv_scores(se: &[Vec<f64>], held: &[usize]) -> Vec<(f64, f64)> {
    let count: usize = held.iter().sum();
    se.iter()
        .map(|per_block| {
            let total: f64 = per_block.iter().sum();
            let rmse: Vec<f64> = per_block
                .iter()
                .zip(held)
                .map(|(e, &m)| (e / m as f64).sqrt())
                .collect();
            let k = rmse.len() as f64;
            let mean = rmse.iter().sum::<f64>() / k;
            let var = rmse.iter().map(|r| (r - mean).powi(2)).sum::<f64>() / (k - 1.0).max(1.0);
            ((total / count as f64).sqrt(), (var / k).sqrt())
        })
        .collect()
}

/// The index of the ridge weight `rule` picks from the `scores` of [`cv_scores`]; an error when
/// no weight has a finite score.
fn pick_ridge(ridges: &[f64], scores: &[(f64, f64)], rule: Rule) -> Result<usize, SolveError> {
    let best = (0..ridges.len())
        .filter(|&r| scores[r].0.is_finite())
        .min_by(|&a, &b| scores[a].0.total_cmp(&scores[b].0))
        .ok_or(SolveError::NoConvergence)?;
    Ok(match rule {
        Rule::MinimumCv => best,
        // Among ridge weights the CV cannot tell from the best, the most regularised.
        Rule::OneStandardError => (0..ridges.len())
            .filter(|&r| scores[r].0 <= scores[best].0 + scores[best].1)
            .max_by(|&a, &b| ridges[a].total_cmp(&ridges[b]))
            .unwrap_or(best),
    })
}

/// A candidate set of inputs: which of the machine's temperature differences a model reads.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct InputSet {
    /// What the set holds, for reports.
    pub label: &'static str,
    /// Indices into the machine's differences.
    pub differences: Vec<usize>,
}

/// Candidate input sets of a machine, each larger than the one before: differences of measured
/// channels only; with the lags of temperature sensors (the structure behind a sensor); with
/// the lags of operating state as well (what the control knows before a sensor does).
pub fn input_sets(machine: &Machine) -> Vec<InputSet> {
    // 0 measured, 1 lag of a sensor, 2 lag of operating state; a difference is the most
    // derived of its channels.
    let level = |c: usize| match machine.temperatures[c].lag.map(|l| l.source) {
        None => 0,
        Some(LagSource::Temperature(_)) => 1,
        Some(LagSource::Operating { .. }) => 2,
    };
    let of = |d: &TemperatureDifference| match d.minus {
        Reference::Sensor(m) => level(d.plus).max(level(m)),
        Reference::Fixed(_) => level(d.plus),
    };
    let upto = |max: u8| -> Vec<usize> {
        (0..machine.differences.len())
            .filter(|&i| of(&machine.differences[i]) <= max)
            .collect()
    };
    let mut sets = vec![InputSet {
        label: "measured sensors",
        differences: upto(0),
    }];
    for (max, label) in [
        (1, "+ lagged sensors"),
        (2, "+ lagged sensors + spindle load"),
    ] {
        let differences = upto(max);
        if differences.len() > sets.last().map_or(0, |l| l.differences.len()) {
            sets.push(InputSet { label, differences });
        }
    }
    sets
}

#[cfg(test)]
mod tests {
    use super::*;

    fn twin_machine() -> Machine {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../examples/twin/machine.toml");
        truepos_io::machine_file::load(&path).unwrap().machine
    }

    #[test]
    fn families_parse_by_their_command_line_names_and_build_on_the_twin() {
        let machine = twin_machine();
        let diffs: Vec<usize> = (0..machine.differences.len()).collect();
        let reference = reference_sensor(&machine);
        assert_eq!(
            reference.map(|r| machine.temperatures[r].id.as_str()),
            Some("ambient")
        );
        for f in Family::ALL {
            assert_eq!(f.key().parse::<Family>(), Ok(f));
            assert_eq!(f.to_string(), f.key());
            let d = family_differences(&machine, f, &diffs, reference);
            let m = structure("m", &machine, f, &d, &[2], true).unwrap();
            // Per difference: K0 (+ a term per axis, + squares, + the bed summands) + constant.
            let per = match f {
                // Without owners no difference carries a position.
                Family::ReferenceSensor
                | Family::PositionIndependent
                | Family::OwnAxis
                | Family::Serial => 1,
                Family::AllAxes => 4,
                Family::AllAxesSquared => 7,
                // X and Y ride on beds: two bed-multiplied summands of two coefficients each.
                Family::BedFactor => 4 + 2 * 2,
            };
            assert_eq!(m.parameter_count(), per * d.len() + 1, "{f}");
        }
        // dT_y_saddle (difference 1) belongs to Y, on which X rests: own-axis carries r_Y,
        // serial r_Y and r_X (KFA: both ride on beds).
        let owners = [None, Some(1)];
        for (f, n) in [(Family::OwnAxis, 2), (Family::Serial, 3)] {
            let shape = Shape {
                name: "m",
                machine: &machine,
                differences: &[0, 1],
                targets: &[2],
                constant: false,
                owners: &owners,
            };
            let m = f.structure(&shape).unwrap();
            assert_eq!(m.parameter_count(), 1 + n, "{f}");
        }
        // The reference-sensor regression reads only the differences against the reference sensor.
        let c = family_differences(&machine, Family::ReferenceSensor, &diffs, reference);
        assert_eq!(c.len(), 18);
        assert!("warm"
            .parse::<Family>()
            .unwrap_err()
            .starts_with("expected one of reference-sensor, prior-art"));
    }

    #[test]
    fn input_sets_grow_and_the_fit_finds_the_position_dependent_truth() {
        let machine = twin_machine();
        let sets = input_sets(&machine);
        assert_eq!(sets[0].label, "measured sensors");
        for w in sets.windows(2) {
            assert!(w[0].differences.len() < w[1].differences.len());
        }
        // The truth: the all-axes form on the measured sensors, with made-up coefficients.
        let truth = structure(
            "truth",
            &machine,
            Family::AllAxes,
            &sets[0].differences,
            &[0, 1, 2],
            true,
        )
        .unwrap();
        let theta: Vec<f64> = (0..truth.parameter_count())
            .map(|i| ((i * 7919) % 13) as f64 / 13.0 - 0.5)
            .collect();
        let truth = truth.with_parameters(&machine, &theta).unwrap();
        let mut rng = 12345u64;
        let mut draw = || {
            rng = rng
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (rng >> 11) as f64 / (1u64 << 53) as f64
        };
        let rows: Vec<(Vec<f64>, Vec<f64>)> = (0..300)
            .map(|_| {
                let temps = (0..machine.temperatures.len())
                    .map(|_| 18.0 + 8.0 * draw())
                    .collect();
                let pos = machine
                    .axes
                    .iter()
                    .map(|a| a.travel_min + (a.travel_max - a.travel_min) * draw())
                    .collect();
                (temps, pos)
            })
            .collect();
        let op = vec![0.0; machine.operating.len()];
        fn input<'a>(r: &'a (Vec<f64>, Vec<f64>), op: &'a [f64]) -> CycleInput<'a> {
            CycleInput {
                temperatures_c: &r.0,
                positions: &r.1,
                operating: op,
            }
        }
        let mut obs = Vec::new();
        for r in &rows {
            let e = truth.evaluate(&input(r, &op)).unwrap();
            for a in 0..3 {
                obs.push(Observation {
                    input: input(r, &op),
                    axis: a,
                    error_um: e.error_um()[a],
                });
            }
        }
        // Fitted on the truth's input set, the all-axes family finds it; the prior art cannot.
        let fit = |family| {
            let s = structure(
                "m",
                &machine,
                family,
                &sets[0].differences,
                &[0, 1, 2],
                true,
            )
            .unwrap();
            fit_structure(&s, &machine, obs.iter().copied()).unwrap()
        };
        let best = fit(Family::AllAxes);
        assert!(fit(Family::PositionIndependent).score_um > 100.0 * best.score_um);
        assert!(best.score_um < 1e-3, "{}", best.score_um);
    }
}
