//! Hot model reload through the host: a watched model file rewritten (temporary file and
//! rename, as `truepos reidentify` writes it) replaces the running model without a restart and
//! the output blends to it within the envelope; a file that does not parse, or a model for
//! another axis combination, leaves the running model untouched and logs the file and reason.

mod support;

use std::path::Path;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use support::{repo, scratch, vmc};
use truepos_io::model_file::load_set;
use truepos_io::model_file::position::{self, ModelFile};
use truepos_model::{CycleInput, Model};
use truepos_runtime::host::ReloadSetup;
use truepos_runtime::{
    log, Frame, LinkError, MachineConfig, Running, ServiceConfig, ServiceHost, Source,
};

struct Steady(Arc<Mutex<(Vec<f64>, Vec<f64>)>>);

impl Source for Steady {
    fn name(&self) -> &str {
        "steady"
    }
    fn read(&mut self, frame: &mut Frame) -> Result<(), LinkError> {
        let v = self.0.lock().unwrap();
        for (c, &t) in v.0.iter().enumerate() {
            frame.set_temperature(c, t);
        }
        for (a, &p) in v.1.iter().enumerate() {
            frame.set_position(a, p);
        }
        Ok(())
    }
}

fn write_atomically(path: &Path, text: &str) {
    let tmp = path.with_extension("tmp");
    std::fs::write(&tmp, text).unwrap();
    std::fs::rename(&tmp, path).unwrap();
}

fn scaled(model: &Model, machine: &MachineConfig, k: f64) -> Model {
    let theta: Vec<f64> = model.parameters().iter().map(|p| p * k).collect();
    model.with_parameters(&machine.machine, &theta).unwrap()
}

/// Cycles every 10 ms of service time (and real time) until the reload thread's result has
/// been applied; checks the envelope's rate on every cycle on the way.
fn cycle_until_reload(
    running: &mut Running,
    t: &mut f64,
    rate: f64,
) -> truepos_runtime::host::ReloadReport {
    let start = Instant::now();
    let mut prev = running.service.output().offset_um;
    while start.elapsed() < Duration::from_secs(5) {
        *t += 0.01;
        let out = running.service.cycle(*t).offset_um;
        for a in 0..3 {
            assert!(
                (out[a] - prev[a]).abs() <= rate * 0.01 + 1e-9,
                "step at {t}"
            );
        }
        prev = out;
        if let Some(r) = running.poll_reload() {
            return r;
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    panic!("no reload within 5 s");
}

fn expected(model: &Model, temps: &[f64], pos: &[f64], n_op: usize) -> [f64; 3] {
    let op = vec![f64::NAN; n_op];
    let c = model
        .evaluate(&CycleInput {
            temperatures_c: temps,
            positions: pos,
            operating: &op,
        })
        .unwrap();
    [0, 1, 2].map(|a| c.compensation_um(a))
}

#[test]
fn a_rewritten_model_file_blends_in_and_a_bad_one_changes_nothing() {
    let dir = scratch("reload");
    let machine = vmc();
    let file = dir.join("model.toml");
    let original = position::load(&repo("examples/vmc3/model.toml"), &machine.machine).unwrap();
    let text = |m: &Model| {
        let mut f = ModelFile::from_model(m, &machine.machine);
        f.axis_index = Some(vec![101, 102, 103]);
        f.to_toml()
    };
    write_atomically(&file, &text(&original));
    let n_t = machine.machine.temperatures.len();
    let n_op = machine.machine.operating.len();
    let temps: Vec<f64> = (0..n_t).map(|c| 22.0 + 0.3 * c as f64).collect();
    let pos = vec![400.0, 300.0, 200.0];
    let shared = Arc::new(Mutex::new((temps.clone(), pos.clone())));
    let loader_machine = machine.clone();
    let setup = ReloadSetup {
        files: vec![file.clone()],
        loader: Box::new(move |p| {
            load_set(&[p.to_path_buf()], &loader_machine)
                .map(|mut v| v.remove(0))
                .map_err(|e| e.to_string())
        }),
        watch: true,
    };
    let entries = load_set(std::slice::from_ref(&file), &machine).unwrap();
    let db = dir.join("log.sqlite");
    let config = ServiceConfig {
        blend_s: 0.5,
        ..ServiceConfig::default()
    };
    let rate = machine.axes[0].max_rate_um_per_s;
    let mut running = ServiceHost::new(machine.clone(), entries)
        .source(Box::new(Steady(Arc::clone(&shared))))
        .config(config)
        .log(Some(db.clone()))
        .reload(Some(setup))
        .start()
        .unwrap();
    let mut t = 0.0;
    for _ in 0..300 {
        t += 0.01;
        running.service.cycle(t);
    }
    let before = expected(&original, &temps, &pos, n_op);
    let out = running.service.output().offset_um;
    for a in 0..3 {
        assert!((out[a] - before[a]).abs() < 1e-9, "{out:?} vs {before:?}");
    }

    // A re-identified model: the output blends from the old value to the new one.
    let new = scaled(&original, &machine, 1.5);
    write_atomically(&file, &text(&new));
    let report = cycle_until_reload(&mut running, &mut t, rate);
    assert_eq!(report.reloaded, vec![(0, file.clone())], "{report:?}");
    assert!(report.failed.is_empty());
    for _ in 0..300 {
        t += 0.01;
        running.service.cycle(t);
    }
    let after = expected(&new, &temps, &pos, n_op);
    let out = running.service.output().offset_um;
    for a in 0..3 {
        assert!((out[a] - after[a]).abs() < 1e-9, "{out:?} vs {after:?}");
    }

    // A file that does not parse, then a model for another axis combination: refused, the
    // running model stays.
    write_atomically(&file, "format = \"truepos-model\"\nversion = 1\nname = \n");
    let report = cycle_until_reload(&mut running, &mut t, rate);
    assert!(report.reloaded.is_empty());
    let (f, why) = &report.failed[0];
    assert_eq!(f, &file);
    assert!(why.starts_with(&format!("{}:3:", file.display())), "{why}");
    let mut other = ModelFile::from_model(&new, &machine.machine);
    other.axis_index = Some(vec![101, 102]);
    write_atomically(&file, &other.to_toml());
    let report = cycle_until_reload(&mut running, &mut t, rate);
    assert!(
        report.failed[0].1.contains("axis combination"),
        "{report:?}"
    );
    for _ in 0..100 {
        t += 0.01;
        let out = running.service.cycle(t).offset_um;
        for a in 0..3 {
            assert!(
                (out[a] - after[a]).abs() < 1e-9,
                "moved after a refused reload"
            );
        }
    }
    // On request (the HAL pin): the file as it is now is still refused.
    running.request_reload();
    let report = cycle_until_reload(&mut running, &mut t, rate);
    assert_eq!(report.failed.len(), 1);

    let stopped = running.stop();
    stopped.log.unwrap().0.unwrap();
    let events = log::read_events(&db).unwrap();
    let reloaded: Vec<_> = events
        .iter()
        .filter(|e| e.kind == "model-reloaded")
        .collect();
    let failed: Vec<_> = events
        .iter()
        .filter(|e| e.kind == "model-reload-failed")
        .collect();
    assert_eq!(reloaded.len(), 1, "{events:?}");
    assert_eq!(reloaded[0].detail, file.display().to_string());
    assert_eq!(failed.len(), 3, "{events:?}");
    assert!(failed[0].detail.contains(&file.display().to_string()));
    assert!(failed[0].detail.ends_with("the running model stays"));
    std::fs::remove_dir_all(&dir).ok();
}
