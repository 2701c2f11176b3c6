//! Model sets, models per axis combination: every model carries an axis-combination index
//! B = (b1, b2, b3), b_i = 100·path + axis number; the service builds the target index D of each
//! path from the control's axis configuration and sets the matching model for that path.

use truepos_model::envelope::{Beyond, TrainingEnvelope};
use truepos_model::{CycleInput, DynamicError, EvalError, MAX_AXES};

pub use truepos_model::config::{index_of, ModelEntry, INDEX_SLOTS};

/// What the runtime keeps of a model that keeps state (a fitted dynamic model): its filters
/// advance every cycle, whether or not it is the one in effect, so that a switch to it finds
/// them current; its output is that of its last good step.
#[derive(Debug, Clone, Copy)]
struct Stepped {
    /// Predicted error per machine axis after the last good step (µm).
    error_um: [f64; MAX_AXES],
    /// Whether the last step succeeded (every input good and finite).
    valid: bool,
    /// Service time of the last good step, NaN before the first.
    last_s: f64,
    /// The input farthest beyond the model's training envelope in its last evaluation.
    beyond: Option<Beyond>,
}

impl Stepped {
    const NEW: Self = Self {
        error_um: [0.0; MAX_AXES],
        valid: false,
        last_s: f64::NAN,
        beyond: None,
    };
}

/// The models and, per path, which of them match its current axis combination.
#[derive(Debug, Clone)]
pub struct ModelSet {
    entries: Vec<ModelEntry>,
    /// Per entry: the runtime's state of a model that keeps state (unused for the others).
    stepped: Vec<Stepped>,
    /// This cycle's temperatures with every channel the validator refused as NaN, for the
    /// models that keep state (capacity reserved at construction).
    masked: Vec<f64>,
    /// A model's inputs clamped to its training envelope (capacity reserved, as `masked`).
    guarded_t: Vec<f64>,
    guarded_o: Vec<f64>,
    /// Per path: the target index D and the matching models in set order (preferred first).
    targets: Vec<[u32; INDEX_SLOTS]>,
    candidates: Vec<Vec<usize>>,
}

impl ModelSet {
    /// A set of models; `paths` is the largest number of paths the control may have.
    pub fn new(entries: Vec<ModelEntry>, paths: usize) -> Self {
        let n = entries.len();
        let channels = entries
            .iter()
            .filter_map(|e| e.model.as_dynamic())
            .map(|d| d.channels().temperatures)
            .max()
            .unwrap_or(0);
        let (t, o) = envelope_channels(&entries);
        Self {
            stepped: vec![Stepped::NEW; n],
            masked: Vec::with_capacity(channels),
            guarded_t: Vec::with_capacity(t),
            guarded_o: Vec::with_capacity(o),
            entries,
            targets: vec![[0; INDEX_SLOTS]; paths],
            // Capacity for every model, so that re-selecting never allocates.
            candidates: (0..paths).map(|_| Vec::with_capacity(n)).collect(),
        }
    }

    /// The models.
    pub fn entries(&self) -> &[ModelEntry] {
        &self.entries
    }

    /// Mutable access to a model (to switch its parts on or off).
    pub fn entry_mut(&mut self, i: usize) -> Option<&mut ModelEntry> {
        self.entries.get_mut(i)
    }

    /// Puts `entry` in place of model `i` and returns the model it replaces (`None`: no model
    /// `i`; nothing changes). The caller checks that it serves the same axis combination
    /// ([`crate::Service::replace_model`]). A model that keeps state starts with fresh filters.
    /// Allocates only for a dynamic model that reads more channels than any before it; call it
    /// between cycles.
    pub fn replace(&mut self, i: usize, entry: ModelEntry) -> Option<ModelEntry> {
        let slot = self.entries.get_mut(i)?;
        if let Some(d) = entry.model.as_dynamic() {
            let channels = d.channels().temperatures;
            self.masked
                .reserve(channels.saturating_sub(self.masked.len()));
        }
        if let Some(env) = entry.model.envelope() {
            let (t, o) = (env.temperatures.len(), env.operating.len());
            self.guarded_t
                .reserve(t.saturating_sub(self.guarded_t.capacity()));
            self.guarded_o
                .reserve(o.saturating_sub(self.guarded_o.capacity()));
        }
        self.stepped[i] = Stepped::NEW;
        Some(std::mem::replace(slot, entry))
    }

