//! The fault campaign: random fault schedules over thousands of cycles, with the output
//! invariant (ARCHITECTURE.md, "The output invariant") checked on every axis and every cycle
//! against an independent reference — the models evaluated by the test on the inputs it
//! delivered, and a blend reconstructed from the path states the service reports.
//!
//! The number of schedules follows `PROPTEST_CASES` (256 by default; the README's test command
//! runs 10 000 in a release build).

use std::sync::{Arc, Mutex};

use proptest::prelude::*;
use truepos_io::cycles;
use truepos_io::model_file::position;
use truepos_model::envelope::TrainingEnvelope;
use truepos_model::{CycleInput, EvalError, Model};
use truepos_runtime::model_set::ModelEntry;
use truepos_runtime::*;

mod support;
use support::{repo, vmc};

/// The example model and a fallback without its spindle part (no spindle sensors), both for
/// the machine's one path. The example carries a training envelope narrower than the
/// schedules' warm-ups (up to 8 K), so that extrapolation — inputs clamped, output capped —
/// is part of the campaign.
fn models(machine: &MachineConfig) -> Vec<ModelEntry> {
    let mut full = position::load(&repo("examples/vmc3/model.toml"), &machine.machine).unwrap();
    let m = &machine.machine;
    full.set_envelope(Some(TrainingEnvelope {
        temperatures: vec![Some((19.5, 23.0)); m.temperatures.len()],
        operating: vec![None; m.operating.len()],
        max_abs_um: vec![Some(12.0); m.axes.len()],
    }));
    let parts = full.parts()[..1].to_vec();
    let fallback = Model::new("structure-only", &machine.machine, parts).unwrap();
    vec![
        ModelEntry {
            name: "full".into(),
            model: full.into(),
            index: [101, 102, 103],
        },
        ModelEntry {
            name: "structure-only".into(),
            model: fallback.into(),
            index: [101, 102, 103],
        },
    ]
}

/// The compensation (−error) per axis of `model` at `input` as the service must apply it:
/// guarded by its training envelope when it has one. Restated here, independently of
/// `truepos_model::envelope`: each input clamped to its range widened by 25 % (temperatures at
/// least 2 K), each axis' error limited to 1.5 × its training maximum.
fn reference_compensation(model: &Model, input: &CycleInput<'_>) -> Result<Vec<f64>, EvalError> {
    let mut t = input.temperatures_c.to_vec();
    let mut o = input.operating.to_vec();
    let axes = input.positions.len();
    let mut limit = vec![f64::INFINITY; axes];
    if let Some(env) = model.envelope() {
        let widen = |v: &mut f64, range: &Option<(f64, f64)>, least: f64| {
            if let (Some((lo, hi)), true) = (range, v.is_finite()) {
                let m = (0.25 * (hi - lo)).max(least);
                *v = v.clamp(lo - m, hi + m);
            }
        };
        for (v, r) in t.iter_mut().zip(&env.temperatures) {
            widen(v, r, 2.0);
        }
        for (v, r) in o.iter_mut().zip(&env.operating) {
            widen(v, r, 0.0);
        }
        for (l, m) in limit.iter_mut().zip(&env.max_abs_um) {
            if let Some(m) = m {
                *l = 1.5 * m;
            }
        }
    }
    let c = model.evaluate(&CycleInput {
        temperatures_c: &t,
        positions: input.positions,
        operating: &o,
    })?;
    Ok((0..axes)
        .map(|a| 0.0 - c.error_um()[a].clamp(-limit[a], limit[a]))
        .collect())
}

/// What the test delivers in one cycle.
#[derive(Debug, Clone, Default)]
struct Delivery {
    /// Per temperature channel: `Some(value)` if delivered (stamped) this cycle.
    temperatures: Vec<Option<f64>>,
    /// Per axis: `Some(position)` if delivered this cycle.
    positions: Vec<Option<f64>>,
    /// The control's axis configuration of path 1.
    path: Vec<usize>,
    /// The source fails this cycle (and delivers nothing).
    lost: bool,
}

struct ScriptedSource {
    next: Arc<Mutex<Delivery>>,
}

