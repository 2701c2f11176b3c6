//! Golden tests: every worked case of document A (ES 2 430 543 / CN 102198609) and document C's two
//! regression equations, with the numbers computed by hand in the comments.
//!
//! Conventions of these tests: axis n is `A{n}` (index n−1), travel [0, L_n], r_n = p_n / L_n;
//! ΔT_m is `dT_{m-1}`; K_nmj is the coefficient of ΔT_m in ΔA_n multiplied by g_j.

mod common;

use common::*;
use truepos_model::PositionFactor::{BedFactor, Ratio, RatioSquared};
use truepos_model::*;

/// Example 1 (eqs. 9–10): ΔA1 = ΔT·K_11, ΔA2 = ΔT·[K_21 + K_22·r_1].
/// K_11 = 1.2, K_21 = 2, K_22 = 4 µm/K, ΔT = 5 K, L_1 = 500 mm:
///   ΔA1 = 5·1.2 = 6 µm at any position;
///   ΔA2(r=0) = 5·2 = 10 µm, ΔA2(r=0.5) = 5·(2+2) = 20 µm, ΔA2(r=1) = 5·(2+4) = 30 µm
///   — the seed's "10 µm at position/length 0, 30 µm at 1".
#[test]
fn example_1_ratio_gives_10_to_30_um() {
    let m = serial_machine(&[500.0, 400.0]);
    let model = Model::new(
        "ex1",
        &m,
        vec![part(vec![
            summand(0, 0, 1.2, &[]),
            summand(1, 0, 2.0, &[(0, Ratio, 4.0)]),
        ])],
    )
    .unwrap();
    assert_close(&errors(&model, &m, &[5.0, 0.0], &[0.0, 0.0]), &[6.0, 10.0]);
    assert_close(
        &errors(&model, &m, &[5.0, 0.0], &[250.0, 0.0]),
        &[6.0, 20.0],
    );
    assert_close(
        &errors(&model, &m, &[5.0, 0.0], &[500.0, 0.0]),
        &[6.0, 30.0],
    );
}

/// Example 2 (eqs. 11–12): as example 1 with r_1² — the arc is not linear.
///   ΔA2(r=0) = 10, ΔA2(r=0.5) = 5·(2 + 4·0.25) = 15, ΔA2(r=1) = 30 µm.
#[test]
fn example_2_ratio_squared() {
    let m = serial_machine(&[500.0, 400.0]);
    let model = Model::new(
        "ex2",
        &m,
        vec![part(vec![
            summand(0, 0, 1.2, &[]),
            summand(1, 0, 2.0, &[(0, RatioSquared, 4.0)]),
        ])],
    )
    .unwrap();
    assert_close(&errors(&model, &m, &[5.0, 0.0], &[0.0, 0.0]), &[6.0, 10.0]);
    assert_close(
        &errors(&model, &m, &[5.0, 0.0], &[250.0, 0.0]),
        &[6.0, 15.0],
    );
    assert_close(
        &errors(&model, &m, &[5.0, 0.0], &[500.0, 0.0]),
        &[6.0, 30.0],
    );
}

// The N = 2 cases below share: L = (500, 400) mm, p = (100, 300) mm → r = (0.2, 0.75),
// ΔT = (4, −2) K.
const L2: [f64; 2] = [500.0, 400.0];
const P2: [f64; 2] = [100.0, 300.0];
const DT2: [f64; 2] = [4.0, -2.0];

/// Embodiment 1 (eqs. 13–14): each ΔT term carries its own axis' position.
///   K_110 = 1, K_111 = 2, K_120 = 0.5, K_122 = −1, K_210 = 3, K_211 = 1, K_220 = −0.5, K_222 = 2
///   ΔA1 = 4·(1 + 2·0.2) + (−2)·(0.5 − 0.75) = 5.6 + 0.5 = 6.1 µm
///   ΔA2 = 4·(3 + 0.2) + (−2)·(−0.5 + 1.5) = 12.8 − 2 = 10.8 µm
fn embodiment_1_summands() -> Vec<Summand> {
    vec![
        summand(0, 0, 1.0, &[(0, Ratio, 2.0)]),
        summand(0, 1, 0.5, &[(1, Ratio, -1.0)]),
        summand(1, 0, 3.0, &[(0, Ratio, 1.0)]),
        summand(1, 1, -0.5, &[(1, Ratio, 2.0)]),
    ]
}

