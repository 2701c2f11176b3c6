//! The OPC UA configurations: the shipped examples load against the vmc3 machine, every
//! mistake names its file and key with what was expected, and no text makes the parser panic.

use std::path::{Path, PathBuf};

use proptest::prelude::*;
use truepos_model::Machine;
use truepos_protocols::opcua::{Identity, SinkConfig, SourceConfig};

fn repo(p: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..").join(p)
}

fn machine() -> Machine {
    truepos_io::machine_file::load(&repo("examples/vmc3/machine.toml"))
        .unwrap()
        .machine
}

const CONN: &str =
    "endpoint = \"opc.tcp://127.0.0.1:4840\"\npki_dir = \"pki\"\nuser = \"u\"\npassword = \"p\"\n";
const AXIS: &str = "[[axis]]\naxis = \"X\"\nk0 = \"ns=2;s=/NC/_N_AX_SEA_ACX/$SA_TEMP_COMP_ABS_VALUE[u1]\"\nmax_rate_um_per_s = 5.0\n";

fn sink(text: &str) -> Result<(SinkConfig, Identity), String> {
    let mut c: SinkConfig = toml::from_str(text).map_err(|e| e.to_string())?;
    let (id, _) = c
        .check(Path::new("/cfg"), &machine())
        .map_err(|e| e.to_string())?;
    Ok((c, id))
}

#[test]
fn the_examples_load() {
    std::env::set_var("TRUEPOS_OPCUA_PASSWORD", "example");
    let m = machine();
    for f in ["sinumerik_sink.toml", "twincat_sink.toml"] {
        let (c, id, axes) = SinkConfig::load(&repo(&format!("examples/opcua/{f}")), &m).unwrap();
        assert_eq!(id, Identity::User("truepos".into(), "example".into()));
        assert!(!axes.is_empty() && c.rate_hz == 10.0, "{f}");
        assert!(c.connection.pki_dir.ends_with("examples/opcua/pki"), "{f}");
    }
    let (_, _, targets) =
        SourceConfig::load(&repo("examples/opcua/sinumerik_source.toml"), &m).unwrap();
    assert_eq!(targets.len(), 6);
}

#[test]
fn mistakes_name_the_key_and_the_expectation() {
    let cases = [
        (format!("{CONN}rate_hz = 50\n{AXIS}"), "`rate_hz`: expected 0.1–10 writes per second, found 50"),
        (format!("{CONN}timeout_ms = 60000\n{AXIS}"), "`timeout_ms`: expected at most 5000 ms for a sink"),
        (CONN.replace("opc.tcp://127.0.0.1:4840", "http://x"), "`endpoint`: expected opc.tcp://host:port"),
        (format!("{}{AXIS}", CONN.replace("user = \"u\"\npassword = \"p\"\n", "")), "`user`: expected `user` with `password` or `password_env` (anonymous sessions only with `anonymous = true`)"),
        (format!("{CONN}anonymous = true\n{AXIS}"), "`anonymous`: expected either a user and password or `anonymous = true`, not both"),
        (format!("{CONN}security_policy = \"None\"\n{AXIS}"), "`security_mode`: expected `None` with policy None"),
        (format!("{CONN}{}", AXIS.replace("\"X\"", "\"Q\"")), "`axis[1].axis`: expected an axis of machine `vmc-3axis` (X, Y, Z), found `Q`"),
        (format!("{CONN}{}", AXIS.replace("ns=2;s=", "ns=x;s=")), "`axis[1].k0`: expected a node id"),
        (format!("{CONN}{}", AXIS.replace("5.0", "0.0")), "`axis[1].max_rate_um_per_s`: expected a rate above 0"),
        (format!("{CONN}{AXIS}{AXIS}"), "`axis[2].axis`: axis `X` is mapped twice"),
        (CONN.to_string(), "`axis`: expected at least one [[axis]]"),
        (format!("{CONN}{AXIS}colour = 1\n"), "unknown field `colour`"),
    ];
    for (text, want) in cases {
        let e = sink(&text).unwrap_err();
        assert!(e.contains(want), "{e}\nwanted: {want}\n{text}");
    }
    // The file, line and column of a TOML mistake.
    let dir = std::env::temp_dir().join(format!("truepos-opcua-config-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let f = dir.join("bad.toml");
    std::fs::write(&f, format!("{CONN}rate_hz = \"fast\"\n{AXIS}")).unwrap();
    let e = SinkConfig::load(&f, &machine()).unwrap_err().to_string();
    assert!(e.contains("bad.toml:5:11: `rate_hz`: invalid type"), "{e}");
    std::fs::write(
        &f,
        format!("{CONN}sample_ms = 10\n[[channel]]\naxis = \"X\"\nnode = \"ns=2;s=a\"\n"),
    )
    .unwrap();
    let e = SourceConfig::load(&f, &machine()).unwrap_err().to_string();
    let line = CONN.lines().count() + 1;
    assert!(
        e.contains(&format!(
            "bad.toml:{line}:1: `sample_ms`: expected 100–60 000 ms, found 10"
        )),
        "{e}"
    );
    std::fs::write(&f, format!("{CONN}[[channel]]\naxis = \"X\"\nnode = \"ns=2;s=a\"\n[[channel]]\naxis = \"X\"\nnode = \"ns=2;s=b\"\n")).unwrap();
    let e = SourceConfig::load(&f, &machine()).unwrap_err().to_string();
    assert!(
        e.contains(&format!(
            "bad.toml:{}:1: `channel[2]`",
            CONN.lines().count() + 4
        )) && e.contains("feeds the same one"),
        "{e}"
    );
    std::fs::remove_dir_all(&dir).ok();
}

proptest! {
    /// Any text — random, or a valid mapping with a character replaced — gives a mapping or an
    /// error, never a panic; whatever is accepted passes the checks' own bounds.
    #[test]
    fn no_text_makes_the_mapping_parser_panic(
        noise in ".{0,200}",
        at in 0usize..400,
        c in proptest::char::any(),
    ) {
        let _ = sink(&noise);
        let mut valid: Vec<char> = format!("{CONN}rate_hz = 5\n{AXIS}").chars().collect();
        let i = at % valid.len();
        valid[i] = c;
        let text: String = valid.into_iter().collect();
        if let Ok((cfg, _)) = sink(&text) {
            prop_assert!(cfg.rate_hz.is_finite() && (0.1..=10.0).contains(&cfg.rate_hz));
            prop_assert!(cfg.axis.iter().all(|a| a.max_rate_um_per_s > 0.0 && a.p0_mm.is_finite()));
        }
    }
}
