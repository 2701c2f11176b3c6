//! The judge on samples made by hand: the figures and verdicts of small, known runs.

use super::*;
use truepos_model::{
    Axis, AxisKind, Carriage, Part, PartForm, PositionFactor, PositionTerm, Reference, Summand,
    TemperatureChannel, TemperatureDifference,
};

/// The glossary's worked example: X and Y over 0…500 mm; the Y error is ΔT·(2 + 4·r_X) µm with
/// ΔT = x_bottom − x_top.
fn example() -> (Machine, Model) {
    let axis = |name: &str| Axis {
        name: name.into(),
        kind: AxisKind::Linear,
        travel_min: 0.0,
        travel_max: 500.0,
        carried_by: None,
        carriage: Carriage::Cantilever,
    };
    let sensor = |id: &str| TemperatureChannel {
        id: id.into(),
        location: String::new(),
        valid_min_c: 0.0,
        valid_max_c: 80.0,
        lag: None,
    };
    let machine = Machine {
        name: "example-1".into(),
        axes: vec![axis("X"), axis("Y")],
        temperatures: vec![sensor("x_bottom"), sensor("x_top")],
        differences: vec![TemperatureDifference {
            name: "dT_x".into(),
            plus: 0,
            minus: Reference::Sensor(1),
        }],
        operating: vec![],
    };
    let part = Part {
        name: "structure".into(),
        enabled: true,
        form: PartForm::PositionDependent,
        summands: vec![Summand {
            axis: 1,
            difference: 0,
            k0_um_per_k: 2.0,
            bed_multiplier: None,
            position_terms: vec![PositionTerm {
                axis: 0,
                factor: PositionFactor::Ratio,
                k_um_per_k: 4.0,
            }],
        }],
        constants_um: vec![],
    };
    let model = Model::new("example", &machine, vec![part]).unwrap();
    (machine, model)
}

fn limits(rate: f64) -> Vec<AxisConfig> {
    (1..=2)
        .map(|n| AxisConfig {
            max_offset_um: 100.0,
            max_rate_um_per_s: rate,
            path: 1,
            number: n,
        })
        .collect()
}

/// The example model as the set's only entry, serving X and Y of path 1.
fn entry(model: &Model) -> ModelEntry {
    ModelEntry {
        name: "example".into(),
        model: model.clone().into(),
        index: [101, 102, 0],
    }
}

/// A cycle at X = 250 mm (r = 0.5) with ΔT = 25 − 20 = 5 K: Y error = 5·(2 + 4·0.5) = 20 µm,
/// so the compensation is −20 µm = −0.020 mm; Y applies `applied_y_mm`. The span over X's
/// travel is 5·4 = 20 µm.
fn sample(applied_y_mm: f64) -> Sample {
    Sample {
        nominal: vec![250.0, 100.0],
        applied_mm: vec![0.0, applied_y_mm],
        joint: vec![250.0, 100.0 + applied_y_mm],
        sent_um: vec![0.0, applied_y_mm * 1000.0],
        status: 1,
        select: 0,
        model: 0,
        axis_paths: vec![1, 1],
        servo_clocks: 1000.0,
        temperatures_c: vec![25.0, 20.0],
    }
}

