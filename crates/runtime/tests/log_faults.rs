//! The log and the sinks under faults (issue 11): a full disk, a log of another machine, a
//! failing sink. Each test is bounded in time.

use std::path::Path;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use truepos_io::machine_file;
use truepos_io::model_file::position;
use truepos_runtime::events::EventKind;
use truepos_runtime::log::{self, LogSetup, Logger};
use truepos_runtime::model_set::ModelEntry;
use truepos_runtime::*;

mod support;
use support::{repo, scratch, vmc};

/// A source of fixed values; the test may change a temperature between cycles.
struct Fixed(Arc<Mutex<Vec<f64>>>);

impl Source for Fixed {
    fn name(&self) -> &str {
        "fixed"
    }
    fn read(&mut self, frame: &mut Frame) -> Result<(), LinkError> {
        for (c, &t) in self.0.lock().unwrap().iter().enumerate() {
            frame.set_temperature(c, t);
        }
        for a in 0..3 {
            frame.set_position(a, 100.0);
        }
        Ok(())
    }
}

fn service(sinks: Vec<Box<dyn Sink>>) -> (Service, Arc<Mutex<Vec<f64>>>) {
    let machine = vmc();
    let temps = Arc::new(Mutex::new(vec![21.0; machine.machine.temperatures.len()]));
    let model = ModelEntry {
        name: "vmc3".into(),
        model: position::load(&repo("examples/vmc3/model.toml"), &machine.machine)
            .unwrap()
            .into(),
        index: [101, 102, 103],
    };
    let config = ServiceConfig {
        // Every 10 ms cycle is logged (half the step, against rounding).
        log_every_s: 0.005,
        ..ServiceConfig::default()
    };
    let source: Box<dyn Source> = Box::new(Fixed(Arc::clone(&temps)));
    (
        Service::new(machine, vec![model], vec![source], sinks, config),
        temps,
    )
}

fn start_log(db: &Path, machine: &MachineConfig, s: &Service) -> Logger {
    Logger::start(
        LogSetup {
            path: db,
            machine,
            models: vec!["vmc3".into()],
            sources: vec!["fixed".into()],
            sinks: vec![],
            paths: 1,
            commit_every: Duration::from_millis(250),
        },
        s.events(),
        s.records(),
    )
    .unwrap()
}

fn page_count(db: &Path) -> u64 {
    let conn =
        rusqlite::Connection::open_with_flags(db, rusqlite::OpenFlags::SQLITE_OPEN_READ_ONLY)
            .unwrap();
    conn.query_row("PRAGMA page_count", [], |r| r.get(0))
        .unwrap()
}

/// Runs cycles of 10 ms service time, pacing them at 1 ms of wall time, until `until` holds
/// or `limit` of wall time passed; returns the wall time it took.
fn cycle_until(
    s: &mut Service,
    t: &mut f64,
    limit: Duration,
    mut until: impl FnMut() -> bool,
) -> Option<Duration> {
    let start = Instant::now();
    while start.elapsed() < limit {
        *t += 0.01;
        s.cycle(*t);
        if until() {
            return Some(start.elapsed());
        }
        std::thread::sleep(Duration::from_millis(1));
    }
    None
}