impl Source for ScriptedSource {
    fn name(&self) -> &str {
        "scripted"
    }
    fn read(&mut self, frame: &mut Frame) -> Result<(), LinkError> {
        let d = self.next.lock().unwrap();
        if d.lost {
            return Err(LinkError::Disconnected("scripted loss".into()));
        }
        for (c, v) in d.temperatures.iter().enumerate() {
            if let Some(v) = v {
                frame.set_temperature(c, *v);
            }
        }
        for (a, p) in d.positions.iter().enumerate() {
            if let Some(p) = p {
                frame.set_position(a, *p);
            }
        }
        frame.paths = vec![d.path.clone()];
        Ok(())
    }
}

/// One kind of fault, applied for an episode of cycles.
#[derive(Debug, Clone, Copy)]
enum FaultKind {
    Nan(usize),
    OutOfRange(usize, f64),
    Spike(usize, f64),
    /// Alternates ±0.1 K around the true value (a quantisation flicker).
    Flicker(usize),
    /// Not delivered at all.
    Stale(usize),
    /// Delivered, but frozen at the value when the episode began.
    Stuck(usize),
    /// NaN every `k`-th cycle.
    Intermittent(usize, usize),
    SourceLost,
    PositionNan(usize),
    PositionStale,
    PreferFallback,
    Disabled,
    /// Z leaves the path (parked or handed over).
    AxisOut,
    /// At the episode's start, model `model` is reloaded between cycles: a good file (its
    /// parameters scaled by `scale`, as a re-identification changes them) or a bad one (made
    /// for another axis combination), which must leave the running model untouched.
    Reload {
        model: usize,
        scale: f64,
        good: bool,
    },
}

#[derive(Debug, Clone, Copy)]
struct Episode {
    start: usize,
    len: usize,
    kind: FaultKind,
}

#[derive(Debug, Clone)]
struct Schedule {
    cycles: usize,
    dt: f64,
    /// Per temperature channel: rise in K and time constant in s of a warm-up.
    warmup: Vec<(f64, f64)>,
    /// Per axis: sweep frequency in Hz and phase.
    sweep: Vec<(f64, f64)>,
    episodes: Vec<Episode>,
}

fn fault_kind(n_t: usize) -> impl Strategy<Value = FaultKind> {
    let ch = 0..n_t;
    prop_oneof![
        ch.clone().prop_map(FaultKind::Nan),
        (
            ch.clone(),
            prop_oneof![Just(850.0), Just(-40.0), Just(61.0)]
        )
            .prop_map(|(c, v)| FaultKind::OutOfRange(c, v)),
        (ch.clone(), -8.0..8.0f64).prop_map(|(c, k)| FaultKind::Spike(c, k)),
        ch.clone().prop_map(FaultKind::Flicker),
        ch.clone().prop_map(FaultKind::Stale),
        ch.clone().prop_map(FaultKind::Stuck),
        (ch, 2usize..12).prop_map(|(c, k)| FaultKind::Intermittent(c, k)),
        Just(FaultKind::SourceLost),
        (0usize..3).prop_map(FaultKind::PositionNan),
        Just(FaultKind::PositionStale),
        Just(FaultKind::PreferFallback),
        Just(FaultKind::Disabled),
        Just(FaultKind::AxisOut),
        (0usize..2, 0.3..1.7f64, any::<bool>())
            .prop_map(|(model, scale, good)| FaultKind::Reload { model, scale, good }),
    ]
}

fn schedule(n_t: usize) -> impl Strategy<Value = Schedule> {
    (
        1000usize..3000,
        prop_oneof![Just(0.001), Just(0.01), Just(0.1), Just(0.5)],
        proptest::collection::vec((0.0..8.0f64, 60.0..3600.0f64), n_t),
        proptest::collection::vec((0.001..0.5f64, 0.0..6.3f64), 3),
        proptest::collection::vec((0usize..3000, 1usize..800, fault_kind(n_t)), 0..12),
    )
        .prop_map(|(cycles, dt, warmup, sweep, eps)| Schedule {
            cycles,
            dt,
            warmup,
            sweep,
            episodes: eps
                .into_iter()
                .map(|(start, len, kind)| Episode { start, len, kind })
                .collect(),
        })
}

/// The inputs of cycle `i` without faults.
fn clean_inputs(s: &Schedule, travel: &[(f64, f64)], t: f64) -> (Vec<f64>, Vec<f64>) {
    let temps = s
        .warmup
        .iter()
        .map(|&(rise, tau)| 20.0 + rise * (1.0 - (-t / tau).exp()))
        .collect();
    let positions = s
        .sweep
        .iter()
        .zip(travel)
        .map(|(&(f, ph), &(lo, hi))| {
            lo + (hi - lo) * 0.5 * (1.0 + (std::f64::consts::TAU * f * t + ph).sin())
        })
        .collect();
    (temps, positions)
}

