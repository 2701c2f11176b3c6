//! The cycle end to end without hardware: replayed and scripted sources, model sets, faults,
//! bumpless switching, the envelope, the log.

use std::path::Path;
use std::sync::{Arc, Mutex};

use truepos_io::model_file::position;
use truepos_io::{cycles, machine_file};
use truepos_model::CycleInput;
use truepos_runtime::events::EventKind;
use truepos_runtime::log::{self, LogSetup, Logger};
use truepos_runtime::model_set::ModelEntry;
use truepos_runtime::replay::ReplaySource;
use truepos_runtime::*;

mod support;
use support::{repo, scratch, vmc};

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

/// A source whose values the test sets between cycles.
struct Scripted {
    values: Arc<Mutex<(Vec<f64>, Vec<f64>)>>,
}

impl Source for Scripted {
    fn name(&self) -> &str {
        "scripted"
    }
    fn read(&mut self, frame: &mut Frame) -> Result<(), LinkError> {
        let v = self.values.lock().unwrap();
        for (c, &t) in v.0.iter().enumerate() {
            frame.set_temperature(c, t);
        }
        for (a, &p) in v.1.iter().enumerate() {
            frame.set_position(a, p);
        }
        Ok(())
    }
}

type Shared = Arc<Mutex<(Vec<f64>, Vec<f64>)>>;

fn scripted(temps: Vec<f64>, positions: Vec<f64>) -> (Box<dyn Source>, Shared) {
    let values = Arc::new(Mutex::new((temps, positions)));
    (
        Box::new(Scripted {
            values: Arc::clone(&values),
        }),
        values,
    )
}

fn drain(service: &Service) -> Vec<EventKind> {
    let q = service.events();
    std::iter::from_fn(|| q.pop()).map(|e| e.kind).collect()
}

/// Replaying the example run through the service gives −(model output) on every cycle once the
/// start-up blend is over, within the envelope.
#[test]
fn replay_gives_the_model_output() {
    let machine = vmc();
    let run = cycles::load(&repo("examples/vmc3/run.csv"), &machine.machine, &[]).unwrap();
    let reference = position::load(&repo("examples/vmc3/model.toml"), &machine.machine).unwrap();
    let source = ReplaySource::new("replay", run.run.clone());
    let mut service = Service::new(
        machine,
        vec![vmc_model("vmc3")],
        vec![Box::new(source)],
        vec![],
        ServiceConfig::default(),
    );
    let mut checked = 0;
    for (i, &t) in run.run.time_s.iter().enumerate() {
        let out = *service.cycle(t);
        if t < 10.0 {
            continue;
        }
        let c = reference
            .evaluate(&CycleInput {
                temperatures_c: &run.run.temperatures_c[i],
                positions: &run.run.positions[i],
                operating: &run.run.operating[i],
            })
            .unwrap();
        assert_eq!(out.state, CompensationState::Active);
        for a in 0..3 {
            // The run moves slowly enough (60 s samples) that the envelope never binds.
            assert!(
                (out.offset_um[a] - c.compensation_um(a)).abs() < 1e-9,
                "t = {t}, axis {a}: {} vs {}",
                out.offset_um[a],
                c.compensation_um(a)
            );
        }
        checked += 1;
    }
    assert!(checked > 200);
    assert!(service.finished());
}

