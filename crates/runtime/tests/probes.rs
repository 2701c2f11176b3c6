//! Probe events as a service input: each event a source delivers is checked, logged with the
//! inputs of its cycle and the prediction of the model in effect, accepted or rejected with
//! the reason; no record is lost, and a cycle with a probe event allocates nothing.

mod support;

use std::sync::{Arc, Mutex};

use support::{repo, scratch, vmc};
use truepos_io::model_file::position;
use truepos_runtime::model_set::ModelEntry;
use truepos_runtime::probe::ProbeInput;
use truepos_runtime::{log, Frame, LinkError, ServiceHost, Source};

/// Temperatures, positions and a pending probe event the test sets between cycles.
type Shared = Arc<Mutex<(Vec<f64>, Vec<f64>, Option<ProbeInput>)>>;

struct Scripted(Shared);

impl Source for Scripted {
    fn name(&self) -> &str {
        "scripted"
    }
    fn read(&mut self, frame: &mut Frame) -> Result<(), LinkError> {
        let mut v = self.0.lock().unwrap();
        for (c, &t) in v.0.iter().enumerate() {
            frame.set_temperature(c, t);
        }
        for (a, &p) in v.1.iter().enumerate() {
            frame.set_position(a, p);
        }
        if let Some(p) = v.2.take() {
            frame.probe = Some(p);
        }
        Ok(())
    }
}

fn probe(z_um: f64, x_mm: f64) -> ProbeInput {
    let mut p = ProbeInput::EMPTY;
    p.position_mm[..3].copy_from_slice(&[x_mm, 200.0, 100.0]);
    p.deviation_um[2] = z_um;
    p.measured[2] = true;
    p
}

#[test]
fn every_probe_event_is_logged_with_its_cycle_accepted_or_rejected() {
    let dir = scratch("probes");
    let db = dir.join("log.sqlite");
    let machine = vmc();
    let n_t = machine.machine.temperatures.len();
    let model = position::load(&repo("examples/vmc3/model.toml"), &machine.machine).unwrap();
    let shared: Shared = Arc::new(Mutex::new((
        (0..n_t).map(|c| 21.0 + c as f64 * 0.5).collect(),
        vec![100.0, 100.0, 100.0],
        None,
    )));
    let entry = ModelEntry {
        name: "vmc3".into(),
        model: model.clone().into(),
        index: [101, 102, 103],
    };
    let mut running = ServiceHost::new(machine.clone(), vec![entry])
        .source(Box::new(Scripted(Arc::clone(&shared))))
        .log(Some(db.clone()))
        .start()
        .unwrap();
    let mut t = 0.0;
    let events = [
        probe(12.5, 300.0),
        probe(f64::NAN, 300.0),
        probe(5e4, 300.0),
        probe(3.0, 5000.0),
        ProbeInput::EMPTY,
        probe(-4.0, 10.0),
    ];
    for (i, ev) in events.iter().enumerate() {
        for _ in 0..20 {
            t += 0.01;
            running.service.cycle(t);
        }
        shared.lock().unwrap().2 = Some(*ev);
        if i == events.len() - 1 {
            // The last event's cycle allocates nothing.
            let counted = allocation_counter::measure(|| {
                t += 0.01;
                running.service.cycle(t);
            });
            assert_eq!(counted.count_total, 0);
        }
    }
    for _ in 0..5 {
        t += 0.01;
        running.service.cycle(t);
    }
    let stopped = running.stop();
    let (result, health) = stopped.log.unwrap();
    result.unwrap();
    assert_eq!(health.probes_dropped, 0);
    assert_eq!(stopped.service.probes_dropped(), 0);

    let table = log::read_probes(&db).unwrap();
    assert_eq!(table.rows.len(), events.len(), "no probe event lost");
    let col = |name: &str| table.columns.iter().position(|c| c == name).unwrap();
    let statuses: Vec<(bool, &str)> = table
        .rows
        .iter()
        .map(|r| (r.accepted, r.reason.as_str()))
        .collect();
    assert!(statuses[0].0 && statuses[0].1.is_empty(), "{statuses:?}");
    assert!(
        statuses[1].1.contains("measured error of Z is NaN"),
        "{statuses:?}"
    );
    assert!(statuses[2].1.contains("within ±1000"), "{statuses:?}");
    assert!(
        statuses[3].1.contains("probed position of X is 5000"),
        "{statuses:?}"
    );
    assert_eq!(statuses[4].1, "no axis measured");
    assert!(statuses[5].0, "{statuses:?}");
    let first = &table.rows[0];
    assert_eq!(first.values[col("probe_dz_um")], Some(12.5));
    assert_eq!(first.values[col("probe_x_mm")], Some(300.0));
    assert_eq!(first.values[col("probe_dx_um")], None, "X was not measured");
    assert_eq!(first.values[col("model_path1")], Some(0.0));
    assert_eq!(first.values[col("X_mm")], Some(100.0));
    // The prediction is the model's error at the probed position with the cycle's inputs.
    let temps: Vec<f64> = (0..n_t).map(|c| 21.0 + c as f64 * 0.5).collect();
    let op = vec![f64::NAN; machine.machine.operating.len()];
    let expected = model
        .evaluate(&truepos_model::CycleInput {
            temperatures_c: &temps,
            positions: &[300.0, 200.0, 100.0],
            operating: &op,
        })
        .unwrap()
        .error_um()[2];
    let logged = first.values[col("predicted_dz_um")].unwrap();
    assert!((logged - expected).abs() < 1e-9, "{logged} vs {expected}");
    let id = &machine.machine.temperatures[1].id;
    assert_eq!(first.values[col(id)], Some(21.5));
    assert_eq!(log::integrity_check(&db).unwrap(), "ok");
    std::fs::remove_dir_all(&dir).ok();
}
