//! `reidentify` writes what the probes taught it up to the last event, not the parameters the
//! switch rule took after its first few measurements: a machine whose structure is the model's
//! but whose coefficients are 1.5 times larger, probed 300 times; the rule switches once early
//! (after that the running error stays under the threshold), and the estimate keeps improving.

use std::path::Path;

use truepos_fit::position_model::{fit_structure, structure, Family, Observation};
use truepos_fit::reidentify::{reidentify, ProbeEvent, Reidentifier, Settings, Verdict};
use truepos_model::{CycleInput, Machine, Model};

fn machine() -> Machine {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/twin/machine.toml");
    truepos_io::machine_file::load(&path).unwrap().machine
}

/// Temperatures of every channel at step k: slow, differently phased swings around 22 °C.
fn temperatures(machine: &Machine, k: usize) -> Vec<f64> {
    (0..machine.temperatures.len())
        .map(|c| 22.0 + 3.0 * ((k as f64) * 0.013 * (1.0 + 0.17 * c as f64) + c as f64).sin())
        .collect()
}

fn position(k: usize) -> Vec<f64> {
    vec![
        100.0 + (k * 37 % 600) as f64,
        50.0 + (k * 23 % 400) as f64,
        50.0 + (k * 29 % 400) as f64,
    ]
}

#[test]
fn the_written_model_holds_what_the_later_probes_taught() {
    let machine = machine();
    let op = vec![f64::NAN; machine.operating.len()];
    let s = structure(
        "drift",
        &machine,
        Family::AllAxes,
        &[0, 1, 2],
        &[0, 1, 2],
        true,
    )
    .unwrap();
    // The model as built: fitted on errors the structure makes with known coefficients.
    let temps: Vec<Vec<f64>> = (0..400).map(|k| temperatures(&machine, k)).collect();
    let pos: Vec<Vec<f64>> = (0..400).map(position).collect();
    let built_theta: Vec<f64> = (0..s.parameters().len())
        .map(|i| 0.5 + 0.25 * (i % 5) as f64)
        .collect();
    let built: Model = s.with_parameters(&machine, &built_theta).unwrap();
    let drifted = s
        .with_parameters(
            &machine,
            &built_theta.iter().map(|v| 1.5 * v).collect::<Vec<_>>(),
        )
        .unwrap();
    let truth = |m: &Model, k: usize| {
        let input = CycleInput {
            temperatures_c: &temps[k],
            positions: &pos[k],
            operating: &op,
        };
        m.evaluate(&input).unwrap().error_um().to_vec()
    };
    let obs = (0..100).flat_map(|k| {
        let e = truth(&built, k);
        let (temps, pos, op) = (&temps, &pos, &op);
        (0..3).map(move |a| Observation {
            input: CycleInput {
                temperatures_c: &temps[k],
                positions: &pos[k],
                operating: op,
            },
            axis: a,
            error_um: e[a],
        })
    });
    let original = fit_structure(&s, &machine, obs).unwrap().model;

    // 300 probe events on the drifted machine, every axis measured.
    let events: Vec<ProbeEvent> = (100..400)
        .map(|k| ProbeEvent {
            time_s: k as f64,
            place: format!("event {k}"),
            temperatures_c: temps[k].clone(),
            operating: op.clone(),
            position_mm: pos[k].clone(),
            measured_um: truth(&drifted, k).into_iter().map(Some).collect(),
        })
        .collect();
    let out = reidentify(&original, &machine, &events, Settings::default());
    assert_eq!(out.verdict, Verdict::Switched, "{}", out.reason);

    // What the rule switched to along the way: the parameters of its last switch.
    let mut re = Reidentifier::new(original.clone(), 0.999, 3.0);
    for ev in &events {
        let input = CycleInput {
            temperatures_c: &ev.temperatures_c,
            positions: &ev.position_mm,
            operating: &ev.operating,
        };
        for (a, m) in ev.measured_um.iter().enumerate() {
            re.observe(&machine, &input, a, m.unwrap());
        }
    }
    assert_eq!(re.switches(), out.switches);
    let rms = |m: &Model| {
        let (mut se, mut n) = (0.0, 0);
        for k in 300..400 {
            for (p, t) in truth(m, k).iter().zip(truth(&drifted, k)) {
                se += (p - t).powi(2);
                n += 1;
            }
        }
        (se / n as f64).sqrt()
    };
    let written = rms(out.model.as_ref().unwrap());
    let at_switch = rms(re.running());
    println!(
        "switches {}; RMS error on the last 100 events: original {:.3} µm, last switch {at_switch:.3} µm, written {written:.3} µm",
        out.switches,
        rms(&original)
    );
    assert!(
        written < 0.5 * at_switch,
        "written {written:.3} µm, last switch {at_switch:.3} µm"
    );
}