/// A NaN on a sensor the only model reads: the service holds the last compensation and ramps it
/// to zero; the output never steps faster than the envelope allows; the fault is an event.
#[test]
fn a_bad_sensor_holds_and_ramps_to_zero() {
    let machine = vmc();
    let n_t = machine.machine.temperatures.len();
    let mut temps = vec![20.0; n_t];
    temps[1] = 25.0; // x_slide_bottom: dT_x_slide = 5 K → Z error 2·5 + 4·5·r_X
    let (source, values) = scripted(temps, vec![800.0, 250.0, 250.0]);
    let config = ServiceConfig {
        blend_s: 2.0,
        hold_ramp_s: 10.0,
        ..ServiceConfig::default()
    };
    let mut service = Service::new(
        machine,
        vec![vmc_model("vmc3")],
        vec![source],
        vec![],
        config,
    );
    struct Track {
        t: f64,
        last: [f64; 3],
        max_rate: f64,
    }
    fn run(service: &mut Service, until: f64, k: &mut Track) {
        let dt = 0.01;
        while k.t < until {
            k.t += dt;
            let out = *service.cycle(k.t);
            for a in 0..3 {
                k.max_rate = k.max_rate.max((out.offset_um[a] - k.last[a]).abs() / dt);
                k.last[a] = out.offset_um[a];
            }
        }
    }
    let mut k = Track {
        t: 0.0,
        last: [0.0; 3],
        max_rate: 0.0,
    };
    run(&mut service, 5.0, &mut k);
    // Z error = 5·(2 + 4·1) = 30 µm → compensation −30 µm.
    assert!((k.last[2] + 30.0).abs() < 1e-9, "{:?}", k.last);
    assert_eq!(service.path_states()[0], PathState::Model(0));
    values.lock().unwrap().0[1] = f64::NAN;
    run(&mut service, 10.0, &mut k);
    assert_eq!(service.path_states()[0], PathState::Holding);
    // 5 s into a 10 s ramp: half of −30 µm.
    assert!((k.last[2] + 15.0).abs() < 0.2, "{:?}", k.last);
    run(&mut service, 16.0, &mut k);
    assert_eq!(k.last[2], 0.0);
    assert!(k.max_rate <= 50.0 + 1e-6, "step rate {} µm/s", k.max_rate);
    let events = drain(&service);
    assert!(events.iter().any(|e| matches!(
        e,
        EventKind::SensorFault {
            channel: 1,
            fault: sensor_validation::Fault::NotANumber
        }
    )));
    assert!(events.contains(&EventKind::Holding { path: 1 }));
}

/// A model that knows where it was trained: a sensor far beyond its training range is clamped
/// to the range widened by its margin, the event names it, the output stays what the edge of
/// the range gives (never the extrapolation), and the end is an event too.
#[test]
fn a_model_beyond_its_training_envelope_is_clamped_and_said() {
    let machine = vmc();
    let n_t = machine.machine.temperatures.len();
    let mut entry = vmc_model("vmc3");
    entry.model.as_static_mut().unwrap().set_envelope(Some(
        truepos_model::envelope::TrainingEnvelope {
            temperatures: vec![Some((19.0, 21.0)); n_t],
            operating: vec![None; machine.machine.operating.len()],
            max_abs_um: vec![Some(40.0); 3],
        },
    ));
    let mut temps = vec![20.0; n_t];
    temps[1] = 22.0; // x_slide_bottom: dT_x_slide = 2 K → Z error 2·(2 + 4·1) = 12 µm at X 800
    let (source, values) = scripted(temps, vec![800.0, 250.0, 250.0]);
    let mut service = Service::new(
        machine,
        vec![entry],
        vec![source],
        vec![],
        ServiceConfig::default(),
    );
    let mut t = 0.0;
    // Moves x_slide_bottom to `to` at 1 K/min (the validator refuses faster), then holds 20 s.
    let mut ramp = |service: &mut Service, to: f64| -> f64 {
        let mut z = 0.0;
        let mut hold = 0.0;
        while hold < 20.0 {
            t += 0.1;
            let mut v = values.lock().unwrap();
            let now = v.0[1];
            let step = (to - now).clamp(-0.1 / 60.0, 0.1 / 60.0);
            v.0[1] = now + step;
            drop(v);
            if step == 0.0 {
                hold += 0.1;
            }
            z = service.cycle(t).offset_um[2];
        }
        z
    };
    assert!((ramp(&mut service, 22.0) + 12.0).abs() < 1e-9);
    assert!(!service.extrapolating());
    // 27 °C where training saw at most 21: clamped to 21 + 2 K → dT 3 K → 18 µm, not 42.
    let z = ramp(&mut service, 27.0);
    assert!((z + 18.0).abs() < 1e-9, "{z}");
    assert!(service.extrapolating());
    assert!((ramp(&mut service, 22.0) + 12.0).abs() < 1e-6);
    assert!(!service.extrapolating());
    let events = drain(&service);
    let beyond = events.iter().find_map(|e| match e {
        EventKind::Extrapolating {
            path: 1,
            input,
            value,
            limit,
        } => Some((*input, *value > 23.0, *limit)),
        _ => None,
    });
    assert_eq!(
        beyond,
        Some((truepos_model::MachineInput::Temperature(1), true, 23.0)),
        "{events:?}"
    );
    assert!(events.contains(&EventKind::ExtrapolationEnded { path: 1 }));
}

