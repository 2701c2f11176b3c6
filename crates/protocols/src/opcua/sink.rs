//! The OPC UA sink: the cycle hands its output and inputs over (one slot, latest wins) and a
//! thread of its own projects them onto each axis' line and writes K0/tanβ/P0 to the control
//! at the configured rate, every write's status checked; lost sessions are reopened with
//! backoff.

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use opcua::types::{
    AttributeId, DataValue, NodeId, NumericRange, ReadValueId, StatusCode, TimestampsToReturn,
    Variant, WriteValue,
};
use truepos_files::InputError;
use truepos_model::{Machine, Model};
use truepos_runtime::events::Reason;
use truepos_runtime::sources::{stop_thread, Backoff, LinkStatus, OutageReporter, STOP_LIMIT};
use truepos_runtime::{CompensationState, Frame, LinkError, MachineConfig, Output, Sink};

use super::client::{connect, describe, node_id, Open};
use super::config::{Identity, SinkConfig, ValueType};
use super::form::{self, AxisLimits, Ends, Snapshot, Written};
use super::latest::Latest;

/// Round trips and outcomes of the sink's writes.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct WriteStats {
    /// Write requests sent.
    pub writes: u64,
    /// Requests every node of which answered Good.
    pub good: u64,
    /// Round trip of every answered request, ms.
    pub round_trips_ms: Vec<f64>,
    /// Sessions opened.
    pub sessions: u64,
}

impl WriteStats {
    /// The `q` quantile of the round trips, ms (nearest rank; `None` before any).
    pub fn quantile_ms(&self, q: f64) -> Option<f64> {
        let mut v = self.round_trips_ms.clone();
        if v.is_empty() {
            return None;
        }
        v.sort_by(f64::total_cmp);
        Some(v[((v.len() - 1) as f64 * q).round() as usize])
    }
}

/// One axis' nodes, parsed.
struct AxisOut {
    axis: usize,
    name: String,
    lim: AxisLimits,
    k0: NodeId,
    tan_beta: Option<NodeId>,
    p0: Option<NodeId>,
    value_type: ValueType,
}

/// The OPC UA sink.
pub struct OpcUaSink {
    name: String,
    latest: Arc<Latest>,
    /// The cells of the snapshot: time, state, offsets, positions, temperatures, operating.
    layout: [usize; 4],
    status: Arc<LinkStatus>,
    outage: OutageReporter,
    stop: Arc<AtomicBool>,
    stats: Arc<Mutex<WriteStats>>,
    /// Set once the first session attempt is over: until then there is nothing to report (a
    /// sink that is still opening its first session has not failed) — up to `first_deadline`.
    tried: Arc<AtomicBool>,
    /// When a first attempt still under way counts as failed: the request deadline and one
    /// second from the start, however long the connection library takes to give up.
    first_deadline: Instant,
    /// What is reported then.
    first_missed: Reason,
    thread: Option<JoinHandle<()>>,
}

const STATE_CODES: [CompensationState; 4] = [
    CompensationState::Active,
    CompensationState::Holding,
    CompensationState::Disabled,
    CompensationState::NoModel,
];

