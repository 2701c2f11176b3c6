//! Whole-twin tests: the machine description matches the twin, runs are deterministic and their
//! CSV follows docs/formats.md, energy is conserved, sensors lag, probes measure the truth.

use std::path::Path;

use truepos_sim::network::Network;
use truepos_sim::{Operating, Scenario, Twin, AXES, BUILTIN};

fn workspace() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .and_then(Path::parent)
        .expect("crates/sim")
}

fn short(name: &str, minutes: f64) -> Scenario {
    let mut s = Scenario::builtin(name).expect("built-in");
    let mut left = minutes * 60.0;
    s.phases.retain_mut(|p| {
        let keep = left > 0.0;
        p.duration_s = p.duration_s.min(left);
        left -= p.duration_s;
        keep
    });
    s
}

#[test]
fn machine_description_matches_the_twin() {
    let path = workspace().join("examples/twin/machine.toml");
    let file = truepos_io::machine_file::load(&path).expect("examples/twin/machine.toml is valid");
    let m = &file.machine;
    let twin = Twin::reference();
    assert_eq!(m.name, twin.name);
    let names: Vec<&str> = m.axes.iter().map(|a| a.name.as_str()).collect();
    assert_eq!(names, AXES);
    for (a, t) in m.axes.iter().zip(twin.travel_mm) {
        assert_eq!([a.travel_min, a.travel_max], t);
    }
    assert_eq!(m.axes[0].carried_by, Some(1), "X rests on Y");
    // Every measured channel is a twin sensor, in order; lagged channels are computed from them.
    let ids: Vec<&str> = m
        .temperatures
        .iter()
        .filter(|t| t.lag.is_none())
        .map(|t| t.id.as_str())
        .collect();
    let twin_ids: Vec<&str> = twin.sensors.iter().map(|s| s.id.as_str()).collect();
    assert_eq!(ids, twin_ids);
    for t in m.temperatures.iter().filter(|t| t.lag.is_some()) {
        let Some(truepos_model::LagSource::Temperature(s)) = t.lag.map(|l| l.source) else {
            panic!("{}: the twin's lagged channels follow its sensors", t.id);
        };
        assert!(twin_ids.contains(&m.temperatures[s].id.as_str()));
    }
    // Operating channels are CSV columns of a run.
    let run = twin.run(&short("mixed-shift", 3.0), 1).unwrap();
    let header = run.header(false);
    for o in &m.operating {
        assert!(header.contains(&o.id), "{} is not a CSV column", o.id);
    }
}

#[test]
fn example_scenarios_are_the_builtins() {
    for name in BUILTIN {
        let path = workspace().join(format!("examples/twin/scenarios/{name}.toml"));
        let text = std::fs::read_to_string(&path).unwrap();
        assert_eq!(
            text,
            Scenario::builtin_toml(name).unwrap(),
            "{} differs from the built-in",
            path.display()
        );
    }
}

#[test]
fn runs_are_deterministic_per_seed() {
    let twin = Twin::reference();
    let sc = short("mixed-shift", 40.0);
    let a = twin.run(&sc, 7).unwrap();
    let b = twin.run(&sc, 7).unwrap();
    let c = twin.run(&sc, 8).unwrap();
    assert_eq!(a.rows, b.rows);
    assert_ne!(a.rows, c.rows);
    // Rows sampled every 10 s over 40 min, plus probe touches (none before 30 min + one
    // cycle of 18 points at 30 min).
    assert!(a.rows.len() >= 241, "{}", a.rows.len());
}

#[test]
fn csv_follows_the_run_format() {
    let twin = Twin::reference();
    let run = twin.run(&short("mixed-shift", 65.0), 3).unwrap();
    let mut buf = Vec::new();
    run.write_csv(&mut buf, true).unwrap();
    let mut rdr = csv::Reader::from_reader(buf.as_slice());
    let header: Vec<String> = rdr.headers().unwrap().iter().map(String::from).collect();
    assert_eq!(&header[..4], ["time_s", "X_mm", "Y_mm", "Z_mm"]);
    for col in [
        "spindle_rpm",
        "X_speed_mm_min",
        "coolant_on",
        "dx_um",
        "dy_um",
        "dz_um",
        "probe_dz_um",
        "ambient",
    ] {
        assert!(header.iter().any(|h| h == col), "{col} missing");
    }
    assert_eq!(
        header.iter().filter(|h| h.starts_with("node:")).count(),
        twin.node_count()
    );
    let mut last = -1.0;
    let mut probes = 0;
    for rec in rdr.records() {
        let rec = rec.unwrap();
        let t: f64 = rec[0].parse().unwrap();
        assert!(t > last, "time must increase strictly: {t} after {last}");
        last = t;
        for (h, v) in header.iter().zip(rec.iter()) {
            if h.starts_with("probe_") && v.is_empty() {
                continue;
            }
            let x: f64 = v
                .parse()
                .unwrap_or_else(|_| panic!("{h} = {v:?} at t = {t}"));
            assert!(x.is_finite(), "{h} = {v} at t = {t}");
        }
        if !rec[header.iter().position(|h| h == "probe_dz_um").unwrap()].is_empty() {
            probes += 1;
        }
    }
    assert_eq!(probes, 2 * 18, "two probing cycles of 3 × 3 × 2 points");
    assert!((last - 65.0 * 60.0).abs() < 1e-9);
}