/// A position no axis can have (1e308 from a retyped node, a wrong scale) is a position fault,
/// said as an event, and the service holds; back within reach, the positions recover.
#[test]
fn an_implausible_position_is_a_position_fault() {
    let machine = vmc();
    let n_t = machine.machine.temperatures.len();
    let (source, values) = scripted(vec![20.0; n_t], vec![400.0, 250.0, 250.0]);
    let mut service = Service::new(
        machine,
        vec![vmc_model("vmc3")],
        vec![source],
        vec![],
        ServiceConfig::default(),
    );
    let mut t = 0.0;
    let mut run = |service: &mut Service, until: f64| {
        while t < until {
            t += 0.01;
            service.cycle(t);
        }
    };
    run(&mut service, 1.0);
    assert_eq!(service.path_states()[0], PathState::Model(0));
    // 1 600 mm on an 800 mm axis is still a position (the model's business); 1e308 is not.
    values.lock().unwrap().1[0] = 1e308;
    run(&mut service, 2.0);
    assert_eq!(service.path_states()[0], PathState::Holding);
    values.lock().unwrap().1[0] = 400.0;
    run(&mut service, 3.0);
    let events = drain(&service);
    assert!(
        events.contains(&EventKind::PositionFault { axis: 0 }),
        "{events:?}"
    );
    assert!(events.contains(&EventKind::PositionRecovered), "{events:?}");
}

/// With two models for the same axis combination, a fault on a sensor only the first reads
/// makes the service substitute the second, bumplessly (documents C and D).
#[test]
fn a_bad_sensor_substitutes_a_model_without_it() {
    let machine = vmc();
    let mut primary = vmc_model("with-spindle-sensors");
    // The fallback: the same structure part, without the spindle part (no spindle sensors).
    let mut fallback = vmc_model("structure-only");
    let parts: Vec<_> = fallback.model.as_static().unwrap().parts()[..1].to_vec();
    fallback.model = truepos_model::Model::new("structure-only", &machine.machine, parts)
        .unwrap()
        .into();
    primary.name = "with-spindle-sensors".into();
    let n_t = machine.machine.temperatures.len();
    let mut temps = vec![20.0; n_t];
    temps[10] = 30.0; // spindle front bearing: +3.1 µm/K · 10 K = 31 µm along Z
    let (source, values) = scripted(temps, vec![0.0, 0.0, 0.0]);
    let mut service = Service::new(
        machine,
        vec![primary, fallback],
        vec![source],
        vec![],
        ServiceConfig {
            blend_s: 4.0,
            ..ServiceConfig::default()
        },
    );
    let mut t = 0.0;
    let mut last = 0.0;
    let mut max_rate = 0.0_f64;
    for i in 0..2000 {
        t += 0.01;
        if i == 1000 {
            values.lock().unwrap().0[10] = 400.0; // open circuit
        }
        let z = service.cycle(t).offset_um[2];
        max_rate = max_rate.max((z - last).abs() / 0.01);
        last = z;
        if i == 999 {
            assert!((z + 31.0).abs() < 1e-9, "{z}");
        }
    }
    assert_eq!(service.path_states()[0], PathState::Model(1));
    // After the 4 s blend the structure-only model gives 0 along Z at these temperatures.
    assert!(last.abs() < 1e-9);
    assert!(max_rate <= 50.0 + 1e-6);
    let events = drain(&service);
    assert!(
        events.contains(&EventKind::ModelSubstituted {
            path: 1,
            from: 0,
            to: 1
        }),
        "{events:?}"
    );
}

