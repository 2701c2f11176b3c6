//! Fitting seed A's position-dependent form — and its special cases, down to the
//! position-independent prior art — to measured tool-tip errors.
//!
//! A [`Family`] fixes which coefficients exist ([`structure`] builds the model with all of them
//! zero); [`fit_structure`] estimates them by least squares through the model's own regressors
//! (`Model::regressors`: error = Σ θ·φ), so the fitted model is exactly the model file the
//! control evaluates. The ridge weight is chosen by blocked time-series cross-validation inside
//! the observations given (the training part), never on data the caller holds out.

use std::fmt;

use truepos_model::{
    Carriage, CycleInput, LagSource, Machine, Model, ModelError, Part, PartForm, PositionFactor,
    PositionTerm, Reference, Summand, TemperatureDifference,
};

use crate::least_squares::{Accumulator, Solution, SolveError, SolveOptions};

/// Which coefficients a position-dependent model has.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Family {
    /// Prior art (seed A eqs. 1–2): ΔA_n = Σ_m ΔT_m·K_nm, no position.
    PositionIndependent,
    /// Seed A embodiment 5: ΔA_n = Σ_m ΔT_m·[K_nm0 + Σ_j K_nmj·g_j] over every axis j, with g_j
    /// the axis' natural factor (r for a cantilevered slide, KFA for a slide on a bed).
    AllAxes,
    /// As [`Family::AllAxes`] with r_j² terms as well (seed A example 2: the arc is not linear).
    AllAxesSquared,
}

impl Family {
    /// The name used in reports.
    pub fn name(self) -> &'static str {
        match self {
            Self::PositionIndependent => "position-independent (prior art, seed A eqs. 1–2)",
            Self::AllAxes => "position-dependent, all axes (seed A embodiment 5)",
            Self::AllAxesSquared => {
                "position-dependent, all axes with squares (seed A emb. 5 + ex. 2)"
            }
        }
    }
}

/// The model of a family with every coefficient zero: for each target axis n and each listed
/// difference m one summand, plus a constant per target axis when `constant` is set.
pub fn structure(
    name: &str,
    machine: &Machine,
    family: Family,
    differences: &[usize],
    targets: &[usize],
    constant: bool,
) -> Result<Model, ModelError> {
    let natural = |j: usize| match machine.axes[j].carriage {
        Carriage::Cantilever => PositionFactor::Ratio,
        Carriage::Bed => PositionFactor::BedFactor,
    };
    let mut summands = Vec::new();
    for &n in targets {
        for &m in differences {
            let mut position_terms = Vec::new();
            if family != Family::PositionIndependent {
                for j in 0..machine.axes.len() {
                    position_terms.push(PositionTerm {
                        axis: j,
                        factor: natural(j),
                        k_um_per_k: 0.0,
                    });
                    if family == Family::AllAxesSquared {
                        position_terms.push(PositionTerm {
                            axis: j,
                            factor: PositionFactor::RatioSquared,
                            k_um_per_k: 0.0,
                        });
                    }
                }
            }
            summands.push(Summand {
                axis: n,
                difference: m,
                k0_um_per_k: 0.0,
                position_terms,
                bed_multiplier: None,
            });
        }
    }
    let part = Part {
        name: "thermal".into(),
        enabled: true,
        form: PartForm::PositionDependent,
        summands,
        constants_um: if constant {
            targets.iter().map(|&n| (n, 0.0)).collect()
        } else {
            Vec::new()
        },
    };
    Model::new(name, machine, vec![part])
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

/// Estimates the coefficients of `structure` from observations (in time order). The ridge
/// weight is chosen from [`RIDGE_GRID`] by blocked cross-validation over [`CV_BLOCKS`]
/// contiguous blocks of the observations, then the model is fitted on all of them.
pub fn fit_structure<'a>(
    structure: &Model,
    machine: &Machine,
    observations: impl IntoIterator<Item = Observation<'a>>,
) -> Result<Fitted, SolveError> {
    let n = structure.parameter_count();
    let mut rows: Vec<(Vec<f64>, f64)> = Vec::new();
    let mut skipped = 0;
    for o in observations {
        let mut phi = vec![0.0; n];
        if !o.error_um.is_finite() || structure.regressors(&o.input, o.axis, &mut phi).is_err() {
            skipped += 1;
            continue;
        }
        rows.push((phi, o.error_um));
    }
    if rows.len() < 2 * CV_BLOCKS {
        return Err(SolveError::Empty);
    }
    // One QR accumulator per contiguous block; a fold's training triangle is the merge of the
    // other blocks, factored once and solved for every ridge weight.
    let block = rows.len().div_ceil(CV_BLOCKS);
    let mut blocks = Vec::with_capacity(CV_BLOCKS);
    for chunk in rows.chunks(block) {
        let mut acc = Accumulator::new(n, 1);
        for (phi, y) in chunk {
            acc.push_row(phi, &[*y], 1.0)?;
        }
        blocks.push(acc);
    }
    let options = |ridge: f64| SolveOptions {
        ridge,
        unpenalized: Vec::new(),
        rcond: None,
    };
    let mut se = vec![0.0; RIDGE_GRID.len()];
    let mut count = 0usize;
    for (b, held) in rows.chunks(block).enumerate() {
        let mut train = Accumulator::new(n, 1);
        for (k, acc) in blocks.iter().enumerate() {
            if k != b {
                train.merge(acc.clone())?;
            }
        }
        let triangle = train.finish();
        for (r, &ridge) in RIDGE_GRID.iter().enumerate() {
            let theta = &triangle.solve(&options(ridge))?.coefficients[0];
            for (phi, y) in held {
                let p: f64 = phi.iter().zip(theta).map(|(a, t)| a * t).sum();
                se[r] += (y - p) * (y - p);
            }
        }
        count += held.len();
    }
    let cv: Vec<(f64, f64)> = RIDGE_GRID
        .iter()
        .zip(&se)
        .map(|(&ridge, &e)| (ridge, (e / count.max(1) as f64).sqrt()))
        .collect();
    let ridge = cv
        .iter()
        .filter(|c| c.1.is_finite())
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .map_or(0.0, |c| c.0);
    let mut all = Accumulator::new(n, 1);
    for acc in blocks {
        all.merge(acc)?;
    }
    let solution = all.finish().solve(&options(ridge))?;
    let model = structure
        .with_parameters(machine, &solution.coefficients[0])
        .map_err(|_| SolveError::NoConvergence)?;
    Ok(Fitted {
        model,
        solution,
        ridge,
        cv_rmse_um: cv,
        observations: rows.len(),
        skipped,
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

/// One candidate of [`choose`]: a family on an input set, fitted.
#[derive(Debug, Clone)]
pub struct Candidate {
    /// The family.
    pub family: Family,
    /// The input set's label.
    pub inputs: &'static str,
    /// The lowest cross-validated RMSE over the ridge grid, µm.
    pub cv_rmse_um: f64,
    /// The fitted model.
    pub fitted: Fitted,
}

/// Why no model could be chosen.
#[derive(Debug, Clone, PartialEq)]
pub enum ChooseError {
    /// A structure could not be built on the machine.
    Model(ModelError),
    /// A fit failed.
    Solve(SolveError),
    /// No family or no input set was given.
    NoCandidate,
}

impl fmt::Display for ChooseError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Model(e) => write!(f, "{e}"),
            Self::Solve(e) => write!(f, "{e}"),
            Self::NoCandidate => write!(f, "no family or no input set to choose from"),
        }
    }
}