#[test]
fn lag_fraction_and_rate_by_hand() {
    let (machine, model) = example();
    let model = entry(&model);
    let mut samples = vec![sample(-0.020); 9];
    // The last cycle applies −20.1 µm: 0.1 µm off, 0.1 / 20 = 0.5 % of the span; it moved
    // 0.1 µm in one 1 ms cycle.
    samples.push(sample(-0.0201));
    let config = CheckConfig {
        period_s: 0.001,
        settle_s: 0.002,
        min_span_um: 2.0,
        rate_window_s: 0.002,
        max_lag_fraction: 0.01,
        // The axes stand still here: no moving cycle to ask for.
        min_in_step_moving_cycles: 0,
        ..CheckConfig::default()
    };
    let r = check(
        &machine,
        std::slice::from_ref(&model),
        &limits(100.0),
        &samples,
        &config,
    );
    assert_eq!(r.samples, 10);
    assert_eq!(r.compared, 8); // the first 2 cycles (settle_s = 2 ms) are left out
    assert!((r.max_diff_um - 0.1).abs() < 1e-9, "{}", r.max_diff_um);
    assert!((r.max_lag_fraction - 0.005).abs() < 1e-9);
    assert!(r.joint_mismatch_mm < 1e-12);
    // Over the 2 ms window: 0.1 µm / 0.002 s = 50 µm/s.
    assert!((r.max_rate_um_per_s[1] - 50.0).abs() < 1e-6);
    assert!(r.passed(), "{:?}", r.failures);
    // With a 10 µm/s envelope the allowance is 10·(2 + 2)/2 + 2·0.01/0.002 = 30 µm/s < 50.
    let r = check(
        &machine,
        std::slice::from_ref(&model),
        &limits(10.0),
        &samples,
        &config,
    );
    assert_eq!(r.failures.len(), 1, "{:?}", r.failures);
    assert!(r.failures[0].contains("axis Y: offset rate 50.00 µm/s"));
    // A lag of 2 % of the span fails: −20.4 µm applied.
    samples[9] = sample(-0.0204);
    let config = CheckConfig {
        rate_window_s: 0.05,
        ..config
    };
    let r = check(
        &machine,
        std::slice::from_ref(&model),
        &limits(100.0),
        &samples,
        &config,
    );
    assert!((r.max_lag_fraction - 0.02).abs() < 1e-9);
    assert!(!r.passed());
    // The same 0.4 µm off right after a 0.1 K step of the model's input (the model now says
    // −20.4 µm; a quantisation flicker reaches the axis one update later) is compared but
    // gives no lag fraction.
    let mut flicker = samples.clone();
    flicker[9].temperatures_c[0] = 25.1;
    flicker[9].applied_mm[1] = -0.0208;
    flicker[9].sent_um[1] = -20.8;
    let r = check(
        &machine,
        std::slice::from_ref(&model),
        &limits(100.0),
        &flicker,
        &config,
    );
    assert_eq!(r.compared, 8);
    assert!((r.max_diff_um - 0.4).abs() < 1e-9, "{}", r.max_diff_um);
    assert!(r.max_lag_fraction < 1e-9, "{}", r.max_lag_fraction);
}

#[test]
fn update_gaps_are_reported_and_in_step_moving_cycles_judged() {
    let (machine, model) = example();
    let model = entry(&model);
    let config = CheckConfig {
        period_s: 0.001,
        settle_s: 0.002,
        min_span_um: 2.0,
        rate_window_s: 0.05,
        max_lag_fraction: 0.01,
        min_in_step_moving_cycles: 0,
        ..CheckConfig::default()
    };
    // An update gap: X moves 1 mm per cycle for 40 cycles, truepos's sent offset changes up
    // to cycle 10 only. Cycles 11…40 repeat it (a gap of 30); a gap counts once it exceeds
    // 2 cycles, so cycles 13…40 = 28 of the 40 moving cycles (70 %) are in it.
    let moving: Vec<Sample> = (0..41)
        .map(|k| {
            let mut s = sample(-0.020);
            s.nominal[0] = 100.0 + k as f64;
            s.sent_um[1] = -20.0 - 0.01 * (k.min(10) as f64);
            s
        })
        .collect();
    let r = check(
        &machine,
        std::slice::from_ref(&model),
        &limits(100.0),
        &moving,
        &config,
    );
    assert_eq!(r.longest_update_gap_cycles, 30);
    assert!((r.gap_fraction - 0.7).abs() < 1e-12, "{}", r.gap_fraction);
    // The gaps' share is reported, not judged. In step and compared: cycles 2…12 = 11 (the
    // first two settle); a run needs at least `min_in_step_moving_cycles` of them.
    assert_eq!(r.in_step_moving_cycles, 11);
    assert!(!r.failures.iter().any(|f| f.contains("update gaps")));
    let strict = CheckConfig {
        min_in_step_moving_cycles: 12,
        ..config
    };
    let r = check(&machine, &[model], &limits(100.0), &moving, &strict);
    assert!(
        r.failures
            .iter()
            .any(|f| f.contains("only 11 moving cycles ran in step")),
        "{:?}",
        r.failures
    );
}