#[test]
fn embodiment_1_two_axes() {
    let m = serial_machine(&L2);
    let model = Model::new("e1", &m, vec![part(embodiment_1_summands())]).unwrap();
    assert_close(&errors(&model, &m, &DT2, &P2), &[6.1, 10.8]);
}

/// Embodiment 2 (eqs. 15–16): the ΔT_1 terms also carry r_2 (the bent slide S1 tilts axis 2).
///   add K_112 = 0.8, K_212 = −1.5:
///   ΔA1 = 4·(1 + 0.4 + 0.8·0.75) + 0.5 = 4·2.0 + 0.5 = 8.5 µm
///   ΔA2 = 4·(3 + 0.2 − 1.5·0.75) − 2 = 4·2.075 − 2 = 6.3 µm
/// Embodiment 4 with N = 2 (j ≥ m) is the same form, so it gives the same numbers.
fn embodiment_2_summands() -> Vec<Summand> {
    vec![
        summand(0, 0, 1.0, &[(0, Ratio, 2.0), (1, Ratio, 0.8)]),
        summand(0, 1, 0.5, &[(1, Ratio, -1.0)]),
        summand(1, 0, 3.0, &[(0, Ratio, 1.0), (1, Ratio, -1.5)]),
        summand(1, 1, -0.5, &[(1, Ratio, 2.0)]),
    ]
}

#[test]
fn embodiment_2_and_4_two_axes() {
    let m = serial_machine(&L2);
    let model = Model::new("e2", &m, vec![part(embodiment_2_summands())]).unwrap();
    assert_close(&errors(&model, &m, &DT2, &P2), &[8.5, 6.3]);
}

/// Embodiment 2's physical point, as a sign: with only S1 bent (ΔT_2 = 0) and axis 1 at rest,
/// moving axis 2 changes the error along axis 1 (K_112 ≠ 0); the change is ΔT_1·K_112·Δr_2.
///   r_2 from 0 to 1: 4·0.8·1 = +3.2 µm.
#[test]
fn embodiment_2_moving_axis_2_shifts_axis_1() {
    let m = serial_machine(&L2);
    let model = Model::new("e2", &m, vec![part(embodiment_2_summands())]).unwrap();
    let at0 = errors(&model, &m, &[4.0, 0.0], &[100.0, 0.0]);
    let at1 = errors(&model, &m, &[4.0, 0.0], &[100.0, 400.0]);
    assert!((at1[0] - at0[0] - 3.2).abs() < 1e-9);
}

/// Embodiment 3 (eqs. 17–18): every ΔT term carries every axis' position.
///   add K_121 = 2, K_221 = −1 to embodiment 2:
///   ΔA1 = 8 + (−2)·(0.5 + 2·0.2 − 0.75) = 8 − 0.3 = 7.7 µm
///   ΔA2 = 8.3 + (−2)·(−0.5 − 0.2 + 1.5) = 8.3 − 1.6 = 6.7 µm
/// Embodiment 5 with N = 2 (all j) is the same form.
#[test]
fn embodiment_3_and_5_two_axes() {
    let m = serial_machine(&L2);
    let summands = vec![
        summand(0, 0, 1.0, &[(0, Ratio, 2.0), (1, Ratio, 0.8)]),
        summand(0, 1, 0.5, &[(0, Ratio, 2.0), (1, Ratio, -1.0)]),
        summand(1, 0, 3.0, &[(0, Ratio, 1.0), (1, Ratio, -1.5)]),
        summand(1, 1, -0.5, &[(0, Ratio, -1.0), (1, Ratio, 2.0)]),
    ];
    let model = Model::new("e3", &m, vec![part(summands)]).unwrap();
    assert_close(&errors(&model, &m, &DT2, &P2), &[7.7, 6.7]);
}

