//! The Modbus client and source against a misbehaving server on loopback (a few lines of
//! std::net written here, since a real server does not misbehave on request): silence,
//! answers that do not match the request, a NaN float.

use std::io::{ErrorKind, Read, Write};
use std::net::{SocketAddr, TcpListener};
use std::path::Path;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use truepos_protocols::modbus::{
    Addressing, Encoding, ModbusChannelConfig, ModbusClient, ModbusConfig, ModbusError,
    ModbusSource, RegisterKind, WordOrder,
};
use truepos_runtime::sources::{BackoffConfig, LinkEventKind};
use truepos_runtime::{LinkError, Source};

// One support module with the runtime's tests: the example machine, a source read into a frame.
#[path = "../../runtime/tests/support/mod.rs"]
mod support;
use support::{frame_for, machine, read, wait_until};

type Answer = fn(&[u8; 12]) -> Option<Vec<u8>>;

/// A loopback server answering every 12-byte request with `answer` (or not at all).
struct FakeServer {
    address: SocketAddr,
    connections: Arc<AtomicU64>,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

impl FakeServer {
    fn start(answer: Answer) -> Self {
        let listener = TcpListener::bind("127.0.0.1:0").unwrap();
        listener.set_nonblocking(true).unwrap();
        let address = listener.local_addr().unwrap();
        let stop = Arc::new(AtomicBool::new(false));
        let connections = Arc::new(AtomicU64::new(0));
        let (s, c) = (Arc::clone(&stop), Arc::clone(&connections));
        let thread = std::thread::spawn(move || {
            let end = Instant::now() + Duration::from_secs(60);
            while !s.load(Ordering::SeqCst) && Instant::now() < end {
                let mut stream = match listener.accept() {
                    Ok((stream, _)) => stream,
                    Err(e) if e.kind() == ErrorKind::WouldBlock => {
                        std::thread::sleep(Duration::from_millis(5));
                        continue;
                    }
                    Err(e) => panic!("accept: {e}"),
                };
                c.fetch_add(1, Ordering::SeqCst);
                stream.set_nonblocking(false).unwrap();
                stream
                    .set_read_timeout(Some(Duration::from_millis(10)))
                    .unwrap();
                let mut request = [0u8; 12];
                let mut have = 0;
                while !s.load(Ordering::SeqCst) && Instant::now() < end {
                    match stream.read(&mut request[have..]) {
                        Ok(0) => break,
                        Ok(n) => have += n,
                        Err(e)
                            if matches!(e.kind(), ErrorKind::WouldBlock | ErrorKind::TimedOut) =>
                        {
                            continue
                        }
                        Err(_) => break,
                    }
                    if have == 12 {
                        have = 0;
                        if let Some(bytes) = answer(&request) {
                            if stream.write_all(&bytes).is_err() {
                                break;
                            }
                        }
                    }
                }
            }
        });
        Self {
            address,
            connections,
            stop,
            thread: Some(thread),
        }
    }
}

impl Drop for FakeServer {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// A correct answer to a read of `count` registers, all with `value`.
fn registers(request: &[u8; 12], value: [u16; 2]) -> Vec<u8> {
    let count = u16::from_be_bytes([request[10], request[11]]);
    let mut out = vec![request[0], request[1], 0, 0];
    out.extend_from_slice(&(3 + 2 * count).to_be_bytes());
    out.extend_from_slice(&[request[6], request[7], (2 * count) as u8]);
    for i in 0..count {
        out.extend_from_slice(&value[usize::from(i % 2)].to_be_bytes());
    }
    out
}

fn silent(_: &[u8; 12]) -> Option<Vec<u8>> {
    None
}

fn wrong_transaction(request: &[u8; 12]) -> Option<Vec<u8>> {
    let mut a = registers(request, [0x00F1, 0x00F1]);
    a[1] = a[1].wrapping_add(1);
    Some(a)
}

fn huge_length(request: &[u8; 12]) -> Option<Vec<u8>> {
    Some(vec![request[0], request[1], 0, 0, 0xFF, 0xFF, 1, 3])
}

fn nan_float(request: &[u8; 12]) -> Option<Vec<u8>> {
    Some(registers(request, [0x7FC0, 0x0000]))
}

fn config(address: SocketAddr, encoding: Encoding) -> ModbusConfig {
    ModbusConfig {
        address: address.to_string(),
        poll_ms: 20,
        timeout_ms: 150,
        addressing: Addressing::ZeroBased,
        backoff: BackoffConfig {
            initial_ms: 20,
            max_ms: 100,
        },
        channels: vec![ModbusChannelConfig {
            temperature: Some("ambient".into()),
            axis: None,
            operating: None,
            unit: 1,
            function: RegisterKind::Input,
            register: 0,
            encoding,
            word_order: WordOrder::HighFirst,
        }],
    }
}

#[test]
fn a_silent_server_times_out() {
    let server = FakeServer::start(silent);
    let mut client = ModbusClient::connect(server.address, Duration::from_millis(100)).unwrap();
    let t = Instant::now();
    let e = client
        .read_registers(1, RegisterKind::Holding, 0, 1)
        .unwrap_err();
    assert!(t.elapsed() < Duration::from_secs(2));
    assert_eq!(
        e,
        ModbusError::Io("no answer within 100 ms (timeout)".into())
    );
    assert!(!e.keeps_connection());
}

#[test]
fn mismatched_or_oversized_answers_are_protocol_errors() {
    let server = FakeServer::start(wrong_transaction);
    let mut client = ModbusClient::connect(server.address, Duration::from_millis(500)).unwrap();
    let e = client
        .read_registers(1, RegisterKind::Input, 0, 2)
        .unwrap_err();
    assert_eq!(
        e,
        ModbusError::Protocol("expected transaction 1, found 2".into())
    );
    let server = FakeServer::start(huge_length);
    let mut client = ModbusClient::connect(server.address, Duration::from_millis(500)).unwrap();
    let e = client
        .read_registers(1, RegisterKind::Input, 0, 2)
        .unwrap_err();
    assert_eq!(
        e,
        ModbusError::Protocol("expected an MBAP length of 2 to 254, found 65535".into())
    );
}

#[test]
fn the_source_reconnects_after_protocol_errors_and_stays_stale() {
    let server = FakeServer::start(wrong_transaction);
    let m = machine();
    let epoch = Instant::now();
    let mut source =
        ModbusSource::start(&config(server.address, Encoding::Int16Tenths), &m, epoch).unwrap();
    let mut frame = frame_for(&m);
    // Every answer is refused, so the connection is dropped and made again, with backoff.
    assert!(wait_until(Duration::from_secs(5), || server
        .connections
        .load(Ordering::SeqCst)
        >= 3));
    match read(&mut source, &mut frame, epoch) {
        Err(LinkError::Disconnected(_)) | Ok(()) => {}
        other => panic!("{other:?}"),
    }
    let amb = m.temperature_index("ambient").unwrap();
    assert!(frame.temperatures_c[amb].is_nan());
    assert_eq!(frame.temperature_stamp_s[amb], truepos_runtime::NEVER);
    let events = source.link().drain_events();
    assert!(events.iter().any(|e| e.kind == LinkEventKind::Lost
        && e.message
            .ends_with("registers 0–0: expected transaction 1, found 2")));
}

#[test]
fn a_nan_float_is_published_as_nan_and_reported_once() {
    let server = FakeServer::start(nan_float);
    let m = machine();
    let epoch = Instant::now();
    let mut source =
        ModbusSource::start(&config(server.address, Encoding::Float32), &m, epoch).unwrap();
    let mut frame = frame_for(&m);
    let amb = m.temperature_index("ambient").unwrap();
    // The value is stamped (the module answered) but NaN, so validation rejects it.
    assert!(wait_until(Duration::from_secs(5), || {
        read(&mut source, &mut frame, epoch).is_ok() && frame.temperature_stamp_s[amb] > 0.0
    }));
    assert!(frame.temperatures_c[amb].is_nan());
    std::thread::sleep(Duration::from_millis(100));
    let bad: Vec<_> = source
        .link()
        .drain_events()
        .into_iter()
        .filter(|e| e.kind == LinkEventKind::BadData)
        .collect();
    assert_eq!(bad.len(), 1, "{bad:?}");
    assert!(
        bad[0].message.ends_with(
            "unit 1 register 0: expected a finite float32, found 0x7FC00000 (NaN or infinity)"
        ),
        "{}",
        bad[0].message
    );
}

#[test]
fn configuration_errors_name_the_key_and_the_expectation() {
    let m = machine();
    let mut c = config("127.0.0.1:502".parse().unwrap(), Encoding::Float32);
    c.addressing = Addressing::OneBased;
    let e = c.resolve(&m).unwrap_err();
    assert_eq!(e.key.as_deref(), Some("modbus.channel[1].register"));
    assert_eq!(
        e.message,
        "expected a register number from 1 to 65535 (1-based addressing, 2 register(s)), found 0"
    );
    c.addressing = Addressing::ZeroBased;
    c.channels[0].register = 65535;
    let e = c.resolve(&m).unwrap_err();
    assert!(e.message.contains("from 0 to 65534"), "{e}");
    c.channels[0].register = 65534;
    let (targets, spans) = c.resolve(&m).unwrap();
    assert_eq!(targets.len(), 1);
    assert_eq!(spans, [(1, RegisterKind::Input, 65534, 2)]);
    c.poll_ms = 0;
    assert_eq!(
        c.resolve(&m).unwrap_err().key.as_deref(),
        Some("modbus.poll_ms")
    );
    let e = ModbusConfig::load(Path::new("/nonexistent/modbus.toml")).unwrap_err();
    assert_eq!(e.file, Path::new("/nonexistent/modbus.toml"));
    assert!(
        e.message
            .starts_with("cannot read the Modbus source configuration"),
        "{e}"
    );
}

fn ambient_24_1(request: &[u8; 12]) -> Option<Vec<u8>> {
    Some(registers(request, [0x00F1, 0x00F1]))
}

/// `read` runs on the cycle: it must not allocate, connected or not (only the first read of an
/// outage carries its reason).
#[test]
fn reading_allocates_nothing() {
    let server = FakeServer::start(ambient_24_1);
    let m = machine();
    let epoch = Instant::now();
    let mut source =
        ModbusSource::start(&config(server.address, Encoding::Int16Tenths), &m, epoch).unwrap();
    let mut frame = frame_for(&m);
    let amb = m.temperature_index("ambient").unwrap();
    assert!(wait_until(Duration::from_secs(5), || {
        read(&mut source, &mut frame, epoch).is_ok() && frame.temperatures_c[amb] == 24.1
    }));
    // A value newer than the frame's clock reading gets the frame's time.
    frame.time_s = 0.0;
    source.read(&mut frame).unwrap();
    assert_eq!(frame.temperature_stamp_s[amb], 0.0);
    let counted = allocation_counter::measure(|| {
        for _ in 0..10_000 {
            assert!(read(&mut source, &mut frame, epoch).is_ok());
        }
    });
    assert_eq!(counted.count_total, 0);
    drop(server);
    assert!(wait_until(Duration::from_secs(5), || read(
        &mut source,
        &mut frame,
        epoch
    )
    .is_err()));
    let counted = allocation_counter::measure(|| {
        for _ in 0..10_000 {
            assert!(matches!(
                read(&mut source, &mut frame, epoch),
                Err(LinkError::Disconnected(why)) if !why.is_empty()
            ));
        }
    });
    assert_eq!(counted.count_total, 0);
}
