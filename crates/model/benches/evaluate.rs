//! One control cycle of the reference 3-axis machine: 16 temperature channels, 16 temperature
//! differences, and full cross-axis terms — every axis' error carries every difference with
//! K_nm0 plus r_j, r_j² and KFA_j of all three axes (3 × 16 × 10 = 480 coefficients).
//!
//! Run: `cargo bench -p truepos-model --bench evaluate`. Target: median ≤ 1 µs.

use divan::{black_box, Bencher};
use truepos_model::*;

fn main() {
    divan::main();
}

fn reference_machine() -> Machine {
    let axis = |name: &str, max: f64, carried_by, carriage| Axis {
        name: name.into(),
        kind: AxisKind::Linear,
        travel_min: 0.0,
        travel_max: max,
        carried_by,
        carriage,
    };
    let temperatures = (0..16)
        .map(|i| TemperatureChannel {
            id: format!("t{i}"),
            location: String::new(),
            valid_min_c: 0.0,
            valid_max_c: 80.0,
            lag: None,
        })
        .collect();
    // t15 is ambient: 15 sensors against it, and ambient against 20 °C.
    let mut differences: Vec<_> = (0..15)
        .map(|i| TemperatureDifference {
            name: format!("d{i}"),
            plus: i,
            minus: Reference::Sensor(15),
        })
        .collect();
    differences.push(TemperatureDifference {
        name: "ambient".into(),
        plus: 15,
        minus: Reference::Fixed(20.0),
    });
    Machine {
        name: "reference-vmc".into(),
        axes: vec![
            axis("X", 800.0, Some(1), Carriage::Cantilever),
            axis("Y", 500.0, None, Carriage::Bed),
            axis("Z", 500.0, None, Carriage::Cantilever),
        ],
        temperatures,
        differences,
        operating: vec![],
    }
}

fn full_model(machine: &Machine) -> Model {
    let factors = [
        PositionFactor::Ratio,
        PositionFactor::RatioSquared,
        PositionFactor::BedFactor,
    ];
    let mut summands = Vec::new();
    for n in 0..3 {
        for m in 0..16 {
            let k = |j: usize| 0.1 * ((n * 31 + m * 7 + j * 3) % 17) as f64 - 0.8;
            let mut position_terms = Vec::new();
            for j in 0..3 {
                for (f, factor) in factors.iter().enumerate() {
                    position_terms.push(PositionTerm {
                        axis: j,
                        factor: *factor,
                        k_um_per_k: k(3 * j + f + 1),
                    });
                }
            }
            summands.push(Summand {
                axis: n,
                difference: m,
                k0_um_per_k: k(0),
                position_terms,
                bed_multiplier: None,
            });
        }
    }
    let part = Part {
        name: "structure".into(),
        enabled: true,
        form: PartForm::PositionDependent,
        summands,
        constants_um: vec![],
    };
    Model::new("full-cross-axis", machine, vec![part]).unwrap()
}

#[divan::bench]
fn evaluate_reference_vmc_16_channels_full_cross_axis(bencher: Bencher) {
    let machine = reference_machine();
    let model = full_model(&machine);
    let temperatures: Vec<f64> = (0..16).map(|i| 21.0 + 0.37 * i as f64).collect();
    let positions = [412.5, 133.0, 250.25];
    bencher.bench_local(|| {
        let input = CycleInput {
            temperatures_c: black_box(&temperatures),
            positions: black_box(&positions),
            operating: &[],
        };
        black_box(model.evaluate(&input))
    });
}