#[test]
fn axis_switching_follows_the_axis_combination_rule() {
    let (machine, model) = example();
    // Model 0 serves X and Y (101, 102), model 1 X alone (101).
    let models = [
        entry(&model),
        ModelEntry {
            index: [101, 0, 0],
            ..entry(&model)
        },
    ];
    let limits = limits(100.0);
    assert_eq!(expected_model(&models, &limits, &[1, 1], 0), Some(0));
    assert_eq!(expected_model(&models, &limits, &[1, 1], 1), Some(0));
    assert_eq!(expected_model(&models, &limits, &[1, 0], 0), Some(1));
    assert_eq!(expected_model(&models, &limits, &[0, 1], 0), None);
    // Y leaves path 1: the component must use model 1 and give Y no offset (the model's Y
    // term is not applied); X carries none in this model anyway.
    let sample = |applied_y_mm: f64, model: i32| Sample {
        nominal: vec![250.0, 100.0],
        applied_mm: vec![0.0, applied_y_mm],
        joint: vec![250.0, 100.0 + applied_y_mm],
        sent_um: vec![0.0, applied_y_mm * 1000.0],
        status: 1,
        select: 0,
        model,
        axis_paths: vec![1, 0],
        servo_clocks: 1000.0,
        temperatures_c: vec![25.0, 20.0],
    };
    let config = CheckConfig {
        settle_s: 0.0,
        rate_window_s: 0.002,
        min_in_step_moving_cycles: 0, // the axes stand still here
        ..CheckConfig::default()
    };
    let r = check(
        &machine,
        &models,
        &limits,
        &vec![sample(0.0, 1); 5],
        &config,
    );
    assert!(r.passed(), "{:?}", r.failures);
    assert_eq!(r.compared, 5);
    // Still model 0, and Y still offset: both fail.
    let r = check(
        &machine,
        &models,
        &limits,
        &vec![sample(-0.02, 0); 5],
        &config,
    );
    assert_eq!(r.wrong_model_cycles, 5);
    assert!((r.max_parked_offset_um - 20.0).abs() < 1e-9);
    assert_eq!(r.failures.len(), 2, "{:?}", r.failures);
}

/// Y at the example's −20 µm, then an intermittent fault: the status flaps between active
/// (1) and holding (2) every third cycle while Y moves at the envelope's rate of 50 µm/s.
fn flapping(step_um: f64, cycles: usize) -> Vec<Sample> {
    (0..cycles)
        .map(|k| {
            let y_um = -20.0 + step_um * k.saturating_sub(10) as f64;
            Sample {
                nominal: vec![250.0, 100.0],
                applied_mm: vec![0.0, y_um / 1000.0],
                joint: vec![250.0, 100.0 + y_um / 1000.0],
                // The component is a cycle ahead of what LinuxCNC applied.
                sent_um: vec![0.0, y_um + step_um],
                status: if k >= 10 && k % 3 == 2 { 2 } else { 1 },
                select: 0,
                model: 0,
                axis_paths: vec![1, 1],
                servo_clocks: 1000.0,
                temperatures_c: vec![25.0, 20.0],
            }
        })
        .collect()
}

/// The default check of runs whose axes stand still: no moving cycle to ask for.
fn standing() -> CheckConfig {
    CheckConfig {
        min_in_step_moving_cycles: 0,
        ..CheckConfig::default()
    }
}

#[test]
fn the_output_invariant_catches_a_runaway_beyond_model_and_hold() {
    let (machine, model) = example();
    let models = [entry(&model)];
    let limits = limits(50.0);
    let config = standing();
    // Standing at the model's value through the flapping: inside every bracket.
    let r = output_invariant(&machine, &models, &limits, &flapping(0.0, 400), &config);
    assert_eq!(r.max_bracket_excess_um, vec![0.0, 0.0]);
    assert!(r.state_changes > 200, "{}", r.state_changes);
    assert!(r.max_step_ratio[1] < 1e-12);
    // Running away at the envelope's rate, 0.05 µm per cycle, towards +100 µm (the bug of
    // f5778f7): the rate is kept, but after 389 cycles the output is 19.4 µm above both the
    // model's −20 µm and the held value (ramping to zero over 60 s), which the bracket does
    // not follow.
    let r = output_invariant(&machine, &models, &limits, &flapping(0.05, 400), &config);
    assert!(r.max_step_ratio[1] <= 1.0, "{:?}", r.max_step_ratio);
    assert!(
        r.max_bracket_excess_um[1] > 19.0,
        "{:?}",
        r.max_bracket_excess_um
    );
    let report = check(&machine, &models, &limits, &flapping(0.05, 400), &config);
    assert!(
        report
            .failures
            .iter()
            .any(|f| f.contains("axis Y: the applied offset left")),
        "{:?}",
        report.failures
    );
    // A hold ramps to zero: over 0.4 s, −19.95 µm ramp at 50 µm/s; following it from −20 µm
    // is inside (the first 10 cycles sit 0.05 µm below the value sent)...
    let mut hold = flapping(0.05, 600);
    for s in &mut hold {
        s.status = 2;
    }
    let fast_ramp = CheckConfig {
        hold_ramp_s: 0.4,
        ..config.clone()
    };
    let r = output_invariant(&machine, &models, &limits, &hold[..300], &fast_ramp);
    assert!(
        r.max_bracket_excess_um[1] < 0.06,
        "{:?}",
        r.max_bracket_excess_um
    );
    // ...but not beyond zero (+9.45 µm at the end).
    let r = output_invariant(&machine, &models, &limits, &hold, &fast_ramp);
    assert!(
        r.max_bracket_excess_um[1] > 9.0,
        "{:?}",
        r.max_bracket_excess_um
    );
}

