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