impl OpcUaSink {
    /// Starts the writing thread for a checked mapping. `model`: the static (position-dependent)
    /// model whose line is projected — the service's only model, so that "active" means this model;
    /// without one (a fitted dynamic model, a set of several models) each axis gets the service's
    /// output as a constant.
    pub fn start(
        config: &SinkConfig,
        identity: Identity,
        axes: &[(usize, super::config::AxisNodes)],
        machine: &MachineConfig,
        model: Option<Model>,
    ) -> Result<Self, InputError> {
        let m = &machine.machine;
        let mut out = Vec::new();
        for (i, (a, nodes)) in axes.iter().enumerate() {
            let key = |k: &str| format!("axis[{}].{k}", i + 1);
            let parse = |t: &str, k: &str| node_id(t).map_err(|e| InputError::at_key(key(k), e));
            let axis = &m.axes[*a];
            out.push(AxisOut {
                axis: *a,
                name: axis.name.clone(),
                lim: AxisLimits {
                    travel_min: axis.travel_min,
                    travel_max: axis.travel_max,
                    max_offset_um: machine.axes[*a].max_offset_um,
                    max_rate_um_per_s: nodes.max_rate_um_per_s,
                    p0_mm: nodes.p0_mm,
                },
                k0: parse(&nodes.k0, "k0")?,
                tan_beta: nodes
                    .tan_beta
                    .as_deref()
                    .map(|t| parse(t, "tan_beta"))
                    .transpose()?,
                p0: nodes.p0.as_deref().map(|t| parse(t, "p0")).transpose()?,
                value_type: nodes.value_type,
            });
        }
        // The frame's temperatures include the lagged channels (machine order).
        let (n, t, o) = (m.axes.len(), m.temperatures.len(), m.operating.len());
        let layout = [2, 2 + n, 2 + 2 * n, 2 + 2 * n + t];
        let latest = Arc::new(Latest::new(layout[3] + o));
        let status = Arc::new(LinkStatus::default());
        let stop = Arc::new(AtomicBool::new(false));
        let stats = Arc::new(Mutex::new(WriteStats::default()));
        let tried = Arc::new(AtomicBool::new(false));
        let name = format!("opcua {}", config.connection.endpoint);
        let first_deadline = Instant::now()
            + Duration::from_millis(config.connection.timeout_ms)
            + Duration::from_secs(1);
        let first_missed = Reason::new(&format!(
            "no session open within {} ms",
            config.connection.timeout_ms
        ));
        let writer = Writer {
            config: config.clone(),
            identity,
            machine: m.clone(),
            model,
            axes: out,
            latest: Arc::clone(&latest),
            layout,
            status: Arc::clone(&status),
            stop: Arc::clone(&stop),
            stats: Arc::clone(&stats),
            tried: Arc::clone(&tried),
            epoch: Instant::now(),
            reported: AtomicU64::new(0),
        };
        let thread = std::thread::Builder::new()
            .name(name.clone())
            .spawn(move || writer.run())
            .map_err(|e| {
                InputError::at_key("opcua", format!("cannot start the writing thread: {e}"))
            })?;
        Ok(Self {
            name,
            latest,
            layout,
            status,
            outage: OutageReporter::default(),
            stop,
            stats,
            tried,
            first_deadline,
            first_missed,
            thread: Some(thread),
        })
    }

    /// The writes so far.
    pub fn stats(&self) -> WriteStats {
        self.stats.lock().unwrap_or_else(|e| e.into_inner()).clone()
    }
}

impl Sink for OpcUaSink {
    fn name(&self) -> &str {
        &self.name
    }

    fn write(&mut self, _output: &Output) -> Result<(), LinkError> {
        if !self.tried.load(Ordering::Acquire) {
            if Instant::now() < self.first_deadline {
                return Ok(());
            }
            return Err(LinkError::Disconnected(self.first_missed));
        }
        self.outage.check(&self.status)
    }

    /// Hands the cycle over to the writing thread (atomics only) and reports the link's state.
    fn write_cycle(&mut self, output: &Output, frame: &Frame) -> Result<(), LinkError> {
        let n = output.axes;
        let state = STATE_CODES
            .iter()
            .position(|s| *s == output.state)
            .unwrap_or(2) as f64;
        debug_assert_eq!(self.layout[1] - self.layout[0], n);
        self.latest.publish(
            [output.time_s, state]
                .into_iter()
                .chain(output.offsets().iter().copied())
                .chain(output.positions[..n].iter().copied())
                .chain(frame.temperatures_c.iter().copied())
                .chain(frame.operating.iter().copied()),
        );
        self.write(output)
    }
}

