//! The Modbus TCP client and source against a real Modbus TCP server: pymodbus
//! (`scripts/modbus_server.py`) in the repository's Python environment, started by each test on
//! loopback. `scripts/setup_python.sh` installs it (`.ci/run` calls it); without it these tests
//! fail — they never skip.

use std::net::{SocketAddr, TcpListener, TcpStream};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use truepos_protocols::modbus::{
    decode, Addressing, Encoding, ModbusChannelConfig, ModbusClient, ModbusConfig, ModbusError,
    ModbusSource, RegisterKind, WordOrder,
};
use truepos_runtime::sources::{BackoffConfig, LinkEventKind};
use truepos_runtime::{LinkError, NEVER};

// One support module with the runtime's tests: the example machine, a source read into a frame.
#[path = "../../runtime/tests/support/mod.rs"]
mod support;
use support::{frame_for, machine, messages, read, repo, wait_until};

/// A free loopback port: bind, read the port, close.
fn free_port() -> u16 {
    TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

/// The pymodbus server of `scripts/modbus_server.py` on a loopback port, killed when dropped.
struct Server {
    child: Child,
    port: u16,
}

impl Server {
    fn start(port: u16) -> Self {
        let python = repo(".venv/bin/python");
        assert!(
            python.exists(),
            "{} is missing: run scripts/setup_python.sh (it installs pymodbus in .venv)",
            python.display()
        );
        let child = Command::new(&python)
            .arg(repo("scripts/modbus_server.py"))
            .arg(port.to_string())
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap_or_else(|e| panic!("cannot start {}: {e}", python.display()));
        let mut server = Self { child, port };
        // Wait (at most 20 s) until the server accepts connections.
        let end = Instant::now() + Duration::from_secs(20);
        loop {
            if TcpStream::connect_timeout(&server.address(), Duration::from_millis(200)).is_ok() {
                return server;
            }
            if let Ok(Some(status)) = server.child.try_wait() {
                let mut err = String::new();
                if let Some(mut e) = server.child.stderr.take() {
                    let _ = std::io::Read::read_to_string(&mut e, &mut err);
                }
                panic!("the Modbus server exited ({status}): {err}");
            }
            assert!(
                Instant::now() < end,
                "the Modbus server did not listen on port {port} within 20 s"
            );
            std::thread::sleep(Duration::from_millis(50));
        }
    }

    fn address(&self) -> SocketAddr {
        SocketAddr::from(([127, 0, 0, 1], self.port))
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

#[test]
fn client_reads_every_encoding_from_a_real_server() {
    let server = Server::start(free_port());
    let mut client = ModbusClient::connect(server.address(), Duration::from_secs(2)).unwrap();
    let r = client
        .read_registers(1, RegisterKind::Holding, 0, 9)
        .unwrap();
    assert_eq!(
        r,
        [0x00F1, 0xFF38, 0x0929, 0xF830, 0x41BC, 0x0000, 0x0000, 0x41BC, 0x1234]
    );
    let hf = WordOrder::HighFirst;
    assert_eq!(decode(Encoding::Int16Tenths, hf, &r[0..1]), Ok(24.1));
    assert_eq!(decode(Encoding::Int16Tenths, hf, &r[1..2]), Ok(-20.0));
    assert_eq!(decode(Encoding::Int16Hundredths, hf, &r[2..3]), Ok(23.45));
    assert_eq!(decode(Encoding::Int16Hundredths, hf, &r[3..4]), Ok(-20.0));
    assert_eq!(decode(Encoding::Float32, hf, &r[4..6]), Ok(23.5));
    assert_eq!(
        decode(Encoding::Float32, WordOrder::LowFirst, &r[6..8]),
        Ok(23.5)
    );
    assert_eq!(decode(Encoding::Uint16, hf, &r[8..9]), Ok(4660.0));
    let r = client.read_registers(1, RegisterKind::Input, 0, 3).unwrap();
    assert_eq!(r, [0x00F2, 0x41AA, 0x0000]);
    // 21.25 = 1.328125 · 2^4: exponent 0x83, mantissa 0x2A0000 → 0x41AA0000.
    assert_eq!(decode(Encoding::Float32, hf, &r[1..3]), Ok(21.25));
    // The counter register grows with every read that covers it.
    let a = client
        .read_registers(1, RegisterKind::Holding, 9, 1)
        .unwrap()[0];
    let b = client
        .read_registers(1, RegisterKind::Holding, 9, 1)
        .unwrap()[0];
    assert_eq!(b, a.wrapping_add(1));
}

#[test]
fn exceptions_carry_their_code_and_keep_the_connection() {
    let server = Server::start(free_port());
    let mut client = ModbusClient::connect(server.address(), Duration::from_secs(2)).unwrap();
    // Holding registers end at address 9: reading 8–11 is an illegal data address (02).
    let e = client
        .read_registers(1, RegisterKind::Holding, 8, 4)
        .unwrap_err();
    assert_eq!(
        e,
        ModbusError::Exception {
            function: 3,
            code: 2
        }
    );
    assert_eq!(
        e.to_string(),
        "exception 02 (illegal data address) to function 03"
    );
    let e = client
        .read_registers(1, RegisterKind::Input, 5, 1)
        .unwrap_err();
    assert_eq!(
        e,
        ModbusError::Exception {
            function: 4,
            code: 2
        }
    );
    // The same connection still answers.
    assert_eq!(
        client.read_registers(1, RegisterKind::Input, 0, 1).unwrap(),
        [0x00F2]
    );
}

fn channel(
    temperature: Option<&str>,
    operating: Option<&str>,
    function: RegisterKind,
    register: u32,
    encoding: Encoding,
    word_order: WordOrder,
) -> ModbusChannelConfig {
    ModbusChannelConfig {
        temperature: temperature.map(String::from),
        axis: None,
        operating: operating.map(String::from),
        unit: 1,
        function,
        register,
        encoding,
        word_order,
    }
}

/// The server's registers with 1-based numbers (protocol address + 1).
fn one_based_config(port: u16) -> ModbusConfig {
    use Encoding::*;
    use RegisterKind::*;
    use WordOrder::*;
    ModbusConfig {
        address: format!("127.0.0.1:{port}"),
        poll_ms: 20,
        timeout_ms: 500,
        addressing: Addressing::OneBased,
        backoff: BackoffConfig {
            initial_ms: 20,
            max_ms: 200,
        },
        channels: vec![
            channel(
                Some("x_slide_top"),
                None,
                Holding,
                1,
                Int16Tenths,
                HighFirst,
            ),
            channel(
                Some("x_slide_bottom"),
                None,
                Holding,
                2,
                Int16Tenths,
                HighFirst,
            ),
            channel(
                Some("y_slide_top"),
                None,
                Holding,
                3,
                Int16Hundredths,
                HighFirst,
            ),
            channel(Some("y_slide_bottom"), None, Holding, 5, Float32, HighFirst),
            channel(Some("z_slide_front"), None, Holding, 7, Float32, LowFirst),
            channel(Some("ambient"), None, Input, 1, Int16Tenths, HighFirst),
            channel(Some("z_slide_rear"), None, Input, 2, Float32, HighFirst),
            channel(None, Some("spindle_rpm"), Holding, 9, Uint16, HighFirst),
            channel(None, Some("x_feed"), Holding, 10, Uint16, HighFirst),
        ],
    }
}

#[test]
fn source_feeds_the_frame_with_one_based_addressing() {
    let server = Server::start(free_port());
    let m = machine();
    let epoch = Instant::now();
    let mut source = ModbusSource::start(&one_based_config(server.port), &m, epoch).unwrap();
    let mut frame = frame_for(&m);
    let t = |id: &str| m.temperature_index(id).unwrap();
    let feed = m.operating_index("x_feed").unwrap();
    assert!(
        wait_until(Duration::from_secs(5), || {
            // Holding and input registers come in two requests: wait for both.
            read(&mut source, &mut frame, epoch).is_ok()
                && frame.operating[feed] > 1.0
                && frame.temperatures_c[t("ambient")] == 24.2
        }),
        "no values: {:?}",
        source.status()
    );
    assert_eq!(frame.temperatures_c[t("x_slide_top")], 24.1);
    assert_eq!(frame.temperatures_c[t("x_slide_bottom")], -20.0);
    assert_eq!(frame.temperatures_c[t("y_slide_top")], 23.45);
    assert_eq!(frame.temperatures_c[t("y_slide_bottom")], 23.5);
    assert_eq!(frame.temperatures_c[t("z_slide_front")], 23.5);
    assert_eq!(frame.temperatures_c[t("ambient")], 24.2);
    assert_eq!(frame.temperatures_c[t("z_slide_rear")], 21.25);
    assert_eq!(
        frame.operating[m.operating_index("spindle_rpm").unwrap()],
        4660.0
    );
    // Unfed channels stay never updated.
    assert_eq!(frame.temperature_stamp_s[t("column_front")], NEVER);
    // Polling goes on: the counter grows and the stamps advance.
    let (count, stamp) = (
        frame.operating[feed],
        frame.temperature_stamp_s[t("ambient")],
    );
    assert!(wait_until(Duration::from_secs(5), || {
        read(&mut source, &mut frame, epoch).is_ok()
            && frame.operating[feed] >= count + 3.0
            && frame.temperature_stamp_s[t("ambient")] > stamp
    }));
    // Two holding blocks are not needed: addresses 0–9 are one read, input 0–2 another.
    let s = source.status();
    assert!(
        s.connected && s.connections == 1 && s.bad_data == 0,
        "{s:?}"
    );
}

#[test]
fn an_exception_leaves_its_channels_unstamped_and_is_reported_once() {
    let server = Server::start(free_port());
    let m = machine();
    let mut config = one_based_config(server.port);
    // Input register 51 (address 50) does not exist on the server: exception 02.
    config.channels.push(channel(
        Some("bed_top"),
        None,
        RegisterKind::Input,
        51,
        Encoding::Int16Tenths,
        WordOrder::HighFirst,
    ));
    let epoch = Instant::now();
    let mut source = ModbusSource::start(&config, &m, epoch).unwrap();
    let mut frame = frame_for(&m);
    let amb = m.temperature_index("ambient").unwrap();
    let bed = m.temperature_index("bed_top").unwrap();
    // A refused block makes the source count as lost, with the exception as the reason; the
    // channels that were answered are still delivered.
    assert!(wait_until(Duration::from_secs(5), || {
        read(&mut source, &mut frame, epoch).is_err() && frame.temperatures_c[amb] == 24.2
    }));
    std::thread::sleep(Duration::from_millis(200)); // ten more polls
    let lost = read(&mut source, &mut frame, epoch).unwrap_err();
    assert!(lost.to_string().contains("exception 02"), "{lost}");
    assert_eq!(frame.temperature_stamp_s[bed], NEVER);
    assert!(frame.temperatures_c[bed].is_nan());
    let events = source.link().drain_events();
    let bad: Vec<&str> = events
        .iter()
        .filter(|e| e.kind == LinkEventKind::BadData)
        .map(|e| e.message.as_str())
        .collect();
    assert_eq!(bad.len(), 1, "reported once while it lasts: {bad:?}");
    assert!(
        bad[0].ends_with("unit 1 function 04 registers 50–50: exception 02 (illegal data address) to function 04"),
        "{}",
        bad[0]
    );
    assert!(source.status().connected);
}

#[test]
fn a_lost_server_makes_the_channels_stale_until_it_is_back() {
    let port = free_port();
    let server = Server::start(port);
    let m = machine();
    let epoch = Instant::now();
    let mut source = ModbusSource::start(&one_based_config(port), &m, epoch).unwrap();
    let mut frame = frame_for(&m);
    let amb = m.temperature_index("ambient").unwrap();
    assert!(wait_until(Duration::from_secs(5), || {
        read(&mut source, &mut frame, epoch).is_ok() && frame.temperatures_c[amb] == 24.2
    }));
    drop(server); // SIGKILL: the connection breaks without a goodbye
    let mut why = None;
    assert!(wait_until(Duration::from_secs(5), || {
        match read(&mut source, &mut frame, epoch) {
            Err(LinkError::Disconnected(w)) => {
                why = Some(w);
                true
            }
            _ => false,
        }
    }));
    let why = why.unwrap();
    assert!(
        why.contains("closed the connection")
            || why.contains("reset")
            || why.contains(&format!("cannot connect to Modbus server 127.0.0.1:{port}")),
        "{why}"
    );
    let stamp = frame.temperature_stamp_s[amb];
    std::thread::sleep(Duration::from_millis(300));
    // Every read while down carries the reason (fixed-size text, no allocation).
    assert!(matches!(
        read(&mut source, &mut frame, epoch),
        Err(LinkError::Disconnected(w)) if !w.is_empty()
    ));
    assert_eq!(frame.temperature_stamp_s[amb], stamp, "stale while lost");
    assert!(source.status().failures >= 2, "retrying with backoff");
    // The server comes back on the same port: the source reconnects by itself.
    let _server = Server::start(port);
    assert!(
        wait_until(Duration::from_secs(10), || {
            read(&mut source, &mut frame, epoch).is_ok() && frame.temperature_stamp_s[amb] > stamp
        }),
        "no reconnection: {:?}",
        source.status()
    );
    assert_eq!(frame.temperatures_c[amb], 24.2);
    assert!(source.status().connections >= 2);
}

/// The TOML block of `docs/network_sources.md` whose first line is `marker`.
fn doc_block(marker: &str) -> String {
    let doc = std::fs::read_to_string(repo("docs/network_sources.md")).unwrap();
    let start = doc
        .find(marker)
        .unwrap_or_else(|| panic!("no `{marker}` block"));
    let end = start + doc[start..].find("```").unwrap();
    doc[start..end].to_string()
}

#[test]
fn the_documented_example_reads_the_server() {
    let server = Server::start(free_port());
    let text = doc_block("# truepos: modbus source")
        .replace("127.0.0.1:5020", &format!("127.0.0.1:{}", server.port));
    let config = ModbusConfig::from_toml(&text).unwrap();
    let m = machine();
    let epoch = Instant::now();
    let mut source = ModbusSource::start(&config, &m, epoch).unwrap();
    let mut frame = frame_for(&m);
    let rpm = m.operating_index("spindle_rpm").unwrap();
    let amb = m.temperature_index("ambient").unwrap();
    assert!(
        wait_until(Duration::from_secs(5), || {
            // Holding and input registers come in two requests: wait for both.
            read(&mut source, &mut frame, epoch).is_ok()
                && frame.operating[rpm] == 4660.0
                && frame.temperatures_c[amb] == 21.25
        }),
        "{:?} {:?}",
        source.status(),
        source.link().drain_events()
    );
    let t = |id: &str| frame.temperatures_c[m.temperature_index(id).unwrap()];
    assert_eq!(t("x_slide_top"), 24.1);
    assert_eq!(t("x_slide_bottom"), 23.45);
    assert_eq!(t("ambient"), 21.25);
}

#[test]
fn a_refused_grouped_read_is_split_into_single_reads() {
    let server = Server::start(free_port());
    let m = machine();
    let mut config = one_based_config(server.port);
    config.addressing = Addressing::ZeroBased;
    // Input registers 0 and 12 are close enough to be read together (0–12), but the server has
    // no registers 3–12: exception 02 to the grouped read. Read one by one, register 0 works.
    config.channels = vec![
        channel(
            Some("ambient"),
            None,
            RegisterKind::Input,
            0,
            Encoding::Int16Tenths,
            WordOrder::HighFirst,
        ),
        channel(
            Some("bed_top"),
            None,
            RegisterKind::Input,
            12,
            Encoding::Int16Tenths,
            WordOrder::HighFirst,
        ),
    ];
    let epoch = Instant::now();
    let mut source = ModbusSource::start(&config, &m, epoch).unwrap();
    let mut frame = frame_for(&m);
    let amb = m.temperature_index("ambient").unwrap();
    let bed = m.temperature_index("bed_top").unwrap();
    assert!(
        wait_until(Duration::from_secs(5), || {
            let _ = read(&mut source, &mut frame, epoch);
            frame.temperatures_c[amb] == 24.2
        }),
        "{:?}",
        source.link().drain_events()
    );
    std::thread::sleep(Duration::from_millis(100));
    let lost = read(&mut source, &mut frame, epoch).unwrap_err();
    assert!(
        lost.to_string().contains("registers 12–12: exception 02"),
        "{lost}"
    );
    assert_eq!(frame.temperature_stamp_s[bed], NEVER);
    let bad = messages(source.link(), LinkEventKind::BadData);
    assert_eq!(bad.len(), 2, "{bad:?}");
    assert!(
        bad[0].ends_with("registers 0–12: exception 02 (illegal data address) to a grouped read; reading its 2 channels one by one"),
        "{}",
        bad[0]
    );
    assert!(
        bad[1].ends_with("registers 12–12: exception 02 (illegal data address) to function 04"),
        "{}",
        bad[1]
    );
}
