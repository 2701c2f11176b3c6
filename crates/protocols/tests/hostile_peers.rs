//! Hostile network peers on loopback, each a few lines of std::net written here: MTConnect SHDR
//! adapters that send garbage, drip a line, freeze while still answering `* PING`, or flood
//! `* PONG`; Modbus TCP servers that answer with exceptions, wrong transaction ids, short or
//! oversized frames, or drip an answer. Each source runs inside a `Service` for the example
//! machine and model, beside a well-behaved source for the other channels. For every peer:
//! the reason reaches a `SourceLost` event, memory stays bounded, the output stays finite and
//! within `max_offset_um`, it is never `Active` while the peer's sensors are bad, and dropping
//! the service (and its source thread) takes well under a second whatever the peer is doing.

use std::io::{ErrorKind, Read, Write};
use std::net::{SocketAddr, TcpListener, TcpStream};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use truepos_io::machine_file;
use truepos_io::model_file::position;
use truepos_protocols::modbus::{
    Addressing, Encoding, ModbusChannelConfig, ModbusConfig, ModbusSource, RegisterKind, WordOrder,
};
use truepos_protocols::shdr::{ShdrChannelConfig, ShdrConfig, ShdrSource};
use truepos_runtime::events::EventKind;
use truepos_runtime::model_set::ModelEntry;
use truepos_runtime::sources::BackoffConfig;
use truepos_runtime::*;

// One support module with the runtime's tests: the example machine, a source read into a frame.
#[path = "../../runtime/tests/support/mod.rs"]
mod support;
use support::repo;

/// The channels the hostile peer feeds (the example model reads both).
const PEER_CHANNELS: [&str; 2] = ["x_slide_top", "ambient"];

/// A peer: called once per accepted connection with the stream (blocking, 5 ms read timeout)
/// and the test's stop flag; returns when done with the connection.
type Behaviour = fn(&mut TcpStream, &AtomicBool, &AtomicU64);

