//! The live view's publication point (`truepos_runtime::live::Board`): the host publishes
//! between cycles without allocating, locking or waiting, while readers on other threads read
//! consistent snapshots of what the cycle did.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use truepos_io::cycles;
use truepos_io::model_file::position;
use truepos_runtime::live::{Board, HostFigures, Layout, LogFigures, PathView};
use truepos_runtime::log;
use truepos_runtime::model_set::ModelEntry;
use truepos_runtime::replay::ReplaySource;
use truepos_runtime::*;

mod support;
use support::{repo, vmc};

fn vmc_model(name: &str) -> ModelEntry {
    let m = vmc();
    ModelEntry {
        name: name.into(),
        model: position::load(&repo("examples/vmc3/model.toml"), &m.machine)
            .unwrap()
            .into(),
        index: [101, 102, 103],
    }
}

fn replayed_service() -> Service {
    let machine = vmc();
    let run = cycles::load(&repo("examples/vmc3/run.csv"), &machine.machine, &[]).unwrap();
    let source = ReplaySource::new("replay", run.run);
    Service::new(
        machine,
        vec![vmc_model("vmc3")],
        vec![Box::new(source)],
        vec![],
        ServiceConfig::default(),
    )
}

/// Cycles and publications with a reader hammering the board on another thread: the loop's
/// thread allocates nothing for either, and every snapshot read is one publication whole.
#[test]
fn cycles_and_publications_allocate_nothing_while_a_reader_reads() {
    let mut service = replayed_service();
    service.cycle(0.0);
    let board = Arc::new(Board::new(Layout::of(&service)));
    assert!(board.read().is_none(), "nothing published yet");
    let stop = Arc::new(AtomicBool::new(false));
    let reader = {
        let (board, stop) = (Arc::clone(&board), Arc::clone(&stop));
        std::thread::spawn(move || {
            let mut seen = 0u64;
            let mut last_seq = 0;
            while !stop.load(Ordering::Relaxed) {
                if let Some(s) = board.read() {
                    assert!(s.seq >= last_seq, "publications go forward");
                    // Published in one go: the cycle count and the late count move together.
                    assert_eq!(s.late_cycles, s.cycles / 7, "two publications mixed");
                    last_seq = s.seq;
                    seen += 1;
                }
            }
            seen
        })
    };
    let generations = [3u64];
    let mut t = 0.0;
    let counted = allocation_counter::measure(|| {
        for _ in 0..20_000 {
            t += 0.06;
            service.cycle(t);
            let figures = HostFigures {
                late_cycles: service.cycles() / 7,
                cycle_work_us: 1.5,
                log: Some(LogFigures {
                    failing: false,
                    pending: 4,
                    dropped: 0,
                }),
                generations: &generations,
            };
            board.publish(&service, &figures);
            board.record_work(1.5, std::time::Instant::now());
        }
    });
    stop.store(true, Ordering::Relaxed);
    let seen = reader.join().unwrap();
    assert_eq!(counted.count_total, 0, "the loop allocated");
    assert!(seen > 0, "the reader read");
    let s = board.read().unwrap();
    assert_eq!(s.seq, 20_000);
    assert_eq!(s.cycles, service.cycles());
    assert_eq!(s.time_s, service.output().time_s);
    assert_eq!(s.state, service.output().state);
    assert_eq!(s.generations, vec![3]);
    assert_eq!(s.log.unwrap().pending, 4);
    for (a, v) in s.axes.iter().enumerate() {
        assert_eq!(v.offset_um, service.output().offset_um[a]);
        assert_eq!(v.target_um, service.targets()[a]);
    }
    assert_eq!(s.paths, vec![(PathView::Model(0), false)]);
    assert_eq!(
        s.temperatures.len(),
        service.machine().machine.temperatures.len()
    );
    assert!(
        s.temperatures.iter().all(|t| t.fault == 0),
        "{:?}",
        s.temperatures
    );
    // The replay's rows are a minute apart: every reading is under a minute old.
    assert!(
        s.temperatures
            .iter()
            .all(|t| (0.0..=60.0).contains(&t.age_s)),
        "{:?}",
        s.temperatures
    );
    assert_eq!(s.sources_ok, vec![true]);
    assert_eq!(s.sources_last_ok_s, vec![s.time_s], "delivering now");
    assert_eq!(board.work().total(), (20_000, 30_000.0));
}

/// The history the live view reads from the log: min/max per bucket over the rows of this run
/// only (an appended log's earlier runs are left out), so a one-cycle peak survives.
#[test]
fn history_keeps_each_buckets_extremes_and_only_this_runs_rows() {
    let dir = support::scratch("live-history");
    let db = dir.join("log.sqlite");
    let _ = std::fs::remove_file(&db);
    let run_once = |cycles: usize| {
        let machine = vmc();
        let run = cycles::load(&repo("examples/vmc3/run.csv"), &machine.machine, &[]).unwrap();
        let mut host = ServiceHost::new(machine, vec![vmc_model("vmc3")])
            .source(Box::new(ReplaySource::new("replay", run.run)))
            .config(ServiceConfig {
                log_every_s: 0.0,
                ..ServiceConfig::default()
            })
            .log(Some(db.clone()))
            .start()
            .unwrap();
        for k in 0..cycles {
            host.service.cycle(k as f64 * 0.5);
        }
        host.stop().log.unwrap().0.unwrap();
    };
    run_once(300);
    let before = log::last_rows(&db);
    assert_eq!(before.cycles, 300);
    run_once(1000);
    let all = log::read_history(&db, before.cycles, None, 100).unwrap();
    assert_eq!(all.buckets.iter().map(|b| b.rows).sum::<u64>(), 1000);
    assert!(all.buckets.len() <= 100, "{}", all.buckets.len());
    assert_eq!((all.start_s, all.end_s), (0.0, 499.5));
    let (names, rows) = log::read_cycles(&db, Some(1000)).unwrap();
    for (c, name) in all.columns.iter().enumerate() {
        let col = names.iter().position(|n| n == name).unwrap();
        let values: Vec<f64> = rows.iter().filter_map(|r| r[col].parse().ok()).collect();
        let top = values.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let top_seen = all
            .buckets
            .iter()
            .filter_map(|b| b.max[c])
            .fold(f64::NEG_INFINITY, f64::max);
        assert_eq!(top, top_seen, "column {name}: the peak survives");
        for b in &all.buckets {
            if let (Some(lo), Some(hi)) = (b.min[c], b.max[c]) {
                assert!(lo <= hi);
            }
        }
    }
    let window = log::read_history(&db, before.cycles, Some(100.0), 10).unwrap();
    assert_eq!(window.start_s, 399.5);
    assert_eq!(window.buckets.iter().map(|b| b.rows).sum::<u64>(), 201);
    let events = log::read_events_after(&db, before.events, 1000).unwrap();
    assert!(events.iter().all(|(row, _)| *row > before.events));
    assert!(
        events.iter().any(|(_, e)| e.kind == "model-selected"),
        "{events:?}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}