// The N = 4 cases share: L = 1000 mm each, p = (100, 200, 300, 400) → r = (0.1, 0.2, 0.3, 0.4),
// ΔT_m = m K (1, 2, 3, 4), and every coefficient of ΔA_n equal to n µm/K, so that
// ΔA_n = n · Σ_m m·[1 + Σ_{j in the embodiment's set} r_j].
const L4: [f64; 4] = [1000.0; 4];
const P4: [f64; 4] = [100.0, 200.0, 300.0, 400.0];
const DT4: [f64; 4] = [1.0, 2.0, 3.0, 4.0];

fn n4_model(m: &Machine, js: impl Fn(usize) -> Vec<usize>) -> Model {
    let mut summands = Vec::new();
    for n in 0..4 {
        let k = (n + 1) as f64;
        for dm in 0..4 {
            let terms: Vec<_> = js(dm).into_iter().map(|j| (j, Ratio, k)).collect();
            summands.push(summand(n, dm, k, &terms));
        }
    }
    Model::new("n4", m, vec![part(summands)]).unwrap()
}

/// Embodiment 1, N = 4 (own axis only):
///   Σ_m m·(1 + r_m) = 1·1.1 + 2·1.2 + 3·1.3 + 4·1.4 = 1.1 + 2.4 + 3.9 + 5.6 = 13.0
///   ΔA = (13, 26, 39, 52) µm
#[test]
fn embodiment_1_four_axes() {
    let m = serial_machine(&L4);
    let model = n4_model(&m, |dm| vec![dm]);
    assert_close(&errors(&model, &m, &DT4, &P4), &[13.0, 26.0, 39.0, 52.0]);
}

/// Embodiment 2, N = 4: the ΔT_1 term also carries r_2 (S1 tilts the axis resting on it):
///   13.0 + 1·0.2 = 13.2 → ΔA = (13.2, 26.4, 39.6, 52.8) µm
#[test]
fn embodiment_2_four_axes() {
    let m = serial_machine(&L4);
    let model = n4_model(&m, |dm| if dm == 0 { vec![0, 1] } else { vec![dm] });
    assert_close(&errors(&model, &m, &DT4, &P4), &[13.2, 26.4, 39.6, 52.8]);
}

/// Embodiment 4 (eqs. 19–28), N = 4: ΔT_m carries r_j for all j ≥ m (axes resting on m):
///   Σ_{j≥1} r = 1.0, Σ_{j≥2} = 0.9, Σ_{j≥3} = 0.7, Σ_{j≥4} = 0.4
///   1·2.0 + 2·1.9 + 3·1.7 + 4·1.4 = 2 + 3.8 + 5.1 + 5.6 = 16.5 → (16.5, 33, 49.5, 66) µm
#[test]
fn embodiment_4_four_axes() {
    let m = serial_machine(&L4);
    let model = n4_model(&m, |dm| (dm..4).collect());
    assert_close(&errors(&model, &m, &DT4, &P4), &[16.5, 33.0, 49.5, 66.0]);
}

/// Embodiments 3 and 5 (eqs. 29–38), N = 4: every ΔT term carries every axis:
///   Σ_m m·(1 + 1.0) = 10·2 = 20 → (20, 40, 60, 80) µm
#[test]
fn embodiment_3_and_5_four_axes() {
    let m = serial_machine(&L4);
    let model = n4_model(&m, |_| (0..4).collect());
    assert_close(&errors(&model, &m, &DT4, &P4), &[20.0, 40.0, 60.0, 80.0]);
}

/// The bed factor KFA = (p − L/2)/(L/2) (eq. 41): −1 at one end, 0 in the middle, +1 at the
/// other; L = 1000: p = 250 → (250 − 500)/500 = −0.5.
#[test]
fn bed_factor_values() {
    let axis = Axis {
        name: "Z".into(),
        kind: AxisKind::Linear,
        travel_min: 0.0,
        travel_max: 1000.0,
        carried_by: None,
        carriage: Carriage::Bed,
    };
    for (p, kfa) in [(0.0, -1.0), (250.0, -0.5), (500.0, 0.0), (1000.0, 1.0)] {
        assert!((BedFactor.of_ratio(axis.ratio(p)) - kfa).abs() < 1e-12);
    }
    // Travel that does not start at 0: [−200, 300], L = 500, middle at 50.
    let offset = Axis {
        travel_min: -200.0,
        travel_max: 300.0,
        ..axis
    };
    assert!((BedFactor.of_ratio(offset.ratio(50.0))).abs() < 1e-12);
    assert!((BedFactor.of_ratio(offset.ratio(300.0)) - 1.0).abs() < 1e-12);
}