/// Finding: on a full disk the logger stopped for good after 1 s, the service ran on and the
/// error appeared only at exit. Now the failure shows within a second, the service runs on,
/// and once there is room again the log resumes with every record and event queued meanwhile.
/// The full disk is SQLite's own SQLITE_FULL, through `max_page_count`.
#[test]
fn a_full_disk_shows_within_a_second_and_the_log_resumes_without_losing_the_queue() {
    let dir = scratch("logfault-full");
    let db = dir.join("log.sqlite");
    let machine = vmc();
    let (mut s, temps) = service(vec![]);
    let logger = start_log(&db, &machine, &s);
    let mut t = 0.0;
    cycle_until(&mut s, &mut t, Duration::from_millis(400), || false);
    // Let the thread commit what is queued, then cap the file where it stands: the next
    // pages the records need are refused as on a full disk.
    std::thread::sleep(Duration::from_millis(300));
    logger.set_page_limit(page_count(&db));
    let took = cycle_until(&mut s, &mut t, Duration::from_secs(3), || {
        logger.health().failing.is_some()
    })
    .expect("the failure shows in the logger's health");
    assert!(took < Duration::from_secs(1), "shown after {took:?}");
    let h = logger.health();
    assert!(
        h.failing.as_deref().unwrap().contains("full"),
        "{:?}",
        h.failing
    );
    // The service runs on; a sensor fault while the log fails is kept for later.
    temps.lock().unwrap()[3] = f64::NAN;
    cycle_until(&mut s, &mut t, Duration::from_millis(800), || false);
    assert!(logger.health().failing.is_some());
    assert!(logger.health().pending > 0);
    // The lock-free figures a real-time thread reads say the same.
    let (failing, pending, _) = logger.figures();
    assert!(failing && pending > 0, "{:?}", logger.figures());
    logger.set_page_limit(1 << 30);
    cycle_until(&mut s, &mut t, Duration::from_secs(5), || {
        logger.health().failing.is_none()
    })
    .expect("the log resumes once there is room (backoff at most 2 s)");
    let h = logger.health();
    assert!(!logger.figures().0);
    assert_eq!(h.resumed, 1);
    assert_eq!((h.records_dropped, h.events_dropped), (0, 0));
    logger.stop().expect("a resumed log ends well");
    assert_eq!(s.records_dropped(), 0);

    assert_eq!(log::integrity_check(&db).unwrap(), "ok");
    let events = log::read_events(&db).unwrap();
    let kinds: Vec<&str> = events.iter().map(|e| e.kind.as_str()).collect();
    let failed = kinds
        .iter()
        .position(|k| *k == "log-failed")
        .expect("log-failed");
    let resumed = kinds
        .iter()
        .position(|k| *k == "log-resumed")
        .expect("log-resumed");
    assert!(failed < resumed, "{kinds:?}");
    assert!(events[failed].detail.contains("full"), "{events:?}");
    assert!(
        events[resumed]
            .detail
            .contains("0 records and 0 events dropped"),
        "{events:?}"
    );
    assert!(events
        .iter()
        .any(|e| e.kind == "sensor-fault" && e.subject == "y_slide_bottom"));
    // Every record reached the file: no gap in service time.
    let (names, rows) = log::read_cycles(&db, None).unwrap();
    let c = names.iter().position(|n| n == "time_s").unwrap();
    let times: Vec<f64> = rows.iter().map(|r| r[c].parse().unwrap()).collect();
    assert!(times.len() > 100);
    for w in times.windows(2) {
        assert!(w[1] - w[0] < 0.0151, "gap {} → {}", w[0], w[1]);
    }
    std::fs::remove_dir_all(&dir).ok();
}

/// A log still full at the end: `stop` says so, naming the file and the reason.
#[test]
fn a_log_still_failing_at_the_end_is_an_error_of_stop() {
    let dir = scratch("logfault-still");
    let db = dir.join("log.sqlite");
    let machine = vmc();
    let (mut s, _) = service(vec![]);
    let logger = start_log(&db, &machine, &s);
    let mut t = 0.0;
    cycle_until(&mut s, &mut t, Duration::from_millis(300), || false);
    std::thread::sleep(Duration::from_millis(300));
    logger.set_page_limit(page_count(&db));
    cycle_until(&mut s, &mut t, Duration::from_secs(3), || {
        logger.health().failing.is_some()
    })
    .expect("the failure shows");
    let e = logger.stop().expect_err("the log never resumed");
    let text = e.to_string();
    assert!(
        text.contains("log.sqlite") && text.contains("never resumed"),
        "{text}"
    );
    assert!(text.contains("full"), "{text}");
    std::fs::remove_dir_all(&dir).ok();
}

