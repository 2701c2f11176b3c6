//! A fleet's load on a broker: N simulated machines, each sending what a truepos service sends
//! (`truepos run --mqtt`), for the fleet benchmark (`scripts/fleet_bench.sh`, docs/fleet.md).
//!
//! Every machine is one MQTT connection of its own (client id and Sparkplug edge node
//! `sim-00001`, …) on one thread with a small stack: CONNECT with its NDEATH as will, the
//! service's NBIRTH (the log's columns with aliases, `birth_payload`), then one NDATA a second
//! (`unit_payload`, QoS 1) with the min/mean/max of every column of a second of a real log,
//! payload and metric timestamps set to the time of sending, so that a store's
//! `received_at - t` is the latency from publish to row. The machines' seconds are spread
//! evenly over the second, as independent machines' clocks are. At the end each sends its
//! NDEATH and disconnects, as a stopping service does.
//!
//! ```sh
//! truepos run --fast --source replay:examples/vmc3/run.csv --log run.sqlite --duration-s 600
//! cargo run --release -p truepos-fleet --example fleet_load -- \
//!     --mqtt mqtt://127.0.0.1:1883 --log run.sqlite --machines 1000 --duration-s 60
//! ```
//!
//! Prints one line of JSON on stdout: messages sent and acknowledged, connections that failed,
//! how late the machines sent (the generator's own lag), and the window of the data's times.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use truepos_fleet::mqtt::{BrokerUrl, Connection, Incoming, Will};
use truepos_fleet::publisher::{birth_payload, unit_payload};
use truepos_fleet::sparkplug::{self, MessageType, Metric, Payload, Value};
use truepos_fleet::store::{LogReader, Second, Unit};

struct Options {
    broker: BrokerUrl,
    log: std::path::PathBuf,
    machines: usize,
    duration_s: f64,
    ramp_s: f64,
    group: String,
}

fn options() -> Result<Options, String> {
    let mut broker = None;
    let mut log = None;
    let (mut machines, mut duration_s, mut ramp_s) = (1000usize, 60.0f64, None);
    let mut group = "fleetbench".to_string();
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        let mut value = || args.next().ok_or(format!("{a} needs a value"));
        match a.as_str() {
            "--mqtt" => broker = Some(BrokerUrl::parse(&value()?)?),
            "--log" => log = Some(value()?.into()),
            "--machines" => machines = value()?.parse().map_err(|e| format!("--machines: {e}"))?,
            "--duration-s" => {
                duration_s = value()?
                    .parse()
                    .map_err(|e| format!("--duration-s: {e}"))?
            }
            "--ramp-s" => ramp_s = Some(value()?.parse().map_err(|e| format!("--ramp-s: {e}"))?),
            "--group" => group = value()?,
            _ => return Err(format!("unknown option {a}: give --mqtt URL --log LOG [--machines N] [--duration-s D] [--ramp-s R] [--group G]")),
        }
    }
    Ok(Options {
        broker: broker.ok_or("--mqtt URL is required")?,
        log: log
            .ok_or("--log LOG (a service's log: its columns and seconds are sent) is required")?,
        machines: machines.max(1),
        duration_s,
        // Connections are opened over the ramp, 500 a second unless given.
        ramp_s: ramp_s.unwrap_or(machines as f64 / 500.0),
        group,
    })
}

fn now_ms() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_millis() as u64)
}

#[derive(Default)]
struct Counters {
    connected: AtomicU64,
    failed: AtomicU64,
    sent: AtomicU64,
    acked: AtomicU64,
    bytes: AtomicU64,
    /// Sends more than 100 ms after their machine's second began (the generator fell behind).
    late: AtomicU64,
    max_lag_ms: AtomicU64,
    first_ms: AtomicU64,
    last_ms: AtomicU64,
}

struct Machine {
    index: usize,
    node: String,
    columns: Vec<String>,
    seconds: Arc<Vec<Second>>,
    counters: Arc<Counters>,
    errors: Arc<Mutex<Vec<String>>>,
}

impl Machine {
    fn run(self, o: &Options, connect_at: Instant, start: Instant, end: Instant) {
        if let Err(e) = self.session(o, connect_at, start, end) {
            self.counters.failed.fetch_add(1, Ordering::Relaxed);
            if let Ok(mut l) = self.errors.lock() {
                if l.len() < 5 {
                    l.push(format!("{}: {e}", self.node));
                }
            }
        }
    }