impl std::error::Error for ChooseError {}

/// Fits every family on every input set (`name`d models of every target axis, with a constant)
/// and returns the one with the lowest cross-validated RMSE, the first of equals in the order
/// given: the choice is made inside the observations (the training part) only. `tried` sees
/// every candidate as it is fitted.
pub fn choose(
    name: &str,
    machine: &Machine,
    families: &[Family],
    sets: &[InputSet],
    targets: &[usize],
    observations: &[Observation<'_>],
    tried: &mut dyn FnMut(&Candidate),
) -> Result<Candidate, ChooseError> {
    let mut candidates = Vec::new();
    for &family in families {
        for set in sets {
            let s = structure(name, machine, family, &set.differences, targets, true)
                .map_err(ChooseError::Model)?;
            let fitted = fit_structure(&s, machine, observations.iter().copied())
                .map_err(ChooseError::Solve)?;
            let cv_rmse_um = fitted
                .cv_rmse_um
                .iter()
                .map(|c| c.1)
                .fold(f64::INFINITY, f64::min);
            let candidate = Candidate {
                family,
                inputs: set.label,
                cv_rmse_um,
                fitted,
            };
            tried(&candidate);
            candidates.push(candidate);
        }
    }
    // A stable sort: among equal scores the first given (the simpler) wins.
    candidates.sort_by(|a, b| a.cv_rmse_um.total_cmp(&b.cv_rmse_um));
    candidates
        .into_iter()
        .next()
        .ok_or(ChooseError::NoCandidate)
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
    fn input_sets_grow_and_the_choice_finds_the_position_dependent_truth() {
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
        let mut tried = 0;
        let families = [Family::PositionIndependent, Family::AllAxes];
        let best = choose(
            "m",
            &machine,
            &families,
            &sets[..1],
            &[0, 1, 2],
            &obs,
            &mut |_| tried += 1,
        )
        .unwrap();
        assert_eq!(tried, 2);
        assert_eq!(best.family, Family::AllAxes);
        assert!(best.cv_rmse_um < 1e-3, "{}", best.cv_rmse_um);
    }
}
