//! On-line re-identification on the twin with a machine whose behaviour drifts: a model fitted
//! on day A of the reference twin runs on day B of a twin whose spindle grows 40 % more per
//! kelvin (a longer tool holder, a worn bearing seat); the touch-probe grid of the day
//! re-estimates the parameters on line, the switch rule swaps them in, and the error falls.

use std::path::Path;

use truepos_fit::position_model::{fit_structure, structure, Family, Observation};
use truepos_fit::reidentify::Reidentifier;
use truepos_model::{CycleInput, Machine};
use truepos_sim::{Scenario, SimRun, Twin};

fn machine() -> Machine {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/twin/machine.toml");
    truepos_io::machine_file::load(&path).unwrap().machine
}

/// Temperatures of every row in the machine's channel order; the machine's lagged channels are
/// computed from their sensors as the control would.
fn temperatures(run: &SimRun, machine: &Machine) -> Vec<Vec<f64>> {
    for t in machine.temperatures.iter().filter(|t| t.lag.is_none()) {
        assert!(run.sensor_ids.contains(&t.id), "no sensor `{}`", t.id);
    }
    let time: Vec<f64> = run.rows.iter().map(|r| r.time_s).collect();
    let operating = vec![vec![f64::NAN; machine.operating.len()]; run.rows.len()];
    truepos_io::cycles::machine_temperatures(
        machine,
        &run.sensor_ids,
        &time,
        run.rows.iter().map(|r| r.temperatures_c.as_slice()),
        &operating,
    )
}

#[test]
fn probe_measurements_re_identify_a_drifted_machine() {
    let machine = machine();
    let op = vec![f64::NAN; machine.operating.len()];

    // Day A on the machine as built: fit the position-dependent model on the tool's path.
    let twin = Twin::reference();
    let day_a = twin
        .run(&Scenario::builtin("mixed-shift").unwrap(), 1)
        .unwrap();
    let temps_a = temperatures(&day_a, &machine);
    let all: Vec<usize> = (0..machine.differences.len()).collect();
    let s = structure("drift", &machine, Family::AllAxes, &all, &[0, 1, 2], true).unwrap();
    let mut obs = Vec::new();
    for (i, row) in day_a.rows.iter().enumerate() {
        for a in 0..3 {
            obs.push(Observation {
                input: CycleInput {
                    temperatures_c: &temps_a[i],
                    positions: &row.position_mm,
                    operating: &op,
                },
                axis: a,
                error_um: row.error_um[a],
            });
        }
    }
    let original = fit_structure(&s, &machine, obs).unwrap().model;

    // Day B on a machine that drifted: the spindle grows 40 % more per kelvin.
    let mut drifted = Twin::reference();
    drifted.spindle_growth_length_mm *= 1.4;
    let day_b = drifted
        .run(&Scenario::builtin("mixed-shift-b").unwrap(), 2)
        .unwrap();
    let temps_b = temperatures(&day_b, &machine);

    let mut re = Reidentifier::new(original.clone(), 0.995, 3.0);
    let mut first_switch_row = None;
    let (mut se_orig, mut se_re, mut n) = (0.0, 0.0, 0usize);
    for (i, row) in day_b.rows.iter().enumerate() {
        let here = CycleInput {
            temperatures_c: &temps_b[i],
            positions: &row.position_mm,
            operating: &op,
        };
        // Compare both models at the tool's path from the first switch on.
        if first_switch_row.is_some() {
            if let (Ok(a), Ok(b)) = (original.evaluate(&here), re.running().evaluate(&here)) {
                se_orig += (row.error_um[2] - a.error_um()[2]).powi(2);
                se_re += (row.error_um[2] - b.error_um()[2]).powi(2);
                n += 1;
            }
        }
        if let Some(probe) = &row.probe {
            for axis in 0..3 {
                let at = CycleInput {
                    temperatures_c: &temps_b[i],
                    positions: &probe.position_mm,
                    operating: &op,
                };
                let step = re.observe(&machine, &at, axis, probe.measured_um[axis]);
                if step.is_some_and(|s| s.switched) && first_switch_row.is_none() {
                    first_switch_row = Some(i);
                }
            }
        }
    }
    let rmse_orig = (se_orig / n.max(1) as f64).sqrt();
    let rmse_re = (se_re / n.max(1) as f64).sqrt();
    println!(
        "switches {}, first after row {:?} of {}; dz RMSE from then on: original {rmse_orig:.2} µm, re-identified {rmse_re:.2} µm",
        re.switches(),
        first_switch_row,
        day_b.rows.len()
    );
    assert!(re.switches() >= 1, "the drift must trigger a switch");
    assert!(n > 100, "the switch must come early enough to matter");
    assert!(
        rmse_re < 0.7 * rmse_orig,
        "re-identified {rmse_re:.2} µm vs original {rmse_orig:.2} µm"
    );
}
