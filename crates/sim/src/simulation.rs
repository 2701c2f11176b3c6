//! Running a scenario on the twin: the time loop, the recorded run and its CSV.

use std::fmt;
use std::io::Write;

use crate::network::Stepper;
use crate::scenario::{check_fault_sensors, Pattern, Phase, Probing, Scenario, MAX_SAMPLES};
use crate::sensor::{normal, Draws, Noise, SensorState};
use crate::twin::{Operating, Spot, Twin, AXES};

/// A run that could not start (the scenario does not fit the twin).
#[derive(Debug, Clone, PartialEq)]
pub struct SimError(pub String);

impl fmt::Display for SimError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for SimError {}

/// A probe measurement.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ProbeReading {
    /// Where the probe touched (axis positions, mm).
    pub position_mm: [f64; 3],
    /// Measured tool-tip error (true error + probe noise), µm.
    pub measured_um: [f64; 3],
    /// Number of the probing cycle (0, 1, …) it belongs to.
    pub cycle: usize,
}

/// One recorded sample.
#[derive(Debug, Clone, PartialEq)]
pub struct Row {
    /// Time since the start, s.
    pub time_s: f64,
    /// Axis positions X, Y, Z, mm.
    pub position_mm: [f64; 3],
    /// Index of the scenario phase.
    pub phase: usize,
    /// Spindle speed, 1/min.
    pub spindle_rpm: f64,
    /// Axis speeds (magnitude), mm/min.
    pub speed_mm_min: [f64; 3],
    /// Coolant flowing.
    pub coolant_on: bool,
    /// Sensor readings, °C, in the order of [`SimRun::sensor_ids`].
    pub temperatures_c: Vec<f64>,
    /// Ground-truth tool-tip error at the current position, µm (actual − nominal).
    pub error_um: [f64; 3],
    /// The true ambient temperature, °C.
    pub ambient_true_c: f64,
    /// Probe measurement taken at this instant, if any.
    pub probe: Option<ProbeReading>,
}

/// A simulated run, in memory.
#[derive(Debug, Clone)]
pub struct SimRun {
    /// Machine name.
    pub machine: String,
    /// Scenario name.
    pub scenario: String,
    /// Seed of the random draws.
    pub seed: u64,
    /// Sensor ids (CSV columns), in order.
    pub sensor_ids: Vec<String>,
    /// Thermal node names, in order.
    pub node_names: Vec<String>,
    /// Recorded rows.
    pub rows: Vec<Row>,
    /// True node temperatures at each row (`rows.len() × node_names.len()`, row-major).
    pub states: Vec<f64>,
}

/// Peak figures of a run.
#[derive(Debug, Clone, PartialEq)]
pub struct Summary {
    /// Duration, s.
    pub duration_s: f64,
    /// Rows recorded.
    pub rows: usize,
    /// Probe measurements.
    pub probe_points: usize,
    /// Thermal nodes.
    pub nodes: usize,
    /// Per direction (dx, dy, dz): the error of largest magnitude (µm), its time (s) and the
    /// axis positions (mm) where it occurred.
    pub peak_error: [(f64, f64, [f64; 3]); 3],
    /// Per sensor: id and highest reading (°C).
    pub peak_sensor_c: Vec<(String, f64)>,
    /// Hottest node: name and temperature (°C).
    pub peak_node: (String, f64),
    /// Per direction: the time (s) at which the error first reached 63.2 % of its peak change
    /// from the start (the time constant of a first-order response).
    pub t63_s: [f64; 3],
    /// Per direction: the probing cycle with the largest spread of the true error over its
    /// points, as `(time_s, (min_um, position), (max_um, position))`; `None` without probing.
    pub probe_spread: [Option<Spread>; 3],
}

/// The spread of the error over one probing cycle: when, and the smallest and largest value with
/// the axis positions where they occurred.
pub type Spread = (f64, (f64, [f64; 3]), (f64, [f64; 3]));

impl SimRun {
    /// Appends a row and the network's temperatures at its instant.
    fn push(&mut self, row: Row, temps: &[f64]) {
        self.rows.push(row);
        self.states.extend_from_slice(temps);
    }