/// Document D in the service: when the control switches an axis to a combination no model serves,
/// the user is told (no-model event) and the output blends to zero; switching back selects the
/// model again.
#[test]
fn axis_switch_reselects_and_reports_no_model() {
    let machine = vmc();
    let n_t = machine.machine.temperatures.len();
    let mut temps = vec![20.0; n_t];
    temps[1] = 25.0;
    let (source, _values) = scripted(temps, vec![800.0, 250.0, 250.0]);
    let mut service = Service::new(
        machine,
        vec![vmc_model("vmc3")],
        vec![
            source,
            Box::new(PathSwitcher {
                at_s: 3.0,
                back_s: 8.0,
                out: 1,
            }),
        ],
        vec![],
        ServiceConfig {
            blend_s: 1.0,
            ..ServiceConfig::default()
        },
    );
    let mut t = 0.0;
    while t < 6.0 {
        t += 0.01;
        service.cycle(t);
    }
    assert_eq!(service.path_states()[0], PathState::NoModel);
    assert_eq!(service.output().offset_um[2], 0.0);
    while t < 12.0 {
        t += 0.01;
        service.cycle(t);
    }
    assert_eq!(service.path_states()[0], PathState::Model(0));
    assert!((service.output().offset_um[2] + 30.0).abs() < 1e-9);
    let events = drain(&service);
    assert!(events.contains(&EventKind::AxisSwitch));
    assert!(events.contains(&EventKind::NoModel {
        path: 1,
        target: [101, 103, 0]
    }));
}

/// Document D with a model for the new combination: Z leaves path 1, the X-Y model takes over, and
/// Z, now in no path, blends to zero over the blend time (well inside the envelope's rate, no
/// clamp); back in the path, the X-Y-Z model blends in again.
#[test]
fn an_axis_leaving_every_path_blends_to_zero() {
    let machine = vmc();
    let n_t = machine.machine.temperatures.len();
    let mut temps = vec![20.0; n_t];
    temps[1] = 25.0;
    let (source, _values) = scripted(temps, vec![800.0, 250.0, 250.0]);
    let xy = ModelEntry {
        index: [101, 102, 0],
        ..vmc_model("vmc3-xy")
    };
    let mut service = Service::new(
        machine,
        vec![vmc_model("vmc3"), xy],
        vec![
            source,
            Box::new(PathSwitcher {
                at_s: 10.0,
                back_s: 20.0,
                out: 2,
            }),
        ],
        vec![],
        ServiceConfig {
            blend_s: 3.0,
            ..ServiceConfig::default()
        },
    );
    let mut t = 0.0;
    while t < 9.99 {
        t += 0.01;
        service.cycle(t);
    }
    assert!((service.output().offset_um[2] + 30.0).abs() < 1e-9);
    drain(&service);
    let mut z = Vec::new();
    while t < 19.99 {
        t += 0.01;
        service.cycle(t);
        z.push(service.output().offset_um[2]);
    }
    assert_eq!(service.path_states()[0], PathState::Model(1));
    // A linear blend of 30 µm over 3 s: 10 µm/s, a fifth of the envelope's 50 µm/s.
    let fastest = z
        .windows(2)
        .map(|w| (w[1] - w[0]).abs())
        .fold(0.0, f64::max)
        / 0.01;
    assert!((fastest - 10.0).abs() < 0.5, "{fastest} µm/s");
    assert!((z[100] + 20.0).abs() < 0.5, "{}", z[100]); // a third of the way after 1 s
    assert_eq!(*z.last().unwrap(), 0.0);
    let events = drain(&service);
    assert!(events.contains(&EventKind::AxisSwitch));
    assert!(events.contains(&EventKind::ModelSelected { path: 1, model: 1 }));
    assert!(
        !events
            .iter()
            .any(|e| matches!(e, EventKind::Clamped { .. })),
        "{events:?}"
    );
    while t < 30.0 {
        t += 0.01;
        service.cycle(t);
    }
    assert_eq!(service.path_states()[0], PathState::Model(0));
    assert!((service.output().offset_um[2] + 30.0).abs() < 1e-9);
}

/// A control source that takes an axis (Y unless told) out of path 1 between two times.
struct PathSwitcher {
    at_s: f64,
    back_s: f64,
    out: usize,
}

impl Source for PathSwitcher {
    fn name(&self) -> &str {
        "control"
    }
    fn read(&mut self, frame: &mut Frame) -> Result<(), LinkError> {
        let p = &mut frame.paths[0];
        p.clear();
        if frame.time_s >= self.at_s && frame.time_s < self.back_s {
            p.extend((0..3).filter(|&a| a != self.out));
        } else {
            p.extend_from_slice(&[0, 1, 2]);
        }
        Ok(())
    }
}