#[test]
fn probes_measure_the_true_error_within_their_noise() {
    let twin = Twin::reference();
    let run = twin.run(&short("mixed-shift", 95.0), 5).unwrap();
    let mut n = 0;
    for r in &run.rows {
        if let Some(p) = r.probe {
            n += 1;
            assert_eq!(
                p.position_mm, r.position_mm,
                "the axes stand at the probed point"
            );
            for k in 0..3 {
                assert!((p.measured_um[k] - r.error_um[k]).abs() < 5.0 * 0.5);
            }
        }
    }
    assert_eq!(n, 3 * 18);
    // The probe's positions span the travel: X 0…800, Y 0…500, Z 50…450.
    let xs = run.column("probe_x_mm").unwrap();
    let max = xs
        .iter()
        .copied()
        .filter(|v| v.is_finite())
        .fold(f64::MIN, f64::max);
    assert_eq!(max, 800.0);
}

/// The reference network with convection switched off keeps every joule the heat sources put
/// in: Σ C_i·ΔT_i = Σ P·t over an hour of spindle and axis heat.
#[test]
fn energy_is_conserved_on_the_reference_network_without_convection() {
    let twin = Twin::reference();
    let mut net: Network = twin.network.clone();
    net.ambient_w_per_k.iter_mut().for_each(|g| *g = 0.0);
    let mut st = net.discretise(1.0);
    let mut temps = vec![20.0; net.len()];
    let op = Operating {
        spindle_rpm: 9000.0,
        position_mm: [100.0, 400.0, 300.0],
        speed_mm_min: [5000.0, 3000.0, 1000.0],
        coolant_on: false,
        servo_on: true,
    };
    let mut powers = Vec::new();
    twin.heat(&op, &mut powers);
    let p_total: f64 = powers.iter().map(|p| p.1).sum();
    assert!(p_total > 300.0, "{p_total} W");
    for _ in 0..3600 {
        st.step(&mut temps, &powers, 20.0);
    }
    let stored: f64 = temps
        .iter()
        .zip(&net.capacity_j_per_k)
        .map(|(t, c)| (t - 20.0) * c)
        .sum();
    let added = p_total * 3600.0;
    assert!(
        (stored - added).abs() < 1e-9 * added,
        "{stored} J vs {added} J"
    );
}

/// Document C's early-minutes problem: the spindle heats at once, the sensor in its bore (τ = 90 s)
/// shows the housing's rise late.
#[test]
fn sensors_lag_the_metal_in_the_first_minutes() {
    let twin = Twin::reference();
    let mut sc = short("spindle-warmup", 10.0);
    sc.sensor_noise_c = 0.0;
    sc.sensor_resolution_c = 0.0;
    let run = twin.run(&sc, 1).unwrap();
    let i = twin
        .sensors
        .iter()
        .position(|s| s.id == "spindle_front")
        .unwrap();
    let row = run.rows.iter().position(|r| r.time_s == 120.0).unwrap();
    let reading = run.rows[row].temperatures_c[i];
    let metal = run.state(row)[twin.spindle.front];
    assert!(
        metal - 20.0 > 1.2 * (reading - 20.0),
        "metal {metal}, sensor {reading}"
    );
    assert!(reading > 20.0);
}

#[test]
fn faults_show_in_the_readings() {
    let twin = Twin::reference();
    let src = format!(
        "{}\n[[fault]]\nsensor = \"x_table_bottom\"\nkind = \"open-circuit\"\nstart_min = 10\nend_min = 20\n",
        Scenario::builtin_toml("spindle-warmup").unwrap()
    );
    let mut sc = Scenario::parse(&src, "f.toml", Some(twin.travel_mm)).unwrap();
    sc.phases.truncate(1);
    sc.phases[0].duration_s = 1800.0;
    let run = twin.run(&sc, 1).unwrap();
    let col = run.column("x_table_bottom").unwrap();
    let t = run.column("time_s").unwrap();
    for (v, t) in col.iter().zip(&t) {
        if (600.0..1200.0).contains(t) {
            assert_eq!(*v, 850.0);
        } else {
            assert!(*v < 30.0);
        }
    }
    let bad = format!("{src}[[fault]]\nsensor = \"nowhere\"\nkind = \"stuck\"\nstart_min = 1\n");
    let sc = Scenario::parse(&bad, "f.toml", None).unwrap();
    let e = twin.run(&sc, 1).unwrap_err().to_string();
    assert!(
        e.contains("fault[1].sensor") && e.contains("nowhere"),
        "{e}"
    );
}