    /// True node temperatures at row `i`.
    pub fn state(&self, i: usize) -> &[f64] {
        let n = self.node_names.len();
        &self.states[i * n..(i + 1) * n]
    }

    /// A column by its CSV name (`time_s`, `X_mm`, a sensor id, `dx_um`, …); probe columns are
    /// NaN where no probe point was taken.
    pub fn column(&self, name: &str) -> Option<Vec<f64>> {
        let f: Box<dyn Fn(&Row) -> f64> = match name {
            "time_s" => Box::new(|r| r.time_s),
            "phase" => Box::new(|r| r.phase as f64),
            "spindle_rpm" => Box::new(|r| r.spindle_rpm),
            "coolant_on" => Box::new(|r| f64::from(u8::from(r.coolant_on))),
            "ambient_true_c" => Box::new(|r| r.ambient_true_c),
            "dx_um" | "dy_um" | "dz_um" => {
                let k = usize::from(name == "dy_um") + 2 * usize::from(name == "dz_um");
                Box::new(move |r| r.error_um[k])
            }
            _ => {
                if let Some(i) = self.sensor_ids.iter().position(|s| s == name) {
                    Box::new(move |r| r.temperatures_c[i])
                } else if let Some(a) = AXES.iter().position(|a| name == format!("{a}_mm")) {
                    Box::new(move |r| r.position_mm[a])
                } else if let Some(a) = AXES
                    .iter()
                    .position(|a| name == format!("{a}_speed_mm_min"))
                {
                    Box::new(move |r| r.speed_mm_min[a])
                } else if let Some(a) = ["probe_x_mm", "probe_y_mm", "probe_z_mm"]
                    .iter()
                    .position(|c| *c == name)
                {
                    Box::new(move |r| r.probe.map_or(f64::NAN, |p| p.position_mm[a]))
                } else if let Some(a) = ["probe_dx_um", "probe_dy_um", "probe_dz_um"]
                    .iter()
                    .position(|c| *c == name)
                {
                    Box::new(move |r| r.probe.map_or(f64::NAN, |p| p.measured_um[a]))
                } else {
                    return None;
                }
            }
        };
        Some(self.rows.iter().map(f).collect())
    }

    /// The CSV header (see `docs/twin.md`).
    pub fn header(&self, with_nodes: bool) -> Vec<String> {
        let mut h: Vec<String> = vec!["time_s".into()];
        h.extend(AXES.iter().map(|a| format!("{a}_mm")));
        h.push("phase".into());
        h.push("spindle_rpm".into());
        h.extend(AXES.iter().map(|a| format!("{a}_speed_mm_min")));
        h.push("coolant_on".into());
        h.extend(self.sensor_ids.iter().cloned());
        h.extend(["dx_um", "dy_um", "dz_um"].map(String::from));
        h.extend(
            [
                "probe_x_mm",
                "probe_y_mm",
                "probe_z_mm",
                "probe_dx_um",
                "probe_dy_um",
                "probe_dz_um",
            ]
            .map(String::from),
        );
        if with_nodes {
            h.push("ambient_true_c".into());
            h.extend(self.node_names.iter().map(|n| format!("node:{n}")));
        }
        h
    }

    /// Writes the run as CSV; `with_nodes` adds the true ambient and every node temperature.
    pub fn write_csv<W: Write>(&self, w: W, with_nodes: bool) -> Result<(), csv::Error> {
        let mut out = csv::Writer::from_writer(w);
        out.write_record(self.header(with_nodes))?;
        // `+ 0.0` turns −0 into 0 so that no "-0.000" is written.
        let f = |v: f64, d: usize| format!("{:.d$}", v + 0.0);
        for (i, r) in self.rows.iter().enumerate() {
            let mut rec: Vec<String> = Vec::with_capacity(40);
            rec.push(f(r.time_s, 1));
            rec.extend(r.position_mm.iter().map(|v| f(*v, 3)));
            rec.push(r.phase.to_string());
            rec.push(f(r.spindle_rpm, 0));
            rec.extend(r.speed_mm_min.iter().map(|v| f(*v, 0)));
            rec.push(u8::from(r.coolant_on).to_string());
            rec.extend(r.temperatures_c.iter().map(|v| f(*v, 3)));
            rec.extend(r.error_um.iter().map(|v| f(*v, 3)));
            match r.probe {
                Some(p) => {
                    rec.extend(p.position_mm.iter().map(|v| f(*v, 3)));
                    rec.extend(p.measured_um.iter().map(|v| f(*v, 3)));
                }
                None => rec.extend(std::iter::repeat_n(String::new(), 6)),
            }
            if with_nodes {
                rec.push(f(r.ambient_true_c, 4));
                rec.extend(self.state(i).iter().map(|v| f(*v, 4)));
            }
            out.write_record(&rec)?;
        }
        out.flush()?;
        Ok(())
    }

