//! Thermal compensation models: the general position-dependent form and the linear regression
//! against a reference sensor, as parts that superimpose.
//!
//! The all-axes form (with the bed-factor family's multiplier):
//!
//! ```text
//! ΔA_n = Σ_m ΔT_m · [K_nm0 + Σ_j K_nmj · g_j] · (KFA_b if the summand is bed-multiplied)
//! ```
//!
//! where g_j is r_j, r_j² or KFA_j of axis j. Each [`Summand`] is one `ΔT_m · […]` of one target
//! axis n. Every family of the position-dependent model, the position-independent prior art
//! (ΔA_n = Σ ΔT·K) and the reference-sensor regression (Y = Σ k_i·(t_i − t_r) + c) are this form
//! with some coefficients left out (docs/glossary.md names each).

use alloc::string::String;
use alloc::vec::Vec;
use core::fmt;

use crate::envelope::TrainingEnvelope;
use crate::machine::{Machine, Reference, MAX_AXES};

/// Most temperature differences one model may read. Differences are evaluated into a stack array
/// of this size so that evaluation never allocates.
pub const MAX_MODEL_DIFFERENCES: usize = 64;

/// The position factor g_j of an axis.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum PositionFactor {
    /// r = (position − travel_min) / length, 0 … 1 (docs/glossary.md: r).
    Ratio,
    /// r², for a bend that follows an arc rather than a line.
    RatioSquared,
    /// KFA = (position − L/2) / (L/2) = 2r − 1, −1 … 1, for a slide on a bed.
    BedFactor,
}

impl PositionFactor {
    /// g as a function of the ratio r.
    #[inline]
    pub fn of_ratio(self, r: f64) -> f64 {
        match self {
            Self::Ratio => r,
            Self::RatioSquared => r * r,
            Self::BedFactor => 2.0 * r - 1.0,
        }
    }

    /// The name used in model files.
    pub fn name(self) -> &'static str {
        match self {
            Self::Ratio => "ratio",
            Self::RatioSquared => "ratio-squared",
            Self::BedFactor => "bed",
        }
    }
}

/// One position-dependent coefficient K_nmj · g_j.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PositionTerm {
    /// Axis j whose position enters.
    pub axis: usize,
    /// r_j, r_j² or KFA_j.
    pub factor: PositionFactor,
    /// K_nmj in µm/K.
    pub k_um_per_k: f64,
}

/// One summand ΔT_m · [K_nm0 + Σ_j K_nmj · g_j] (· KFA_b) of the error of one axis.
#[derive(Debug, Clone, PartialEq)]
pub struct Summand {
    /// Target axis n: the direction of the error this summand describes.
    pub axis: usize,
    /// Temperature difference m (index into the machine's differences).
    pub difference: usize,
    /// K_nm0 in µm/K, the position-independent part.
    pub k0_um_per_k: f64,
    /// The K_nmj · g_j.
    pub position_terms: Vec<PositionTerm>,
    /// The bed-factor family: multiply the whole summand by the bed factor KFA of this axis.
    pub bed_multiplier: Option<usize>,
}

/// Which form a part was written in; kept so that a model file reads back as written.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PartForm {
    /// The position-dependent form.
    PositionDependent,
    /// The linear regression on temperature differences against a reference sensor, with a
    /// constant.
    Regression,
}

/// A switchable part of the correction (structure, spindle growth, …). Parts superimpose: the
/// correction of an axis is the sum over its enabled parts.
#[derive(Debug, Clone, PartialEq)]
pub struct Part {
    /// Name (`structure`, `spindle-growth`).
    pub name: String,
    /// Whether it contributes.
    pub enabled: bool,
    /// Form it was written in.
    pub form: PartForm,
    /// Its summands.
    pub summands: Vec<Summand>,
    /// Constant error per axis in µm (the regression's "+ c"), as (axis, value).
    pub constants_um: Vec<(usize, f64)>,
}

/// A model that does not fit its machine or holds an unusable number.
#[derive(Debug, Clone, PartialEq)]
pub enum ModelError {
    /// A summand's or constant's axis is not an axis of the machine.
    UnknownAxis {
        /// The part.
        part: String,
        /// The index.
        axis: usize,
    },
    /// A summand's difference is not a difference of the machine.
    UnknownDifference {
        /// The part.
        part: String,
        /// The index.
        difference: usize,
    },
    /// A coefficient or constant is NaN or infinite.
    NonFiniteCoefficient {
        /// The part.
        part: String,
    },
    /// The model reads more than [`MAX_MODEL_DIFFERENCES`] differences.
    TooManyDifferences(usize),
    /// Two parts share a name.
    DuplicatePart(String),
}