/// Where an axis' target comes from, as the test reconstructs it from what it observes.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Origin {
    Zero,
    Model(usize),
    Hold,
}

/// The test's own account of one axis.
#[derive(Debug, Clone, Copy)]
struct AxisTrack {
    origin: Origin,
    /// The output when the origin last changed, and when.
    from: f64,
    since: f64,
}

struct Campaign {
    service: Service,
    next: Arc<Mutex<Delivery>>,
    reference: Vec<Model>,
    machine: truepos_model::Machine,
    limits: Vec<AxisConfig>,
    ranges: Vec<(f64, f64)>,
    config: ServiceConfig,
    tracks: Vec<AxisTrack>,
    /// The values the frame holds: the last delivered per channel.
    held_t: Vec<f64>,
    held_p: Vec<f64>,
    /// Operating channels: never delivered (the static models do not read them).
    operating: Vec<f64>,
    /// The axis configuration the frame holds (a lost source does not change it).
    held_path: Vec<usize>,
    prev_out: Vec<f64>,
    prev_time: f64,
}

impl Campaign {
    fn new(config: ServiceConfig) -> Self {
        let machine = vmc();
        let entries = models(&machine);
        let reference = entries
            .iter()
            .map(|e| e.model.as_static().unwrap().clone())
            .collect();
        let next = Arc::new(Mutex::new(Delivery::default()));
        let source = ScriptedSource {
            next: Arc::clone(&next),
        };
        let n_t = machine.machine.temperatures.len();
        let n_a = machine.machine.axes.len();
        let n_o = machine.machine.operating.len();
        let limits = machine.axes.clone();
        let ranges = machine
            .machine
            .temperatures
            .iter()
            .map(|t| (t.valid_min_c, t.valid_max_c))
            .collect();
        let bound = machine.machine.clone();
        let service = Service::new(
            machine,
            entries,
            vec![Box::new(source)],
            vec![],
            config.clone(),
        );
        Self {
            service,
            next,
            reference,
            machine: bound,
            limits,
            ranges,
            config,
            tracks: vec![
                AxisTrack {
                    origin: Origin::Zero,
                    from: 0.0,
                    since: 0.0,
                };
                n_a
            ],
            held_t: vec![f64::NAN; n_t],
            held_p: vec![f64::NAN; n_a],
            operating: vec![f64::NAN; n_o],
            held_path: (0..n_a).collect(),
            prev_out: vec![0.0; n_a],
            prev_time: f64::NAN,
        }
    }

