//! Builders shared by the model crate's tests: a machine of N serial linear axes, each with a
//! two-sensor temperature difference, and a compact way to write summands.
#![allow(dead_code)]

use truepos_model::*;

/// N linear axes with the given travel lengths (travel [0, L]), axis i+1 resting on axis i;
/// sensors `hot_i` and `cold_i` per axis and difference `dT_i = hot_i − cold_i`.
pub fn serial_machine(lengths: &[f64]) -> Machine {
    let n = lengths.len();
    let mut temperatures = Vec::new();
    let mut differences = Vec::new();
    for i in 0..n {
        for side in ["hot", "cold"] {
            temperatures.push(TemperatureChannel {
                id: format!("{side}_{i}"),
                location: String::new(),
                valid_min_c: -300.0,
                valid_max_c: 300.0,
                lag: None,
            });
        }
        differences.push(TemperatureDifference {
            name: format!("dT_{i}"),
            plus: 2 * i,
            minus: Reference::Sensor(2 * i + 1),
        });
    }
    let machine = Machine {
        name: format!("serial-{n}"),
        axes: lengths
            .iter()
            .enumerate()
            .map(|(i, &l)| Axis {
                name: format!("A{}", i + 1),
                kind: AxisKind::Linear,
                travel_min: 0.0,
                travel_max: l,
                carried_by: if i == 0 { None } else { Some(i - 1) },
                carriage: Carriage::Cantilever,
            })
            .collect(),
        temperatures,
        differences,
        operating: vec![],
    };
    machine.check().unwrap();
    machine
}

/// Temperatures giving ΔT_i = `deltas[i]` (cold side at 20 °C).
pub fn temperatures_for(deltas: &[f64]) -> Vec<f64> {
    deltas.iter().flat_map(|&d| [20.0 + d, 20.0]).collect()
}

/// ΔT_m · [k0 + Σ k·g_j] as the error of axis n (0-based indices).
pub fn summand(n: usize, m: usize, k0: f64, terms: &[(usize, PositionFactor, f64)]) -> Summand {
    Summand {
        axis: n,
        difference: m,
        k0_um_per_k: k0,
        position_terms: terms
            .iter()
            .map(|&(axis, factor, k)| PositionTerm {
                axis,
                factor,
                k_um_per_k: k,
            })
            .collect(),
        bed_multiplier: None,
    }
}

/// One enabled position-dependent part.
pub fn part(summands: Vec<Summand>) -> Part {
    Part {
        name: "structure".into(),
        enabled: true,
        form: PartForm::PositionDependent,
        summands,
        constants_um: vec![],
    }
}

/// Predicted errors for the given ΔT and positions.
pub fn errors(model: &Model, machine: &Machine, deltas: &[f64], positions: &[f64]) -> Vec<f64> {
    let t = temperatures_for(deltas);
    let op = vec![0.0; machine.operating.len()];
    model
        .evaluate(&CycleInput {
            temperatures_c: &t,
            positions,
            operating: &op,
        })
        .unwrap()
        .error_um()
        .to_vec()
}

/// Asserts equality to 1e-9 µm, element by element.
pub fn assert_close(got: &[f64], want: &[f64]) {
    assert_eq!(got.len(), want.len(), "got {got:?}, want {want:?}");
    for (g, w) in got.iter().zip(want) {
        assert!((g - w).abs() < 1e-9, "got {got:?}, want {want:?}");
    }
}