    /// Advances the filters of every model that keeps state to service time `now_s`, from this
    /// cycle's values of the channels `good` accepts. A cycle with a bad or non-finite input
    /// leaves a model's filters untouched and the model invalid until its next good cycle (whose
    /// step then spans the gap); two cycles at one instant advance nothing. Allocates nothing.
    pub fn step_all(
        &mut self,
        now_s: f64,
        temperatures_c: &[f64],
        operating: &[f64],
        good: impl Fn(usize) -> bool + Copy,
    ) {
        if !self.entries.iter().any(|e| e.model.keeps_state()) {
            return;
        }
        self.masked.clear();
        self.masked
            .extend(
                temperatures_c
                    .iter()
                    .enumerate()
                    .map(|(c, &v)| if good(c) { v } else { f64::NAN }),
            );
        let input = CycleInput {
            temperatures_c: &self.masked,
            // Positions are read only by models that keep no state.
            positions: &[],
            operating,
        };
        for (e, st) in self.entries.iter_mut().zip(&mut self.stepped) {
            if !e.model.keeps_state() {
                continue;
            }
            let dt = if st.last_s.is_finite() {
                now_s - st.last_s
            } else {
                0.0
            };
            match e
                .model
                .step_guarded(dt, &input, (&mut self.guarded_t, &mut self.guarded_o))
            {
                Ok((error_um, beyond)) => {
                    st.error_um = error_um;
                    st.valid = true;
                    st.last_s = now_s;
                    st.beyond = beyond;
                }
                // Two cycles at one instant: nothing to advance.
                Err(EvalError::Filter(DynamicError::BadTimeStep)) if dt <= 0.0 => {}
                Err(_) => st.valid = false,
            }
        }
    }

    /// Writes the compensation (−error, µm) of every machine axis by model `i` into `out` and
    /// returns whether this cycle gives a valid output (`false`: an input is bad or out of
    /// range). A model that keeps state gives the output of its last step ([`Self::step_all`]);
    /// the others are evaluated on `input`. Allocates nothing.
    pub fn compensation(
        &mut self,
        i: usize,
        input: &CycleInput<'_>,
        out: &mut [f64; MAX_AXES],
    ) -> bool {
        let (Some(e), Some(st)) = (self.entries.get_mut(i), self.stepped.get(i)) else {
            return false;
        };
        let error_um = if e.model.keeps_state() {
            if !st.valid {
                return false;
            }
            st.error_um
        } else {
            // A model without state ignores the time step.
            match e
                .model
                .step_guarded(0.0, input, (&mut self.guarded_t, &mut self.guarded_o))
            {
                Ok((error_um, beyond)) => {
                    if let Some(st) = self.stepped.get_mut(i) {
                        st.beyond = beyond;
                    }
                    error_um
                }
                Err(_) => return false,
            }
        };
        for (f, e) in out.iter_mut().zip(&error_um) {
            // 0 − e rather than −e: a zero error gives +0, not −0.
            *f = 0.0 - e;
        }
        true
    }

    /// The input farthest beyond model `i`'s training envelope in its last evaluation (its
    /// inputs were clamped and its output capped), if any.
    pub fn beyond(&self, i: usize) -> Option<Beyond> {
        self.stepped.get(i).and_then(|st| st.beyond)
    }

    /// Number of paths.
    pub fn paths(&self) -> usize {
        self.targets.len()
    }

    /// The target index D of a path (0-based).
    pub fn target(&self, path: usize) -> [u32; INDEX_SLOTS] {
        self.targets[path]
    }

    /// The models matching a path, preferred first.
    pub fn candidates(&self, path: usize) -> &[usize] {
        &self.candidates[path]
    }

    /// Builds the target index of every path from the control's axis configuration (machine
    /// axis indices per path) and the axes' codes, and compares it with every model's index
    /// (docs/glossary.md: model set). Returns whether anything changed. Allocates nothing.
    pub fn select(&mut self, paths: &[Vec<usize>], codes: &[u32]) -> bool {
        let mut changed = false;
        for p in 0..self.targets.len() {
            let axes = paths.get(p).map(Vec::as_slice).unwrap_or(&[]);
            let target = index_of(axes.iter().filter_map(|&a| codes.get(a).copied()));
            if target == self.targets[p] && !self.candidates[p].is_empty() {
                continue;
            }
            changed |= target != self.targets[p];
            self.targets[p] = target;
            let list = &mut self.candidates[p];
            list.clear();
            if target != [0; INDEX_SLOTS] {
                for (i, e) in self.entries.iter().enumerate() {
                    if e.index == target {
                        list.push(i);
                    }
                }
            }
        }
        changed
    }
}