impl Drop for OpcUaSink {
    fn drop(&mut self) {
        if let Some(t) = self.thread.take() {
            stop_thread(&self.stop, t, STOP_LIMIT + Duration::from_secs(2));
        }
        let s = self.stats();
        let q = |x: f64| {
            s.quantile_ms(x)
                .map_or("–".into(), |v| format!("{v:.2} ms"))
        };
        eprintln!(
            "{}: {} writes, {} all Good, {} sessions; round trip p50 {}, p99 {}, max {} ({} answered)",
            self.name,
            s.writes,
            s.good,
            s.sessions,
            q(0.5),
            q(0.99),
            q(1.0),
            s.round_trips_ms.len()
        );
    }
}

/// The writing thread.
struct Writer {
    config: SinkConfig,
    identity: Identity,
    machine: Machine,
    model: Option<Model>,
    axes: Vec<AxisOut>,
    latest: Arc<Latest>,
    layout: [usize; 4],
    status: Arc<LinkStatus>,
    stop: Arc<AtomicBool>,
    stats: Arc<Mutex<WriteStats>>,
    tried: Arc<AtomicBool>,
    epoch: Instant,
    /// The last problem reported on stderr (a hash), so a lasting one is said once.
    reported: AtomicU64,
}

/// The values the control holds for one axis, as far as we know (read or written Good).
#[derive(Debug, Clone, Copy)]
struct Held {
    k0_mm: f64,
    tan_beta: f64,
    /// P0 confirmed (written Good or no P0 node).
    p0_ok: bool,
}

impl Writer {
    fn now_s(&self) -> f64 {
        self.epoch.elapsed().as_secs_f64()
    }

    fn say(&self, what: &str) {
        use std::hash::{Hash, Hasher};
        let mut h = std::collections::hash_map::DefaultHasher::new();
        what.hash(&mut h);
        if self.reported.swap(h.finish(), Ordering::Relaxed) != h.finish() {
            eprintln!("{}: {what}", self.config.connection.endpoint);
        }
    }

    fn run(self) {
        let rt = match tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
        {
            Ok(rt) => rt,
            Err(e) => {
                self.status
                    .set_lost(0.0, format!("cannot start the OPC UA runtime: {e}"));
                return;
            }
        };
        rt.block_on(self.sessions());
    }

    async fn sessions(&self) {
        let conn = &self.config.connection;
        let mut backoff = Backoff::new(conn.backoff);
        let timeout = Duration::from_millis(conn.timeout_ms);
        while !self.stop.load(Ordering::Relaxed) {
            match connect(conn, &self.identity).await {
                Err(why) => {
                    self.say(&why);
                    self.status.set_lost(self.now_s(), why);
                    self.tried.store(true, Ordering::Release);
                    self.sleep(backoff.next_delay()).await;
                }
                Ok(mut open) => {
                    backoff.reset();
                    self.lock_stats().sessions += 1;
                    self.status
                        .set_connected(self.now_s(), format!("session open on {}", conn.endpoint));
                    self.tried.store(true, Ordering::Release);
                    self.reported.store(0, Ordering::Relaxed);
                    let why = self.write_loop(&open).await;
                    let ended = open.ended(conn).await;
                    open.close(timeout).await;
                    let why = match (why, ended) {
                        (Some(w), Some(r)) => Some(format!("{w}: {r}")),
                        (why, _) => why,
                    };
                    if let Some(why) = why {
                        self.say(&why);
                        self.status.set_lost(self.now_s(), why);
                        self.sleep(backoff.next_delay()).await;
                    }
                }
            }
        }
    }

    async fn sleep(&self, d: Duration) {
        let end = Instant::now() + d;
        while !self.stop.load(Ordering::Relaxed) && Instant::now() < end {
            tokio::time::sleep(Duration::from_millis(20).min(end - Instant::now())).await;
        }
    }