/// The ground truth can be evaluated anywhere at any recorded instant: at the end of a 4 h
/// spindle run the error at the parked position is the recorded one.
#[test]
fn error_anywhere_at_a_recorded_instant() {
    let twin = Twin::reference();
    let mut sc = Scenario::builtin("spindle-warmup").unwrap();
    sc.phases.truncate(1);
    let run = twin.run(&sc, 1).unwrap();
    let last = run.rows.len() - 1;
    let here = twin.error_um(run.state(last), run.rows[last].position_mm);
    assert_eq!(here, run.rows[last].error_um);
    assert!(here[2] < -20.0, "{here:?}");
    let d = twin.deformation(run.state(last));
    let corners: Vec<[f64; 3]> = [0.0, 800.0]
        .iter()
        .flat_map(|&x| {
            [0.0, 500.0]
                .iter()
                .flat_map(move |&y| [0.0, 500.0].map(|z| [x, y, z]))
        })
        .collect();
    let worst = corners
        .iter()
        .map(|p| d.error_um(*p)[2].abs())
        .fold(0.0, f64::max);
    assert!(worst > 20.0 && worst < 200.0, "{worst}");
}

/// `truepos eval` reads a twin run with the twin's machine description: every sensor, axis and
/// operating column is found and numeric.
#[test]
fn a_twin_run_reads_as_cycles_of_the_example_machine() {
    let path = workspace().join("examples/twin/machine.toml");
    let file = truepos_io::machine_file::load(&path).unwrap();
    let twin = Twin::reference();
    let run = twin.run(&short("mixed-shift", 35.0), 2).unwrap();
    let mut buf = Vec::new();
    run.write_csv(&mut buf, false).unwrap();
    let all: Vec<usize> = (0..file.machine.temperatures.len()).collect();
    let cycles =
        truepos_io::cycles::read(Path::new("twin.csv"), buf.as_slice(), &file.machine, &all)
            .unwrap();
    assert_eq!(cycles.run.positions.len(), run.rows.len());
    assert_eq!(cycles.run.positions[5], run.rows[5].position_mm.to_vec());
    assert!(cycles
        .run
        .operating
        .iter()
        .all(|o| o.iter().all(|v| v.is_finite())));
}

/// `examples/twin/twin.toml` spells out the built-in values; the chilled variant differs where
/// it says and warms the spindle far less.
#[test]
fn twin_descriptions() {
    use truepos_sim::TwinParams;
    let read = |name: &str| {
        let path = workspace().join("examples/twin").join(name);
        let text = std::fs::read_to_string(&path).unwrap();
        TwinParams::parse(&text, &path.display().to_string()).unwrap()
    };
    let reference = read("twin.toml");
    // twin.toml also lists every sensor lag (the built-in values).
    let defaults = TwinParams {
        sensor_tau_s: reference.sensor_tau_s.clone(),
        ..TwinParams::default()
    };
    assert_eq!(reference, defaults);
    let built_in = Twin::reference();
    for s in &built_in.sensors {
        assert_eq!(reference.sensor_tau_s[&s.id], s.tau_s, "{}", s.id);
    }
    let chilled = Twin::from_params(&read("twin-chilled.toml"));
    assert_eq!(chilled.name, "twin-vmc3-chilled");
    let sc = short("spindle-warmup", 120.0);
    let hot = built_in.run(&sc, 1).unwrap().summary().peak_error[2].0;
    let cool = chilled.run(&sc, 1).unwrap().summary().peak_error[2].0;
    assert!(
        cool.abs() < 0.5 * hot.abs(),
        "chilled {cool} µm vs {hot} µm"
    );
}

/// An open-circuit reading that is not a number is refused at its key (it reached the readings
/// as NaN before).
#[test]
fn an_open_circuit_reading_must_be_a_number() {
    let twin = Twin::reference();
    let src = format!(
        "{}\n[[fault]]\nsensor = \"x_table_bottom\"\nkind = \"open-circuit\"\nstart_min = 10\nrail_c = nan\n",
        Scenario::builtin_toml("spindle-warmup").unwrap()
    );
    let e = Scenario::parse(&src, "f.toml", Some(twin.travel_mm))
        .unwrap_err()
        .to_string();
    assert!(e.contains("rail_c") && e.contains("got NaN"), "{e}");
}