/// The most temperature and operating channels any model's envelope clamps: the capacity of
/// the scratch, so that guarding never allocates.
fn envelope_channels(entries: &[ModelEntry]) -> (usize, usize) {
    entries
        .iter()
        .filter_map(|e| e.model.envelope())
        .map(|env: &TrainingEnvelope| (env.temperatures.len(), env.operating.len()))
        .fold((0, 0), |(t, o), (a, b)| (t.max(a), o.max(b)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use truepos_model::{Axis, AxisKind, Carriage, Machine, Model};

    fn model() -> Model {
        let axis = |n: &str| Axis {
            name: n.into(),
            kind: AxisKind::Linear,
            travel_min: 0.0,
            travel_max: 100.0,
            carried_by: None,
            carriage: Carriage::Cantilever,
        };
        let m = Machine {
            name: "two-path lathe".into(),
            axes: vec![axis("X1"), axis("Z1"), axis("X2"), axis("Z2")],
            temperatures: vec![],
            differences: vec![],
            operating: vec![],
        };
        Model::new("m", &m, vec![]).unwrap()
    }

    /// The glossary's axis-switching example: path 1 = X1, Z1 → [101, 102, 0]; path 2 = X2, Z2 →
    /// [201, 202, 0]. After X1 and X2 are switched: path 1 → [201, 102, 0] (model 3), path 2 →
    /// [101, 202, 0] (model 4).
    #[test]
    fn each_axis_combination_selects_its_model() {
        let entry = |name: &str, index| ModelEntry {
            name: name.into(),
            model: model().into(),
            index,
        };
        let mut set = ModelSet::new(
            vec![
                entry("model 1", [101, 102, 0]),
                entry("model 2", [201, 202, 0]),
                entry("model 3", [201, 102, 0]),
                entry("model 4", [101, 202, 0]),
            ],
            2,
        );
        // Machine axes X1, Z1, X2, Z2 with codes 101, 102, 201, 202.
        let codes = [101, 102, 201, 202];
        assert!(set.select(&[vec![0, 1], vec![2, 3]], &codes));
        assert_eq!(set.target(0), [101, 102, 0]);
        assert_eq!(set.target(1), [201, 202, 0]);
        assert_eq!(set.candidates(0), &[0]);
        assert_eq!(set.candidates(1), &[1]);
        // Nothing changed: no new selection.
        assert!(!set.select(&[vec![0, 1], vec![2, 3]], &codes));
        // X1 and X2 switched between the paths.
        assert!(set.select(&[vec![2, 1], vec![0, 3]], &codes));
        assert_eq!(set.target(0), [201, 102, 0]);
        assert_eq!(set.target(1), [101, 202, 0]);
        assert_eq!(set.candidates(0), &[2]);
        assert_eq!(set.candidates(1), &[3]);
    }

    #[test]
    fn no_match_leaves_no_candidate() {
        let mut set = ModelSet::new(
            vec![ModelEntry {
                name: "only".into(),
                model: model().into(),
                index: [101, 102, 0],
            }],
            1,
        );
        set.select(&[vec![0, 2]], &[101, 102, 201, 202]);
        assert_eq!(set.target(0), [101, 201, 0]);
        assert!(set.candidates(0).is_empty());
    }

    #[test]
    fn selecting_allocates_nothing() {
        let mut set = ModelSet::new(
            (0..4)
                .map(|i| ModelEntry {
                    name: format!("m{i}"),
                    model: model().into(),
                    index: [101, 102, 0],
                })
                .collect(),
            2,
        );
        let codes = [101, 102, 201, 202];
        let a = [vec![0, 1], vec![2, 3]];
        let b = [vec![2, 1], vec![0, 3]];
        set.select(&a, &codes);
        let counted = allocation_counter::measure(|| {
            for _ in 0..100 {
                set.select(&b, &codes);
                set.select(&a, &codes);
            }
        });
        assert_eq!(counted.count_total, 0);
        assert_eq!(set.candidates(0).len(), 4);
    }
}
