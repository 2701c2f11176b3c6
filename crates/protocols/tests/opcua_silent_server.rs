//! A control that accepts the connection and never answers (red team, issue 32): the sink is
//! failed within a second of its request deadline — not silent for as long as the connection
//! library keeps trying.

use std::io::Read;
use std::net::TcpListener;
use std::path::Path;
use std::time::{Duration, Instant};

use truepos_protocols::opcua::{OpcUaSink, SinkConfig};
use truepos_runtime::{Frame, LinkError, Output, Sink};

#[test]
fn a_server_that_never_answers_fails_the_sink_within_a_second_of_its_deadline() {
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let port = listener.local_addr().unwrap().port();
    // Accepts, reads and never answers; ends with the test process.
    std::thread::spawn(move || {
        let mut held = Vec::new();
        for mut conn in listener.incoming().flatten() {
            let mut buf = [0u8; 4096];
            let _ = conn.set_read_timeout(Some(Duration::from_millis(10)));
            let _ = conn.read(&mut buf);
            held.push(conn);
        }
    });
    let repo = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let machine = truepos_io::machine_file::load(&repo.join("examples/vmc3/machine.toml")).unwrap();
    let m = &machine.machine;
    let pki = std::env::temp_dir().join(format!("truepos-opcua-silent-{}", std::process::id()));
    let timeout_ms = 1500;
    let text = format!(
        "endpoint = \"opc.tcp://127.0.0.1:{port}\"\nsecurity_policy = \"None\"\nsecurity_mode = \"None\"\nanonymous = true\ntimeout_ms = {timeout_ms}\npki_dir = \"{}\"\n[[axis]]\naxis = \"X\"\nk0 = \"ns=2;s=k0\"\nmax_rate_um_per_s = 5.0\n",
        pki.display()
    );
    let mut cfg: SinkConfig = toml::from_str(&text).unwrap();
    let (identity, axes) = cfg.check(Path::new("."), m).unwrap();
    let start = Instant::now();
    let mut sink = OpcUaSink::start(&cfg, identity, &axes, &machine, None).unwrap();
    let frame = Frame::new(m.temperatures.len(), m.axes.len(), m.operating.len());
    let output = Output::zero(m.axes.len());
    let failed = loop {
        match sink.write_cycle(&output, &frame) {
            Err(LinkError::Disconnected(why)) => break why,
            Err(e) => panic!("{e:?}"),
            Ok(()) => {}
        }
        assert!(
            start.elapsed() < Duration::from_millis(timeout_ms + 1000 + 300),
            "still no failure after {:?}",
            start.elapsed()
        );
        std::thread::sleep(Duration::from_millis(10));
    };
    assert!(!failed.is_empty());
    // And it stays failed.
    std::thread::sleep(Duration::from_millis(50));
    assert!(sink.write_cycle(&output, &frame).is_err());
    drop(sink);
    std::fs::remove_dir_all(&pki).ok();
}
