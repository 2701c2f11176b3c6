//! The service host end to end: a replayed run through a hosted service with a log.

use std::path::Path;

use truepos_runtime::replay::ReplaySource;
use truepos_runtime::{log, ServiceHost};

mod support;
use support::scratch;

/// The host names the log's models, sources and sinks after the service's own, logs the
/// cycles, and stopping drains the queues and reports a healthy log.
#[test]
fn a_hosted_service_logs_under_its_own_names_and_stops_cleanly() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/vmc3");
    let machine = truepos_io::machine_file::load(&root.join("machine.toml")).unwrap();
    let entries = truepos_io::model_file::load_set(&[root.join("model.toml")], &machine).unwrap();
    let run = truepos_io::cycles::load(&root.join("run.csv"), &machine.machine, &[]).unwrap();
    let run = run.run;
    let dir = scratch("host");
    let db = dir.join("log.sqlite");
    let mut running = ServiceHost::new(machine, entries)
        .source(Box::new(ReplaySource::new("replay r", run)))
        .log(Some(db.clone()))
        .start()
        .unwrap();
    assert_eq!(running.model_names().len(), 1);
    for k in 0..1000 {
        running.service.cycle(f64::from(k) * 1e-3);
    }
    assert_eq!(running.log_health().map(|h| h.failing), Some(None));
    let stopped = running.stop();
    let (result, health) = stopped.log.unwrap();
    assert!(result.is_ok(), "{result:?}");
    assert_eq!(health.first_failure, None);
    assert_eq!(stopped.service.cycles(), 1000);
    let meta = log::read_meta(&db).unwrap().unwrap();
    assert_eq!(meta["sources"], serde_json::json!(["replay r"]));
    assert_eq!(meta["sinks"], serde_json::json!([]));
    let (_, rows) = log::read_cycles(&db, None).unwrap();
    assert_eq!(rows.len(), 10);
    let _ = std::fs::remove_dir_all(&dir);
}
