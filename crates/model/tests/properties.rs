//! Property tests of the general form: zero coefficients give zero, the error is linear in ΔT at
//! fixed positions, and the order of summands does not matter.

mod common;

use common::*;
use proptest::prelude::*;
use truepos_model::*;

const LENGTHS: [f64; 3] = [800.0, 500.0, 400.0];

fn factor() -> impl Strategy<Value = PositionFactor> {
    prop_oneof![
        Just(PositionFactor::Ratio),
        Just(PositionFactor::RatioSquared),
        Just(PositionFactor::BedFactor),
    ]
}

/// A random summand over 3 axes and 3 differences, coefficients from `k`.
fn summand_strategy(k: impl Strategy<Value = f64> + Clone) -> impl Strategy<Value = Summand> {
    (
        0..3usize,
        0..3usize,
        k.clone(),
        prop::collection::vec((0..3usize, factor(), k), 0..4),
        prop::option::of(0..3usize),
    )
        .prop_map(|(n, m, k0, terms, bed)| {
            let mut s = summand(n, m, k0, &terms);
            s.bed_multiplier = bed;
            s
        })
}

fn positions() -> impl Strategy<Value = Vec<f64>> {
    (0.0..=1.0f64, 0.0..=1.0f64, 0.0..=1.0f64)
        .prop_map(|(a, b, c)| vec![a * LENGTHS[0], b * LENGTHS[1], c * LENGTHS[2]])
}

fn deltas() -> impl Strategy<Value = Vec<f64>> {
    prop::collection::vec(-30.0..30.0f64, 3)
}

proptest! {
    #[test]
    fn all_zero_coefficients_give_zero(
        summands in prop::collection::vec(summand_strategy(Just(0.0)), 0..12),
        p in positions(),
        dt in deltas(),
    ) {
        let m = serial_machine(&LENGTHS);
        let model = Model::new("zero", &m, vec![part(summands)]).unwrap();
        for e in errors(&model, &m, &dt, &p) {
            prop_assert_eq!(e, 0.0);
        }
    }

    #[test]
    fn error_is_linear_in_delta_t(
        summands in prop::collection::vec(summand_strategy(-10.0..10.0f64), 1..12),
        p in positions(),
        dt1 in deltas(),
        dt2 in deltas(),
        a in -3.0..3.0f64,
    ) {
        let m = serial_machine(&LENGTHS);
        let model = Model::new("lin", &m, vec![part(summands)]).unwrap();
        // f(a·ΔT1 + ΔT2) = a·f(ΔT1) + f(ΔT2)
        let mixed: Vec<f64> = dt1.iter().zip(&dt2).map(|(x, y)| a * x + y).collect();
        let lhs = errors(&model, &m, &mixed, &p);
        let f1 = errors(&model, &m, &dt1, &p);
        let f2 = errors(&model, &m, &dt2, &p);
        for i in 0..3 {
            let rhs = a * f1[i] + f2[i];
            prop_assert!((lhs[i] - rhs).abs() <= 1e-9 * (1.0 + rhs.abs()), "{} vs {}", lhs[i], rhs);
        }
    }

    #[test]
    fn order_of_summands_does_not_matter(
        summands in prop::collection::vec(summand_strategy(-10.0..10.0f64), 1..12),
        p in positions(),
        dt in deltas(),
        rotate in 0..12usize,
    ) {
        let m = serial_machine(&LENGTHS);
        let forward = Model::new("a", &m, vec![part(summands.clone())]).unwrap();
        let mut shuffled = summands;
        shuffled.reverse();
        let k = rotate % shuffled.len();
        shuffled.rotate_left(k);
        let backward = Model::new("b", &m, vec![part(shuffled)]).unwrap();
        let a = errors(&forward, &m, &dt, &p);
        let b = errors(&backward, &m, &dt, &p);
        for i in 0..3 {
            prop_assert!((a[i] - b[i]).abs() <= 1e-9 * (1.0 + a[i].abs()));
        }
    }

    /// Whatever finite or non-finite values arrive, evaluation returns a finite correction or an
    /// error — never a NaN — and never panics.
    #[test]
    fn never_a_nan_correction(
        summands in prop::collection::vec(summand_strategy(-10.0..10.0f64), 1..12),
        t in prop::collection::vec(prop_oneof![
            4 => -60.0..160.0f64,
            1 => Just(f64::NAN), 1 => Just(f64::INFINITY), 1 => Just(f64::NEG_INFINITY),
        ], 6),
        p in prop::collection::vec(prop_oneof![
            4 => -100.0..900.0f64,
            1 => Just(f64::NAN), 1 => Just(f64::INFINITY),
        ], 3),
    ) {
        let m = serial_machine(&LENGTHS);
        let model = Model::new("any", &m, vec![part(summands)]).unwrap();
        let r = model.evaluate(&CycleInput { temperatures_c: &t, positions: &p, operating: &[] });
        if let Ok(c) = r {
            for e in c.error_um() {
                prop_assert!(e.is_finite());
            }
        }
    }
}