    fn lock_stats(&self) -> std::sync::MutexGuard<'_, WriteStats> {
        self.stats.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// The values the control holds now; a node that cannot be read counts as 0 (a control's
    /// power-on value), so the first writes ramp from there.
    async fn read_held(&self, open: &Open) -> Vec<Held> {
        let ids: Vec<ReadValueId> = self
            .axes
            .iter()
            .flat_map(|a| [Some(&a.k0), a.tan_beta.as_ref()])
            .map(|n| ReadValueId::from(n.cloned().unwrap_or_else(NodeId::null)))
            .collect();
        let values = open
            .session
            .read(&ids, TimestampsToReturn::Neither, 0.0)
            .await
            .unwrap_or_default();
        let num = |i: usize| -> f64 {
            values
                .get(i)
                .filter(|v| v.status.is_none_or(|s| s.is_good()))
                .and_then(|v| v.value.as_ref())
                .and_then(|v| match v {
                    Variant::Double(x) => Some(*x),
                    Variant::Float(x) => Some(f64::from(*x)),
                    _ => None,
                })
                .filter(|x| x.is_finite())
                .unwrap_or(0.0)
        };
        self.axes
            .iter()
            .enumerate()
            .map(|(k, a)| Held {
                k0_mm: num(2 * k),
                tan_beta: if a.tan_beta.is_some() {
                    num(2 * k + 1)
                } else {
                    0.0
                },
                p0_ok: a.p0.is_none(),
            })
            .collect()
    }

    fn snapshot(&self, cells: &mut [f64]) -> Option<Snapshot> {
        let seq = self.latest.read(cells)?;
        if seq == 0 {
            return None;
        }
        let [o, p, t, op] = self.layout;
        Some(Snapshot {
            time_s: cells[0],
            state: STATE_CODES[(cells[1] as usize).min(3)],
            offsets_um: cells[o..p].to_vec(),
            positions: cells[p..t].to_vec(),
            temperatures_c: cells[t..op].to_vec(),
            operating: cells[op..].to_vec(),
        })
    }

    /// Writes at the configured rate until the session is lost (`Some(why)`) or the sink stops.
    async fn write_loop(&self, open: &Open) -> Option<String> {
        let conn = &self.config.connection;
        let period = Duration::from_secs_f64(1.0 / self.config.rate_hz);
        let dt = period.as_secs_f64();
        let timeout = Duration::from_millis(conn.timeout_ms);
        let mut held = self.read_held(open).await;
        let mut ticker = tokio::time::interval(period);
        // A late write is not followed by a burst: the next one waits a full period.
        ticker.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
        let mut cells = vec![0.0; self.latest_len()];
        let lims: Vec<(usize, AxisLimits)> = self.axes.iter().map(|a| (a.axis, a.lim)).collect();
        loop {
            ticker.tick().await;
            if self.stop.load(Ordering::Relaxed) {
                return None;
            }
            if open.lost() {
                return Some("the session was lost".into());
            }
            let Some(snap) = self.snapshot(&mut cells) else {
                continue;
            };
            let targets = form::target(&self.machine, self.model.as_ref(), &snap, &lims);
            let (values, what) = self.planned_writes(&held, &targets, &snap, dt);
            self.lock_stats().writes += 1;
            let sent = Instant::now();
            let answer = tokio::time::timeout(timeout, open.session.write(&values)).await;
            let results = match answer {
                Err(_) => {
                    let why = format!(
                        "a write got no answer within {} ms; the values are not taken as applied",
                        conn.timeout_ms
                    );
                    self.say(&why);
                    self.status.set_failing(self.now_s(), why);
                    continue;
                }
                Ok(Err(e)) => return Some(format!("a write failed: {e}")),
                Ok(Ok(r)) => r,
            };
            self.lock_stats()
                .round_trips_ms
                .push(sent.elapsed().as_secs_f64() * 1e3);
            let bad = self.take_answers(&mut held, &what, &values, &results);
            match bad {
                Some(why) => {
                    self.say(&why);
                    self.status.set_failing(self.now_s(), why);
                }
                None => {
                    self.lock_stats().good += 1;
                    if self.status.snapshot().failing {
                        self.status
                            .set_delivering(self.now_s(), "writes taken again".into());
                    }
                    self.reported.store(0, Ordering::Relaxed);
                }
            }
        }
    }