impl fmt::Display for ModelError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::UnknownAxis { part, axis } => {
                write!(f, "part `{part}`: axis #{axis} is not an axis of the machine")
            }
            Self::UnknownDifference { part, difference } => write!(
                f,
                "part `{part}`: difference #{difference} is not a difference of the machine"
            ),
            Self::NonFiniteCoefficient { part } => {
                write!(f, "part `{part}`: coefficients must be finite numbers")
            }
            Self::TooManyDifferences(n) => write!(
                f,
                "the model reads {n} temperature differences; at most {MAX_MODEL_DIFFERENCES} are supported"
            ),
            Self::DuplicatePart(name) => write!(f, "duplicate part name `{name}`"),
        }
    }
}

impl core::error::Error for ModelError {}

/// Number of position factors per axis in the per-cycle g table.
pub(crate) const FACTORS: usize = 3;

/// Where g = factor(r_axis) sits in the per-cycle table.
pub(crate) fn g_index(axis: usize, factor: PositionFactor) -> usize {
    FACTORS * axis
        + match factor {
            PositionFactor::Ratio => 0,
            PositionFactor::RatioSquared => 1,
            PositionFactor::BedFactor => 2,
        }
}

/// What the cycle path needs of one difference the model reads.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct DifferenceInput {
    pub plus: usize,
    pub minus: Reference,
}

/// What the cycle path needs of one axis.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct AxisInput {
    pub travel_min: f64,
    pub length: f64,
}

/// A compiled summand: indices local to the model, position terms as a range of a flat list.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct CompiledSummand {
    pub part: usize,
    pub axis: usize,
    pub local_difference: usize,
    pub k0: f64,
    pub terms_start: usize,
    pub terms_end: usize,
    pub bed_multiplier: Option<usize>,
}

/// A thermal compensation model bound to one machine, ready to evaluate every cycle.
///
/// Build it with [`Model::new`]; the machine is checked against the parts then, so that
/// [`Model::evaluate`] needs no checks beyond the values of one cycle.
#[derive(Debug, Clone, PartialEq)]
pub struct Model {
    name: String,
    machine: String,
    parts: Vec<Part>,
    pub(crate) axes: Vec<AxisInput>,
    pub(crate) temperature_count: usize,
    pub(crate) operating_count: usize,
    pub(crate) valid_ranges: Vec<(f64, f64)>,
    /// Machine difference index of each local difference.
    pub(crate) used_differences: Vec<usize>,
    pub(crate) difference_inputs: Vec<DifferenceInput>,
    /// Temperature channels the model reads (sorted, unique).
    pub(crate) used_sensors: Vec<usize>,
    pub(crate) summands: Vec<CompiledSummand>,
    /// Position terms as (index into the per-cycle table of g values, K): the table holds
    /// r, r², KFA of every axis, so the inner loop is one load and one multiply-add.
    pub(crate) terms: Vec<(usize, f64)>,
    pub(crate) constants: Vec<(usize, usize, f64)>,
    pub(crate) part_enabled: Vec<bool>,
    /// Where it was trained, if its file says ([`crate::envelope`]).
    envelope: Option<TrainingEnvelope>,
}

/// The parts flattened for the cycle: every summand with its range of position terms, the
/// constants, and the machine's differences the model reads in the order of first use (the
/// summands' local difference indices).
#[derive(Default)]
struct Compiled {
    used_differences: Vec<usize>,
    summands: Vec<CompiledSummand>,
    terms: Vec<(usize, f64)>,
    constants: Vec<(usize, usize, f64)>,
}

impl Compiled {
    /// Checks part `pi`'s axes, differences and coefficients against the machine and appends
    /// its summands, position terms and constants.
    fn add_part(
        &mut self,
        pi: usize,
        part: &Part,
        machine: &Machine,
        axis_count: usize,
    ) -> Result<(), ModelError> {
        let bad_axis = |axis: usize| ModelError::UnknownAxis {
            part: part.name.clone(),
            axis,
        };
        let non_finite = || ModelError::NonFiniteCoefficient {
            part: part.name.clone(),
        };
        for s in &part.summands {
            if s.axis >= axis_count {
                return Err(bad_axis(s.axis));
            }
            if s.difference >= machine.differences.len() {
                return Err(ModelError::UnknownDifference {
                    part: part.name.clone(),
                    difference: s.difference,
                });
            }
            if let Some(b) = s.bed_multiplier {
                if b >= axis_count {
                    return Err(bad_axis(b));
                }
            }
            if !s.k0_um_per_k.is_finite() {
                return Err(non_finite());
            }
            let local = match self
                .used_differences
                .iter()
                .position(|&d| d == s.difference)
            {
                Some(l) => l,
                None => {
                    self.used_differences.push(s.difference);
                    self.used_differences.len() - 1
                }
            };
            let terms_start = self.terms.len();
            for t in &s.position_terms {
                if t.axis >= axis_count {
                    return Err(bad_axis(t.axis));
                }
                if !t.k_um_per_k.is_finite() {
                    return Err(non_finite());
                }
                self.terms.push((g_index(t.axis, t.factor), t.k_um_per_k));
            }
            self.summands.push(CompiledSummand {
                part: pi,
                axis: s.axis,
                local_difference: local,
                k0: s.k0_um_per_k,
                terms_start,
                terms_end: self.terms.len(),
                bed_multiplier: s.bed_multiplier,
            });
        }
        for &(axis, value) in &part.constants_um {
            if axis >= axis_count {
                return Err(bad_axis(axis));
            }
            if !value.is_finite() {
                return Err(non_finite());
            }
            self.constants.push((pi, axis, value));
        }
        Ok(())
    }
}

