//! The SHDR source against an adapter stand-in: a TCP server on loopback, started by each test,
//! that speaks SHDR lines and answers `* PING` with `* PONG <ms>` (or stops answering, or closes
//! the connection, as the test asks).

use std::io::{ErrorKind, Read, Write};
use std::net::{TcpListener, TcpStream};
use std::path::Path;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use truepos_protocols::shdr::{ShdrChannelConfig, ShdrConfig, ShdrSource};
use truepos_runtime::sources::{BackoffConfig, LinkEventKind, PolledSource};
use truepos_runtime::{Frame, LinkError, Source, NEVER};

// One support module with the runtime's tests: the example machine, a source read into a frame.
#[path = "../../runtime/tests/support/mod.rs"]
mod support;
use support::{frame_for, machine, messages, repo, wait_until};

/// What the adapter stand-in does; the test changes it while it runs.
#[derive(Default)]
struct Behaviour {
    /// Answer `* PING` (with `* PONG <pong_ms>`).
    answer_pings: AtomicBool,
    pong_ms: AtomicU64,
    /// Close the current connection at the next chance.
    drop_connection: AtomicBool,
    /// Lines sent to every new client, one connection after the other (the last one repeats).
    greetings: Mutex<Vec<Vec<String>>>,
    /// Lines to send on the current connection.
    outbox: Mutex<Vec<String>>,
    connections: AtomicU64,
    pings: AtomicU64,
    stop: AtomicBool,
}

/// A loopback SHDR adapter: one client at a time, until dropped.
struct Adapter {
    port: u16,
    behaviour: Arc<Behaviour>,
    thread: Option<JoinHandle<()>>,
}

impl Adapter {
    fn start(pong_ms: u64, greetings: Vec<Vec<&str>>) -> Self {
        let listener = TcpListener::bind("127.0.0.1:0").expect("bind loopback");
        listener.set_nonblocking(true).unwrap();
        let port = listener.local_addr().unwrap().port();
        let behaviour = Arc::new(Behaviour::default());
        behaviour.answer_pings.store(true, Ordering::SeqCst);
        behaviour.pong_ms.store(pong_ms, Ordering::SeqCst);
        *behaviour.greetings.lock().unwrap() = greetings
            .into_iter()
            .map(|g| g.into_iter().map(String::from).collect())
            .collect();
        let b = Arc::clone(&behaviour);
        let thread = std::thread::spawn(move || {
            // Bounded: the test drops the adapter within its own time limits; 60 s is a backstop.
            let end = Instant::now() + Duration::from_secs(60);
            while !b.stop.load(Ordering::SeqCst) && Instant::now() < end {
                match listener.accept() {
                    Ok((stream, _)) => serve(stream, &b, end),
                    Err(e) if e.kind() == ErrorKind::WouldBlock => {
                        std::thread::sleep(Duration::from_millis(5))
                    }
                    Err(e) => panic!("adapter accept: {e}"),
                }
            }
        });
        Self {
            port,
            behaviour,
            thread: Some(thread),
        }
    }

    fn address(&self) -> String {
        format!("127.0.0.1:{}", self.port)
    }

    fn send(&self, line: &str) {
        self.behaviour.outbox.lock().unwrap().push(line.to_string());
    }
}

