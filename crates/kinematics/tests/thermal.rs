//! Document A's "other parts": the per-axis thermal compensation superimposes on the set-points the
//! kinematics returns.

mod machines;

use truepos_kinematics::{superimpose, Directions, Geometry, Pose};
use truepos_model::*;

#[test]
fn thermal_compensation_superimposes_on_kinematic_set_points() {
    let chain = machines::head_ac();
    // Machine in control order X Y Z A C with one sensor pair.
    let axis = |name: &str, kind, lo, hi| Axis {
        name: name.into(),
        kind,
        travel_min: lo,
        travel_max: hi,
        carried_by: None,
        carriage: Carriage::Cantilever,
    };
    let machine = Machine {
        name: "head-ac".into(),
        axes: vec![
            axis("X", AxisKind::Linear, -1000.0, 1000.0),
            axis("Y", AxisKind::Linear, -800.0, 800.0),
            axis("Z", AxisKind::Linear, -600.0, 600.0),
            axis("A", AxisKind::Rotary, -110.0, 110.0),
            axis("C", AxisKind::Rotary, -720.0, 720.0),
        ],
        temperatures: vec![TemperatureChannel {
            id: "spindle".into(),
            location: String::new(),
            valid_min_c: 0.0,
            valid_max_c: 80.0,
            lag: None,
        }],
        differences: vec![TemperatureDifference {
            name: "dT".into(),
            plus: 0,
            minus: Reference::Fixed(20.0),
        }],
        operating: vec![],
    };
    // Z grows 3 µm/K (spindle growth), C turns 2 µrad/K.
    let summand = |axis, k| Summand {
        axis,
        difference: 0,
        k0_um_per_k: k,
        position_terms: vec![],
        bed_multiplier: None,
    };
    let part = Part {
        name: "spindle".into(),
        enabled: true,
        form: PartForm::PositionDependent,
        summands: vec![summand(2, 3.0), summand(4, 2.0)],
        constants_um: vec![],
    };
    let model = Model::new("m", &machine, vec![part]).unwrap();
    let positions = [0.0, 0.0, 0.0, 30.0, 10.0];
    // ΔT = 30 − 20 = 10 K: Z error 30 µm, C error 20 µrad.
    let correction = model
        .evaluate(&CycleInput {
            temperatures_c: &[30.0],
            positions: &positions,
            operating: &[],
        })
        .unwrap();
    let target = Pose {
        position: [100.0, 50.0, 20.0],
        direction: [0.0, -0.5, 0.75f64.sqrt()],
    };
    let mut q = [0.0; 5];
    chain
        .inverse(
            &target,
            100.0,
            &positions,
            Directions(0),
            Geometry::Actual,
            &mut q,
        )
        .unwrap();
    let before = q;
    superimpose(&chain, &mut q, &correction, &[0, 1, 2, 3, 4]);
    // Compensation = −error: Z moves by −30 µm = −0.030 mm; C by −20 µrad = −0.001145916°.
    assert!((q[2] - before[2] + 0.030).abs() < 1e-12);
    assert!((q[4] - before[4] + 20e-6_f64.to_degrees()).abs() < 1e-12);
    assert_eq!(&q[..2], &before[..2]);
    assert_eq!(q[3], before[3]);
}
