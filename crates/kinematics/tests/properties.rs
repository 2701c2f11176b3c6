//! Properties of the kinematics table over random reachable poses of every example machine:
//! fwd(inv(p)) = p within 1 nm / 1 µrad (also within 0.01° of the pole), a chain whose tables
//! are all zero is exactly the nominal chain, nothing allocates, bad input is a value.

mod machines;

use machines::*;
use proptest::prelude::*;
use truepos_kinematics::{Chain, Directions, Geometry, KinError, Pose};
use truepos_model::AxisKind;

const TOOL: f64 = 100.0;

/// Axis positions from unit-interval samples, inside travel (rotary axes within ±100° / their
/// travel; the pole axis within `pole_deg` of 0 if given).
fn positions(chain: &Chain, u: &[f64], pole: Option<(usize, f64)>) -> Vec<f64> {
    chain
        .axes()
        .iter()
        .enumerate()
        .map(|(j, a)| {
            if let Some((pj, width)) = pole {
                if pj == j {
                    return (2.0 * u[j] - 1.0) * width;
                }
            }
            let (lo, hi) = match a.kind {
                AxisKind::Linear => (
                    a.travel_min * 0.8 + a.travel_max * 0.2,
                    a.travel_max * 0.8 + a.travel_min * 0.2,
                ),
                AxisKind::Rotary => (a.travel_min.max(-100.0), a.travel_max.min(100.0)),
            };
            lo + (hi - lo) * u[j]
        })
        .collect()
}

fn dist(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

/// Inverse from a previous set-point near the true one, then forward: the real tool must land
/// on the target.
fn round_trip(
    chain: &Chain,
    q: &[f64],
    nudge: &[f64],
    geometry: Geometry,
) -> Result<(), TestCaseError> {
    let target = chain.forward(q, TOOL, Directions(0), geometry).unwrap();
    let prev: Vec<f64> = q.iter().zip(nudge).map(|(a, b)| a + b).collect();
    let mut out = vec![0.0; q.len()];
    let report = chain
        .inverse(&target, TOOL, &prev, Directions(0), geometry, &mut out)
        .map_err(|e| TestCaseError::fail(format!("inverse failed: {e} at q = {q:?}")))?;
    let got = chain
        .forward(&out, TOOL, report.directions, geometry)
        .unwrap();
    let dp = dist(&got.position, &target.position);
    let dd = dist(&got.direction, &target.direction);
    prop_assert!(dp < 1e-6, "TCP off by {dp} mm at q = {q:?} -> {out:?}");
    let rotary = chain
        .axes()
        .iter()
        .filter(|a| a.kind == AxisKind::Rotary)
        .count();
    if rotary >= 2 {
        prop_assert!(
            dd < 1e-6,
            "direction off by {dd} rad at q = {q:?} -> {out:?}"
        );
    }
    prop_assert!(out.iter().all(|v| v.is_finite()));
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(400))]

    #[test]
    fn inverse_then_forward_is_identity(
        u in proptest::collection::vec(0.0f64..1.0, 5),
        nudge in proptest::collection::vec(-0.5f64..0.5, 5),
    ) {
        for (name, chain, _) in all() {
            let n = chain.axes().len();
            let q = positions(&chain, &u[..n], None);
            for geometry in [Geometry::Nominal, Geometry::Actual] {
                round_trip(&chain, &q, &nudge[..n], geometry)
                    .map_err(|e| TestCaseError::fail(format!("{name} {geometry:?}: {e}")))?;
            }
        }
    }

    #[test]
    fn inverse_then_forward_near_the_pole(
        u in proptest::collection::vec(0.0f64..1.0, 5),
        nudge in proptest::collection::vec(-0.5f64..0.5, 5),
    ) {
        for (name, chain, pole) in all() {
            let Some(pj) = pole else { continue };
            let q = positions(&chain, &u, Some((pj, 0.01)));
            for geometry in [Geometry::Nominal, Geometry::Actual] {
                round_trip(&chain, &q, &nudge, geometry)
                    .map_err(|e| TestCaseError::fail(format!("{name} {geometry:?}: {e}")))?;
            }
        }
    }

    #[test]
    fn nominal_inverse_returns_the_nearest_branch(
        u in proptest::collection::vec(0.0f64..1.0, 5),
        nudge in proptest::collection::vec(-0.5f64..0.5, 5),
    ) {
        // Away from the pole, the set-point nearest a previous one half a unit away is the
        // one the target was made from.
        for (name, chain, pole) in all() {
            let n = chain.axes().len();
            let q = positions(&chain, &u[..n], None);
            if let Some(pj) = pole {
                prop_assume!(q[pj].abs() > 2.0);
            }
            let target = chain.forward(&q, TOOL, Directions(0), Geometry::Nominal).unwrap();
            let prev: Vec<f64> = q.iter().zip(&nudge).map(|(a, b)| a + b).collect();
            let mut out = vec![0.0; n];
            chain.inverse(&target, TOOL, &prev, Directions(0), Geometry::Nominal, &mut out).unwrap();
            for j in 0..n {
                prop_assert!((out[j] - q[j]).abs() < 1e-7, "{name}: axis {j}: {} vs {}", out[j], q[j]);
            }
        }
    }

    #[test]
    fn zero_tables_equal_the_nominal_chain_exactly(
        u in proptest::collection::vec(0.0f64..1.0, 5),
    ) {
        for (_, chain, _) in all() {
            let zero = chain.with_zero_tables();
            let q = positions(&chain, &u[..chain.axes().len()], None);
            let a = zero.forward(&q, TOOL, Directions(0), Geometry::Actual).unwrap();
            let b = chain.forward(&q, TOOL, Directions(0), Geometry::Nominal).unwrap();
            prop_assert_eq!(a, b);
        }
    }
}