#[test]
fn the_step_allowance_follows_the_real_time() {
    let (machine, model) = example();
    let models = [entry(&model)];
    let limits = limits(50.0);
    let config = standing();
    // Twice the rate: 0.1 µm per 1 ms cycle against 50 µm/s × (3 + 1) ms + 0.02 = 0.22 µm
    // passes (the pipeline's cycles are allowed), 0.3 µm per cycle does not.
    let r = output_invariant(&machine, &models, &limits, &flapping(0.1, 50), &config);
    assert!(r.max_step_ratio[1] < 1.0, "{:?}", r.max_step_ratio);
    let mut fast = flapping(0.3, 50);
    let r = output_invariant(&machine, &models, &limits, &fast, &config);
    assert!(r.max_step_ratio[1] > 1.0, "{:?}", r.max_step_ratio);
    // The same steps after servo cycles held up by 10 ms each pass (the component went on);
    // the clock's rate comes from the median cycle.
    for s in fast.iter_mut().step_by(3) {
        s.servo_clocks = 10_000.0;
    }
    let r = output_invariant(&machine, &models, &limits, &fast, &config);
    assert!(r.max_step_ratio[1] < 1.0, "{:?}", r.max_step_ratio);
    // The component held up for 10 cycles, then one step of 0.5 µm: allowed too.
    let mut held = flapping(0.0, 40);
    for s in &mut held[30..] {
        s.applied_mm[1] += 0.0005;
    }
    let r = output_invariant(&machine, &models, &limits, &held, &config);
    assert!(r.max_step_ratio[1] < 1.0, "{:?}", r.max_step_ratio);
    assert!((r.max_step_um[1] - 0.5).abs() < 1e-9);
    // Servo cycles catching up after a stall (0.3 ms each) while the component kept its
    // 1 ms pace: 0.15 µm per cycle passes (50 µm/s over 3 + 1 component periods), as the
    // clean-clone CI run of 11:18 needed (0.177 µm against 0.167 µm of servo time).
    let mut catch_up = flapping(0.15, 50);
    for s in catch_up.iter_mut().skip(20).take(10) {
        s.servo_clocks = 300.0;
    }
    let r = output_invariant(&machine, &models, &limits, &catch_up, &config);
    assert!(r.max_step_ratio[1] < 1.0, "{:?}", r.max_step_ratio);
    // A NaN offset fails.
    held[35].applied_mm[0] = f64::NAN;
    let r = output_invariant(&machine, &models, &limits, &held, &config);
    assert_eq!(r.nonfinite_cycles, 1);
}

/// A fitted dynamic model on the example machine: Y error = 1 + 2·rise(x_bottom) +
/// 3·lp100(rise(x_bottom)) µm.
fn dynamic_entry(machine: &Machine) -> ModelEntry {
    use truepos_model::{
        BoundDynamicModel, Channels, DynamicModel, FeatureBank, FeatureSpec, MachineInput,
    };
    let bank = FeatureBank::new(FeatureSpec {
        temperatures: 1,
        operating: 0,
        temperature_rise: true,
        temperature_taus_s: vec![100.0],
        rate_taus_s: vec![],
        operating_taus_s: vec![],
        operating_square: false,
        rise_while_running: false,
    })
    .unwrap();
    let model = DynamicModel::new(bank, vec![1.0], vec![2.0, 3.0]).unwrap();
    let bound = BoundDynamicModel::new(
        "fitted".into(),
        model,
        vec![MachineInput::Temperature(0)],
        vec![Some(1)],
        vec![],
        Channels {
            temperatures: machine.temperatures.len(),
            operating: 0,
            axes: machine.axes.len(),
        },
    )
    .unwrap();
    ModelEntry {
        name: "fitted".into(),
        model: bound.into(),
        index: [101, 102, 0],
    }
}