/// A loopback server running `behaviour` on each connection until dropped; counts bytes sent.
struct Peer {
    address: SocketAddr,
    sent: Arc<AtomicU64>,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

impl Peer {
    fn start(behaviour: Behaviour) -> Self {
        let listener = TcpListener::bind("127.0.0.1:0").unwrap();
        listener.set_nonblocking(true).unwrap();
        let address = listener.local_addr().unwrap();
        let stop = Arc::new(AtomicBool::new(false));
        let sent = Arc::new(AtomicU64::new(0));
        let (s, b) = (Arc::clone(&stop), Arc::clone(&sent));
        let thread = std::thread::spawn(move || {
            let end = Instant::now() + Duration::from_secs(30);
            while !s.load(Ordering::SeqCst) && Instant::now() < end {
                match listener.accept() {
                    Ok((mut stream, _)) => {
                        stream.set_nonblocking(false).unwrap();
                        stream
                            .set_read_timeout(Some(Duration::from_millis(5)))
                            .unwrap();
                        behaviour(&mut stream, &s, &b);
                    }
                    Err(e) if e.kind() == ErrorKind::WouldBlock => {
                        std::thread::sleep(Duration::from_millis(5))
                    }
                    Err(e) => panic!("accept: {e}"),
                }
            }
        });
        Self {
            address,
            sent,
            stop,
            thread: Some(thread),
        }
    }
}

impl Drop for Peer {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

fn send(stream: &mut TcpStream, bytes: &[u8], sent: &AtomicU64) -> bool {
    let ok = stream.write_all(bytes).is_ok();
    if ok {
        sent.fetch_add(bytes.len() as u64, Ordering::Relaxed);
    }
    ok
}

/// Reads whatever the client sent (5 ms timeout): `Some(text)` (possibly empty), `None` once
/// the client closed the connection.
fn poll_input(stream: &mut TcpStream) -> Option<String> {
    let mut buf = [0u8; 512];
    match stream.read(&mut buf) {
        Ok(0) => None,
        Ok(n) => Some(String::from_utf8_lossy(&buf[..n]).into_owned()),
        Err(e) if matches!(e.kind(), ErrorKind::WouldBlock | ErrorKind::TimedOut) => {
            Some(String::new())
        }
        Err(_) => None,
    }
}

/// The process's resident memory in bytes (Linux).
fn rss_bytes() -> u64 {
    let statm = std::fs::read_to_string("/proc/self/statm").unwrap();
    let pages: u64 = statm.split_whitespace().nth(1).unwrap().parse().unwrap();
    pages * 4096
}

/// A source for every channel the peer does not feed: fixed temperatures and positions.
struct Good {
    skip: Vec<usize>,
}

impl Source for Good {
    fn name(&self) -> &str {
        "good"
    }
    fn read(&mut self, frame: &mut Frame) -> Result<(), LinkError> {
        for c in 0..frame.temperatures_c.len() {
            if !self.skip.contains(&c) {
                frame.set_temperature(c, 22.0 + 0.1 * c as f64);
            }
        }
        for (a, p) in [100.0, 200.0, 300.0].into_iter().enumerate() {
            frame.set_position(a, p);
        }
        Ok(())
    }
}

fn service_with(make: impl FnOnce(&truepos_model::Machine, Instant) -> Box<dyn Source>) -> Run {
    let mut machine = machine_file::load(&repo("examples/vmc3/machine.toml")).unwrap();
    let skip: Vec<usize> = PEER_CHANNELS
        .iter()
        .map(|id| machine.machine.temperature_index(id).unwrap())
        .collect();
    // Values the peer stops confirming are refused quickly, so that a test sees it.
    for &c in &skip {
        machine.sensor_checks[c].max_age_s = 0.3;
    }
    let model = ModelEntry {
        name: "vmc".into(),
        model: position::load(&repo("examples/vmc3/model.toml"), &machine.machine)
            .unwrap()
            .into(),
        index: [101, 102, 103],
    };
    let epoch = Instant::now();
    let peer = make(&machine.machine, epoch);
    let limits: Vec<f64> = machine.axes.iter().map(|a| a.max_offset_um).collect();
    let service = Service::new(
        machine,
        vec![model],
        vec![Box::new(Good { skip: skip.clone() }), peer],
        vec![],
        ServiceConfig::default(),
    );
    Run {
        service,
        epoch,
        skip,
        limits,
        reasons: Vec::new(),
        active_cycles: 0,
    }
}

/// A service running with a hostile peer as source 1.
struct Run {
    service: Service,
    epoch: Instant,
    skip: Vec<usize>,
    limits: Vec<f64>,
    /// Reasons of the peer's `SourceLost` events, in order.
    reasons: Vec<String>,
    active_cycles: u64,
}

impl Run {
    /// Runs 2 ms cycles for `duration`, checking the output on every one.
    fn cycles(&mut self, duration: Duration) {
        let end = Instant::now() + duration;
        while Instant::now() < end {
            let now = self.epoch.elapsed().as_secs_f64();
            let out = *self.service.cycle(now);
            for (a, (&v, &limit)) in out.offsets().iter().zip(&self.limits).enumerate() {
                assert!(v.is_finite(), "axis {a}: offset {v} at {now} s");
                assert!(
                    v.abs() <= limit + 1e-9,
                    "axis {a}: offset {v} beyond {limit}"
                );
            }
            let health = self.service.validator().health();
            let peer_bad = self.skip.iter().any(|&c| health[c].is_some());
            if out.state == CompensationState::Active {
                assert!(!peer_bad, "Active at {now} s with the peer's sensors bad");
                self.active_cycles += 1;
            }
            let q = self.service.events();
            while let Some(e) = q.pop() {
                if let EventKind::SourceLost { source: 1, reason } = e.kind {
                    self.reasons.push(reason.to_string());
                }
            }
            std::thread::sleep(Duration::from_millis(2));
        }
    }

    fn reason_with(&self, text: &str) -> bool {
        self.reasons.iter().any(|r| r.contains(text))
    }