/// The temperature channels the differences read, sorted and unique.
fn used_sensors(difference_inputs: &[DifferenceInput]) -> Vec<usize> {
    let mut used_sensors: Vec<usize> = Vec::new();
    for d in difference_inputs {
        used_sensors.push(d.plus);
        if let Reference::Sensor(s) = d.minus {
            used_sensors.push(s);
        }
    }
    used_sensors.sort_unstable();
    used_sensors.dedup();
    used_sensors
}

impl Model {
    /// Binds parts to a machine, checking every index and coefficient.
    pub fn new(
        name: impl Into<String>,
        machine: &Machine,
        parts: Vec<Part>,
    ) -> Result<Self, ModelError> {
        let axis_count = machine.axes.len().min(MAX_AXES);
        let mut compiled = Compiled::default();
        for (pi, part) in parts.iter().enumerate() {
            if parts[..pi].iter().any(|p| p.name == part.name) {
                return Err(ModelError::DuplicatePart(part.name.clone()));
            }
            compiled.add_part(pi, part, machine, axis_count)?;
        }
        let Compiled {
            used_differences,
            summands,
            terms,
            constants,
        } = compiled;
        if used_differences.len() > MAX_MODEL_DIFFERENCES {
            return Err(ModelError::TooManyDifferences(used_differences.len()));
        }
        let difference_inputs: Vec<DifferenceInput> = used_differences
            .iter()
            .map(|&d| DifferenceInput {
                plus: machine.differences[d].plus,
                minus: machine.differences[d].minus,
            })
            .collect();
        let used_sensors = used_sensors(&difference_inputs);
        Ok(Self {
            name: name.into(),
            machine: machine.name.clone(),
            part_enabled: parts.iter().map(|p| p.enabled).collect(),
            envelope: None,
            parts,
            axes: machine
                .axes
                .iter()
                .take(axis_count)
                .map(|a| AxisInput {
                    travel_min: a.travel_min,
                    length: a.length(),
                })
                .collect(),
            temperature_count: machine.temperatures.len(),
            operating_count: machine.operating.len(),
            valid_ranges: machine
                .temperatures
                .iter()
                .map(|t| (t.valid_min_c, t.valid_max_c))
                .collect(),
            used_differences,
            difference_inputs,
            used_sensors,
            summands,
            terms,
            constants,
        })
    }

    /// The model's name.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// The name of the machine it belongs to.
    pub fn machine_name(&self) -> &str {
        &self.machine
    }

    /// The parts as they were given (their `enabled` flags as at construction).
    pub fn parts(&self) -> &[Part] {
        &self.parts
    }

    /// Number of axes the model produces offsets for.
    pub fn axis_count(&self) -> usize {
        self.axes.len()
    }

    /// Indices of the machine's temperature differences the model reads.
    pub fn used_differences(&self) -> &[usize] {
        &self.used_differences
    }

    /// Indices of the machine's temperature channels the model reads.
    pub fn used_sensors(&self) -> &[usize] {
        &self.used_sensors
    }

    /// Switches a part on or off at run time (no allocation). Returns `false` if there is no
    /// part with that index.
    pub fn set_part_enabled(&mut self, part: usize, enabled: bool) -> bool {
        match self.part_enabled.get_mut(part) {
            Some(e) => {
                *e = enabled;
                true
            }
            None => false,
        }
    }

    /// Where the model was trained, if known.
    pub fn envelope(&self) -> Option<&TrainingEnvelope> {
        self.envelope.as_ref()
    }

    /// Stores where the model was trained (from its file or its fit).
    pub fn set_envelope(&mut self, envelope: Option<TrainingEnvelope>) {
        self.envelope = envelope;
    }

    /// Whether a part contributes now.
    pub fn part_enabled(&self, part: usize) -> bool {
        self.part_enabled.get(part).copied().unwrap_or(false)
    }

    /// Index of the part with this name.
    pub fn part_index(&self, name: &str) -> Option<usize> {
        self.parts.iter().position(|p| p.name == name)
    }
}
