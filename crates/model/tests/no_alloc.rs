//! The cycle path allocates nothing: a counting global allocator (from the
//! `allocation-counter` crate) around `Model::evaluate` sees zero allocations, for a good cycle
//! and for a cycle that fails on a NaN.

mod common;

use common::*;
use truepos_model::PositionFactor::{BedFactor, Ratio, RatioSquared};
use truepos_model::*;

#[test]
fn evaluate_allocates_nothing() {
    let m = serial_machine(&[800.0, 500.0, 400.0]);
    let mut summands = Vec::new();
    for n in 0..3 {
        for dm in 0..3 {
            let mut s = summand(
                n,
                dm,
                1.0,
                &[
                    (0, Ratio, 0.5),
                    (1, RatioSquared, -0.3),
                    (2, BedFactor, 0.2),
                ],
            );
            s.bed_multiplier = (n == dm).then_some(1);
            summands.push(s);
        }
    }
    let model = Model::new("full", &m, vec![part(summands)]).unwrap();
    let good = temperatures_for(&[1.0, 2.0, 3.0]);
    let mut bad = good.clone();
    bad[2] = f64::NAN;
    let positions = [100.0, 200.0, 300.0];

    let mut sum = 0.0;
    let counted = allocation_counter::measure(|| {
        for _ in 0..1000 {
            let c = model
                .evaluate(&CycleInput {
                    temperatures_c: &good,
                    positions: &positions,
                    operating: &[],
                })
                .unwrap();
            sum += c.error_um()[0];
            let e = model.evaluate(&CycleInput {
                temperatures_c: &bad,
                positions: &positions,
                operating: &[],
            });
            assert!(e.is_err());
        }
    });
    assert!(sum.is_finite() && sum != 0.0);
    assert_eq!(counted.count_total, 0, "allocations on the cycle path");
}

/// The counter does count: building a model allocates (so the zero above means something).
#[test]
fn the_counter_sees_allocations() {
    let m = serial_machine(&[800.0, 500.0]);
    let counted = allocation_counter::measure(|| {
        let model = Model::new("x", &m, vec![part(vec![summand(0, 0, 1.0, &[])])]).unwrap();
        assert_eq!(model.axis_count(), 2);
    });
    assert!(counted.count_total > 0);
}

/// The one door the control steps a model through allocates nothing either, for a static model
/// and for a fitted dynamic one (input gathering, filters, mapping to axes), on good cycles and
/// on cycles refused for a NaN input.
#[test]
fn compensation_step_allocates_nothing() {
    let m = serial_machine(&[800.0, 500.0]);
    let static_model = Model::new(
        "static",
        &m,
        vec![part(vec![summand(1, 0, 2.0, &[(0, Ratio, 4.0)])])],
    )
    .unwrap();
    let bank = FeatureBank::new(FeatureSpec {
        temperatures: 2,
        operating: 0,
        temperature_rise: true,
        temperature_taus_s: vec![100.0],
        rate_taus_s: vec![50.0],
        operating_taus_s: vec![],
        operating_square: false,
        rise_while_running: false,
    })
    .unwrap();
    let n = bank.features().len();
    let dynamic = DynamicModel::new(bank, vec![0.5, -0.5], vec![1.0; 2 * n]).unwrap();
    let bound = BoundDynamicModel::new(
        "dynamic".into(),
        dynamic,
        vec![MachineInput::Temperature(2), MachineInput::Temperature(0)],
        vec![Some(1), Some(0)],
        vec![],
        Channels {
            temperatures: m.temperatures.len(),
            operating: 0,
            axes: m.axes.len(),
        },
    )
    .unwrap();
    let mut models = [
        CompensationModel::from(static_model),
        CompensationModel::from(bound),
    ];
    let mut good = temperatures_for(&[1.0, 2.0]);
    let mut bad = good.clone();
    bad[0] = f64::NAN;
    let positions = [100.0, 200.0];
    let mut sum = 0.0;
    let counted = allocation_counter::measure(|| {
        for k in 0..1000 {
            good[0] = 21.0 + f64::from(k) * 1e-3;
            for model in &mut models {
                let e = model
                    .step(
                        0.001,
                        &CycleInput {
                            temperatures_c: &good,
                            positions: &positions,
                            operating: &[],
                        },
                    )
                    .unwrap();
                sum += e[0] + e[1];
                assert!(model
                    .step(
                        0.001,
                        &CycleInput {
                            temperatures_c: &bad,
                            positions: &positions,
                            operating: &[],
                        },
                    )
                    .is_err());
            }
        }
    });
    assert!(sum.is_finite() && sum != 0.0);
    assert_eq!(counted.count_total, 0, "allocations on the cycle path");
}
