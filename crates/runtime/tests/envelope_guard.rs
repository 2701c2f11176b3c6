//! The training-envelope guard as a property (issue 27): for random models and random inputs
//! far outside where they were trained, the output never exceeds 1.5 × the largest |prediction|
//! on the training inputs, and the guard says it is extrapolating.

mod support;

use proptest::prelude::*;
use support::vmc;
use truepos_model::envelope::{TrainingEnvelope, OUTPUT_FACTOR};
use truepos_model::{CycleInput, Model, Part, PartForm, Summand};
use truepos_runtime::model_set::{ModelEntry, ModelSet};

fn model(coefficients: &[(usize, usize, f64)], constant: f64) -> Model {
    let m = vmc().machine;
    let summands = coefficients
        .iter()
        .map(|&(axis, difference, k)| Summand {
            axis,
            difference: difference % m.differences.len(),
            k0_um_per_k: k,
            position_terms: vec![],
            bed_multiplier: None,
        })
        .collect();
    Model::new(
        "random",
        &m,
        vec![Part {
            name: "structure".into(),
            enabled: true,
            form: PartForm::Regression,
            summands,
            constants_um: vec![(2, constant)],
        }],
    )
    .unwrap()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]
    #[test]
    fn far_outside_the_output_stays_within_its_training_bound(
        coefficients in prop::collection::vec((0..3usize, 0..8usize, -10.0..10.0f64), 1..8),
        constant in -5.0..5.0f64,
        low in 15.0..24.0f64,
        width in 0.0..8.0f64,
        training in prop::collection::vec(prop::collection::vec(0.0..1.0f64, 16), 1..30),
        far in prop::collection::vec(5.0..60.0f64, 16),
    ) {
        let machine = vmc();
        let m = &machine.machine;
        let n_t = m.temperatures.len();
        let positions = [400.0, 250.0, 250.0];
        let operating = vec![0.0; m.operating.len()];
        let mut model = model(&coefficients, constant);
        // The largest |prediction| over the training inputs, every sensor inside [low, low + width].
        let mut max_abs = [0.0f64; 3];
        for row in &training {
            let t: Vec<f64> = (0..n_t).map(|c| low + width * row[c % row.len()]).collect();
            let e = model
                .evaluate(&CycleInput { temperatures_c: &t, positions: &positions, operating: &operating })
                .unwrap();
            for (m, e) in max_abs.iter_mut().zip(e.error_um()) {
                *m = m.max(e.abs());
            }
        }
        model.set_envelope(Some(TrainingEnvelope {
            temperatures: vec![Some((low, low + width)); n_t],
            operating: vec![None; m.operating.len()],
            max_abs_um: max_abs.iter().map(|&v| Some(v)).collect(),
        }));
        let mut set = ModelSet::new(
            vec![ModelEntry { name: "random".into(), model: model.into(), index: [101, 102, 103] }],
            1,
        );
        let temperatures: Vec<f64> = (0..n_t).map(|c| far[c % far.len()]).collect();
        let input = CycleInput { temperatures_c: &temperatures, positions: &positions, operating: &operating };
        let mut out = [0.0; truepos_model::MAX_AXES];
        prop_assert!(set.compensation(0, &input, &mut out));
        for a in 0..3 {
            prop_assert!(
                out[a].abs() <= OUTPUT_FACTOR * max_abs[a] + 1e-9,
                "axis {a}: {} against a training bound {}", out[a], max_abs[a]
            );
        }
        let margin = (0.25 * width).max(2.0);
        let outside = temperatures.iter().any(|&v| v < low - margin || v > low + width + margin);
        prop_assert_eq!(set.beyond(0).is_some(), outside);
    }
}
