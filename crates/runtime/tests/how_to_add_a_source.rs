//! The worked example of docs/how-to-add-a-source.md, kept compiling and passing: a new kind
//! of source in thirty lines, hosted by the service exactly as `truepos run` hosts the others.
//! If this test needs a change, the how-to needs the same change.

mod support;

use support::{repo, vmc};
use truepos_runtime::{CompensationState, Frame, LinkError, PathState, ServiceHost, Source};

/// A source of every temperature of the machine, all at `base_c` except one sensor warming at
/// `k_per_h`, and every axis standing at the middle of its travel: what a thermocouple module
/// and a control would deliver, computed instead of read.
struct Warming {
    name: String,
    base_c: f64,
    warming: usize,
    k_per_h: f64,
    middle: Vec<f64>,
}

impl Source for Warming {
    fn name(&self) -> &str {
        &self.name
    }

    // Called every cycle: no blocking, no allocation, no I/O. A source fed by a device runs
    // its own thread and copies the latest values here (see `sources::polled`).
    fn read(&mut self, frame: &mut Frame) -> Result<(), LinkError> {
        let warm = self.base_c + self.k_per_h * frame.time_s / 3600.0;
        for channel in 0..frame.temperatures_c.len() {
            let t = if channel == self.warming {
                warm
            } else {
                self.base_c
            };
            frame.set_temperature(channel, t);
        }
        for (axis, &p) in self.middle.iter().enumerate() {
            frame.set_position(axis, p);
        }
        Ok(())
    }
}

#[test]
fn a_new_source_feeds_the_service() {
    let machine = vmc();
    let models =
        truepos_io::model_file::load_set(&[repo("examples/vmc3/model.toml")], &machine).unwrap();
    let m = &machine.machine;
    let source = Warming {
        name: "warming spindle".into(),
        base_c: 20.0,
        warming: m
            .temperatures
            .iter()
            .position(|t| t.id == "spindle_front_bearing")
            .unwrap(),
        k_per_h: 2.0,
        middle: m
            .axes
            .iter()
            .map(|a| 0.5 * (a.travel_min + a.travel_max))
            .collect(),
    };
    let mut running = ServiceHost::new(machine, models)
        .source(Box::new(source))
        .start()
        .unwrap();
    // One hour at 10 Hz of service time.
    for k in 0..36_000 {
        running.service.cycle(f64::from(k) * 0.1);
    }
    let out = *running.service.output();
    assert_eq!(out.state, CompensationState::Active);
    assert_eq!(running.service.path_states(), &[PathState::Model(0)]);
    // The example model's spindle growth: 3.1 µm/K on Z for the front bearing against ambient,
    // so about 2 K after an hour asks about −6 µm of Z (the compensation is −error).
    assert!((-6.6..=-5.6).contains(&out.offset_um[2]), "{out:?}");
    running.stop();
}
