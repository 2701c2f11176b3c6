//! Model files: written and read back they evaluate identically, the order of terms in a file
//! does not change results, and the shipped examples load and bind.

use std::path::Path;

use proptest::prelude::*;
use truepos_io::model_file::position;
use truepos_io::{cycles, machine_file};
use truepos_model::*;

mod support;
use support::{repo, vmc};

fn factor() -> impl Strategy<Value = PositionFactor> {
    prop_oneof![
        Just(PositionFactor::Ratio),
        Just(PositionFactor::RatioSquared),
        Just(PositionFactor::BedFactor),
    ]
}

/// Random summands over the VMC's 3 axes and 16 differences.
fn summands() -> impl Strategy<Value = Vec<Summand>> {
    prop::collection::vec(
        (
            0..3usize,
            0..16usize,
            -10.0..10.0f64,
            prop::collection::vec((0..3usize, factor(), -10.0..10.0f64), 0..4),
            prop::option::of(0..3usize),
        )
            .prop_map(|(axis, difference, k0, terms, bed)| Summand {
                axis,
                difference,
                k0_um_per_k: k0,
                position_terms: terms
                    .into_iter()
                    .map(|(axis, factor, k)| PositionTerm {
                        axis,
                        factor,
                        k_um_per_k: k,
                    })
                    .collect(),
                bed_multiplier: bed,
            }),
        1..20,
    )
}

fn evaluate(model: &Model, t: &[f64], p: &[f64]) -> Vec<f64> {
    model
        .evaluate(&CycleInput {
            temperatures_c: t,
            positions: p,
            operating: &[0.0; 4],
        })
        .unwrap()
        .error_um()
        .to_vec()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    #[test]
    fn written_and_read_back_evaluates_identically_in_any_term_order(
        s in summands(),
        rotate in 0..20usize,
        t in prop::collection::vec(15.0..45.0f64, 16),
        p in (0.0..=800.0f64, 0.0..=500.0f64, 0.0..=500.0f64),
    ) {
        let machine = vmc();
        let part = Part {
            name: "structure".into(),
            enabled: true,
            form: PartForm::PositionDependent,
            summands: s,
            constants_um: vec![(2, 1.5)],
        };
        let model = Model::new("random", &machine, vec![part]).unwrap();
        let file = position::ModelFile::from_model(&model, &machine);
        let text = file.to_toml();
        let back = position::parse(Path::new("random.toml"), &text, &machine).unwrap();

        let mut reordered = file.clone();
        reordered.part[0].term.reverse();
        let n = reordered.part[0].term.len();
        reordered.part[0].term.rotate_left(rotate % n);
        reordered.inputs.differences.reverse();
        let shuffled = position::parse(Path::new("shuffled.toml"), &reordered.to_toml(), &machine).unwrap();

        let pos = [p.0, p.1, p.2];
        let a = evaluate(&model, &t, &pos);
        let b = evaluate(&back, &t, &pos);
        let c = evaluate(&shuffled, &t, &pos);
        // Written and read back: bit for bit (TOML floats round-trip exactly).
        prop_assert_eq!(&a, &b);
        for i in 0..3 {
            prop_assert!((a[i] - c[i]).abs() <= 1e-9 * (1.0 + a[i].abs()));
        }
    }
}

#[test]
fn regression_parts_are_written_as_regression() {
    let machine = vmc();
    let model = position::load(&repo("examples/vmc3/model.toml"), &machine).unwrap();
    let text = position::ModelFile::from_model(&model, &machine).to_toml();
    assert!(text.contains("form = \"regression\""), "{text}");
    let back = position::parse(Path::new("x.toml"), &text, &machine).unwrap();
    assert_eq!(back.parts(), model.parts());
}

#[test]
fn json_model_files_are_read_too() {
    let machine = vmc();
    let model = position::load(&repo("examples/vmc3/model.toml"), &machine).unwrap();
    let file = position::ModelFile::from_model(&model, &machine);
    let json = serde_json::to_string_pretty(&file).unwrap();
    let back = position::parse_json(Path::new("x.json"), &json, &machine).unwrap();
    assert_eq!(back.parts(), model.parts());
}

#[test]
fn shipped_examples_load() {
    for dir in ["examples/vmc3", "examples/cross-slide"] {
        let machine = machine_file::load(&repo(&format!("{dir}/machine.toml")))
            .unwrap()
            .machine;
        let model = position::load(&repo(&format!("{dir}/model.toml")), &machine).unwrap();
        let run = cycles::load(
            &repo(&format!("{dir}/run.csv")),
            &machine,
            model.used_sensors(),
        )
        .unwrap();
        assert!(run.run.time_s.len() > 2, "{dir}");
        for i in 0..run.run.time_s.len() {
            model
                .evaluate(&CycleInput {
                    temperatures_c: &run.run.temperatures_c[i],
                    positions: &run.run.positions[i],
                    operating: &run.run.operating[i],
                })
                .unwrap_or_else(|e| panic!("{dir} row {i}: {e}"));
        }
    }
}

#[test]
fn cycles_errors_name_line_column_and_key() {
    let machine = vmc();
    let header = "time_s,X_mm,Y_mm,Z_mm,x_slide_top,x_slide_bottom\n";
    let read = |body: &str, required: &[usize]| {
        cycles::read(
            Path::new("run.csv"),
            format!("{header}{body}").as_bytes(),
            &machine,
            required,
        )
        .unwrap_err()
        .to_string()
    };
    assert_eq!(
        read("0,1,2,3,20,21\n1,1,2,x,20,21\n", &[0, 1]),
        "run.csv:3:4: `Z_mm`: expected a number, got `x`"
    );
    assert_eq!(
        read("0,1,2,3,20,21\n0,1,2,3,20,21\n", &[0, 1]),
        "run.csv:3:1: `time_s`: expected time to increase, got 0 after 0"
    );
    assert_eq!(
        read("0,1,2,3,20,21\n", &[15]),
        "run.csv:1:1: `ambient`: missing column `ambient` (temperature the model reads); the header has: time_s, X_mm, Y_mm, Z_mm, x_slide_top, x_slide_bottom"
    );
    assert_eq!(read("", &[]), "run.csv: no data rows after the header");
    assert_eq!(
        read("0,1,2,3,20\n", &[]),
        "run.csv:2:1: expected 6 fields as in the header, found 5"
    );
}

/// A spindle test run (ISO 230-3) has no axis positions: a model that reads none may be
/// evaluated on it (positions read NaN), one that may read them is refused with the column named.
#[test]
fn positions_may_be_absent_only_when_the_model_reads_none() {
    let machine = vmc();
    let text = "time_s,x_slide_top\n0,20\n15,20.5\n";
    let read = |positions| {
        cycles::read_with(
            Path::new("spindle.csv"),
            text.as_bytes(),
            &machine,
            &[0],
            positions,
        )
    };
    let run = read(cycles::Positions::Optional).unwrap();
    assert_eq!(run.run.time_s, [0.0, 15.0]);
    assert_eq!(run.run.temperatures_c[1][0], 20.5);
    assert!(run.run.positions.iter().flatten().all(|p| p.is_nan()));
    assert_eq!(
        read(cycles::Positions::Required).unwrap_err().to_string(),
        "spindle.csv:1:1: `X_mm`: missing column `X_mm` (axis position); the header has: time_s, x_slide_top"
    );
}