/// Switching compensation off and on blends; nothing jumps.
#[test]
fn enable_and_disable_are_bumpless() {
    let machine = vmc();
    let n_t = machine.machine.temperatures.len();
    let mut temps = vec![20.0; n_t];
    temps[1] = 25.0;
    let (source, _values) = scripted(temps, vec![800.0, 250.0, 250.0]);
    let mut service = Service::new(
        machine,
        vec![vmc_model("vmc3")],
        vec![source],
        vec![],
        ServiceConfig {
            blend_s: 2.0,
            ..ServiceConfig::default()
        },
    );
    let mut t = 0.0;
    let mut last = 0.0;
    let mut biggest = 0.0_f64;
    for i in 0..1500 {
        t += 0.01;
        if i == 500 {
            service.set_enabled(false);
        }
        if i == 1000 {
            service.set_enabled(true);
        }
        let z = service.cycle(t).offset_um[2];
        biggest = biggest.max((z - last).abs());
        last = z;
        if i == 499 {
            assert!((z + 30.0).abs() < 1e-9);
        }
        if i == 999 {
            assert_eq!(z, 0.0);
        }
    }
    assert!((last + 30.0).abs() < 1e-9);
    // 30 µm over 2 s at 10 ms steps: 0.15 µm per cycle, never more.
    assert!(biggest <= 0.15 + 1e-9, "{biggest}");
}

/// A cycle allocates nothing: sources, validation, selection, evaluation, envelope, queues.
#[test]
fn a_cycle_allocates_nothing() {
    let machine = vmc();
    let run = cycles::load(&repo("examples/vmc3/run.csv"), &machine.machine, &[]).unwrap();
    let source = ReplaySource::new("replay", run.run.clone());
    // A second model that carries a training envelope narrower than the run: the guard (inputs
    // clamped into the set's scratch, the output capped) runs every cycle and allocates nothing.
    let mut guarded = vmc_model("vmc3-guarded");
    guarded.model.as_static_mut().unwrap().set_envelope(Some(
        truepos_model::envelope::TrainingEnvelope {
            temperatures: vec![Some((20.0, 20.5)); machine.machine.temperatures.len()],
            operating: vec![None; machine.machine.operating.len()],
            max_abs_um: vec![Some(1.0); 3],
        },
    ));
    let mut service = Service::new(
        machine,
        vec![guarded, vmc_model("vmc3")],
        vec![
            Box::new(source),
            Box::new(PathSwitcher {
                at_s: 1.0,
                back_s: 2.0,
                out: 1,
            }),
        ],
        vec![],
        ServiceConfig::default(),
    );
    service.cycle(0.0);
    let events = service.events();
    let mut t = 0.0;
    // 60 ms cycles: 300 s of the run, so that the replay moves through its rows.
    let counted = allocation_counter::measure(|| {
        for _ in 0..5000 {
            t += 0.06;
            service.cycle(t);
        }
    });
    assert_eq!(counted.count_total, 0);
    assert!(events.pop().is_some(), "the axis switch raised events");
}

/// The log holds cycles and events with names, and passes SQLite's integrity check.
#[test]
fn the_log_keeps_cycles_and_named_events() {
    let dir = scratch("log");
    let db = dir.join("log.sqlite");
    let _ = std::fs::remove_file(&db);
    let machine = vmc();
    let n_t = machine.machine.temperatures.len();
    let (source, values) = scripted(vec![21.0; n_t], vec![100.0, 100.0, 100.0]);
    let mut service = Service::new(
        machine.clone(),
        vec![vmc_model("vmc3")],
        vec![source],
        vec![],
        ServiceConfig::default(),
    );
    let logger = Logger::start(
        LogSetup {
            path: &db,
            machine: &machine,
            models: vec!["vmc3".into()],
            sources: vec!["scripted".into()],
            sinks: vec![],
            paths: 1,
            commit_every: std::time::Duration::from_millis(20),
        },
        service.events(),
        service.records(),
    )
    .unwrap();
    let mut t = 0.0;
    for i in 0..300 {
        t += 0.01;
        if i == 150 {
            values.lock().unwrap().0[3] = f64::INFINITY;
        }
        service.cycle(t);
    }
    logger.stop().unwrap();
    assert_eq!(log::integrity_check(&db).unwrap(), "ok");
    let events = log::read_events(&db).unwrap();
    let fault = events
        .iter()
        .find(|e| e.kind == "sensor-fault")
        .expect("a sensor-fault event");
    assert_eq!(fault.subject, "y_slide_bottom");
    assert_eq!(fault.detail, "not a number");
    assert!(events
        .iter()
        .any(|e| e.kind == "model-selected" && e.detail == "vmc3"));
    let (names, rows) = log::read_cycles(&db, None).unwrap();
    assert!(names.contains(&"X_mm".to_string()));
    assert!(names.contains(&"ambient".to_string()));
    assert!(names.contains(&"Z_offset_um".to_string()));
    // 3 s at one record per 0.1 s.
    assert!((29..=31).contains(&rows.len()), "{}", rows.len());
    std::fs::remove_dir_all(&dir).ok();
}

