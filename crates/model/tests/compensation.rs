//! The one door of a compensation model (`CompensationModel::step`) gives the figures of the
//! forms it wraps: a static model's step is its evaluation; a dynamic model's step is its
//! filters' output, with inputs gathered by the channel mapping and outputs mapped to axes.

mod common;

use common::*;
use proptest::prelude::*;
use truepos_model::PositionFactor::{Ratio, RatioSquared};
use truepos_model::*;

fn spec() -> FeatureSpec {
    FeatureSpec {
        temperatures: 2,
        operating: 1,
        temperature_rise: true,
        temperature_taus_s: vec![120.0],
        rate_taus_s: vec![60.0],
        operating_taus_s: vec![30.0],
        operating_square: true,
        rise_while_running: true,
    }
}

/// A dynamic model with two outputs over two temperatures and one operating input.
fn dynamic(coefficients: &[f64]) -> DynamicModel {
    let bank = FeatureBank::new(spec()).unwrap();
    let n = bank.features().len();
    let c: Vec<f64> = (0..2 * n)
        .map(|i| coefficients[i % coefficients.len()])
        .collect();
    DynamicModel::new(bank, vec![0.25, -1.5], c).unwrap()
}

/// Two serial axes with their sensors.
fn machine() -> Machine {
    serial_machine(&[800.0, 500.0])
}

fn bound(m: &Machine, coefficients: &[f64]) -> BoundDynamicModel {
    BoundDynamicModel::new(
        "dyn".into(),
        dynamic(coefficients),
        // Model input 0 ← hot_1, 1 ← hot_0, 2 ← spindle_rpm; output 0 → axis A2, output 1 → none.
        vec![
            MachineInput::Temperature(2),
            MachineInput::Temperature(0),
            MachineInput::Operating(0),
        ],
        vec![Some(1), None],
        vec!["spare_um".into()],
        Channels {
            temperatures: m.temperatures.len(),
            // One operating channel, spindle speed: the machine's are not needed to bind.
            operating: 1,
            axes: m.axes.len(),
        },
    )
    .unwrap()
}

proptest! {
    /// A static model's step is exactly its evaluation, whatever `dt`.
    #[test]
    fn a_static_step_is_the_evaluation(
        k in prop::collection::vec(-5.0f64..5.0, 3),
        deltas in prop::collection::vec(-10.0f64..10.0, 2),
        x in 0.0f64..800.0,
        y in 0.0f64..500.0,
        dt in -1.0f64..1.0,
    ) {
        let m = serial_machine(&[800.0, 500.0]);
        let model = Model::new(
            "s",
            &m,
            vec![part(vec![
                summand(1, 0, k[0], &[(0, Ratio, k[1])]),
                summand(0, 1, k[2], &[(1, RatioSquared, k[0])]),
            ])],
        )
        .unwrap();
        let t = temperatures_for(&deltas);
        let positions = [x, y];
        let input = CycleInput { temperatures_c: &t, positions: &positions, operating: &[] };
        let want = model.evaluate(&input).unwrap();
        let mut door = CompensationModel::from(model);
        let got = door.step(dt, &input).unwrap();
        prop_assert_eq!(&got[..2], want.error_um());
        prop_assert!(got[2..].iter().all(|&e| e == 0.0));
        prop_assert!(!door.keeps_state());
    }

    /// A dynamic model's step is the real-time model's output on the mapped inputs, output 0 on
    /// axis A2, nothing elsewhere, over a random sequence of cycles.
    #[test]
    fn a_dynamic_step_is_the_filters_output(
        coefficients in prop::collection::vec(-3.0f64..3.0, 1..6),
        cycles in prop::collection::vec((15.0f64..40.0, 15.0f64..40.0, 0.0f64..3000.0, 0.01f64..20.0), 1..40),
    ) {
        let m = machine();
        let mut reference = dynamic(&coefficients);
        let mut door = CompensationModel::from(bound(&m, &coefficients));
        prop_assert!(door.keeps_state());
        prop_assert_eq!(door.used_sensors(), &[0, 2]);
        let mut t = vec![20.0; m.temperatures.len()];
        for (k, &(hot0, hot1, rpm, dt)) in cycles.iter().enumerate() {
            t[0] = hot0;
            t[2] = hot1;
            let dt = if k == 0 { 0.0 } else { dt };
            let want = reference.step(dt, &[hot1, hot0, rpm]).unwrap()[0];
            let got = door
                .step(dt, &CycleInput { temperatures_c: &t, positions: &[], operating: &[rpm] })
                .unwrap();
            prop_assert_eq!(got[1], want);
            prop_assert!(got.iter().enumerate().all(|(a, &e)| a == 1 || e == 0.0));
        }
    }
}

/// A non-finite input is refused naming its channel, and leaves the filters where they were;
/// a reset starts them again.
#[test]
fn a_dynamic_step_refuses_a_bad_input_by_channel() {
    let m = machine();
    let mut door = CompensationModel::from(bound(&m, &[1.0, 0.5]));
    let mut t = vec![20.0; m.temperatures.len()];
    let at = |door: &mut CompensationModel, t: &[f64], rpm: f64, dt: f64| {
        door.step(
            dt,
            &CycleInput {
                temperatures_c: t,
                positions: &[],
                operating: &[rpm],
            },
        )
    };
    let first = at(&mut door, &t, 1000.0, 0.0).unwrap();
    t[2] = 22.0;
    let before = door.clone();
    t[0] = f64::NAN;
    assert_eq!(
        at(&mut door, &t, 1000.0, 1.0),
        Err(EvalError::NonFiniteTemperature { channel: 0 })
    );
    t[0] = 20.0;
    assert_eq!(
        at(&mut door, &t, f64::INFINITY, 1.0),
        Err(EvalError::NonFiniteOperating { channel: 0 })
    );
    assert_eq!(
        at(&mut door, &t, 1000.0, 0.0),
        Err(EvalError::Filter(DynamicError::BadTimeStep))
    );
    assert_eq!(door, before);
    assert!(matches!(
        at(&mut door, &t[..1], 1000.0, 1.0),
        Err(EvalError::InputLength { .. })
    ));
    door.reset();
    t[2] = 20.0;
    assert_eq!(at(&mut door, &t, 1000.0, 5.0).unwrap(), first);
}