    /// Peak figures.
    pub fn summary(&self) -> Summary {
        let mut peak_error = [(0.0f64, 0.0f64, [0.0f64; 3]); 3];
        for r in &self.rows {
            for (k, p) in peak_error.iter_mut().enumerate() {
                if r.error_um[k].abs() > p.0.abs() {
                    *p = (r.error_um[k], r.time_s, r.position_mm);
                }
            }
        }
        let peak_sensor_c = self
            .sensor_ids
            .iter()
            .enumerate()
            .map(|(i, id)| {
                let m = self
                    .rows
                    .iter()
                    .map(|r| r.temperatures_c[i])
                    .fold(f64::NEG_INFINITY, f64::max);
                (id.clone(), m)
            })
            .collect();
        let n = self.node_names.len();
        let (imax, tmax) =
            self.states
                .iter()
                .enumerate()
                .fold(
                    (0, f64::NEG_INFINITY),
                    |acc, (i, &t)| if t > acc.1 { (i, t) } else { acc },
                );
        let mut t63_s = [0.0; 3];
        if let Some(first) = self.rows.first() {
            for k in 0..3 {
                let e0 = first.error_um[k];
                let target = 0.632_120_558_8 * (peak_error[k].0 - e0);
                t63_s[k] = self
                    .rows
                    .iter()
                    .find(|r| target != 0.0 && (r.error_um[k] - e0) / target >= 1.0)
                    .map_or(0.0, |r| r.time_s);
            }
        }
        let mut probe_spread: [Option<Spread>; 3] = [None; 3];
        let mut cycles: Vec<Vec<&Row>> = Vec::new();
        for r in self.rows.iter().filter(|r| r.probe.is_some()) {
            let c = r.probe.map_or(0, |p| p.cycle);
            if cycles.len() <= c {
                cycles.resize(c + 1, Vec::new());
            }
            cycles[c].push(r);
        }
        for rows in cycles.iter().filter(|c| c.len() > 1) {
            for (k, best) in probe_spread.iter_mut().enumerate() {
                let val = |r: &&Row| r.error_um[k];
                let pos = |r: &&Row| r.probe.map_or([0.0; 3], |p| p.position_mm);
                let lo = rows
                    .iter()
                    .min_by(|a, b| val(a).total_cmp(&val(b)))
                    .expect("non-empty");
                let hi = rows
                    .iter()
                    .max_by(|a, b| val(a).total_cmp(&val(b)))
                    .expect("non-empty");
                let spread = val(hi) - val(lo);
                if best.is_none_or(|b| b.2 .0 - b.1 .0 < spread) {
                    *best = Some((
                        hi.time_s.max(lo.time_s),
                        (val(lo), pos(lo)),
                        (val(hi), pos(hi)),
                    ));
                }
            }
        }
        Summary {
            t63_s,
            probe_spread,
            duration_s: self.rows.last().map_or(0.0, |r| r.time_s),
            rows: self.rows.len(),
            probe_points: self.rows.iter().filter(|r| r.probe.is_some()).count(),
            nodes: n,
            peak_error,
            peak_sensor_c,
            peak_node: (
                self.node_names
                    .get(imax % n.max(1))
                    .cloned()
                    .unwrap_or_default(),
                tmax,
            ),
        }
    }
}

/// Motion state of one axis.
#[derive(Debug, Clone, Copy)]
struct AxisState {
    pos: f64,
    dir: f64,
    target: Option<f64>,
    dwell_left: f64,
}