    fn session(
        &self,
        o: &Options,
        connect_at: Instant,
        start: Instant,
        end: Instant,
    ) -> Result<(), String> {
        std::thread::sleep(connect_at.saturating_duration_since(Instant::now()));
        let group = &o.group;
        let death = |bd: u8| {
            Payload {
                timestamp_ms: now_ms(),
                seq: None,
                metrics: vec![Metric::new("bdSeq", Value::UInt64(u64::from(bd)))],
            }
            .encode()
        };
        let topic_death = sparkplug::topic(group, MessageType::NDeath, &self.node);
        let topic_data = sparkplug::topic(group, MessageType::NData, &self.node);
        let will = death(0);
        let mut conn = Connection::connect(
            &o.broker,
            &format!("truepos-{group}-{}", self.node),
            10,
            Will {
                topic: &topic_death,
                payload: &will,
            },
            Duration::from_secs(10),
        )?;
        let birth = birth_payload(0, &self.node, "model.json", &self.columns, now_ms()).encode();
        conn.publish(
            &sparkplug::topic(group, MessageType::NBirth, &self.node),
            1,
            &birth,
        )?;
        self.counters.connected.fetch_add(1, Ordering::Relaxed);
        let mut unacked: u64 = 1;
        // The broker drops a connection silent for 1.5 keep-alives: during the ramp a machine
        // pings, as a service's publisher does when it has nothing to send.
        let mut last_send = Instant::now();
        let mut incoming = Vec::new();
        // This machine's seconds begin at its phase within the second.
        let phase = Duration::from_secs_f64(self.index as f64 / o.machines as f64);
        let mut next = start + phase;
        let (mut seq, mut id, mut k) = (0u64, 1u16, self.index * 7);
        while next < end {
            // Until this machine's next second: read acknowledgements.
            while Instant::now() < next {
                if last_send.elapsed() >= Duration::from_secs(5) {
                    conn.ping()?;
                    last_send = Instant::now();
                }
                let wait = next
                    .saturating_duration_since(Instant::now())
                    .min(Duration::from_secs(1));
                conn.poll(wait, &mut incoming)?;
                for p in incoming.drain(..) {
                    if let Incoming::PubAck(_) = p {
                        unacked = unacked.saturating_sub(1);
                        self.counters.acked.fetch_add(1, Ordering::Relaxed);
                    }
                }
            }
            let lag = Instant::now().saturating_duration_since(next).as_millis() as u64;
            if lag > 100 {
                self.counters.late.fetch_add(1, Ordering::Relaxed);
            }
            self.counters.max_lag_ms.fetch_max(lag, Ordering::Relaxed);
            seq = (seq + 1) % 256;
            id = id.checked_add(1).unwrap_or(1);
            let second = Unit::Second(self.seconds[k % self.seconds.len()].clone());
            k += 1;
            let t = now_ms();
            let payload = unit_payload(&second, self.columns.len(), t, seq, false, t).encode();
            conn.publish(&topic_data, id, &payload)?;
            last_send = Instant::now();
            unacked += 1;
            self.counters.sent.fetch_add(1, Ordering::Relaxed);
            self.counters
                .bytes
                .fetch_add(payload.len() as u64, Ordering::Relaxed);
            self.counters.first_ms.fetch_min(t, Ordering::Relaxed);
            self.counters.last_ms.fetch_max(t, Ordering::Relaxed);
            next += Duration::from_secs(1);
        }
        // A clean stop: the last acknowledgements, NDEATH, DISCONNECT.
        let deadline = Instant::now() + Duration::from_secs(5);
        conn.publish(&topic_death, id.checked_add(1).unwrap_or(1), &death(0))?;
        unacked += 1;
        while unacked > 0 && Instant::now() < deadline {
            conn.poll(Duration::from_millis(100), &mut incoming)?;
            for p in incoming.drain(..) {
                if let Incoming::PubAck(_) = p {
                    unacked -= 1;
                    self.counters.acked.fetch_add(1, Ordering::Relaxed);
                }
            }
        }
        conn.disconnect();
        Ok(())
    }
}

fn main() {
    let o = match options() {
        Ok(o) => Arc::new(o),
        Err(e) => {
            eprintln!("fleet_load: {e}");
            std::process::exit(2);
        }
    };
    let reader = LogReader::open(&o.log).unwrap_or_else(|e| {
        eprintln!("fleet_load: {e}");
        std::process::exit(2)
    });
    let columns = reader.columns().to_vec();
    let seconds = reader.seconds(0, true, 3600).unwrap_or_else(|e| {
        eprintln!("fleet_load: {e}");
        std::process::exit(2)
    });
    if seconds.is_empty() {
        eprintln!("fleet_load: {} holds no second of cycles", o.log.display());
        std::process::exit(2);
    }
    let seconds = Arc::new(seconds);
    let counters = Arc::new(Counters {
        first_ms: AtomicU64::new(u64::MAX),
        ..Counters::default()
    });
    let errors = Arc::new(Mutex::new(Vec::new()));
    let t0 = Instant::now();
    let start = t0 + Duration::from_secs_f64(o.ramp_s + 1.0);
    let end = start + Duration::from_secs_f64(o.duration_s);
    let mut threads = Vec::with_capacity(o.machines);
    for index in 0..o.machines {
        let m = Machine {
            index,
            node: format!("sim-{:05}", index + 1),
            columns: columns.clone(),
            seconds: Arc::clone(&seconds),
            counters: Arc::clone(&counters),
            errors: Arc::clone(&errors),
        };
        let connect_at = t0 + Duration::from_secs_f64(o.ramp_s * index as f64 / o.machines as f64);
        let o = Arc::clone(&o);
        let t = std::thread::Builder::new()
            .name(m.node.clone())
            .stack_size(128 * 1024)
            .spawn(move || m.run(&o, connect_at, start, end));
        match t {
            Ok(t) => threads.push(t),
            Err(e) => {
                eprintln!("fleet_load: thread {index}: {e}");
                counters.failed.fetch_add(1, Ordering::Relaxed);
            }
        }
    }
    for t in threads {
        let _ = t.join();
    }
    let c = &counters;
    let get = |a: &AtomicU64| a.load(Ordering::Relaxed);
    let sent = get(&c.sent);
    let errors = errors.lock().map(|e| e.clone()).unwrap_or_default();
    println!(
        "{}",
        serde_json::json!({
            "machines": o.machines,
            "connected": get(&c.connected),
            "failed": get(&c.failed),
            "ndata_sent": sent,
            "acknowledged": get(&c.acked),
            "payload_bytes_per_ndata": get(&c.bytes).checked_div(sent).unwrap_or(0),
            "late_sends": get(&c.late),
            "max_lag_ms": get(&c.max_lag_ms),
            "first_ms": get(&c.first_ms),
            "last_ms": get(&c.last_ms),
            "columns": columns.len(),
            "errors": errors,
        })
    );
}