/// A model that reads a lagged channel (the twin's `spindle_front` through a 30 min lag): the
/// service computes the lag itself, after validation, and a fault of the lag's sensor stops the
/// model like a fault of a sensor it reads directly.
#[test]
fn lagged_channels_are_computed_by_the_service_from_good_sensors_only() {
    let machine = machine_file::load(&repo("examples/twin/machine.toml")).unwrap();
    let m = &machine.machine;
    let front = m.temperature_index("spindle_front").unwrap();
    let lag = m.temperature_index("spindle_front_lag30min").unwrap();
    let model_text = r#"format = "truepos-model"
version = 1
name = "lagged-spindle"
machine = "twin-vmc3"
axis_index = [101, 102, 103]

[[inputs.axes]]
name = "Z"
travel = [0.0, 500.0]

[[inputs.differences]]
name = "dT_spindle_front_lag30min"
plus = "spindle_front_lag30min"
minus = "ambient"
plus_lag = "spindle_front, 1800 s"

[[part]]
name = "spindle"
form = "position-dependent"

[[part.term]]
axis = "Z"
difference = "dT_spindle_front_lag30min"
k0_um_per_k = 1000.0
"#;
    let model = position::parse(Path::new("lagged.toml"), model_text, m).unwrap();
    // The same model refuses a machine whose lag differs.
    let other = machine_file::parse(
        Path::new("m.toml"),
        &std::fs::read_to_string(repo("examples/twin/machine.toml"))
            .unwrap()
            .replacen("lag_s = 1800.0", "lag_s = 1700.0", 1),
    )
    .unwrap();
    let refused = position::parse(Path::new("lagged.toml"), model_text, &other.machine)
        .expect_err("another lag is another input")
        .to_string();
    assert!(refused.contains("spindle_front, 1700 s"), "{refused}");

    // Every measured sensor at 20 °C; the lagged channels are NaN in what the source delivers:
    // the service must compute them, never read them.
    let mut temps = vec![20.0; m.temperatures.len()];
    for (c, t) in m.temperatures.iter().enumerate() {
        if t.lag.is_some() {
            temps[c] = f64::NAN;
        }
    }
    let (source, values) = scripted(temps, vec![400.0, 250.0, 250.0]);
    let mut service = Service::new(
        machine,
        vec![ModelEntry {
            name: "lagged".into(),
            model: model.into(),
            index: [101, 102, 103],
        }],
        vec![source],
        vec![],
        ServiceConfig::default(),
    );
    for t in 0..=10 {
        let out = *service.cycle(t as f64);
        assert_eq!(out.offset_um[2], 0.0, "t = {t}");
    }
    // spindle_front steps 20 → 20.03 °C at t = 11 s (within the 2 K/min rate check; a larger
    // step would be held as a spike until plausible). The filter holds each input over the step
    // that ends with it, so at t = 1811 s the new value has acted for 1801 s: the lag reads
    // 20 + 0.03·(1 − e^(−1801/1800)) = 20.018969746 °C: error 1000 µm/K · 0.018969746 K =
    // +18.969746 µm, compensation −18.969746 µm.
    values.lock().unwrap().0[front] = 20.03;
    let mut out = *service.cycle(11.0);
    for t in 12..=1811 {
        out = *service.cycle(t as f64);
    }
    assert_eq!(out.state, CompensationState::Active);
    assert!(
        (out.offset_um[2] + 18.969_746).abs() < 1e-5,
        "{}",
        out.offset_um[2]
    );
    drain(&service);
    // The sensor fails: the lag is as bad as its sensor, the only model is left, the output
    // holds; one event names the sensor, none the computed channel.
    values.lock().unwrap().0[front] = f64::NAN;
    let out = *service.cycle(1812.0);
    assert_eq!(out.state, CompensationState::Holding);
    let events = drain(&service);
    assert!(events
        .iter()
        .any(|e| matches!(e, EventKind::SensorFault { channel, .. } if *channel == front)));
    assert!(!events
        .iter()
        .any(|e| matches!(e, EventKind::SensorFault { channel, .. } if *channel == lag)));
}