/// Embodiment 6 (eqs. 39–41), N = 2: a cross slide (axis 2) on a bed slide (axis 1):
///   ΔA_11 = ΔT_1·[K_110 + K_111·KFA1 + K_112·r_2]·KFA1
///   L = (1000, 300), K_110 = 2, K_111 = 4, K_112 = −2, ΔT_1 = 3 K, p_2 = 150 → r_2 = 0.5
///   p_1 = 750: KFA1 = 0.5 → 3·(2 + 2 − 1)·0.5 = 4.5 µm
///   p_1 = 500: KFA1 = 0   → 0 µm (the bed's error is smallest in the middle)
///   p_1 = 0:   KFA1 = −1  → 3·(2 − 4 − 1)·(−1) = 9 µm
#[test]
fn embodiment_6_two_axes() {
    let m = serial_machine(&[1000.0, 300.0]);
    let mut s = summand(0, 0, 2.0, &[(0, BedFactor, 4.0), (1, Ratio, -2.0)]);
    s.bed_multiplier = Some(0);
    let model = Model::new("e6", &m, vec![part(vec![s])]).unwrap();
    let dt = [3.0, 0.0];
    assert_close(&errors(&model, &m, &dt, &[750.0, 150.0]), &[4.5, 0.0]);
    assert_close(&errors(&model, &m, &dt, &[500.0, 150.0]), &[0.0, 0.0]);
    assert_close(&errors(&model, &m, &dt, &[0.0, 150.0]), &[9.0, 0.0]);
}

/// Embodiment 6, N = 4: the bracket also carries K_113·r_3 + K_114·r_4:
///   L = (1000, 300, 400, 200), p = (750, 150, 100, 200) → KFA1 = 0.5, r = (·, 0.5, 0.25, 1.0)
///   K_113 = 1, K_114 = 0.5: bracket = 2 + 4·0.5 − 2·0.5 + 1·0.25 + 0.5·1 = 3.75
///   ΔA_1 = 3·3.75·0.5 = 5.625 µm
#[test]
fn embodiment_6_four_axes() {
    let m = serial_machine(&[1000.0, 300.0, 400.0, 200.0]);
    let mut s = summand(
        0,
        0,
        2.0,
        &[
            (0, BedFactor, 4.0),
            (1, Ratio, -2.0),
            (2, Ratio, 1.0),
            (3, Ratio, 0.5),
        ],
    );
    s.bed_multiplier = Some(0);
    let model = Model::new("e6n4", &m, vec![part(vec![s])]).unwrap();
    assert_close(
        &errors(
            &model,
            &m,
            &[3.0, 0.0, 0.0, 0.0],
            &[750.0, 150.0, 100.0, 200.0],
        ),
        &[5.625, 0.0, 0.0, 0.0],
    );
}

/// Prior art (eqs. 1–2): ΔA_n = Σ_m ΔT_m·K_nm, no position at all.
///   K_11 = 1.5, K_12 = 0.25, K_21 = −1, K_22 = 2; ΔT = (4, −2):
///   ΔA1 = 6 − 0.5 = 5.5 µm, ΔA2 = −4 − 4 = −8 µm, the same at every position.
#[test]
fn prior_art_position_independent() {
    let m = serial_machine(&L2);
    let model = Model::new(
        "prior-art",
        &m,
        vec![part(vec![
            summand(0, 0, 1.5, &[]),
            summand(0, 1, 0.25, &[]),
            summand(1, 0, -1.0, &[]),
            summand(1, 1, 2.0, &[]),
        ])],
    )
    .unwrap();
    for p in [[0.0, 0.0], [100.0, 300.0], [500.0, 400.0]] {
        assert_close(&errors(&model, &m, &DT2, &p), &[5.5, -8.0]);
    }
}