impl AxisState {
    /// Moves towards `target` by at most `max_mm`; returns whether it arrived.
    fn approach(&mut self, target: f64, max_mm: f64) -> bool {
        let d = target - self.pos;
        if d.abs() <= max_mm {
            self.pos = target;
            true
        } else {
            self.pos += max_mm * d.signum();
            false
        }
    }
}

enum ProbeState {
    Idle { next_s: f64 },
    Active { point: usize, dwell_left: f64 },
}

/// The sensors of a run: their states, the faults scheduled for each, the noise they read with.
struct Sensing<'a> {
    states: Vec<SensorState>,
    faults: Vec<Vec<&'a crate::scenario::Fault>>,
    noise: Noise,
}

impl Sensing<'_> {
    /// Every sensor's reading at `t`, drawing its noise from `rng` in sensor order.
    fn read_all(&mut self, rng: &mut fastrand::Rng, t: f64) -> Vec<f64> {
        self.states
            .iter_mut()
            .zip(&self.faults)
            .map(|(s, f)| {
                let d = Draws {
                    normal: normal(rng),
                    uniform: rng.f64(),
                    sign: if rng.bool() { 1.0 } else { -1.0 },
                };
                s.read(t, &self.noise, d, f)
            })
            .collect()
    }
}

/// Where the probing cycles stand: the state and the cycle counters the readings carry.
struct ProbeClock {
    state: ProbeState,
    cycle: usize,
    cycle_of_touch: usize,
}

impl ProbeClock {
    /// At the start of a step at `t`: whether a probing cycle runs now, and the position
    /// touched if the probe measures in place at this instant.
    fn begin(
        &mut self,
        probing: Option<&Probing>,
        phase_probes: bool,
        t: f64,
        position: [f64; 3],
    ) -> (bool, Option<[f64; 3]>) {
        match (&mut self.state, probing) {
            (ProbeState::Idle { next_s }, Some(p)) if t >= *next_s - 1e-9 => {
                if !phase_probes {
                    while *next_s <= t + 1e-9 {
                        *next_s += p.every_s;
                    }
                    return (false, None);
                }
                self.cycle_of_touch = self.cycle;
                self.cycle += 1;
                if p.in_place {
                    *next_s += p.every_s;
                    (false, Some(position))
                } else {
                    self.state = ProbeState::Active {
                        point: 0,
                        dwell_left: p.dwell_s,
                    };
                    (true, None)
                }
            }
            (ProbeState::Active { .. }, Some(_)) => (true, None),
            _ => (false, None),
        }
    }
}

/// The temperature a sensor's spot has: the mean of its nodes, the air or the coolant.
fn spot(s: &Spot, temps: &[f64], amb: f64, cool: f64) -> f64 {
    match s {
        Spot::Nodes(v) => v.iter().map(|&i| temps[i]).sum::<f64>() / v.len() as f64,
        Spot::Ambient => amb,
        Spot::Coolant => cool,
    }
}

impl Twin {
    /// Runs `scenario` with random draws from `seed` (the same seed gives the same run).
    pub fn run(&self, scenario: &Scenario, seed: u64) -> Result<SimRun, SimError> {
        self.run_with_progress(scenario, seed, &mut |_| {})
    }