    /// Drops the service with its source thread; returns how long that took.
    fn stop(self) -> Duration {
        let t = Instant::now();
        drop(self.service);
        t.elapsed()
    }
}

// ----- MTConnect SHDR adapters -----

fn shdr_config(address: SocketAddr) -> ShdrConfig {
    let channel = |item: &str, t: &str| ShdrChannelConfig {
        data_item: item.into(),
        temperature: Some(t.into()),
        axis: None,
        operating: None,
    };
    ShdrConfig {
        address: address.to_string(),
        connect_timeout_ms: 500,
        ping_ms: 50,
        first_pong_timeout_ms: 1000,
        line_timeout_ms: 300,
        data_timeout_ms: 300,
        backoff: BackoffConfig {
            initial_ms: 50,
            max_ms: 200,
        },
        channels: vec![channel("Txtop", "x_slide_top"), channel("Tamb", "ambient")],
    }
}

fn shdr_run(behaviour: Behaviour) -> (Peer, Run) {
    let peer = Peer::start(behaviour);
    let config = shdr_config(peer.address);
    let run = service_with(|m, epoch| Box::new(ShdrSource::start(&config, m, epoch).unwrap()));
    (peer, run)
}

/// Answers every `* PING` with `* PONG 200`; false once the client has gone.
fn answer_pings(stream: &mut TcpStream, sent: &AtomicU64) -> bool {
    match poll_input(stream) {
        None => false,
        Some(text) => {
            for _ in 0..text.matches("* PING").count() {
                if !send(stream, b"* PONG 200\n", sent) {
                    return false;
                }
            }
            true
        }
    }
}

fn garbage_flood(stream: &mut TcpStream, stop: &AtomicBool, sent: &AtomicU64) {
    let line = [
        b"this is not SHDR at all, no pipes here ".repeat(20),
        b"\n".to_vec(),
    ]
    .concat();
    let block = line.repeat(64); // ≈ 50 KB per write
    while !stop.load(Ordering::SeqCst) {
        if !answer_pings(stream, sent) || !send(stream, &block, sent) {
            return;
        }
    }
}

#[test]
fn shdr_garbage_flood_fails_with_its_reason_and_bounded_memory() {
    let before = rss_bytes();
    let (peer, mut run) = shdr_run(garbage_flood);
    run.cycles(Duration::from_millis(1500));
    let grown = rss_bytes().saturating_sub(before);
    let sent = peer.sent.load(Ordering::Relaxed);
    eprintln!("garbage flood: {sent} bytes sent, RSS grew by {grown} bytes");
    assert!(sent > 2_000_000, "only {sent} bytes of garbage sent");
    assert!(grown < 64 << 20, "RSS grew by {grown} bytes");
    assert!(
        run.reason_with("garbage only (3 lines in a row)") && run.reason_with("no `|` in the line"),
        "{:?}",
        run.reasons
    );
    assert_eq!(run.active_cycles, 0);
    assert_eq!(
        run.service
            .source_reason(1)
            .map(|r| r.contains("garbage only")),
        Some(true)
    );
    let took = run.stop();
    eprintln!("garbage flood: stopped in {took:?}");
    assert!(took < Duration::from_secs(1), "{took:?}");
}

fn drip(stream: &mut TcpStream, stop: &AtomicBool, sent: &AtomicU64) {
    for &b in b"|Txtop|24.1|Tamb|21.0\n".iter().cycle() {
        if stop.load(Ordering::SeqCst) || !send(stream, &[b], sent) {
            return;
        }
        std::thread::sleep(Duration::from_millis(100));
    }
}

#[test]
fn shdr_dripping_adapter_loses_the_connection_on_the_line_deadline() {
    let (_peer, mut run) = shdr_run(drip);
    run.cycles(Duration::from_millis(1200));
    assert!(
        run.reason_with("a line took longer than 300 ms"),
        "{:?}",
        run.reasons
    );
    assert_eq!(run.active_cycles, 0);
    let took = run.stop();
    eprintln!("dripping adapter: stopped in {took:?}");
    assert!(took < Duration::from_secs(1), "{took:?}");
}

fn freeze(stream: &mut TcpStream, stop: &AtomicBool, sent: &AtomicU64) {
    if !send(stream, b"|Txtop|24.1|Tamb|21.0\n", sent) {
        return;
    }
    while !stop.load(Ordering::SeqCst) && answer_pings(stream, sent) {}
}

#[test]
fn shdr_frozen_adapter_answering_pings_fails_and_its_values_go_stale() {
    let (_peer, mut run) = shdr_run(freeze);
    // The values arrive and are confirmed by PONGs until data_timeout_ms (300 ms) without data.
    run.cycles(Duration::from_millis(200));
    assert!(!run.reason_with("sent no data"), "{:?}", run.reasons);
    assert!(run.active_cycles > 0, "the values never became good");
    run.cycles(Duration::from_millis(1300));
    assert!(
        run.reason_with("sent no data for 300 ms while answering `* PING`"),
        "{:?}",
        run.reasons
    );
    // PONGs no longer confirm the values: they went stale, so the output is not Active now.
    let health = run.service.validator().health();
    assert!(run.skip.iter().all(|&c| health[c].is_some()), "{health:?}");
    assert_ne!(run.service.output().state, CompensationState::Active);
    let took = run.stop();
    assert!(took < Duration::from_secs(1), "{took:?}");
}

fn pong_flood(stream: &mut TcpStream, stop: &AtomicBool, sent: &AtomicU64) {
    let block = b"* PONG 1000\n".repeat(4096);
    let _ = send(stream, b"|Txtop|24.1|Tamb|21.0\n", sent);
    while !stop.load(Ordering::SeqCst) && poll_input(stream).is_some() {
        if !send(stream, &block, sent) {
            return;
        }
    }
}

#[test]
fn shdr_pong_flood_ends_the_connection_and_confirms_nothing() {
    let before = rss_bytes();
    let (peer, mut run) = shdr_run(pong_flood);
    run.cycles(Duration::from_millis(1500));
    let grown = rss_bytes().saturating_sub(before);
    eprintln!(
        "PONG flood: {} bytes sent, RSS grew by {grown} bytes",
        peer.sent.load(Ordering::Relaxed)
    );
    assert!(grown < 64 << 20, "RSS grew by {grown} bytes");
    assert!(run.reason_with("(a PONG flood)"), "{:?}", run.reasons);
    let took = run.stop();
    assert!(took < Duration::from_secs(1), "{took:?}");
}

// ----- Modbus TCP servers -----

/// Reads one 12-byte request; `None` once the client has gone or the test stops.
fn request(stream: &mut TcpStream, stop: &AtomicBool) -> Option<[u8; 12]> {
    let mut r = [0u8; 12];
    let mut have = 0;
    while have < 12 {
        if stop.load(Ordering::SeqCst) {
            return None;
        }
        match stream.read(&mut r[have..]) {
            Ok(0) => return None,
            Ok(n) => have += n,
            Err(e) if matches!(e.kind(), ErrorKind::WouldBlock | ErrorKind::TimedOut) => {}
            Err(_) => return None,
        }
    }
    Some(r)
}

/// A well-formed answer to `r`: every register 0x00F1 (24.1 °C in tenths).
fn registers(r: &[u8; 12]) -> Vec<u8> {
    let count = usize::from(u16::from_be_bytes([r[10], r[11]]));
    let mut a = vec![
        r[0],
        r[1],
        0,
        0,
        0,
        (3 + 2 * count) as u8,
        r[6],
        r[7],
        2 * count as u8,
    ];
    for _ in 0..count {
        a.extend_from_slice(&[0x00, 0xF1]);
    }
    a
}

fn modbus_run(behaviour: Behaviour) -> (Peer, Run) {
    let peer = Peer::start(behaviour);
    let channel = |t: &str, register| ModbusChannelConfig {
        temperature: Some(t.into()),
        axis: None,
        operating: None,
        unit: 1,
        function: RegisterKind::Holding,
        register,
        encoding: Encoding::Int16Tenths,
        word_order: WordOrder::HighFirst,
    };
    let config = ModbusConfig {
        address: peer.address.to_string(),
        poll_ms: 20,
        timeout_ms: 150,
        addressing: Addressing::ZeroBased,
        backoff: BackoffConfig {
            initial_ms: 50,
            max_ms: 200,
        },
        channels: vec![channel("x_slide_top", 0), channel("ambient", 1)],
    };
    let run = service_with(|m, epoch| Box::new(ModbusSource::start(&config, m, epoch).unwrap()));
    (peer, run)
}

fn answer_with(
    stream: &mut TcpStream,
    stop: &AtomicBool,
    sent: &AtomicU64,
    f: fn([u8; 12]) -> Vec<u8>,
) {
    while let Some(r) = request(stream, stop) {
        if !send(stream, &f(r), sent) {
            return;
        }
    }
}

fn exception_02(stream: &mut TcpStream, stop: &AtomicBool, sent: &AtomicU64) {
    answer_with(stream, stop, sent, |r| {
        vec![r[0], r[1], 0, 0, 0, 3, r[6], r[7] | 0x80, 0x02]
    });
}

#[test]
fn modbus_exception_on_every_answer_is_a_lost_source_with_the_code_and_range() {
    let (_peer, mut run) = modbus_run(exception_02);
    run.cycles(Duration::from_millis(800));
    assert!(
        run.reason_with("unit 1 function 03 registers 0–0: exception 02 (illegal data address)"),
        "{:?}",
        run.reasons
    );
    assert_eq!(run.active_cycles, 0);
    assert!(run.service.source_reason(1).is_some());
    assert!(run.stop() < Duration::from_secs(1));
}

fn wrong_transaction(stream: &mut TcpStream, stop: &AtomicBool, sent: &AtomicU64) {
    answer_with(stream, stop, sent, |r| {
        let mut a = registers(&r);
        a[1] = a[1].wrapping_add(1);
        a
    });
}

#[test]
fn modbus_wrong_transaction_id_is_reported() {
    let (_peer, mut run) = modbus_run(wrong_transaction);
    run.cycles(Duration::from_millis(600));
    assert!(
        run.reason_with("registers 0–1: expected transaction 1, found 2"),
        "{:?}",
        run.reasons
    );
    assert_eq!(run.active_cycles, 0);
    assert!(run.stop() < Duration::from_secs(1));
}

fn short_frame(stream: &mut TcpStream, stop: &AtomicBool, sent: &AtomicU64) {
    // The header announces the whole answer; only part of it comes, then nothing.
    answer_with(stream, stop, sent, |r| registers(&r)[..10].to_vec());
}

#[test]
fn modbus_short_frame_times_out_naming_what_arrived() {
    let (_peer, mut run) = modbus_run(short_frame);
    run.cycles(Duration::from_millis(800));
    assert!(
        run.reason_with("answer incomplete after 150 ms (timeout; 10 of 13 bytes)"),
        "{:?}",
        run.reasons
    );
    assert_eq!(run.active_cycles, 0);
    assert!(run.stop() < Duration::from_secs(1));
}

fn oversized(stream: &mut TcpStream, stop: &AtomicBool, sent: &AtomicU64) {
    answer_with(stream, stop, sent, |r| {
        let mut a = registers(&r);
        a[4..6].copy_from_slice(&300u16.to_be_bytes());
        a.resize(6 + 300, 0);
        a
    });
}

#[test]
fn modbus_oversized_frame_is_reported() {
    let (_peer, mut run) = modbus_run(oversized);
    run.cycles(Duration::from_millis(600));
    assert!(
        run.reason_with("expected an MBAP length of 2 to 254, found 300"),
        "{:?}",
        run.reasons
    );
    assert_eq!(run.active_cycles, 0);
    assert!(run.stop() < Duration::from_secs(1));
}

fn modbus_drip(stream: &mut TcpStream, stop: &AtomicBool, sent: &AtomicU64) {
    while let Some(r) = request(stream, stop) {
        for b in registers(&r) {
            if stop.load(Ordering::SeqCst) || !send(stream, &[b], sent) {
                return;
            }
            std::thread::sleep(Duration::from_millis(100));
        }
    }
}

/// The user's finding: one byte every 0.4 s kept a per-read timeout from ever firing, and
/// shutdown waited 19 s. One deadline covers the whole answer now.
#[test]
fn modbus_dripping_answer_times_out_and_shutdown_is_prompt() {
    let (_peer, mut run) = modbus_run(modbus_drip);
    run.cycles(Duration::from_millis(700));
    assert!(
        run.reason_with("answer incomplete after 150 ms (timeout"),
        "{:?}",
        run.reasons
    );
    assert_eq!(run.active_cycles, 0);
    let took = run.stop();
    eprintln!("dripping Modbus server: stopped in {took:?}");
    assert!(took < Duration::from_secs(1), "{took:?}");
}

/// A reason that changes while the source stays lost raises a new event (exception → timeout).
fn exception_then_silence(stream: &mut TcpStream, stop: &AtomicBool, sent: &AtomicU64) {
    let t = Instant::now();
    // Exceptions for 300 ms, then no answer at all.
    while let Some(r) = request(stream, stop) {
        let exception = [r[0], r[1], 0, 0, 0, 3, r[6], r[7] | 0x80, 0x04];
        if t.elapsed() < Duration::from_millis(300) && !send(stream, &exception, sent) {
            return;
        }
    }
}

#[test]
fn modbus_changed_reason_raises_a_new_event() {
    let (_peer, mut run) = modbus_run(exception_then_silence);
    run.cycles(Duration::from_millis(900));
    let exception = run
        .reasons
        .iter()
        .position(|r| r.contains("exception 04 (server device failure)"));
    let timeout = run
        .reasons
        .iter()
        .position(|r| r.contains("no answer within 150 ms"));
    assert!(
        matches!((exception, timeout), (Some(e), Some(t)) if e < t),
        "{:?}",
        run.reasons
    );
    assert!(run.stop() < Duration::from_secs(1));
}
