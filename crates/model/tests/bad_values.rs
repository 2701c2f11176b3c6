//! Bad values on the cycle path give an error value naming the channel, never a NaN offset.

mod common;

use common::*;
use truepos_model::PositionFactor::Ratio;
use truepos_model::*;

fn model(m: &Machine) -> Model {
    // Reads dT_0 (sensors 0, 1) only; sensors 2, 3 (dT_1) are not used.
    Model::new(
        "m",
        m,
        vec![part(vec![summand(1, 0, 2.0, &[(0, Ratio, 4.0)])])],
    )
    .unwrap()
}

fn eval(model: &Model, t: &[f64], p: &[f64]) -> Result<Correction, EvalError> {
    model.evaluate(&CycleInput {
        temperatures_c: t,
        positions: p,
        operating: &[],
    })
}

#[test]
fn non_finite_temperature_is_an_error() {
    let m = serial_machine(&[500.0, 400.0]);
    let model = model(&m);
    for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
        assert_eq!(
            eval(&model, &[bad, 20.0, 20.0, 20.0], &[0.0, 0.0]),
            Err(EvalError::NonFiniteTemperature { channel: 0 })
        );
        assert_eq!(
            eval(&model, &[25.0, bad, 20.0, 20.0], &[0.0, 0.0]),
            Err(EvalError::NonFiniteTemperature { channel: 1 })
        );
    }
}

#[test]
fn a_fault_on_a_sensor_the_model_does_not_read_is_ignored() {
    let m = serial_machine(&[500.0, 400.0]);
    let model = model(&m);
    let c = eval(&model, &[25.0, 20.0, f64::NAN, 1e9], &[500.0, 0.0]).unwrap();
    assert_close(c.error_um(), &[0.0, 30.0]);
}

#[test]
fn out_of_range_temperature_is_an_error() {
    // Valid range of the test machine is [−300, 300] °C: an open thermocouple reading 850 °C.
    let m = serial_machine(&[500.0, 400.0]);
    let model = model(&m);
    assert_eq!(
        eval(&model, &[850.0, 20.0, 20.0, 20.0], &[0.0, 0.0]),
        Err(EvalError::TemperatureOutOfRange {
            channel: 0,
            value: 850.0
        })
    );
}

#[test]
fn bad_positions_are_errors() {
    let m = serial_machine(&[500.0, 400.0]);
    let model = model(&m);
    let t = [25.0, 20.0, 20.0, 20.0];
    assert_eq!(
        eval(&model, &t, &[f64::NAN, 0.0]),
        Err(EvalError::NonFinitePosition { axis: 0 })
    );
    assert_eq!(
        eval(&model, &t, &[0.0, f64::INFINITY]),
        Err(EvalError::NonFinitePosition { axis: 1 })
    );
    // 1 % of 500 mm = 5 mm of tolerance: 504 mm holds the end value, 520 mm is a fault.
    assert_close(
        eval(&model, &t, &[504.0, 0.0]).unwrap().error_um(),
        &[0.0, 30.0],
    );
    assert_eq!(
        eval(&model, &t, &[520.0, 0.0]),
        Err(EvalError::PositionOutsideTravel {
            axis: 0,
            value: 520.0
        })
    );
}

#[test]
fn wrong_input_lengths_are_errors() {
    let m = serial_machine(&[500.0, 400.0]);
    let model = model(&m);
    assert_eq!(
        eval(&model, &[25.0, 20.0], &[0.0, 0.0]),
        Err(EvalError::InputLength {
            input: "temperatures_c",
            expected: 4,
            got: 2
        })
    );
    assert_eq!(
        eval(&model, &[25.0, 20.0, 20.0, 20.0], &[0.0]),
        Err(EvalError::InputLength {
            input: "positions",
            expected: 2,
            got: 1
        })
    );
}

#[test]
fn huge_finite_values_do_not_become_infinite_offsets() {
    // Coefficients of 1e300 with ΔT = 100 K overflow to ∞: reported, not written.
    let mut m = serial_machine(&[500.0, 400.0]);
    m.temperatures[0].valid_max_c = 1e6;
    let model = Model::new("huge", &m, vec![part(vec![summand(0, 0, 1e307, &[])])]).unwrap();
    assert_eq!(
        eval(&model, &[120.0, 20.0, 20.0, 20.0], &[0.0, 0.0]),
        Err(EvalError::NonFiniteResult { axis: 0 })
    );
}

#[test]
fn model_construction_rejects_bad_indices_and_numbers() {
    let m = serial_machine(&[500.0, 400.0]);
    let bad_axis = Model::new("x", &m, vec![part(vec![summand(5, 0, 1.0, &[])])]);
    assert!(matches!(
        bad_axis,
        Err(ModelError::UnknownAxis { axis: 5, .. })
    ));
    let bad_diff = Model::new("x", &m, vec![part(vec![summand(0, 9, 1.0, &[])])]);
    assert!(matches!(
        bad_diff,
        Err(ModelError::UnknownDifference { difference: 9, .. })
    ));
    let nan = Model::new("x", &m, vec![part(vec![summand(0, 0, f64::NAN, &[])])]);
    assert!(matches!(nan, Err(ModelError::NonFiniteCoefficient { .. })));
    let dup = Model::new("x", &m, vec![part(vec![]), part(vec![])]);
    assert_eq!(dup, Err(ModelError::DuplicatePart("structure".into())));
}