/// Document C (MCV 1000 SPEED): three spindle-head sensors t1…t3 against the column reference tr:
///   Y = −0.4378·(t1−tr) + 1.2762·(t2−tr) + 23.3865·(t3−tr)
///   Z = −4.281·(t1−tr)  + 10.437·(t2−tr) + 12.3149·(t3−tr)      [µm]
/// With tr = 22, t1 = 25, t2 = 24, t3 = 23 °C the differences are 3, 2, 1 K:
///   Y = −1.3134 + 2.5524 + 23.3865 = 24.6255 µm
///   Z = −12.843 + 20.874 + 12.3149 = 20.3459 µm
#[test]
fn seed_c_regression_equations() {
    let sensor = |id: &str| TemperatureChannel {
        id: id.into(),
        location: String::new(),
        valid_min_c: 0.0,
        valid_max_c: 80.0,
        lag: None,
    };
    let diff = |name: &str, plus| TemperatureDifference {
        name: name.into(),
        plus,
        minus: Reference::Sensor(3),
    };
    let axis = |name: &str| Axis {
        name: name.into(),
        kind: AxisKind::Linear,
        travel_min: 0.0,
        travel_max: 500.0,
        carried_by: None,
        carriage: Carriage::Cantilever,
    };
    let m = Machine {
        name: "mcv1000".into(),
        axes: vec![axis("X"), axis("Y"), axis("Z")],
        temperatures: vec![sensor("t1"), sensor("t2"), sensor("t3"), sensor("tr")],
        differences: vec![diff("d1", 0), diff("d2", 1), diff("d3", 2)],
        operating: vec![],
    };
    m.check().unwrap();
    let regression = |name: &str, axis: usize, k: [f64; 3]| Part {
        name: name.into(),
        enabled: true,
        form: PartForm::Regression,
        summands: (0..3).map(|i| summand(axis, i, k[i], &[])).collect(),
        constants_um: vec![(axis, 0.0)],
    };
    let model = Model::new(
        "seed-c",
        &m,
        vec![
            regression("y", 1, [-0.4378, 1.2762, 23.3865]),
            regression("z", 2, [-4.281, 10.437, 12.3149]),
        ],
    )
    .unwrap();
    let c = model
        .evaluate(&CycleInput {
            temperatures_c: &[25.0, 24.0, 23.0, 22.0],
            positions: &[0.0, 0.0, 0.0],
            operating: &[],
        })
        .unwrap();
    assert_close(c.error_um(), &[0.0, 24.6255, 20.3459]);
}

/// Superposition: the correction is the sum of the enabled parts; switching a part off removes
/// exactly its share. Parts: example 1's bend (ΔA2 = 30 µm at r = 1) and a 2.5 µm constant.
#[test]
fn parts_superimpose_and_switch() {
    let m = serial_machine(&L2);
    let bend = part(vec![summand(1, 0, 2.0, &[(0, Ratio, 4.0)])]);
    let offset = Part {
        name: "offset".into(),
        enabled: true,
        form: PartForm::PositionDependent,
        summands: vec![],
        constants_um: vec![(1, 2.5)],
    };
    let mut model = Model::new("sum", &m, vec![bend, offset]).unwrap();
    assert_close(
        &errors(&model, &m, &[5.0, 0.0], &[500.0, 0.0]),
        &[0.0, 32.5],
    );
    assert!(model.set_part_enabled(0, false));
    assert_close(&errors(&model, &m, &[5.0, 0.0], &[500.0, 0.0]), &[0.0, 2.5]);
    assert!(model.set_part_enabled(0, true));
    assert!(model.set_part_enabled(1, false));
    assert_close(
        &errors(&model, &m, &[5.0, 0.0], &[500.0, 0.0]),
        &[0.0, 30.0],
    );
    assert!(!model.set_part_enabled(7, false));
}