/// Finding: a second service pointed at the same log replaced its `meta` with another machine
/// and failed only at exit. Now it is refused at start, naming the file and both machines, and
/// the log is left as it was.
#[test]
fn a_log_of_another_machine_is_refused_at_start_naming_both_machines() {
    let dir = scratch("logfault-owner");
    let db = dir.join("log.sqlite");
    let machine = vmc();
    let (s, _) = service(vec![]);
    start_log(&db, &machine, &s).stop().unwrap();
    // The same machine again appends.
    start_log(&db, &machine, &s).stop().unwrap();
    let twin = machine_file::load(&repo("examples/twin/machine.toml")).unwrap();
    let refused = Logger::start(
        LogSetup {
            path: &db,
            machine: &twin,
            models: vec![],
            sources: vec![],
            sinks: vec![],
            paths: 1,
            commit_every: Duration::from_millis(250),
        },
        s.events(),
        s.records(),
    );
    let text = match refused {
        Ok(_) => panic!("a log of another machine was accepted"),
        Err(e) => e.to_string(),
    };
    assert!(text.contains("log.sqlite"), "{text}");
    assert!(
        text.contains("vmc-3axis") && text.contains("twin-vmc3"),
        "{text}"
    );
    let conn = rusqlite::Connection::open(&db).unwrap();
    let meta: String = conn
        .query_row("SELECT value FROM meta WHERE key = 'service'", [], |r| {
            r.get(0)
        })
        .unwrap();
    assert!(meta.contains("vmc-3axis"), "{meta}");
    std::fs::remove_dir_all(&dir).ok();
}

/// A sink that fails from a given cycle on and recovers at another.
struct Flaky {
    cycle: u32,
    fail: std::ops::Range<u32>,
    axes: bool,
}

impl Sink for Flaky {
    fn name(&self) -> &str {
        "flaky"
    }
    fn write(&mut self, _: &Output) -> Result<(), LinkError> {
        self.cycle += 1;
        if self.fail.contains(&self.cycle) {
            Err(LinkError::Failed("no space left on device".into()))
        } else {
            Ok(())
        }
    }
    fn drives_axes(&self) -> bool {
        self.axes
    }
}

/// A failing sink raises one event with its reason when it fails and one when it is back, its
/// state shows meanwhile, and only a sink that drives the axes makes them unreachable.
#[test]
fn a_failing_sink_is_one_event_and_a_state() {
    for axes in [false, true] {
        let sink = Flaky {
            cycle: 0,
            fail: 10..110,
            axes,
        };
        let (mut s, _) = service(vec![Box::new(sink)]);
        let q = s.events();
        let mut t = 0.0;
        let mut failed = Vec::new();
        for i in 1..=200u32 {
            t += 0.01;
            s.cycle(t);
            while let Some(e) = q.pop() {
                match e.kind {
                    EventKind::SinkFailed { sink, reason } => {
                        failed.push((i, sink, reason.as_str().to_string()))
                    }
                    EventKind::SinkBack { sink } => failed.push((i, sink, "back".into())),
                    _ => {}
                }
            }
            let failing = (10..110).contains(&i);
            assert_eq!(s.sink_health()[0].failing_since_s.is_some(), failing, "{i}");
            assert_eq!(s.axes_unreachable().is_some(), failing && axes, "{i}");
        }
        assert_eq!(
            failed,
            vec![
                (10, 0, "no space left on device".to_string()),
                (110, 0, "back".to_string())
            ]
        );
        let h = s.sink_health()[0];
        assert_eq!(h.failed_writes, 100);
        assert!((h.first_failure_s.unwrap() - 0.10).abs() < 1e-9);
    }
}

/// The CSV sink on a device that takes nothing fails at its first write and stays failed (no
/// flicker between cycles); on a file it writes every row.
#[test]
fn the_csv_sink_fails_steadily_on_a_full_device() {
    let axes = vec!["X".to_string(), "Y".to_string(), "Z".to_string()];
    let mut full = replay::CsvSink::create(Path::new("/dev/full"), &axes, 0.0, &[]).unwrap();
    let mut out = Output::zero(3);
    for i in 0..100 {
        out.time_s = f64::from(i) * 0.01;
        let r = full.write(&out);
        assert!(
            matches!(&r, Err(LinkError::Failed(m)) if m.contains("No space")),
            "{i}: {r:?}"
        );
    }
    let dir = scratch("logfault-csv");
    let file = dir.join("out.csv");
    {
        let mut csv = replay::CsvSink::create(&file, &axes, 0.0, &[]).unwrap();
        for i in 0..100 {
            out.time_s = f64::from(i) * 0.01;
            csv.write(&out).unwrap();
        }
    }
    let text = std::fs::read_to_string(&file).unwrap();
    assert_eq!(text.lines().count(), 101);
    assert!(text.starts_with("time_s,X_offset_um,Y_offset_um,Z_offset_um,state,clamped\n"));
    assert!(
        text.contains("\n0.9900,0.0000,0.0000,0.0000,disabled,0\n"),
        "{text}"
    );
    std::fs::remove_dir_all(&dir).ok();
}