#[test]
fn exactly_at_the_pole_the_outer_axis_keeps_its_value() {
    for (name, chain, pole) in all() {
        let Some(pj) = pole else { continue };
        let mut q = vec![10.0, -20.0, 30.0, 0.0, 0.0];
        q[pj] = 0.0;
        for c in [-250.0, 0.0, 33.0, 400.0] {
            q[4] = c;
            let target = chain
                .forward(&q, TOOL, Directions(0), Geometry::Nominal)
                .unwrap();
            let prev = vec![0.0, 0.0, 0.0, 0.0, c];
            let mut out = vec![0.0; 5];
            chain
                .inverse(
                    &target,
                    TOOL,
                    &prev,
                    Directions(0),
                    Geometry::Nominal,
                    &mut out,
                )
                .unwrap();
            assert_eq!(out[4], c, "{name}: C jumped at the pole");
            assert!(out.iter().all(|v| v.is_finite()));
            // With errors the pole moves slightly; the result stays finite and on target.
            let target = chain
                .forward(&q, TOOL, Directions(0), Geometry::Actual)
                .unwrap();
            let rep = chain
                .inverse(
                    &target,
                    TOOL,
                    &prev,
                    Directions(0),
                    Geometry::Actual,
                    &mut out,
                )
                .unwrap();
            let got = chain
                .forward(&out, TOOL, rep.directions, Geometry::Actual)
                .unwrap();
            assert!(dist(&got.position, &target.position) < 1e-6, "{name}");
            assert!(dist(&got.direction, &target.direction) < 1e-6, "{name}");
        }
    }
}

#[test]
fn head_ac_hand_computed_pose() {
    // Document B's head, nominal, tool 100 mm, all axes 0 except A = 90°, C = 90°:
    // tip frame → pivot: (0, 0, −250); R_x(90°): (0, 250, 0); + (0.02, −0.015, 0) →
    // (0.02, 249.985, 0); R_z(90°): (x, y) → (−y, x) = (−249.985, 0.02, 0); + (0, 0, 400) →
    // TCP (−249.985, 0.02, 400).
    // Direction: e_z → R_x(90°) → (0, −1, 0) → R_z(90°) → (1, 0, 0).
    let chain = head_ac();
    let p = chain
        .forward(
            &[0.0, 0.0, 0.0, 90.0, 90.0],
            TOOL,
            Directions(0),
            Geometry::Nominal,
        )
        .unwrap();
    let want = [-249.985, 0.02, 400.0];
    assert!(dist(&p.position, &want) < 1e-12, "{:?}", p.position);
    assert!(
        dist(&p.direction, &[1.0, 0.0, 0.0]) < 1e-15,
        "{:?}",
        p.direction
    );
}

