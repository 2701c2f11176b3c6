//! The cycle's side of the OPC UA sink and source allocates nothing, locks nothing and reports
//! an unreachable server on every call — while their threads try to connect beside it.

use std::path::Path;
use std::time::{Duration, Instant};

use truepos_protocols::opcua::{OpcUaSink, OpcUaSource, SinkConfig, SourceConfig};
use truepos_runtime::{Frame, LinkError, Output, Sink, Source};

const CONN: &str = "endpoint = \"opc.tcp://127.0.0.1:1\"\nsecurity_policy = \"None\"\nsecurity_mode = \"None\"\nanonymous = true\ntimeout_ms = 200\n";

#[test]
fn the_cycle_side_allocates_nothing() {
    let repo = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let machine = truepos_io::machine_file::load(&repo.join("examples/vmc3/machine.toml")).unwrap();
    let m = &machine.machine;
    let pki = std::env::temp_dir().join(format!("truepos-opcua-noalloc-{}", std::process::id()));
    let text = format!(
        "{CONN}pki_dir = \"{}\"\n[[axis]]\naxis = \"X\"\nk0 = \"ns=2;s=k0\"\ntan_beta = \"ns=2;s=tb\"\nmax_rate_um_per_s = 5.0\n",
        pki.display()
    );
    let mut cfg: SinkConfig = toml::from_str(&text).unwrap();
    let (identity, axes) = cfg.check(Path::new("."), m).unwrap();
    let mut sink = OpcUaSink::start(&cfg, identity, &axes, &machine, None).unwrap();
    let text = format!(
        "{CONN}pki_dir = \"{}\"\n[[channel]]\naxis = \"X\"\nnode = \"ns=2;s=x\"\n",
        pki.display()
    );
    let mut cfg: SourceConfig = toml::from_str(&text).unwrap();
    let (identity, targets) = cfg.check(Path::new("."), m).unwrap();
    let mut source = OpcUaSource::start(&cfg, identity, targets, Instant::now()).unwrap();

    let mut frame = Frame::new(m.temperatures.len(), m.axes.len(), m.operating.len());
    let mut output = Output::zero(m.axes.len());
    // Until the first attempt is over; then every call says why.
    let end = Instant::now() + Duration::from_secs(10);
    while sink.write_cycle(&output, &frame).is_ok() && Instant::now() < end {
        std::thread::sleep(Duration::from_millis(10));
    }
    let counted = allocation_counter::measure(|| {
        for k in 0..10_000 {
            output.time_s = k as f64 * 0.001;
            frame.time_s = output.time_s;
            assert!(
                matches!(sink.write_cycle(&output, &frame), Err(LinkError::Disconnected(why)) if !why.is_empty())
            );
            assert!(matches!(
                source.read(&mut frame),
                Err(LinkError::Disconnected(_))
            ));
        }
    });
    assert_eq!(counted.count_total, 0);
    assert!(frame.positions[0].is_nan(), "a value from nowhere");
    drop(sink);
    drop(source);
    std::fs::remove_dir_all(&pki).ok();
}