    /// Runs one cycle with `delivery` and checks the invariant; returns the output.
    fn step(&mut self, t: f64, delivery: Delivery) -> Result<Output, TestCaseError> {
        if !delivery.lost {
            for (h, d) in self.held_t.iter_mut().zip(&delivery.temperatures) {
                if let Some(v) = d {
                    *h = *v;
                }
            }
            for (h, d) in self.held_p.iter_mut().zip(&delivery.positions) {
                if let Some(v) = d {
                    *h = *v;
                }
            }
        }
        if !delivery.lost {
            self.held_path.clone_from(&delivery.path);
        }
        let path = self.held_path.clone();
        *self.next.lock().unwrap() = delivery;
        let out = *self.service.cycle(t);
        let state = self.service.path_states()[0];
        let dt = if self.prev_time.is_nan() {
            0.0
        } else {
            t - self.prev_time
        };
        let reference = match state {
            PathState::Model(m) => Some(self.check_model_inputs(m, t)?),
            _ => None,
        };
        for a in 0..self.tracks.len() {
            let origin = if !path.contains(&a) {
                Origin::Zero
            } else {
                match state {
                    PathState::Model(m) => Origin::Model(m),
                    PathState::Holding => Origin::Hold,
                    PathState::NoModel | PathState::Disabled => Origin::Zero,
                }
            };
            let tr = &mut self.tracks[a];
            if origin != tr.origin {
                *tr = AxisTrack {
                    origin,
                    from: self.prev_out[a],
                    since: t,
                };
            }
            let target = match origin {
                Origin::Zero => 0.0,
                Origin::Model(_) => reference.as_ref().unwrap()[a],
                Origin::Hold => {
                    let left = if self.config.hold_ramp_s > 0.0 {
                        (1.0 - (t - tr.since) / self.config.hold_ramp_s).clamp(0.0, 1.0)
                    } else {
                        0.0
                    };
                    tr.from * left
                }
            };
            let o = out.offset_um[a];
            let prev = self.prev_out[a];
            let lim = self.limits[a];
            let eps = 1e-9 * (1.0 + o.abs());
            prop_assert!(o.is_finite(), "t {t} axis {a}: output {o}");
            prop_assert!(o.abs() <= lim.max_offset_um + eps, "t {t} axis {a}: {o}");
            prop_assert!(
                (o - prev).abs() <= lim.max_rate_um_per_s * dt + eps,
                "t {t} axis {a}: step {} in {dt} s",
                o - prev
            );
            // The output moves from where it was towards a value between the output it left
            // (at the latest change of origin) and its current target, never beyond.
            let lo = prev.min(tr.from).min(target) - eps;
            let hi = prev.max(tr.from).max(target) + eps;
            prop_assert!(
                (lo..=hi).contains(&o),
                "t {t} axis {a}: output {o} outside [{lo}, {hi}] (prev {prev}, from {}, target {target}, origin {:?} since {})",
                tr.from,
                tr.origin,
                tr.since
            );
            // Active, blend over and no clamp binding: exactly the model's value.
            let settled = t - tr.since >= self.config.blend_s;
            let free = (o - prev).abs() < lim.max_rate_um_per_s * dt - eps
                && o.abs() < lim.max_offset_um - eps;
            if matches!(origin, Origin::Model(_)) && settled && free {
                prop_assert!(
                    (o - target).abs() <= eps,
                    "t {t} axis {a}: active output {o} but model {target}"
                );
            }
        }
        self.prev_out.copy_from_slice(out.offsets());
        self.prev_time = t;
        Ok(out)
    }

    /// Reloads model `m` between cycles (see [`FaultKind::Reload`]). A good reload of the model
    /// an axis follows is a change of origin for the test's account: the blend restarts from
    /// the output last sent, at the time of the last cycle.
    fn reload(&mut self, m: usize, scale: f64, good: bool) -> Result<(), TestCaseError> {
        let theta: Vec<f64> = self.reference[m]
            .parameters()
            .iter()
            .map(|p| p * scale)
            .collect();
        let new = self.reference[m]
            .with_parameters(&self.machine, &theta)
            .unwrap();
        let index = if good { [101, 102, 103] } else { [101, 102, 0] };
        let result = self.service.replace_model(
            m,
            ModelEntry {
                name: format!("reloaded {m}"),
                model: new.clone().into(),
                index,
            },
        );
        if !good {
            prop_assert!(
                result.is_err(),
                "a model for another axis combination was taken"
            );
            return Ok(());
        }
        prop_assert!(
            result.is_ok(),
            "a good reload was refused: {:?}",
            result.err()
        );
        self.reference[m] = new;
        let since = if self.prev_time.is_nan() {
            0.0
        } else {
            self.prev_time
        };
        for (a, tr) in self.tracks.iter_mut().enumerate() {
            if tr.origin == Origin::Model(m) {
                *tr = AxisTrack {
                    origin: tr.origin,
                    from: self.prev_out[a],
                    since,
                };
            }
        }
        Ok(())
    }

    /// A path reported active uses a model whose inputs, as delivered, are numbers within their
    /// valid range and whose positions are usable; returns the reference compensation.
    fn check_model_inputs(&self, m: usize, t: f64) -> Result<Vec<f64>, TestCaseError> {
        let model = &self.reference[m];
        for &c in model.used_sensors() {
            let v = self.held_t[c];
            let (lo, hi) = self.ranges[c];
            prop_assert!(
                v.is_finite() && (lo..=hi).contains(&v),
                "t {t}: active on model {m} while sensor {c} reads {v}"
            );
        }
        prop_assert!(
            self.held_p.iter().all(|p| p.is_finite()),
            "t {t}: active with positions {:?}",
            self.held_p
        );
        reference_compensation(
            model,
            &CycleInput {
                temperatures_c: &self.held_t,
                positions: &self.held_p,
                operating: &self.operating,
            },
        )
        .map_err(|e| TestCaseError::fail(format!("t {t}: active but the model fails: {e}")))
    }
}

