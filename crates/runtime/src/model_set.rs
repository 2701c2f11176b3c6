//! Model sets (seed D, DE 10 2019 215 634 B4): every model carries an axis-combination index
//! B = (b1, b2, b3), b_i = 100·path + axis number; the service builds the target index D of each
//! path from the control's axis configuration and sets the matching model for that path.

use truepos_io::dynamic_model_file::{self, BoundDynamicModel, MachineInput};
use truepos_model::{CycleInput, Model, MAX_AXES};

/// Slots of an axis-combination index (seed D uses three).
pub const INDEX_SLOTS: usize = 3;

/// A model the service runs: seed A/C's form (evaluated afresh every cycle) or a fitted dynamic
/// model (its filters advance every cycle, whether or not it is the one in effect, so that a
/// switch to it finds its filters current).
// Built once at load time and kept in one Vec: the variants' sizes cost nothing on the cycle,
// a Box would cost an indirection on it.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone)]
pub enum RuntimeModel {
    /// A model of seed A's general form / seed C's regression (`truepos-model` file).
    Static(Model),
    /// A fitted dynamic model (`truepos-dynamic-model` file).
    Dynamic(DynamicEntry),
}

impl From<Model> for RuntimeModel {
    fn from(m: Model) -> Self {
        Self::Static(m)
    }
}

/// A dynamic model with its input buffer and its last output.
#[derive(Debug, Clone)]
pub struct DynamicEntry {
    bound: BoundDynamicModel,
    sensors: Vec<usize>,
    input: Vec<f64>,
    /// Predicted error per machine axis after the last good step (µm).
    error_um: [f64; MAX_AXES],
    /// Whether the last step succeeded (every input good and finite).
    valid: bool,
    /// Service time of the last good step, NaN before the first.
    last_s: f64,
}

impl DynamicEntry {
    /// Wraps a bound model.
    pub fn new(bound: BoundDynamicModel) -> Self {
        let sensors = bound.temperature_channels();
        Self {
            input: vec![0.0; bound.inputs.len()],
            sensors,
            error_um: [0.0; MAX_AXES],
            valid: false,
            last_s: f64::NAN,
            bound,
        }
    }

    /// The bound model.
    pub fn bound(&self) -> &BoundDynamicModel {
        &self.bound
    }

    /// Advances the filters to service time `now_s` with this cycle's values. A cycle with a
    /// bad or non-finite input leaves the filters untouched and the model invalid until the
    /// next good cycle (whose step then spans the gap). Allocates nothing.
    pub fn step(
        &mut self,
        now_s: f64,
        temperatures_c: &[f64],
        operating: &[f64],
        good: impl Fn(usize) -> bool,
    ) {
        let mut ok = true;
        for (slot, input) in self.input.iter_mut().zip(&self.bound.inputs) {
            *slot = match *input {
                MachineInput::Temperature(c) if good(c) => {
                    temperatures_c.get(c).copied().unwrap_or(f64::NAN)
                }
                MachineInput::Temperature(_) => f64::NAN,
                MachineInput::Operating(c) => operating.get(c).copied().unwrap_or(f64::NAN),
            };
            ok &= slot.is_finite();
        }
        if !ok {
            self.valid = false;
            return;
        }
        let dt = if self.last_s.is_finite() {
            now_s - self.last_s
        } else {
            0.0
        };
        if self.last_s.is_finite() && dt <= 0.0 {
            // Two cycles at one instant: nothing to advance.
            return;
        }
        match self.bound.model.step(dt, &self.input) {
            Ok(out) => {
                self.error_um = [0.0; MAX_AXES];
                for (e, axis) in out.iter().zip(&self.bound.axes) {
                    if let Some(a) = axis.filter(|&a| a < MAX_AXES) {
                        self.error_um[a] = *e;
                    }
                }
                self.valid = true;
                self.last_s = now_s;
            }
            Err(_) => self.valid = false,
        }
    }
}

impl RuntimeModel {
    /// The temperature channels it reads (lagged channels count as what they are).
    pub fn used_sensors(&self) -> &[usize] {
        match self {
            Self::Static(m) => m.used_sensors(),
            Self::Dynamic(d) => &d.sensors,
        }
    }

    /// The static model, if it is one.
    pub fn as_static(&self) -> Option<&Model> {
        match self {
            Self::Static(m) => Some(m),
            Self::Dynamic(_) => None,
        }
    }

    /// Advances a dynamic model's filters (nothing for a static model).
    pub fn step(
        &mut self,
        now_s: f64,
        temperatures_c: &[f64],
        operating: &[f64],
        good: impl Fn(usize) -> bool,
    ) {
        if let Self::Dynamic(d) = self {
            d.step(now_s, temperatures_c, operating, good);
        }
    }