/// x_bottom warms by 1 K over 6 s of 1 ms servo cycles; LinuxCNC applies what the component
/// sent two cycles before, in counts of 0.01 µm. `extra_um` is added to what is applied.
fn warming(extra_um: f64) -> Vec<Sample> {
    let mut reference = truepos_model::DynamicModel::new(
        truepos_model::FeatureBank::new(truepos_model::FeatureSpec {
            temperatures: 1,
            operating: 0,
            temperature_rise: true,
            temperature_taus_s: vec![100.0],
            rate_taus_s: vec![],
            operating_taus_s: vec![],
            operating_square: false,
            rise_while_running: false,
        })
        .unwrap(),
        vec![1.0],
        vec![2.0, 3.0],
    )
    .unwrap();
    let n = 6000;
    let temperature = |k: usize| 25.0 + k as f64 / n as f64;
    let compensation: Vec<f64> = (0..n)
        .map(|k| {
            let dt = if k == 0 { 0.0 } else { 0.001 };
            let e = reference.step(dt, &[temperature(k)]).unwrap()[0];
            ((0.0 - e) * 100.0).round() / 100.0
        })
        .collect();
    (0..n)
        .map(|k| {
            let applied = compensation[k.saturating_sub(2)] + extra_um;
            Sample {
                nominal: vec![250.0, 100.0],
                applied_mm: vec![0.0, applied / 1000.0],
                joint: vec![250.0, 100.0 + applied / 1000.0],
                sent_um: vec![0.0, compensation[k.saturating_sub(1)]],
                status: 1,
                select: 0,
                model: 0,
                axis_paths: vec![1, 1],
                servo_clocks: 1000.0,
                temperatures_c: vec![temperature(k), 20.0],
            }
        })
        .collect()
}

/// The check steps a fitted dynamic model through the recorded cycles and holds the applied
/// offset to it (no lag fraction: it has no position-dependent terms); an offset 0.2 µm off
/// fails, and a set whose dynamic model no cycle used fails too.
#[test]
fn a_fitted_dynamic_model_is_stepped_through_the_recording() {
    let (machine, model) = example();
    let models = [dynamic_entry(&machine)];
    let config = standing();
    let r = check(&machine, &models, &limits(50.0), &warming(0.0), &config);
    assert_eq!(r.dynamic_compared, 3000, "{r:?}");
    assert_eq!(r.compared, 3000);
    assert!(
        r.max_dynamic_excess_um < 0.011,
        "{}",
        r.max_dynamic_excess_um
    );
    assert!(
        r.max_diff_um > 0.0 && r.max_diff_um < 0.05,
        "{}",
        r.max_diff_um
    );
    assert!(r.passed(), "{:?}", r.failures);
    let off = check(&machine, &models, &limits(50.0), &warming(0.2), &config);
    assert!((off.max_dynamic_excess_um - 0.2).abs() < 0.011, "{off:?}");
    assert!(
        off.failures
            .iter()
            .any(|f| f.contains("fitted dynamic model's compensation")),
        "{:?}",
        off.failures
    );
    // The same recording against a set whose first model is static: the dynamic one never runs.
    let both = [entry(&model), dynamic_entry(&machine)];
    let unused = check(&machine, &both, &limits(50.0), &warming(0.0), &config);
    assert_eq!(unused.dynamic_compared, 0);
    assert!(
        unused
            .failures
            .iter()
            .any(|f| f.contains("no settled, active cycle used it")),
        "{:?}",
        unused.failures
    );
    // A recording that starts before the component compensated (the samplers enabled at load,
    // the temperature pins still unconnected) cannot anchor the replay: it fails, naming why.
    let mut early = warming(0.0);
    early[0].status = 0;
    let r = check(&machine, &models, &limits(50.0), &early, &config);
    assert!(
        r.failures
            .iter()
            .any(|f| f.contains("starts in a cycle that is not active")),
        "{:?}",
        r.failures
    );
}