    /// This period's writes, with what each is (axis, part, value): per axis the target line
    /// limited by the envelope and the control's rate from what the control holds — or, until
    /// the control holds our P0, only P0, since K0 means the compensation at P0.
    fn planned_writes(
        &self,
        held: &[Held],
        targets: &[Ends],
        snap: &Snapshot,
        dt: f64,
    ) -> (Vec<WriteValue>, Vec<(usize, Part, f64)>) {
        let mut values = Vec::new();
        let mut what = Vec::new();
        for (k, a) in self.axes.iter().enumerate() {
            if !held[k].p0_ok {
                values.push(write_value(&a.p0, a.lim.p0_mm, a.value_type));
                what.push((k, Part::P0, a.lim.p0_mm));
                continue;
            }
            let applied = Ends::from_written(
                &Written {
                    k0_mm: held[k].k0_mm,
                    tan_beta: held[k].tan_beta,
                    p0_mm: a.lim.p0_mm,
                },
                &a.lim,
            );
            let mut want = targets[k];
            if a.tan_beta.is_none() {
                let p = snap.positions[a.axis];
                want = Ends::constant(if p.is_finite() {
                    want.at(&a.lim, p)
                } else {
                    0.5 * (want.lo_um + want.hi_um)
                });
            }
            let w = want.limited(&applied, &a.lim, dt).written(&a.lim);
            values.push(write_value(&Some(a.k0.clone()), w.k0_mm, a.value_type));
            what.push((k, Part::K0, w.k0_mm));
            if a.tan_beta.is_some() {
                values.push(write_value(&a.tan_beta, w.tan_beta, a.value_type));
                what.push((k, Part::TanBeta, w.tan_beta));
            }
        }
        (values, what)
    }

    /// Takes the control's answer to a write: a value whose node answered Good is what the
    /// control holds now; a refused one is not. Returns the first refusal, said for a person.
    fn take_answers(
        &self,
        held: &mut [Held],
        what: &[(usize, Part, f64)],
        values: &[WriteValue],
        results: &[StatusCode],
    ) -> Option<String> {
        let mut bad = None;
        for (i, &(k, part, v)) in what.iter().enumerate() {
            let s = results
                .get(i)
                .copied()
                .unwrap_or(StatusCode::BadUnexpectedError);
            if s.is_good() {
                match part {
                    Part::P0 => held[k].p0_ok = true,
                    Part::K0 => held[k].k0_mm = v,
                    Part::TanBeta => held[k].tan_beta = v,
                }
            } else if bad.is_none() {
                bad = Some(format!(
                    "axis {}: writing {} to {} refused: {}",
                    self.axes[k].name,
                    part.name(),
                    values[i].node_id,
                    describe(s)
                ));
            }
        }
        bad
    }

    fn latest_len(&self) -> usize {
        self.layout[3] + self.machine.operating.len()
    }
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Part {
    K0,
    TanBeta,
    P0,
}

impl Part {
    fn name(self) -> &'static str {
        match self {
            Part::K0 => "K0",
            Part::TanBeta => "tanβ",
            Part::P0 => "P0",
        }
    }
}

fn write_value(node: &Option<NodeId>, v: f64, t: ValueType) -> WriteValue {
    let value = match t {
        ValueType::Double => Variant::Double(v),
        ValueType::Float => Variant::Float(v as f32),
    };
    WriteValue {
        node_id: node.clone().unwrap_or_else(NodeId::null),
        attribute_id: AttributeId::Value as u32,
        index_range: NumericRange::None,
        value: DataValue::value_only(value),
    }
}