/// A fitted dynamic model file (`truepos fit`'s JSON) runs in the service like any model: its
/// filters advance every cycle, its output named `dz_um` compensates axis Z, a fault of its
/// sensor holds the output.
#[test]
fn a_dynamic_model_file_runs_in_the_service() {
    let machine = vmc();
    let front = machine
        .machine
        .temperature_index("spindle_front_bearing")
        .unwrap();
    // Features rise(T) and lp100(T); dz = 0.5 + 1·rise + 2·lp100 (µm).
    let json = r#"{
      "format": "truepos-dynamic-model", "version": 1, "machine": "vmc-3axis",
      "inputs": [{"name": "spindle_front_bearing", "kind": "temperature"}],
      "temperature_rise": true, "temperature_taus_s": [100.0], "rate_taus_s": [],
      "operating_taus_s": [], "operating_square": false,
      "features": ["rise(spindle_front_bearing)", "lp100(spindle_front_bearing)"],
      "outputs": [{"name": "dz_um", "intercept_um": 0.5, "coefficients": [1.0, 2.0]}],
      "provenance": {}, "validation": {}
    }"#;
    let dir = scratch("dyn");
    let path = dir.join("spindle.dynamic.json");
    std::fs::write(&path, json).unwrap();
    let entries = truepos_io::model_file::load_set(std::slice::from_ref(&path), &machine).unwrap();
    assert_eq!(entries[0].name, "spindle.dynamic");
    assert_eq!(entries[0].model.used_sensors(), &[front]);
    // Bound to the machine: another machine name is refused with the file named.
    let other = std::fs::read_to_string(&path)
        .unwrap()
        .replace("vmc-3axis", "lathe");
    std::fs::write(dir.join("other.json"), other).unwrap();
    let refused = truepos_io::model_file::load_set(&[dir.join("other.json")], &machine)
        .unwrap_err()
        .to_string();
    assert!(
        refused.contains("other.json:2:")
            && refused.contains("`machine`: expected `vmc-3axis`")
            && refused.contains("got `lathe`"),
        "{refused}"
    );

    let temps = vec![20.0; machine.machine.temperatures.len()];
    let (source, values) = scripted(temps, vec![400.0, 250.0, 250.0]);
    let mut service = Service::new(
        machine,
        entries,
        vec![source],
        vec![],
        ServiceConfig::default(),
    );
    let mut out = *service.cycle(0.0);
    for t in 1..=10 {
        out = *service.cycle(t as f64);
    }
    // First cycle: rise 0, lp 0 → error 0.5 µm, compensation −0.5 µm (start-up blend over).
    assert_eq!(out.state, CompensationState::Active);
    assert!(
        (out.offset_um[2] + 0.5).abs() < 1e-9,
        "{}",
        out.offset_um[2]
    );
    assert_eq!(out.offset_um[0], 0.0);
    // +0.03 K at t = 11 s; at t = 111 s it has acted for 101 s:
    // 0.5 + 0.03 + 2·0.03·(1 − e^(−101/100)) = 0.568146861 µm.
    values.lock().unwrap().0[front] = 20.03;
    for t in 11..=111 {
        out = *service.cycle(t as f64);
    }
    assert!(
        (out.offset_um[2] + 0.568_146_861).abs() < 1e-8,
        "{}",
        out.offset_um[2]
    );
    values.lock().unwrap().0[front] = f64::NAN;
    let out = *service.cycle(112.0);
    assert_eq!(out.state, CompensationState::Holding);
    std::fs::remove_dir_all(&dir).ok();
}