/// A probe event every `every`-th cycle beside the fixed inputs.
struct Probing {
    inner: Fixed,
    every: u32,
    count: u32,
}

impl Source for Probing {
    fn name(&self) -> &str {
        "probing"
    }
    fn read(&mut self, frame: &mut Frame) -> Result<(), LinkError> {
        self.count += 1;
        if self.count.is_multiple_of(self.every) {
            let mut p = truepos_runtime::probe::ProbeInput::EMPTY;
            p.position_mm[..3].copy_from_slice(&[100.0, 100.0, 100.0]);
            p.deviation_um[2] = f64::from(self.count) * 1e-3;
            p.measured[2] = true;
            frame.probe = Some(p);
        }
        self.inner.read(frame)
    }
}

/// Probe events met while the disk is full are kept and written when it resumes: every event
/// the service saw is in the `probes` table, in order.
#[test]
fn probe_events_during_a_full_disk_reach_the_log_when_it_resumes() {
    let dir = scratch("logfault-probes");
    let db = dir.join("log.sqlite");
    let machine = vmc();
    let temps = Arc::new(Mutex::new(vec![21.0; machine.machine.temperatures.len()]));
    let model = ModelEntry {
        name: "vmc3".into(),
        model: position::load(&repo("examples/vmc3/model.toml"), &machine.machine)
            .unwrap()
            .into(),
        index: [101, 102, 103],
    };
    let source: Box<dyn Source> = Box::new(Probing {
        inner: Fixed(temps),
        every: 20,
        count: 0,
    });
    let mut s = Service::new(
        machine.clone(),
        vec![model],
        vec![source],
        vec![],
        ServiceConfig::default(),
    );
    let logger = Logger::start_with_probes(
        LogSetup {
            path: &db,
            machine: &machine,
            models: vec!["vmc3".into()],
            sources: vec!["probing".into()],
            sinks: vec![],
            paths: 1,
            commit_every: Duration::from_millis(250),
        },
        s.events(),
        s.records(),
        s.probes(),
    )
    .unwrap();
    let mut t = 0.0;
    cycle_until(&mut s, &mut t, Duration::from_millis(300), || false);
    std::thread::sleep(Duration::from_millis(300));
    logger.set_page_limit(page_count(&db));
    cycle_until(&mut s, &mut t, Duration::from_secs(3), || {
        logger.health().failing.is_some()
    })
    .expect("the failure shows");
    cycle_until(&mut s, &mut t, Duration::from_millis(600), || false);
    logger.set_page_limit(1 << 30);
    cycle_until(&mut s, &mut t, Duration::from_secs(5), || {
        logger.health().failing.is_none()
    })
    .expect("the log resumes");
    let (result, health) = logger.stop_with_health();
    result.unwrap();
    assert_eq!(health.probes_dropped, 0);
    let cycles = s.cycles();
    let table = log::read_probes(&db).unwrap();
    assert_eq!(
        table.rows.len() as u64,
        cycles / 20,
        "every probe event is logged"
    );
    let dz = table
        .columns
        .iter()
        .position(|c| c == "probe_dz_um")
        .unwrap();
    for (i, r) in table.rows.iter().enumerate() {
        assert!(r.accepted, "{r:?}");
        let expect = (20 * (i as u32 + 1)) as f64 * 1e-3;
        assert!(
            (r.values[dz].unwrap() - expect).abs() < 1e-12,
            "row {i}: {r:?}"
        );
    }
    assert_eq!(log::integrity_check(&db).unwrap(), "ok");
    std::fs::remove_dir_all(&dir).ok();
}