fn run_schedule(s: &Schedule) -> Result<(), TestCaseError> {
    let config = ServiceConfig {
        blend_s: 2.0,
        hold_ramp_s: 30.0,
        ..ServiceConfig::default()
    };
    let mut c = Campaign::new(config);
    let travel: Vec<(f64, f64)> = vmc()
        .machine
        .axes
        .iter()
        .map(|a| (a.travel_min, a.travel_max))
        .collect();
    let mut frozen: Vec<Option<f64>> = vec![None; s.warmup.len()];
    let mut enabled = true;
    let mut preferred = None;
    for i in 0..s.cycles {
        let t = i as f64 * s.dt;
        let (temps, positions) = clean_inputs(s, &travel, t);
        let mut d = Delivery {
            temperatures: temps.iter().map(|&v| Some(v)).collect(),
            positions: positions.iter().map(|&p| Some(p)).collect(),
            path: vec![0, 1, 2],
            lost: false,
        };
        let mut want_enabled = true;
        let mut want_pref = None;
        for e in &s.episodes {
            let active = i >= e.start && i < e.start + e.len;
            if let FaultKind::Stuck(ch) = e.kind {
                if i == e.start {
                    frozen[ch] = Some(temps[ch]);
                } else if i == e.start + e.len {
                    frozen[ch] = None;
                }
            }
            if let FaultKind::Reload { model, scale, good } = e.kind {
                if i == e.start {
                    c.reload(model, scale, good)?;
                }
                continue;
            }
            if !active {
                continue;
            }
            apply_fault(e, i, &temps, &frozen, &mut d);
            match e.kind {
                FaultKind::Disabled => want_enabled = false,
                FaultKind::PreferFallback => want_pref = Some(1),
                _ => {}
            }
        }
        if want_enabled != enabled {
            c.service.set_enabled(want_enabled);
            enabled = want_enabled;
        }
        if want_pref != preferred {
            c.service.prefer_model(0, want_pref);
            preferred = want_pref;
        }
        c.step(t, d)?;
    }
    Ok(())
}

fn apply_fault(e: &Episode, i: usize, temps: &[f64], frozen: &[Option<f64>], d: &mut Delivery) {
    match e.kind {
        FaultKind::Nan(ch) => d.temperatures[ch] = Some(f64::NAN),
        FaultKind::OutOfRange(ch, v) => d.temperatures[ch] = Some(v),
        FaultKind::Spike(ch, k) if i == e.start => d.temperatures[ch] = Some(temps[ch] + k),
        FaultKind::Spike(..) => {}
        FaultKind::Flicker(ch) => {
            let s = if i.is_multiple_of(2) { 0.1 } else { -0.1 };
            d.temperatures[ch] = Some(((temps[ch] + s) * 10.0).round() / 10.0);
        }
        FaultKind::Stale(ch) => d.temperatures[ch] = None,
        FaultKind::Stuck(ch) => d.temperatures[ch] = frozen[ch].or(Some(temps[ch])),
        FaultKind::Intermittent(ch, k) if (i - e.start).is_multiple_of(k) => {
            d.temperatures[ch] = Some(f64::NAN)
        }
        FaultKind::Intermittent(..) => {}
        FaultKind::SourceLost => d.lost = true,
        FaultKind::PositionNan(a) => d.positions[a] = Some(f64::NAN),
        FaultKind::PositionStale => d.positions.iter_mut().for_each(|p| *p = None),
        FaultKind::AxisOut => d.path = vec![0, 1],
        FaultKind::PreferFallback | FaultKind::Disabled | FaultKind::Reload { .. } => {}
    }
}

proptest! {
    #![proptest_config(ProptestConfig {
        // The count comes from PROPTEST_CASES; shrinking a 3000-cycle schedule is slow and its
        // first failure is already readable.
        max_shrink_iters: 64,
        failure_persistence: None,
        ..ProptestConfig::default()
    })]

    /// The output invariant holds on every axis and cycle of every random fault schedule.
    #[test]
    fn the_output_invariant_holds_under_random_faults(s in schedule(vmc().machine.temperatures.len())) {
        run_schedule(&s)?;
    }
}