    /// Writes the compensation (−error, µm) of every machine axis into `out` and returns
    /// whether this cycle gives a valid output (`false`: an input is bad or out of range).
    /// Allocates nothing.
    pub fn compensation(&self, input: &CycleInput<'_>, out: &mut [f64; MAX_AXES]) -> bool {
        match self {
            Self::Static(m) => match m.evaluate(input) {
                Ok(c) => {
                    for (a, f) in out.iter_mut().enumerate().take(c.axis_count()) {
                        *f = c.compensation_um(a);
                    }
                    true
                }
                Err(_) => false,
            },
            Self::Dynamic(d) if d.valid => {
                for (f, e) in out.iter_mut().zip(&d.error_um) {
                    *f = -e;
                }
                true
            }
            Self::Dynamic(_) => false,
        }
    }
}

/// A model with the axis combination it serves.
#[derive(Debug, Clone)]
pub struct ModelEntry {
    /// Name for events and status.
    pub name: String,
    /// The model.
    pub model: RuntimeModel,
    /// Its index B, 0 in unused slots.
    pub index: [u32; INDEX_SLOTS],
}

/// Builds an index from axis codes (100·path + number), 0 in unused slots; codes beyond the
/// slots are ignored (a path with more axes than slots matches on its first three).
pub fn index_of(codes: impl IntoIterator<Item = u32>) -> [u32; INDEX_SLOTS] {
    let mut index = [0; INDEX_SLOTS];
    for (slot, code) in index.iter_mut().zip(codes) {
        *slot = code;
    }
    index
}

/// Loads the model files of a set, in order of preference, bound to the machine: static model
/// files (TOML/JSON) and fitted dynamic model files (JSON, recognised by their `format`). A model whose
/// file carries no axis-combination index serves path 1's axes (seed D's index of the axes
/// whose `path` is 1, by their codes).
pub fn load_entries(
    paths: &[std::path::PathBuf],
    machine: &crate::config::MachineConfig,
) -> Result<Vec<ModelEntry>, truepos_io::InputError> {
    let default_index = index_of(
        machine
            .axes
            .iter()
            .filter(|a| a.path == 1)
            .map(|a| a.code()),
    );
    paths
        .iter()
        .map(|path| {
            let text = std::fs::read_to_string(path).unwrap_or_default();
            if dynamic_model_file::is_dynamic(&text) {
                let bound = dynamic_model_file::load(path, &machine.machine)?;
                return Ok(ModelEntry {
                    name: bound.name.clone(),
                    index: bound
                        .axis_index
                        .as_ref()
                        .map_or(default_index, |b| index_of(b.iter().copied())),
                    model: RuntimeModel::Dynamic(DynamicEntry::new(bound)),
                });
            }
            let loaded = truepos_io::model_file::load_entry(path, &machine.machine)?;
            Ok(ModelEntry {
                name: loaded.model.name().to_string(),
                index: loaded
                    .axis_index
                    .as_ref()
                    .map_or(default_index, |b| index_of(b.iter().copied())),
                model: RuntimeModel::Static(loaded.model),
            })
        })
        .collect()
}

/// The models and, per path, which of them match its current axis combination.
#[derive(Debug, Clone)]
pub struct ModelSet {
    entries: Vec<ModelEntry>,
    /// Per path: the target index D and the matching models in set order (preferred first).
    targets: Vec<[u32; INDEX_SLOTS]>,
    candidates: Vec<Vec<usize>>,
}

impl ModelSet {
    /// A set of models; `paths` is the largest number of paths the control may have.
    pub fn new(entries: Vec<ModelEntry>, paths: usize) -> Self {
        let n = entries.len();
        Self {
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

    /// Advances every dynamic model's filters (see [`RuntimeModel::step`]). Allocates nothing.
    pub fn step_all(
        &mut self,
        now_s: f64,
        temperatures_c: &[f64],
        operating: &[f64],
        good: impl Fn(usize) -> bool + Copy,
    ) {
        for e in &mut self.entries {
            e.model.step(now_s, temperatures_c, operating, good);
        }
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
    /// (seed D, Fig. 7). Returns whether anything changed. Allocates nothing.
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

#[cfg(test)]
mod tests {
    use super::*;
    use truepos_model::{Axis, AxisKind, Carriage, Machine};

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

    /// Seed D's example: path 1 = X1, Z1 → [101, 102, 0]; path 2 = X2, Z2 → [201, 202, 0].
    /// After X1 and X2 are switched: path 1 → [201, 102, 0] (model 3), path 2 → [101, 202, 0]
    /// (model 4).
    #[test]
    fn seed_d_example_with_axis_switching() {
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
