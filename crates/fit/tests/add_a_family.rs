//! docs/how-to-add-a-family.md, followed: a position family that is not in the project's list —
//! every difference's summand carries the position of the first axis only — is written as a
//! `PositionDesign` here, handed to the machine's selection beside a shipped family, chosen on
//! a machine where it is the truth, and written into a model the control evaluates.

use std::path::Path;

use truepos_fit::dataset::{Dataset, InputKind, Run};
use truepos_fit::family::PositionFamily;
use truepos_fit::machine_fit::{select, Chosen, MachineData};
use truepos_fit::position_model::{natural_factor, PositionDesign, Shape};
use truepos_fit::settings::Settings;
use truepos_model::{
    CycleInput, Machine, Model, ModelError, Part, PartForm, PositionTerm, RecordedRun, Summand,
};

/// ΔA_n = Σ_m ΔT_m·[K_nm0 + K_nm·g_first]: a machine whose first axis alone moves its heat.
#[derive(Debug)]
struct FirstAxisOnly;

impl PositionDesign for FirstAxisOnly {
    fn key(&self) -> &'static str {
        "first-axis"
    }

    fn name(&self) -> &'static str {
        "position-dependent, the first axis only"
    }

    fn structure(&self, shape: &Shape<'_>) -> Result<Model, ModelError> {
        let mut summands = Vec::new();
        for &n in shape.targets {
            for &m in shape.differences {
                summands.push(Summand {
                    axis: n,
                    difference: m,
                    k0_um_per_k: 0.0,
                    position_terms: vec![PositionTerm {
                        axis: 0,
                        factor: natural_factor(shape.machine, 0),
                        k_um_per_k: 0.0,
                    }],
                    bed_multiplier: None,
                });
            }
        }
        let constants_um = if shape.constant {
            shape.targets.iter().map(|&n| (n, 0.0)).collect()
        } else {
            Vec::new()
        };
        let part = Part {
            name: "first-axis".into(),
            enabled: true,
            form: PartForm::PositionDependent,
            summands,
            constants_um,
        };
        Model::new(shape.name, shape.machine, vec![part])
    }
}

fn twin_machine() -> Machine {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/twin/machine.toml");
    truepos_io::machine_file::load(&path).unwrap().machine
}

/// A run of `rows` samples a minute apart with temperatures and positions drawn at random, and
/// the truth's errors of the X and Z axes as the measured targets.
fn synthetic(machine: &Machine, truth: &Model, rows: usize) -> (Dataset, MachineData) {
    let mut state = 2024u64;
    let mut draw = move || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    let mut run = RecordedRun {
        time_s: Vec::new(),
        temperatures_c: Vec::new(),
        positions: Vec::new(),
        operating: Vec::new(),
    };
    let mut errors = vec![Vec::new(), Vec::new()];
    for i in 0..rows {
        let temps: Vec<f64> = machine
            .temperatures
            .iter()
            .map(|_| 18.0 + 8.0 * draw())
            .collect();
        let pos: Vec<f64> = machine
            .axes
            .iter()
            .map(|a| a.travel_min + (a.travel_max - a.travel_min) * draw())
            .collect();
        let op = vec![0.0; machine.operating.len()];
        let input = CycleInput {
            temperatures_c: &temps,
            positions: &pos,
            operating: &op,
        };
        let e = truth.evaluate(&input).unwrap();
        errors[0].push(e.error_um()[0]);
        errors[1].push(e.error_um()[2]);
        run.time_s.push(60.0 * i as f64);
        run.temperatures_c.push(temps);
        run.positions.push(pos);
        run.operating.push(op);
    }
    let ds = Dataset {
        input_names: vec!["t".into()],
        input_kinds: vec![InputKind::Temperature],
        target_names: vec!["X_error_um".into(), "Z_error_um".into()],
        runs: vec![Run {
            name: "synthetic".into(),
            time_s: run.time_s.clone(),
            inputs: vec![vec![20.0; rows]],
            targets: errors,
        }],
    };
    let data = MachineData {
        machine: machine.clone(),
        runs: vec![run],
        target_axes: vec![0, 2],
        reference: None,
        differences: (0..machine.differences.len()).collect(),
        owners: Vec::new(),
    };
    (ds, data)
}

#[test]
fn a_family_of_ones_own_is_chosen_where_it_is_the_truth() {
    let machine = twin_machine();
    let all: Vec<usize> = (0..machine.differences.len()).collect();
    let zero = FirstAxisOnly
        .structure(&Shape {
            name: "truth",
            machine: &machine,
            differences: &all,
            targets: &[0, 2],
            constant: true,
            owners: &[],
        })
        .unwrap();
    let theta: Vec<f64> = (0..zero.parameter_count())
        .map(|i| ((i * 7919) % 13) as f64 / 13.0 - 0.5)
        .collect();
    let truth = zero.with_parameters(&machine, &theta).unwrap();
    let (ds, data) = synthetic(&machine, &truth, 600);
    let settings = Settings {
        families: Vec::new(),
        absolute_targets: true,
        ..Settings::default()
    };
    let rows: Vec<(usize, usize)> = (0..600).map(|i| (0, i)).collect();
    let shipped = PositionFamily::PositionIndependent;
    let families: [&dyn PositionDesign; 2] = [&shipped, &FirstAxisOnly];
    let sel = select(&ds, &data, None, &rows, &settings, &families).unwrap();

    // Both families were candidates under their own names; the new one was chosen.
    let named: Vec<&str> = sel.candidates.iter().map(|c| c.family.as_str()).collect();
    assert!(
        named.contains(&"prior-art") && named.contains(&"first-axis"),
        "{named:?}"
    );
    for label in &sel.labels {
        assert!(label.starts_with("first-axis on "), "{:?}", sel.labels);
    }
    let Chosen::Position(chosen) = &sel.chosen else {
        panic!("the position form was not chosen: {:?}", sel.labels);
    };
    assert_eq!(chosen.choices[0].family_name, FirstAxisOnly.name());
    assert!(
        sel.cv_rmse_um.iter().all(|&r| r < 0.01),
        "{:?}",
        sel.cv_rmse_um
    );

    // The chosen model is the control's model: it predicts the truth at a new point.
    let temps: Vec<f64> = machine.temperatures.iter().map(|_| 23.5).collect();
    let pos: Vec<f64> = machine.axes.iter().map(|a| a.travel_max).collect();
    let op = vec![0.0; machine.operating.len()];
    let input = CycleInput {
        temperatures_c: &temps,
        positions: &pos,
        operating: &op,
    };
    let want = truth.evaluate(&input).unwrap();
    let got = chosen.model.evaluate(&input).unwrap();
    for a in [0, 2] {
        let (got, want) = (got.error_um()[a], want.error_um()[a]);
        assert!((got - want).abs() < 0.05, "axis {a}: {got} vs {want}");
    }
}