/// Issue 11, case 1: the example run from the warm machine (3 h in) at 10 Hz with
/// `x_slide_top` NaN on every third cycle. The output used to run away to the envelope's
/// 100 µm (X +97.96 µm where the model gave −17.28 µm) while the state read `active`.
#[test]
fn an_intermittent_nan_does_not_run_the_output_away() {
    let machine = vmc();
    let run = cycles::load(&repo("examples/vmc3/run.csv"), &machine.machine, &[]).unwrap();
    let mut c = Campaign::new(ServiceConfig::default());
    let start = run
        .run
        .time_s
        .iter()
        .position(|&t| t >= 3.0 * 3600.0)
        .unwrap();
    let (mut lo, mut hi) = ([0.0f64; 3], [0.0f64; 3]);
    let mut t = 0.0;
    let mut i = 0usize;
    // Ten minutes at 10 Hz, each recorded row (60 s apart) held until the next.
    while t < 600.0 {
        let row = (start + (t / 60.0) as usize).min(run.run.time_s.len() - 1);
        let mut temps: Vec<Option<f64>> = run.run.temperatures_c[row]
            .iter()
            .map(|&v| Some(v))
            .collect();
        if i % 3 == 2 {
            temps[0] = Some(f64::NAN);
        }
        let d = Delivery {
            temperatures: temps,
            positions: run.run.positions[row].iter().map(|&p| Some(p)).collect(),
            path: vec![0, 1, 2],
            lost: false,
        };
        let model = reference_compensation(
            &c.reference[0],
            &CycleInput {
                temperatures_c: &run.run.temperatures_c[row],
                positions: &run.run.positions[row],
                operating: &run.run.operating[row],
            },
        )
        .unwrap();
        for a in 0..3 {
            lo[a] = lo[a].min(model[a]);
            hi[a] = hi[a].max(model[a]);
        }
        let out = c.step(t, d).map_err(|e| e.to_string()).unwrap();
        for a in 0..3 {
            let o = out.offset_um[a];
            assert!(
                o >= lo[a] - 1e-9 && o <= hi[a] + 1e-9,
                "t {t} axis {a}: {o} µm outside the model's range [{}, {}]",
                lo[a],
                hi[a]
            );
        }
        t += 0.1;
        i += 1;
    }
}

/// Reloads at the moments that matter, on one fixed schedule: during the start-up blend, during
/// the blend of a model switch (the fallback preferred), a refused one right after, and a
/// reload of the model the output is blending back to; the invariant holds on every cycle.
#[test]
fn reloads_during_blends_keep_the_invariant() {
    let n_t = vmc().machine.temperatures.len();
    let episode = |start, len, kind| Episode { start, len, kind };
    let s = Schedule {
        cycles: 1200,
        dt: 0.01,
        // Every channel warms differently, so that the differences the models read move.
        warmup: (0..n_t)
            .map(|c| (1.0 + c as f64 * 0.4, 0.5 + c as f64 * 0.3))
            .collect(),
        sweep: vec![(0.2, 0.0), (0.13, 1.0), (0.07, 2.0)],
        episodes: vec![
            // A fifth into the start-up blend, to half the model: restarted from the output
            // sent, the output keeps moving towards the new target; continued from zero, it
            // would fall back, away from it.
            episode(
                40,
                1,
                FaultKind::Reload {
                    model: 0,
                    scale: 0.5,
                    good: true,
                },
            ),
            // Blend from model 0 to the fallback (2 s = 200 cycles) starting at cycle 300.
            episode(300, 400, FaultKind::PreferFallback),
            episode(
                350,
                1,
                FaultKind::Reload {
                    model: 1,
                    scale: 1.6,
                    good: true,
                },
            ),
            episode(
                360,
                1,
                FaultKind::Reload {
                    model: 1,
                    scale: 0.5,
                    good: false,
                },
            ),
            episode(
                420,
                1,
                FaultKind::Reload {
                    model: 0,
                    scale: 0.4,
                    good: true,
                },
            ),
            // Back to model 0 at cycle 700, reloaded twice during that blend.
            episode(
                750,
                1,
                FaultKind::Reload {
                    model: 0,
                    scale: 1.7,
                    good: true,
                },
            ),
            episode(
                760,
                1,
                FaultKind::Reload {
                    model: 0,
                    scale: 0.3,
                    good: true,
                },
            ),
        ],
    };
    run_schedule(&s).map_err(|e| e.to_string()).unwrap();
}
