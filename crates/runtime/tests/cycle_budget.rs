//! A model whose evaluation does not fit the cycle is refused at load (red team, issue 32: a
//! valid 200 000-term model overran 4 993 of 4 999 cycles at 1 kHz); the example fits easily.

mod support;

use support::{repo, vmc};
use truepos_model::{Model, Part, PartForm, Summand};
use truepos_runtime::cycle_budget;
use truepos_runtime::model_set::ModelEntry;

fn entry(name: &str, model: Model) -> ModelEntry {
    ModelEntry {
        name: name.into(),
        model: model.into(),
        index: [101, 102, 103],
    }
}

#[test]
fn a_model_too_slow_for_the_cycle_is_refused_and_the_example_fits() {
    let machine = vmc();
    let m = &machine.machine;
    let example =
        truepos_io::model_file::position::load(&repo("examples/vmc3/model.toml"), m).unwrap();
    let took = cycle_budget::check(&entry("example", example), m, 1e-3).unwrap();
    assert!(took.as_secs_f64() < 250e-6, "{took:?}");

    let summands = (0..20_000)
        .map(|i| Summand {
            axis: i % 3,
            difference: i % m.differences.len(),
            k0_um_per_k: 1e-6,
            position_terms: vec![],
            bed_multiplier: None,
        })
        .collect();
    let part = Part {
        name: "structure".into(),
        enabled: true,
        form: PartForm::PositionDependent,
        summands,
        constants_um: vec![],
    };
    let big = Model::new("big", m, vec![part]).unwrap();
    // 20 000 terms in a 10 µs cycle (a budget of 2.5 µs): refused, naming model and figures.
    let err = cycle_budget::check(&entry("big", big.clone()), m, 1e-5).unwrap_err();
    assert!(
        err.contains("model `big`: one evaluation takes") && err.contains("overrun"),
        "{err}"
    );
    // The same model in a 1 s cycle fits.
    assert!(cycle_budget::check(&entry("big", big), m, 1.0).is_ok());
}