    /// Like [`Twin::run`], calling `progress` with the fraction done (0…1) every simulated
    /// minute.
    pub fn run_with_progress(
        &self,
        sc: &Scenario,
        seed: u64,
        progress: &mut dyn FnMut(f64),
    ) -> Result<SimRun, SimError> {
        sc.check_size().map_err(SimError)?;
        let ids: Vec<String> = self.sensors.iter().map(|s| s.id.clone()).collect();
        check_fault_sensors(sc, &ids).map_err(SimError)?;
        self.check_fits(sc)?;
        let mut rng = fastrand::Rng::with_seed(seed);
        let h = sc.step_s;
        let mut stepper = self.stepper(h);
        let n = self.node_count();
        let amb0 = sc.ambient.at(0.0, sc.start_hour);
        let mut temps = vec![sc.initial_c.unwrap_or(amb0); n];
        let mut coolant_c = amb0;
        let mut sensors = self.sensing(sc, h, &temps, amb0, coolant_c);
        let centre = |a: usize| (self.travel_mm[a][0] + self.travel_mm[a][1]) / 2.0;
        let mut axes = [0, 1, 2].map(|a| AxisState {
            pos: centre(a),
            dir: 1.0,
            target: None,
            dwell_left: 0.0,
        });
        let mut run = SimRun {
            machine: self.name.clone(),
            scenario: sc.name.clone(),
            seed,
            sensor_ids: ids,
            node_names: self.network.names.clone(),
            rows: Vec::new(),
            states: Vec::new(),
        };
        let total_steps = (sc.duration_s() / h).round() as usize;
        let sample_every = (sc.sample_s / h).round().max(1.0) as usize;
        let steps_per_minute = ((60.0 / h).round() as usize).max(1);
        let mut probes = ProbeClock {
            state: ProbeState::Idle {
                next_s: sc.probing.as_ref().map_or(f64::INFINITY, |p| p.every_s),
            },
            cycle: 0,
            cycle_of_touch: 0,
        };
        let mut phase_idx = 0;
        let mut phase_end = sc.phases[0].duration_s;
        let mut op = Operating {
            position_mm: axes.map(|a| a.pos),
            ..Operating::default()
        };
        let mut powers: Vec<(usize, f64)> = Vec::with_capacity(64);
        let r0 = sensors.read_all(&mut rng, 0.0);
        op.servo_on = sc.phases[0].servo_on;
        run.push(self.row(0.0, &temps, &op, 0, r0, amb0), &temps);

        for k in 0..total_steps {
            let t = k as f64 * h;
            let t_end = t + h;
            while t >= phase_end - 1e-9 && phase_idx + 1 < sc.phases.len() {
                phase_idx += 1;
                phase_end += sc.phases[phase_idx].duration_s;
                for a in &mut axes {
                    a.target = None;
                    a.dwell_left = 0.0;
                }
            }
            let phase = &sc.phases[phase_idx];
            let touched = self.operate(sc, phase, &mut probes, &mut axes, &mut op, h, t, &mut rng);
            // Heat, network, coolant, sensors.
            let amb_end = self.advance_heat(
                sc,
                &op,
                &mut temps,
                &mut coolant_c,
                &mut sensors.states,
                &mut stepper,
                &mut powers,
                t,
            );
            op.position_mm = axes.map(|a| a.pos);
            let sample = (k + 1) % sample_every == 0;
            if sample || touched.is_some() {
                let readings = sensors.read_all(&mut rng, t_end);
                let probe = touched.map(|pos| {
                    self.probe_reading(sc, &temps, pos, probes.cycle_of_touch, &mut rng)
                });
                let row = Row {
                    probe,
                    ..self.row(t_end, &temps, &op, phase_idx, readings, amb_end)
                };
                run.push(row, &temps);
                // Probe touches add rows beyond the sampled ones: bound them as well.
                if run.rows.len() as f64 > 2.0 * MAX_SAMPLES {
                    return Err(SimError(format!(
                        "scenario {}: more than {} rows (sampled rows and probe touches); probe less often (probing.every_min)",
                        sc.name,
                        2.0 * MAX_SAMPLES
                    )));
                }
            }
            if (k + 1) % steps_per_minute == 0 {
                progress((k + 1) as f64 / total_steps as f64);
            }
        }
        progress(1.0);
        Ok(run)
    }

