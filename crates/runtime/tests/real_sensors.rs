//! The sensor validation's defaults on real sensors: FL_THERMAL's sixteen temperatures (a real
//! measured 46 h run, read in place from `../shared/data/fl_thermal`) replayed at 10 Hz and
//! quantised to 0.1 K, as a polled 0.1 K module delivers them, raise no fault.

use std::path::Path;

use truepos_model::{Axis, AxisKind, Carriage, Machine, TemperatureChannel};
use truepos_runtime::config::{
    SensorChecks, DEFAULT_MAX_AGE_S, DEFAULT_MAX_RATE_K_PER_MIN, DEFAULT_NOISE_K,
    DEFAULT_RECOVER_AFTER_S, DEFAULT_STUCK_AFTER_S,
};
use truepos_runtime::events::EventQueue;
use truepos_runtime::sensor_validation::SensorValidator;
use truepos_runtime::Frame;

fn fl_thermal() -> (Vec<f64>, Vec<Vec<f64>>) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../../shared/data/fl_thermal/fl_thermal.csv");
    let mut reader = csv::Reader::from_path(&path).unwrap_or_else(|e| {
        panic!(
            "{}: {e} (the shared data must sit beside the repository)",
            path.display()
        )
    });
    let headers = reader.headers().unwrap().clone();
    let time = headers.iter().position(|h| h == "time_s").unwrap();
    let temps: Vec<usize> = (1..=16)
        .map(|i| headers.iter().position(|h| h == format!("t{i}_c")).unwrap())
        .collect();
    let (mut t, mut rows) = (Vec::new(), Vec::new());
    for record in reader.records() {
        let r = record.unwrap();
        t.push(r[time].parse().unwrap());
        rows.push(temps.iter().map(|&c| r[c].parse().unwrap()).collect());
    }
    (t, rows)
}

fn machine(n: usize) -> Machine {
    Machine {
        name: "fl-thermal".into(),
        axes: vec![Axis {
            name: "Z".into(),
            kind: AxisKind::Linear,
            travel_min: 0.0,
            travel_max: 1.0,
            carried_by: None,
            carriage: Carriage::Cantilever,
        }],
        temperatures: (0..n)
            .map(|i| TemperatureChannel {
                id: format!("t{}_c", i + 1),
                location: String::new(),
                valid_min_c: 5.0,
                valid_max_c: 60.0,
                lag: None,
            })
            .collect(),
        differences: vec![],
        operating: vec![],
    }
}

#[test]
fn fl_thermal_quantised_and_polled_at_10_hz_raises_no_fault() {
    let (time, rows) = fl_thermal();
    let n = rows[0].len();
    let checks = SensorChecks {
        max_rate_k_per_s: DEFAULT_MAX_RATE_K_PER_MIN / 60.0,
        max_age_s: DEFAULT_MAX_AGE_S,
        stuck_after_s: DEFAULT_STUCK_AFTER_S,
        noise_k: DEFAULT_NOISE_K,
        recover_after_s: DEFAULT_RECOVER_AFTER_S,
    };
    let mut v = SensorValidator::new(&machine(n), &vec![checks; n]);
    let events = EventQueue::new(1 << 16);
    let mut frame = Frame::new(n, 1, 0);
    let (mut row, mut cycles) = (0, 0u64);
    let end = *time.last().unwrap();
    let mut now = time[0];
    while now <= end {
        while row + 1 < time.len() && time[row + 1] <= now {
            row += 1;
        }
        frame.time_s = now;
        for (c, &value) in rows[row].iter().enumerate() {
            frame.set_temperature(c, (value * 10.0).round() / 10.0);
        }
        v.check(&frame, &events);
        cycles += 1;
        now = time[0] + cycles as f64 * 0.1;
    }
    let raised: Vec<_> = std::iter::from_fn(|| events.pop()).take(10).collect();
    assert!(raised.is_empty(), "{raised:?}");
    assert!(cycles > 1_600_000, "{cycles}");
}