impl Drop for Adapter {
    fn drop(&mut self) {
        self.behaviour.stop.store(true, Ordering::SeqCst);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

fn serve(mut stream: TcpStream, b: &Behaviour, end: Instant) {
    stream.set_nonblocking(false).unwrap();
    stream
        .set_read_timeout(Some(Duration::from_millis(5)))
        .unwrap();
    let n = b.connections.fetch_add(1, Ordering::SeqCst) as usize;
    b.drop_connection.store(false, Ordering::SeqCst);
    b.outbox.lock().unwrap().clear();
    let greeting = {
        let g = b.greetings.lock().unwrap();
        g.get(n).or(g.last()).cloned().unwrap_or_default()
    };
    for line in greeting {
        if stream.write_all(format!("{line}\n").as_bytes()).is_err() {
            return;
        }
    }
    let mut pending = Vec::new();
    let mut chunk = [0u8; 1024];
    while !b.stop.load(Ordering::SeqCst) && Instant::now() < end {
        if b.drop_connection.load(Ordering::SeqCst) {
            return;
        }
        let out: Vec<String> = b.outbox.lock().unwrap().drain(..).collect();
        for line in out {
            if stream.write_all(format!("{line}\n").as_bytes()).is_err() {
                return;
            }
        }
        match stream.read(&mut chunk) {
            Ok(0) => return,
            Ok(k) => pending.extend_from_slice(&chunk[..k]),
            Err(e) if matches!(e.kind(), ErrorKind::WouldBlock | ErrorKind::TimedOut) => {}
            Err(_) => return,
        }
        while let Some(i) = pending.iter().position(|&c| c == b'\n') {
            let line: Vec<u8> = pending.drain(..=i).collect();
            if line.starts_with(b"* PING") {
                b.pings.fetch_add(1, Ordering::SeqCst);
                if b.answer_pings.load(Ordering::SeqCst) {
                    let pong = format!("* PONG {}\n", b.pong_ms.load(Ordering::SeqCst));
                    if stream.write_all(pong.as_bytes()).is_err() {
                        return;
                    }
                }
            }
        }
    }
}

fn channel(data_item: &str, temperature: Option<&str>, axis: Option<&str>) -> ShdrChannelConfig {
    ShdrChannelConfig {
        data_item: data_item.into(),
        temperature: temperature.map(String::from),
        axis: axis.map(String::from),
        operating: None,
    }
}

fn config(address: String) -> ShdrConfig {
    ShdrConfig {
        address,
        connect_timeout_ms: 500,
        ping_ms: 50,
        first_pong_timeout_ms: 1000,
        line_timeout_ms: 1000,
        data_timeout_ms: 300_000,
        backoff: BackoffConfig {
            initial_ms: 20,
            max_ms: 100,
        },
        channels: vec![
            channel("Xact", None, Some("X")),
            channel("Zact", None, Some("Z")),
            channel("Tx", Some("x_slide_bottom"), None),
            channel("Tamb", Some("ambient"), None),
        ],
    }
}

/// Reads the source into the frame at service time `epoch.elapsed()`, checking that no stamp
/// goes backwards.
fn read(source: &mut PolledSource, frame: &mut Frame, epoch: Instant) -> Result<(), LinkError> {
    frame.time_s = epoch.elapsed().as_secs_f64();
    let before = (
        frame.temperature_stamp_s.clone(),
        frame.position_stamp_s.clone(),
    );
    let result = source.read(frame);
    for (old, new) in before
        .0
        .iter()
        .zip(&frame.temperature_stamp_s)
        .chain(before.1.iter().zip(&frame.position_stamp_s))
    {
        assert!(new >= old, "a stamp went back from {old} to {new}");
        assert!(
            *new <= frame.time_s,
            "stamp {new} after the cycle {}",
            frame.time_s
        );
    }
    result
}

#[test]
fn values_positions_and_unavailable_reach_the_frame() {
    let m = machine();
    let adapter = Adapter::start(
        500,
        vec![vec![
            "* shdrVersion: 2",
            "2024-05-01T10:00:00.000Z|Xact|125.5|Zact|-40.25",
            "2024-05-01T10:00:00.000Z|Tx|24.1|Tamb|UNAVAILABLE|exec|ACTIVE",
        ]],
    );
    let epoch = Instant::now();
    let mut source = ShdrSource::start(&config(adapter.address()), &m, epoch).unwrap();
    assert_eq!(source.name(), format!("shdr {}", adapter.address()));
    let mut frame = frame_for(&m);
    let x = m.axis_index("X").unwrap();
    let z = m.axis_index("Z").unwrap();
    let tx = m.temperature_index("x_slide_bottom").unwrap();
    let amb = m.temperature_index("ambient").unwrap();
    assert!(
        wait_until(Duration::from_secs(5), || {
            // The values arrive one after the other: wait for all of them.
            read(&mut source, &mut frame, epoch).is_ok()
                && frame.temperatures_c[tx] == 24.1
                && frame.positions[x] == 125.5
                && frame.positions[z] == -40.25
        }),
        "no values from the adapter: {:?}",
        source.status()
    );
    assert_eq!(frame.positions[x], 125.5);
    assert_eq!(frame.positions[z], -40.25);
    assert!(frame.position_stamp_s[x] >= 0.0 && frame.position_stamp_s[x] <= frame.time_s);
    // UNAVAILABLE arrives as NaN with a stamp: validation rejects the value, not a missing update.
    assert!(frame.temperatures_c[amb].is_nan());
    assert!(frame.temperature_stamp_s[amb] > NEVER);
    // Channels nobody feeds stay NaN and never updated.
    let y = m.axis_index("Y").unwrap();
    assert!(frame.positions[y].is_nan() && frame.position_stamp_s[y] == NEVER);

    // A new value, a malformed line and a text value for a number channel.
    adapter.send("|Xact|130.0");
    adapter.send("this is not SHDR");
    adapter.send("|Tx|open-circuit");
    assert!(wait_until(Duration::from_secs(5), || {
        read(&mut source, &mut frame, epoch).is_ok()
            && frame.temperatures_c[tx].is_nan()
            && frame.positions[x] == 130.0
    }));
    assert_eq!(frame.positions[x], 130.0);
    let events = source.link().drain_events();
    let bad: Vec<&str> = events
        .iter()
        .filter(|e| e.kind == LinkEventKind::BadData)
        .map(|e| e.message.as_str())
        .collect();
    assert_eq!(bad.len(), 2, "{events:?}");
    assert!(bad[0].contains("found no `|` in the line"), "{}", bad[0]);
    assert!(
        bad[1].contains("data item `Tx`: expected a number or UNAVAILABLE, found `open-circuit`"),
        "{}",
        bad[1]
    );
    assert!(source.status().connected);
}

#[test]
fn heartbeat_confirms_unchanged_values() {
    let m = machine();
    let adapter = Adapter::start(200, vec![vec!["|Tx|22.0|Xact|10"]]);
    let epoch = Instant::now();
    let mut source = ShdrSource::start(&config(adapter.address()), &m, epoch).unwrap();
    let mut frame = frame_for(&m);
    let tx = m.temperature_index("x_slide_bottom").unwrap();
    assert!(wait_until(Duration::from_secs(5), || {
        read(&mut source, &mut frame, epoch).is_ok() && frame.temperatures_c[tx] == 22.0
    }));
    let first = frame.temperature_stamp_s[tx];
    std::thread::sleep(Duration::from_millis(400));
    read(&mut source, &mut frame, epoch).unwrap();
    // PINGs every 50 ms, each PONG confirms the value: the stamp is at most ~50 ms old (allow
    // 250 ms for a loaded machine) although the adapter sent no new data line.
    let later = frame.temperature_stamp_s[tx];
    assert!(later > first + 0.2, "stamp {first} → {later}");
    assert!(
        frame.time_s - later < 0.25,
        "stamp {later} at {}",
        frame.time_s
    );
    assert!(adapter.behaviour.pings.load(Ordering::SeqCst) >= 4);
}

#[test]
fn missing_pong_is_a_lost_connection_and_stamps_stop() {
    let m = machine();
    // The first connection sends the temperature, later ones nothing (until the test says).
    let adapter = Adapter::start(150, vec![vec!["|Tx|23.0"], vec![]]);
    let epoch = Instant::now();
    let mut source = ShdrSource::start(&config(adapter.address()), &m, epoch).unwrap();
    let mut frame = frame_for(&m);
    let tx = m.temperature_index("x_slide_bottom").unwrap();
    assert!(wait_until(Duration::from_secs(5), || {
        read(&mut source, &mut frame, epoch).is_ok() && frame.temperatures_c[tx] == 23.0
    }));
    // The adapter stops answering but keeps the socket open: a hung adapter.
    adapter
        .behaviour
        .answer_pings
        .store(false, Ordering::SeqCst);
    let silent_at = epoch.elapsed().as_secs_f64();
    let mut outage = None;
    assert!(
        wait_until(Duration::from_secs(3), || {
            match read(&mut source, &mut frame, epoch) {
                Err(LinkError::Disconnected(why)) => {
                    outage = Some(why);
                    true
                }
                _ => false,
            }
        }),
        "the client did not notice the missing PONG"
    );
    let noticed_after = epoch.elapsed().as_secs_f64() - silent_at;
    // The announced interval is 150 ms: the loss is noticed after it (plus up to one 50 ms ping
    // period and the 20 ms read slice; 1 s allows for a loaded machine).
    assert!(noticed_after < 1.0, "noticed after {noticed_after} s");
    let why = outage.unwrap();
    assert!(
        why.contains("no `* PONG`") && why.contains("within 150 ms"),
        "{why}"
    );
    // The next reads while down carry the latest reason (fixed-size text, no allocation).
    assert!(matches!(
        read(&mut source, &mut frame, epoch),
        Err(LinkError::Disconnected(w)) if !w.is_empty()
    ));
    // Stamps stand still while the adapter stays silent (the client keeps reconnecting and
    // timing out, since the stand-in still accepts but never answers).
    let stamp = frame.temperature_stamp_s[tx];
    assert!(
        stamp <= silent_at + 0.1,
        "stamp {stamp} after silence at {silent_at}"
    );
    std::thread::sleep(Duration::from_millis(300));
    let _ = read(&mut source, &mut frame, epoch);
    assert_eq!(frame.temperature_stamp_s[tx], stamp);
    // The adapter answers again and sends a new value: the client reconnects and the stamps
    // advance.
    *adapter.behaviour.greetings.lock().unwrap() = vec![vec!["|Tx|23.5".to_string()]];
    adapter.behaviour.answer_pings.store(true, Ordering::SeqCst);
    adapter
        .behaviour
        .drop_connection
        .store(true, Ordering::SeqCst);
    assert!(wait_until(Duration::from_secs(5), || {
        read(&mut source, &mut frame, epoch).is_ok() && frame.temperatures_c[tx] == 23.5
    }));
    assert!(frame.temperature_stamp_s[tx] > stamp);
    let s = source.status();
    assert!(s.connections >= 2 && s.failures >= 1, "{s:?}");
}

#[test]
fn reconnection_keeps_values_of_the_old_connection_stale() {
    let m = machine();
    // First connection: X and the slide temperature; second: X only.
    let adapter = Adapter::start(200, vec![vec!["|Xact|1.0|Tx|21.0"], vec!["|Xact|2.0"]]);
    let epoch = Instant::now();
    let mut source = ShdrSource::start(&config(adapter.address()), &m, epoch).unwrap();
    let mut frame = frame_for(&m);
    let x = m.axis_index("X").unwrap();
    let tx = m.temperature_index("x_slide_bottom").unwrap();
    assert!(wait_until(Duration::from_secs(5), || {
        read(&mut source, &mut frame, epoch).is_ok() && frame.positions[x] == 1.0
    }));
    adapter
        .behaviour
        .drop_connection
        .store(true, Ordering::SeqCst);
    let dropped_at = epoch.elapsed().as_secs_f64();
    assert!(wait_until(Duration::from_secs(5), || {
        read(&mut source, &mut frame, epoch).is_ok() && frame.positions[x] == 2.0
    }));
    std::thread::sleep(Duration::from_millis(200));
    read(&mut source, &mut frame, epoch).unwrap();
    // X was re-sent and is confirmed by the new connection's PONGs; the temperature was not:
    // its value is the old one and its stamp stays before the reconnection.
    assert!(frame.position_stamp_s[x] > dropped_at + 0.1);
    assert_eq!(frame.temperatures_c[tx], 21.0);
    assert!(frame.temperature_stamp_s[tx] <= dropped_at + 0.1);
    let events = source.link().drain_events();
    let kinds: Vec<LinkEventKind> = events.iter().map(|e| e.kind).collect();
    assert_eq!(
        kinds,
        [
            LinkEventKind::Connected,
            LinkEventKind::Lost,
            LinkEventKind::Connected
        ],
        "{events:?}"
    );
    assert!(events[1].message.contains("closed the connection"));
}

#[test]
fn refused_connections_back_off_exponentially() {
    // A port nobody listens on: bind, read the port, close.
    let port = {
        let l = TcpListener::bind("127.0.0.1:0").unwrap();
        l.local_addr().unwrap().port()
    };
    let m = machine();
    let mut c = config(format!("127.0.0.1:{port}"));
    c.backoff = BackoffConfig {
        initial_ms: 50,
        max_ms: 200,
    };
    let epoch = Instant::now();
    let mut source = ShdrSource::start(&c, &m, epoch).unwrap();
    std::thread::sleep(Duration::from_millis(1000));
    let mut frame = frame_for(&m);
    match read(&mut source, &mut frame, epoch) {
        Err(LinkError::Disconnected(why)) => assert!(why.contains("cannot connect"), "{why}"),
        other => panic!("expected Disconnected, got {other:?}"),
    }
    // Attempts at 0, 50, 150, 350, 550, 750, 950 ms (waits 50, 100, 200, 200, …): 7 in 1 s.
    // Without backoff (a retry every 20 ms slice) there would be ~50; allow 4 to 9 for timing.
    let failures = source.status().failures;
    assert!((4..=9).contains(&failures), "{failures} attempts in 1 s");
    assert!(frame.temperature_stamp_s.iter().all(|&s| s == NEVER));
}

#[test]
fn configuration_errors_name_the_key_and_the_expectation() {
    let m = machine();
    let mut c = config("127.0.0.1:7878".into());
    c.channels[2].temperature = Some("x_slide_middle".into());
    let e = c.resolve(&m).unwrap_err();
    assert_eq!(e.key.as_deref(), Some("shdr.channel[3].temperature"));
    assert!(
        e.message.starts_with(
            "expected a temperature channel of machine `vmc-3axis` (x_slide_top, x_slide_bottom"
        ),
        "{e}"
    );
    let mut c = config("127.0.0.1:7878".into());
    c.channels[0].temperature = Some("ambient".into());
    let e = c.resolve(&m).unwrap_err();
    assert_eq!(e.key.as_deref(), Some("shdr.channel[1]"));
    assert!(e.message.contains("exactly one of"), "{e}");
    let mut c = config("127.0.0.1:7878".into());
    c.channels[1].axis = Some("X".into());
    let e = c.resolve(&m).unwrap_err();
    assert_eq!(e.key.as_deref(), Some("shdr.channel[2]"));
    assert!(
        e.message.contains("shdr.channel[1] feeds the same one"),
        "{e}"
    );
    let mut c = config("nowhere".into());
    assert_eq!(
        c.resolve(&m).unwrap_err().key.as_deref(),
        Some("shdr.address")
    );
    c.address = "127.0.0.1:7878".into();
    c.channels.clear();
    assert_eq!(
        c.resolve(&m).unwrap_err().key.as_deref(),
        Some("shdr.channel")
    );
    // TOML as the service's configuration holds it.
    let c = ShdrConfig::from_toml(
        "address = \"127.0.0.1:7878\"\nping_ms = 500\n[backoff]\ninitial_ms = 10\nmax_ms = 1000\n\
         [[channel]]\ndata_item = \"Tspindle\"\ntemperature = \"spindle_front_bearing\"\n",
    )
    .unwrap();
    assert_eq!(c.ping_ms, 500);
    assert_eq!(c.backoff.max_ms, 1000);
    assert_eq!(c.resolve(&m).unwrap().len(), 1);
    let e = ShdrConfig::load(Path::new("/nonexistent/shdr.toml")).unwrap_err();
    assert_eq!(e.file, Path::new("/nonexistent/shdr.toml"));
    assert!(
        e.message
            .starts_with("cannot read the SHDR source configuration"),
        "{e}"
    );
}

#[test]
fn the_documented_example_reads_an_adapter() {
    let doc = std::fs::read_to_string(repo("docs/network_sources.md")).unwrap();
    let start = doc.find("# truepos: shdr source").unwrap();
    let text = &doc[start..start + doc[start..].find("```").unwrap()];
    let adapter = Adapter::start(
        1000,
        vec![vec!["|Xact|12.5|Zact|-3|Tspindle|31.5|Tamb|20.5"]],
    );
    let config =
        ShdrConfig::from_toml(&text.replace("127.0.0.1:7878", &adapter.address())).unwrap();
    let m = machine();
    let epoch = Instant::now();
    let mut source = ShdrSource::start(&config, &m, epoch).unwrap();
    let mut frame = frame_for(&m);
    let amb = m.temperature_index("ambient").unwrap();
    assert!(wait_until(Duration::from_secs(5), || {
        read(&mut source, &mut frame, epoch).is_ok()
            && frame.temperatures_c[amb] == 20.5
            && frame.positions[m.axis_index("X").unwrap()] == 12.5
            && frame.positions[m.axis_index("Z").unwrap()] == -3.0
            && frame.temperatures_c[m.temperature_index("spindle_front_bearing").unwrap()] == 31.5
    }));
    assert_eq!(frame.positions[m.axis_index("X").unwrap()], 12.5);
    assert_eq!(frame.positions[m.axis_index("Z").unwrap()], -3.0);
    assert_eq!(
        frame.temperatures_c[m.temperature_index("spindle_front_bearing").unwrap()],
        31.5
    );
}

/// `read` runs on the cycle: it must not allocate, connected or not (only the first read of an
/// outage carries its reason).
#[test]
fn reading_allocates_nothing() {
    let m = machine();
    let adapter = Adapter::start(200, vec![vec!["|Xact|1.0|Tx|21.0|Tamb|UNAVAILABLE"]]);
    let epoch = Instant::now();
    let mut source = ShdrSource::start(&config(adapter.address()), &m, epoch).unwrap();
    let mut frame = frame_for(&m);
    let tx = m.temperature_index("x_slide_bottom").unwrap();
    assert!(wait_until(Duration::from_secs(5), || {
        source.read(&mut frame).is_ok() && frame.temperatures_c[tx] == 21.0
    }));
    let counted = allocation_counter::measure(|| {
        for _ in 0..10_000 {
            frame.time_s += 0.001;
            assert!(source.read(&mut frame).is_ok());
        }
    });
    assert_eq!(counted.count_total, 0);
    drop(adapter);
    assert!(wait_until(Duration::from_secs(5), || source
        .read(&mut frame)
        .is_err()));
    let counted = allocation_counter::measure(|| {
        for _ in 0..10_000 {
            frame.time_s += 0.001;
            assert!(matches!(
                source.read(&mut frame),
                Err(LinkError::Disconnected(why)) if !why.is_empty()
            ));
        }
    });
    assert_eq!(counted.count_total, 0);
}

/// Multi-line assets (`--multiline--<marker>` … `--multiline--<marker>`) are skipped whole.
#[test]
fn multiline_assets_are_skipped() {
    let m = machine();
    let adapter = Adapter::start(
        500,
        vec![vec![
            "2024-05-01T10:00:00Z|@ASSET@|T1|CuttingTool|--multiline--AAAA",
            "<CuttingTool assetId=\"T1\">",
            "  <Description>an end mill | with a pipe</Description>",
            "</CuttingTool>",
            "--multiline--AAAA",
            "|Tx|25.5",
        ]],
    );
    let epoch = Instant::now();
    let mut source = ShdrSource::start(&config(adapter.address()), &m, epoch).unwrap();
    let mut frame = frame_for(&m);
    let tx = m.temperature_index("x_slide_bottom").unwrap();
    assert!(wait_until(Duration::from_secs(5), || {
        read(&mut source, &mut frame, epoch).is_ok() && frame.temperatures_c[tx] == 25.5
    }));
    assert_eq!(
        source.status().bad_data,
        0,
        "{:?}",
        source.link().drain_events()
    );
}

/// A line longer than 64 KiB is a protocol error: the connection is dropped and made again.
#[test]
fn an_endless_line_ends_the_connection() {
    let m = machine();
    let adapter = Adapter::start(500, vec![vec!["|Tx|22.5"]]);
    let epoch = Instant::now();
    let mut source = ShdrSource::start(&config(adapter.address()), &m, epoch).unwrap();
    let mut frame = frame_for(&m);
    let tx = m.temperature_index("x_slide_bottom").unwrap();
    assert!(wait_until(Duration::from_secs(5), || {
        read(&mut source, &mut frame, epoch).is_ok() && frame.temperatures_c[tx] == 22.5
    }));
    adapter.send(&"x".repeat(70_000));
    assert!(wait_until(Duration::from_secs(5), || source
        .status()
        .connections
        >= 2));
    let lost = messages(source.link(), LinkEventKind::Lost);
    assert_eq!(lost.len(), 1, "{lost:?}");
    assert!(
        lost[0].contains("expected lines of at most 65536 bytes"),
        "{}",
        lost[0]
    );
}