    /// The sensors at the start of a run: each sensor's lag settled on its spot's initial
    /// temperature, with the scenario's faults for that sensor and its noise.
    fn sensing<'s>(
        &self,
        sc: &'s Scenario,
        h: f64,
        temps: &[f64],
        amb0: f64,
        coolant_c: f64,
    ) -> Sensing<'s> {
        Sensing {
            states: self
                .sensors
                .iter()
                .map(|s| SensorState::new(s.tau_s, h, spot(&s.spot, temps, amb0, coolant_c)))
                .collect(),
            faults: self
                .sensors
                .iter()
                .map(|s| sc.faults.iter().filter(|f| f.sensor == s.id).collect())
                .collect(),
            noise: Noise {
                sigma_c: sc.sensor_noise_c,
                resolution_c: sc.sensor_resolution_c,
            },
        }
    }

    /// Moves the axes through one step, either in a probing cycle (which pre-empts the
    /// phase when it is due) or in the phase's own operation, and sets what the heat sources
    /// see in `op`: spindle, coolant, servo, each axis's speed and its mean position over the
    /// step. Returns the position a probe touched in this step, if any.
    #[allow(clippy::too_many_arguments)]
    fn operate(
        &self,
        sc: &Scenario,
        phase: &Phase,
        probes: &mut ProbeClock,
        axes: &mut [AxisState; 3],
        op: &mut Operating,
        h: f64,
        t: f64,
        rng: &mut fastrand::Rng,
    ) -> Option<[f64; 3]> {
        let before = axes.map(|a| a.pos);
        let (probing_now, mut touched) = probes.begin(sc.probing.as_ref(), phase.probe, t, before);
        if probing_now {
            let p = sc.probing.as_ref().expect("probing is configured");
            touched = self.probe_step(p, &mut probes.state, axes, h, t);
            let stop = p.stop_spindle;
            op.spindle_rpm = if stop { 0.0 } else { phase.spindle_rpm };
            op.coolant_on = false;
        } else {
            self.phase_step(phase, axes, h, rng);
            op.spindle_rpm = phase.spindle_rpm;
            op.coolant_on = phase.coolant;
        }
        op.servo_on = phase.servo_on;
        for a in 0..3 {
            op.speed_mm_min[a] = (axes[a].pos - before[a]).abs() / h * 60.0;
            op.position_mm[a] = 0.5 * (axes[a].pos + before[a]);
        }
        touched
    }

    /// What the probe reports at `pos`: the true error there plus the probe's noise, drawn
    /// from `rng` after the sensors' draws of the same row (the order keeps runs repeatable).
    fn probe_reading(
        &self,
        sc: &Scenario,
        temps: &[f64],
        pos: [f64; 3],
        cycle: usize,
        rng: &mut fastrand::Rng,
    ) -> ProbeReading {
        let noise_um = sc.probing.as_ref().map_or(0.0, |p| p.noise_um);
        let e = self.error_um(temps, pos);
        ProbeReading {
            position_mm: pos,
            measured_um: e.map(|v| v + noise_um * normal(rng)),
            cycle,
        }
    }

    /// A sampled row (without a probe reading) at `t`: the operation, the readings, the true
    /// error at the current position.
    fn row(
        &self,
        t: f64,
        temps: &[f64],
        op: &Operating,
        phase: usize,
        readings: Vec<f64>,
        amb: f64,
    ) -> Row {
        Row {
            time_s: t,
            position_mm: op.position_mm,
            phase,
            spindle_rpm: op.spindle_rpm,
            speed_mm_min: op.speed_mm_min,
            coolant_on: op.coolant_on,
            temperatures_c: readings,
            error_um: self.error_um(temps, op.position_mm),
            ambient_true_c: amb,
            probe: None,
        }
    }

    /// Every motion and probing point of the scenario stays inside this machine's travel.
    fn check_fits(&self, sc: &Scenario) -> Result<(), SimError> {
        for ph in &sc.phases {
            for m in &ph.motion {
                let [lo, hi] = self.travel_mm[m.axis];
                let inside = |v: f64| v >= lo && v <= hi;
                if !m.range_mm.is_none_or(|[a, b]| inside(a) && inside(b))
                    || !m.at_mm.is_none_or(inside)
                {
                    return Err(SimError(format!(
                        "scenario {}: phase \"{}\": axis {} must stay inside its travel [{lo}, {hi}] mm",
                        sc.name, ph.name, AXES[m.axis]
                    )));
                }
            }
        }
        if let Some(p) = &sc.probing {
            for pt in &p.points {
                for (a, v) in pt.iter().enumerate() {
                    let [lo, hi] = self.travel_mm[a];
                    if *v < lo || *v > hi {
                        return Err(SimError(format!(
                            "scenario {}: probing point {} = {v} mm is outside the travel [{lo}, {hi}] mm",
                            sc.name, AXES[a]
                        )));
                    }
                }
            }
        }
        Ok(())
    }

    /// One step of the heat flow: the operation's losses and the coolant into the network,
    /// the network over the step, the coolant and the sensors after it. Returns the ambient
    /// temperature at the end of the step.
    #[allow(clippy::too_many_arguments)] // the loop's state, borrowed piece by piece
    fn advance_heat(
        &self,
        sc: &Scenario,
        op: &Operating,
        temps: &mut [f64],
        coolant_c: &mut f64,
        sensors: &mut [SensorState],
        stepper: &mut Stepper,
        powers: &mut Vec<(usize, f64)>,
        t: f64,
    ) -> f64 {
        let h = sc.step_s;
        powers.clear();
        self.heat(op, powers);
        if op.coolant_on {
            self.coolant_heat(temps, *coolant_c, powers);
        }
        let amb = sc.ambient.at(t + 0.5 * h, sc.start_hour);
        stepper.step(temps, powers, amb);
        let amb_end = sc.ambient.at(t + h, sc.start_hour);
        let cool_target = amb_end
            + if op.coolant_on {
                self.coolant_rise_k
            } else {
                0.0
            };
        *coolant_c += (1.0 - (-h / self.coolant_tau_s).exp()) * (cool_target - *coolant_c);
        for (s, spec) in sensors.iter_mut().zip(&self.sensors) {
            s.step(spot(&spec.spot, temps, amb_end, *coolant_c));
        }
        amb_end
    }

    /// One step of a probing cycle; returns the touched position when a touch happens.
    fn probe_step(
        &self,
        p: &Probing,
        state: &mut ProbeState,
        axes: &mut [AxisState; 3],
        h: f64,
        t: f64,
    ) -> Option<[f64; 3]> {
        let ProbeState::Active { point, dwell_left } = state else {
            return None;
        };
        let target = p.points[*point];
        let step_mm = p.feed_mm_min / 60.0 * h;
        let mut arrived = true;
        for a in 0..3 {
            arrived &= axes[a].approach(target[a], step_mm);
        }
        if !arrived {
            return None;
        }
        if *dwell_left > 1e-9 {
            *dwell_left -= h;
            if *dwell_left > 1e-9 {
                return None;
            }
        }
        let touched = Some(target);
        if *point + 1 < p.points.len() {
            *point += 1;
            *dwell_left = p.dwell_s;
        } else {
            let mut next_s = p.every_s;
            while next_s <= t + h + 1e-9 {
                next_s += p.every_s;
            }
            *state = ProbeState::Idle { next_s };
        }
        touched
    }

    /// One step of a phase's axis motion.
    fn phase_step(
        &self,
        phase: &Phase,
        axes: &mut [AxisState; 3],
        h: f64,
        rng: &mut fastrand::Rng,
    ) {
        for m in &phase.motion {
            let [lo, hi] = m.range_mm.unwrap_or(self.travel_mm[m.axis]);
            let ax = &mut axes[m.axis];
            let step_mm = m.feed_mm_min / 60.0 * h;
            match m.pattern {
                Pattern::Hold => {
                    let target = m.at_mm.unwrap_or(ax.pos);
                    ax.approach(target, step_mm);
                }
                Pattern::Sweep => {
                    if ax.pos < lo {
                        ax.dir = 1.0;
                    } else if ax.pos > hi {
                        ax.dir = -1.0;
                    }
                    let target = if ax.dir > 0.0 { hi } else { lo };
                    if ax.approach(target, step_mm)
                        && (ax.pos - lo).abs() + (hi - ax.pos).abs() > 0.0
                    {
                        ax.dir = -ax.dir;
                    }
                }
                Pattern::Random => {
                    if ax.dwell_left > 0.0 {
                        ax.dwell_left -= h;
                        continue;
                    }
                    let target = *ax.target.get_or_insert_with(|| lo + (hi - lo) * rng.f64());
                    if ax.approach(target, step_mm) {
                        ax.target = None;
                        ax.dwell_left = m.dwell_s * rng.f64();
                    }
                }
            }
        }
    }
}