/// The sign convention: the compensation added to the set-point is −error.
#[test]
fn compensation_is_minus_error() {
    let m = serial_machine(&L2);
    let model = Model::new("sign", &m, vec![part(vec![summand(1, 0, 2.0, &[])])]).unwrap();
    let c = model
        .evaluate(&CycleInput {
            temperatures_c: &temperatures_for(&[5.0, 0.0]),
            positions: &[0.0, 0.0],
            operating: &[],
        })
        .unwrap();
    assert_eq!(c.error_um()[1], 10.0);
    assert_eq!(c.compensation_um(1), -10.0);
    assert_eq!(c.compensation_um(0), 0.0);
    assert!(c.compensation_um(0).is_sign_positive());
}

/// Document A's timing argument: 100 m/min, 4 ms, 500 mm.
///   100 m/min = 100 000 mm / 60 000 ms = 1.6667 mm/ms → 6.667 mm in 4 ms
///   6.667 / 500 = 0.01333 → 1.3 % (ratio and bed factor);
///   ratio squared at r = 1: 2·0.01333 − 0.01333² = 0.02649 → 2.6 %.
#[test]
fn timing_argument_gives_1_3_percent() {
    assert!((travel_per_update_mm(100_000.0, 4.0) - 6.666_666_666_7).abs() < 1e-9);
    let f = update_error_fraction(100_000.0, 4.0, 500.0, Ratio);
    assert!((f - 0.013_333_333_3).abs() < 1e-9);
    assert_eq!(format!("{:.1}", 100.0 * f), "1.3");
    assert!((update_error_fraction(100_000.0, 4.0, 500.0, BedFactor) - f).abs() < 1e-15);
    let sq = update_error_fraction(100_000.0, 4.0, 500.0, RatioSquared);
    assert!((sq - (2.0 * f - f * f)).abs() < 1e-15);
    // 1 kHz and 10 m/min (the runtime's end-to-end case): 0.1667 mm / 500 mm = 0.033 %.
    assert!(update_error_fraction(10_000.0, 1.0, 500.0, Ratio) < 0.01);
}

/// The regressors reproduce the evaluation: error = Σ θ·φ, for embodiment 6 (bed multiplier)
/// and embodiment 2 (cross terms), and a structure with new θ evaluates with them.
#[test]
fn regressors_times_parameters_equal_the_evaluation() {
    let m = serial_machine(&[1000.0, 300.0]);
    let mut s = summand(0, 0, 2.0, &[(0, BedFactor, 4.0), (1, Ratio, -2.0)]);
    s.bed_multiplier = Some(0);
    let mut parts = vec![part(vec![s, summand(1, 1, 1.5, &[(0, RatioSquared, 0.5)])])];
    parts[0].constants_um.push((1, 0.25));
    let model = Model::new("phi", &m, parts).unwrap();
    // θ = (2, 4, −2 | 1.5, 0.5 | 0.25)
    assert_eq!(model.parameters(), vec![2.0, 4.0, -2.0, 1.5, 0.5, 0.25]);
    let t = temperatures_for(&[3.0, -1.0]);
    let p = [750.0, 150.0];
    let input = CycleInput {
        temperatures_c: &t,
        positions: &p,
        operating: &[],
    };
    let c = model.evaluate(&input).unwrap();
    let mut phi = vec![0.0; model.parameter_count()];
    for axis in 0..2 {
        model.regressors(&input, axis, &mut phi).unwrap();
        let sum: f64 = phi.iter().zip(model.parameters()).map(|(a, b)| a * b).sum();
        assert!((sum - c.error_um()[axis]).abs() < 1e-12);
    }
    // Axis 0: φ = ΔT·KFA·(1, KFA, r₂) = 3·0.5·(1, 0.5, 0.5) = (1.5, 0.75, 0.75), others 0.
    model.regressors(&input, 0, &mut phi).unwrap();
    assert_eq!(phi, vec![1.5, 0.75, 0.75, 0.0, 0.0, 0.0]);
    let doubled: Vec<f64> = model.parameters().iter().map(|v| 2.0 * v).collect();
    let m2 = model.with_parameters(&m, &doubled).unwrap();
    let c2 = m2.evaluate(&input).unwrap();
    assert!((c2.error_um()[0] - 2.0 * c.error_um()[0]).abs() < 1e-12);
    assert!(model.with_parameters(&m, &[1.0]).is_err(), "θ too short");
}