#[test]
fn three_axis_errors_hand_computed() {
    // At X = Y = Z = 0 every positional table reads its value at 0: amp·sin(phase) with
    // amp 6 µm; check the TCP x error against the sum of the X-direction terms computed here.
    let chain = three_axis_21();
    let nom = chain
        .forward(&[0.0, 0.0, 0.0], TOOL, Directions(0), Geometry::Nominal)
        .unwrap();
    // Nominal: the tip lies tool length 100 + fixed 100 mm below the Z carriage's reference
    // point: TCP at (0, 0, −200).
    assert!(dist(&nom.position, &[0.0, 0.0, -200.0]) < 1e-15);
    let act = chain
        .forward(&[0.0, 0.0, 0.0], TOOL, Directions(0), Geometry::Actual)
        .unwrap();
    let e_um: Vec<f64> = act
        .position
        .iter()
        .zip(&nom.position)
        .map(|(a, b)| (a - b) * 1e3)
        .collect();
    // Errors are tens of µm at most.
    assert!(e_um.iter().all(|e| e.abs() < 50.0), "{e_um:?}");
    assert!(e_um.iter().any(|e| e.abs() > 0.1), "{e_um:?}");
}

#[test]
fn bad_input_is_a_value_not_a_panic() {
    let chain = head_ac();
    let mut out = vec![0.0; 5];
    let prev = [0.0; 5];
    assert_eq!(
        chain.forward(
            &[0.0, f64::NAN, 0.0, 0.0, 0.0],
            TOOL,
            Directions(0),
            Geometry::Actual
        ),
        Err(KinError::NonFinite)
    );
    assert!(matches!(
        chain.forward(&[0.0; 4], TOOL, Directions(0), Geometry::Actual),
        Err(KinError::AxisCount {
            expected: 5,
            got: 4
        })
    ));
    let zero_dir = Pose {
        position: [0.0; 3],
        direction: [0.0; 3],
    };
    assert_eq!(
        chain.inverse(
            &zero_dir,
            TOOL,
            &prev,
            Directions(0),
            Geometry::Actual,
            &mut out
        ),
        Err(KinError::ZeroDirection)
    );
    // A tool pointing down (into the spindle from below) is beyond A's ±110°.
    let down = Pose {
        position: [0.0; 3],
        direction: [0.0, 0.0, -1.0],
    };
    assert!(chain
        .inverse(
            &down,
            TOOL,
            &prev,
            Directions(0),
            Geometry::Actual,
            &mut out
        )
        .is_err());
    // Far outside the linear travel.
    let far = Pose {
        position: [5000.0, 0.0, 0.0],
        direction: [0.0, 0.0, 1.0],
    };
    assert!(matches!(
        chain.inverse(&far, TOOL, &prev, Directions(0), Geometry::Actual, &mut out),
        Err(KinError::OutsideTravel { axis: 0, .. })
    ));
    let nan = Pose {
        position: [f64::NAN, 0.0, 0.0],
        direction: [0.0, 0.0, 1.0],
    };
    assert_eq!(
        chain.inverse(&nan, TOOL, &prev, Directions(0), Geometry::Actual, &mut out),
        Err(KinError::NonFinite)
    );
}

#[test]
fn transforms_do_not_allocate() {
    let chain = head_ac();
    let q = [10.0, 20.0, 30.0, 40.0, 50.0];
    let target = chain
        .forward(&q, TOOL, Directions(0), Geometry::Actual)
        .unwrap();
    let mut out = [0.0; 5];
    let mut sum = 0.0;
    let counted = allocation_counter::measure(|| {
        for _ in 0..100 {
            sum += chain
                .forward(&q, TOOL, Directions(0), Geometry::Actual)
                .unwrap()
                .position[0];
            chain
                .inverse(&target, TOOL, &q, Directions(0), Geometry::Actual, &mut out)
                .unwrap();
            sum += out[0];
        }
    });
    assert!(sum.is_finite());
    assert_eq!(counted.count_total, 0);
}
