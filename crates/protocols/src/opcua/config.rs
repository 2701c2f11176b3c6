//! The TOML configurations of the OPC UA sink and source: the connection (endpoint, security,
//! identity, trust list) they share, the sink's per-axis node mapping and the source's channels,
//! checked and resolved against the machine before anything connects.

use std::path::{Path, PathBuf};

use serde::Deserialize;

use crate::channel::channel_config;
use truepos_files::InputError;
use truepos_model::{AxisKind, Machine};
use truepos_runtime::sources::{check_unique_targets, load_toml_file, BackoffConfig, Target};

/// OPC UA security policies the client offers.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
pub enum Policy {
    /// No signing, no encryption (a test bench; a control's write realm should refuse it).
    None,
    /// `Basic256Sha256`: RSA-2048 with SHA-256 signatures, AES-256 encryption.
    Basic256Sha256,
}

/// OPC UA message security modes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
pub enum Mode {
    /// Messages neither signed nor encrypted (only with policy `None`).
    None,
    /// Messages signed.
    Sign,
    /// Messages signed and encrypted.
    SignAndEncrypt,
}

/// How to reach the server and who the client is (shared by the sink and the source).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Connection {
    /// The server's endpoint URL, `opc.tcp://host:port[/path]`.
    pub endpoint: String,
    /// `None` or `Basic256Sha256` (default).
    #[serde(default = "default_policy")]
    pub security_policy: Policy,
    /// `None`, `Sign` or `SignAndEncrypt` (default).
    #[serde(default = "default_mode")]
    pub security_mode: Mode,
    /// The client's PKI directory, relative to the configuration file: the client's own
    /// certificate (`own/cert.der`, `private/private.pem`, made on first use when missing) and
    /// the trust list `trusted/` of server certificates (DER); a server whose certificate is not
    /// there is refused and its certificate put into `rejected/` for a person to inspect.
    pub pki_dir: PathBuf,
    /// User name (with `password` or `password_env`).
    #[serde(default)]
    pub user: Option<String>,
    /// The password, in the file (prefer `password_env`).
    #[serde(default)]
    pub password: Option<String>,
    /// The environment variable holding the password.
    #[serde(default)]
    pub password_env: Option<String>,
    /// Connect without a user: only when the mapping says so (a control that takes anonymous
    /// writes takes them from anyone on its network).
    #[serde(default)]
    pub anonymous: bool,
    /// Deadline of one request (connect, read, write) in ms, 10–60 000 (default 1000).
    #[serde(default = "default_timeout_ms")]
    pub timeout_ms: u64,
    /// Reconnection waits after a lost session.
    #[serde(default)]
    pub backoff: BackoffConfig,
}

fn default_policy() -> Policy {
    Policy::Basic256Sha256
}
fn default_mode() -> Mode {
    Mode::SignAndEncrypt
}
fn default_timeout_ms() -> u64 {
    1000
}

/// Who the session authenticates as.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Identity {
    /// No user (configured explicitly).
    Anonymous,
    /// User name and password.
    User(String, String),
}

impl Connection {
    /// Checks the connection settings; `dir` is the configuration file's directory (the PKI
    /// directory is relative to it). Returns the identity to authenticate with.
    pub fn check(&mut self, dir: &Path) -> Result<Identity, InputError> {
        let url = self.endpoint.strip_prefix("opc.tcp://").unwrap_or("");
        let host_port = url.split('/').next().unwrap_or("");
        if host_port
            .rsplit_once(':')
            .is_none_or(|(h, p)| h.is_empty() || p.parse::<u16>().is_err())
        {
            return Err(InputError::at_key(
                "endpoint",
                format!(
                    "expected opc.tcp://host:port[/path], found `{}`",
                    self.endpoint
                ),
            ));
        }
        match (self.security_policy, self.security_mode) {
            (Policy::None, Mode::None) | (Policy::Basic256Sha256, Mode::Sign | Mode::SignAndEncrypt) => {}
            (p, m) => {
                return Err(InputError::at_key(
                    "security_mode",
                    format!("expected `None` with policy None and `Sign` or `SignAndEncrypt` with Basic256Sha256, found {m:?} with {p:?}"),
                ))
            }
        }
        if !(10..=60_000).contains(&self.timeout_ms) {
            return Err(InputError::at_key(
                "timeout_ms",
                format!("expected 10–60 000 ms, found {}", self.timeout_ms),
            ));
        }
        self.backoff.check("backoff")?;
        if self.pki_dir.is_relative() {
            self.pki_dir = dir.join(&self.pki_dir);
        }
        let password = match (&self.password, &self.password_env) {
            (Some(p), None) => Some(p.clone()),
            (None, Some(var)) => Some(std::env::var(var).map_err(|_| {
                InputError::at_key(
                    "password_env",
                    format!("the environment variable `{var}` is not set"),
                )
            })?),
            (None, None) => None,
            (Some(_), Some(_)) => {
                return Err(InputError::at_key(
                    "password",
                    "expected `password` or `password_env`, not both",
                ))
            }
        };
        match (&self.user, password, self.anonymous) {
            (Some(u), Some(p), false) if !u.is_empty() => Ok(Identity::User(u.clone(), p)),
            (None, None, true) => Ok(Identity::Anonymous),
            (Some(_), _, true) | (_, Some(_), true) => Err(InputError::at_key(
                "anonymous",
                "expected either a user and password or `anonymous = true`, not both",
            )),
            _ => Err(InputError::at_key(
                "user",
                "expected `user` with `password` or `password_env` (anonymous sessions only with `anonymous = true`)",
            )),
        }
    }
}

/// The OPC UA data type a node is written as.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Default)]
pub enum ValueType {
    /// 64-bit float (SINUMERIK setting data, TwinCAT LREAL).
    #[default]
    Double,
    /// 32-bit float (PLC REAL).
    Float,
}

/// One axis' nodes (configuration, TOML).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AxisNodes {
    /// The machine axis.
    pub axis: String,
    /// Node of K0, the compensation at P0 (mm; SD43900).
    pub k0: String,
    /// Node of tanβ, mm per mm (SD43910); without it the form is a constant K0.
    #[serde(default)]
    pub tan_beta: Option<String>,
    /// Node of P0, mm (SD43920), written with `p0_mm` once per session.
    #[serde(default)]
    pub p0: Option<String>,
    /// P0, the reference position the form is written for, mm (default 0).
    #[serde(default)]
    pub p0_mm: f64,
    /// The control's own rate limit of the compensation, µm/s (SINUMERIK MD32760): no write
    /// moves the compensation anywhere on the travel by more than this × the write period.
    pub max_rate_um_per_s: f64,
    /// The data type of the nodes (default `Double`).
    #[serde(default, rename = "type")]
    pub value_type: ValueType,
}

/// A sink's request deadline at most, ms: a write the control has not confirmed by then is a
/// failed sink, said within a second of it (a stale compensation on a warming machine must not
/// go unannounced for longer).
pub const SINK_TIMEOUT_LIMIT_MS: u64 = 5_000;

/// The OPC UA sink (configuration, TOML).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SinkConfig {
    /// How to reach the control.
    #[serde(flatten)]
    pub connection: Connection,
    /// Writes per second, 0.1–10 (default 10: SINUMERIK samples no faster than every 100 ms).
    #[serde(default = "default_rate_hz")]
    pub rate_hz: f64,
    /// The axes written.
    #[serde(default)]
    pub axis: Vec<AxisNodes>,
}

fn default_rate_hz() -> f64 {
    10.0
}

channel_config! {
/// One node feeding one machine channel (configuration, TOML). Give exactly one of
/// `temperature`, `axis` or `operating`.
pub struct ChannelNode {
    ..feeds,
    /// The node, e.g. `ns=2;s=/Channel/MachineAxis/actToolBasePos[u1,1]`.
    pub node: String,
    /// value = raw × scale + offset (defaults 1 and 0).
    #[serde(default = "one")]
    pub scale: f64,
    /// See `scale`.
    #[serde(default)]
    pub offset: f64,
}
}

fn one() -> f64 {
    1.0
}

/// The OPC UA source (configuration, TOML).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SourceConfig {
    /// How to reach the control.
    #[serde(flatten)]
    pub connection: Connection,
    /// Read period in ms, 100–60 000 (default 100: SINUMERIK samples no faster).
    #[serde(default = "default_sample_ms")]
    pub sample_ms: u64,
    /// The nodes read.
    #[serde(default)]
    pub channel: Vec<ChannelNode>,
}

fn default_sample_ms() -> u64 {
    100
}

fn dir_of(path: &Path) -> &Path {
    path.parent()
        .filter(|d| !d.as_os_str().is_empty())
        .unwrap_or(Path::new("."))
}

/// A node id as the configuration gives it: `ns=<n>;s=<string>` or `ns=<n>;i=<number>`.
pub fn check_node(text: &str, key: &str) -> Result<(), InputError> {
    let ok = text.split_once(';').is_some_and(|(ns, id)| {
        ns.strip_prefix("ns=")
            .is_some_and(|n| n.parse::<u16>().is_ok())
            && (id.strip_prefix("s=").is_some_and(|s| !s.is_empty())
                || id
                    .strip_prefix("i=")
                    .is_some_and(|i| i.parse::<u32>().is_ok()))
    });
    if ok {
        Ok(())
    } else {
        Err(InputError::at_key(
            key,
            format!("expected a node id `ns=<n>;s=<name>` or `ns=<n>;i=<number>`, found `{text}`"),
        ))
    }
}

/// The sink's axes resolved against the machine: (machine axis index, nodes).
pub type ResolvedAxes = Vec<(usize, AxisNodes)>;

impl SinkConfig {
    /// Reads and checks a sink mapping; errors name the file and the key.
    pub fn load(
        path: &Path,
        machine: &Machine,
    ) -> Result<(Self, Identity, ResolvedAxes), InputError> {
        let mut c: Self = load_toml_file(path, "OPC UA sink mapping")?;
        let (identity, axes) = c
            .check(dir_of(path), machine)
            .map_err(|e| e.in_file(path, "opcua"))?;
        Ok((c, identity, axes))
    }

    /// Checks a parsed mapping; `dir` is its file's directory.
    pub fn check(
        &mut self,
        dir: &Path,
        machine: &Machine,
    ) -> Result<(Identity, ResolvedAxes), InputError> {
        let identity = self.connection.check(dir)?;
        if self.connection.timeout_ms > SINK_TIMEOUT_LIMIT_MS {
            return Err(InputError::at_key(
                "timeout_ms",
                format!(
                    "expected at most {SINK_TIMEOUT_LIMIT_MS} ms for a sink (the control holds its \
                     last compensation while a write waits), found {}",
                    self.connection.timeout_ms
                ),
            ));
        }
        if !(self.rate_hz.is_finite() && (0.1..=10.0).contains(&self.rate_hz)) {
            return Err(InputError::at_key(
                "rate_hz",
                format!("expected 0.1–10 writes per second, found {}", self.rate_hz),
            ));
        }
        if self.axis.is_empty() {
            return Err(InputError::at_key(
                "axis",
                "expected at least one [[axis]] naming the nodes of an axis",
            ));
        }
        let mut out = Vec::new();
        for (i, a) in self.axis.iter().enumerate() {
            let key = format!("axis[{}]", i + 1);
            let index = machine.axis_index(&a.axis).ok_or_else(|| {
                let names: Vec<&str> = machine.axes.iter().map(|x| x.name.as_str()).collect();
                InputError::at_key(
                    format!("{key}.axis"),
                    format!(
                        "expected an axis of machine `{}` ({}), found `{}`",
                        machine.name,
                        names.join(", "),
                        a.axis
                    ),
                )
            })?;
            if machine.axes[index].kind != AxisKind::Linear {
                return Err(InputError::at_key(
                    format!("{key}.axis"),
                    format!("expected a linear axis; `{}` is rotary", a.axis),
                ));
            }
            if out.iter().any(|(j, _)| *j == index) {
                return Err(InputError::at_key(
                    format!("{key}.axis"),
                    format!("axis `{}` is mapped twice", a.axis),
                ));
            }
            check_node(&a.k0, &format!("{key}.k0"))?;
            if let Some(n) = &a.tan_beta {
                check_node(n, &format!("{key}.tan_beta"))?;
            }
            if let Some(n) = &a.p0 {
                check_node(n, &format!("{key}.p0"))?;
            }
            if !(a.p0_mm.is_finite() && a.p0_mm.abs() <= 1e5) {
                return Err(InputError::at_key(
                    format!("{key}.p0_mm"),
                    format!(
                        "expected a finite position within ±100 000 mm, found {}",
                        a.p0_mm
                    ),
                ));
            }
            if !(a.max_rate_um_per_s.is_finite()
                && a.max_rate_um_per_s > 0.0
                && a.max_rate_um_per_s <= 1e6)
            {
                return Err(InputError::at_key(
                    format!("{key}.max_rate_um_per_s"),
                    format!(
                        "expected a rate above 0 and at most 10⁶ µm/s, found {}",
                        a.max_rate_um_per_s
                    ),
                ));
            }
            out.push((index, a.clone()));
        }
        Ok((identity, out))
    }
}

impl SourceConfig {
    /// Reads and checks a source configuration; errors name the file and the key.
    pub fn load(
        path: &Path,
        machine: &Machine,
    ) -> Result<(Self, Identity, Vec<Target>), InputError> {
        let mut c: Self = load_toml_file(path, "OPC UA source configuration")?;
        let (identity, targets) = c
            .check(dir_of(path), machine)
            .map_err(|e| e.in_file(path, "opcua"))?;
        Ok((c, identity, targets))
    }

    /// Checks a parsed configuration; `dir` is its file's directory.
    pub fn check(
        &mut self,
        dir: &Path,
        machine: &Machine,
    ) -> Result<(Identity, Vec<Target>), InputError> {
        let identity = self.connection.check(dir)?;
        if !(100..=60_000).contains(&self.sample_ms) {
            return Err(InputError::at_key(
                "sample_ms",
                format!("expected 100–60 000 ms, found {}", self.sample_ms),
            ));
        }
        if self.channel.is_empty() {
            return Err(InputError::at_key(
                "channel",
                "expected at least one [[channel]] mapping a node to a machine channel",
            ));
        }
        let mut targets = Vec::new();
        let mut keys = Vec::new();
        for (i, c) in self.channel.iter().enumerate() {
            let key = format!("channel[{}]", i + 1);
            targets.push(c.target(machine, &key)?);
            check_node(&c.node, &format!("{key}.node"))?;
            for (k, v) in [("scale", c.scale), ("offset", c.offset)] {
                if !v.is_finite() || (k == "scale" && v == 0.0) {
                    return Err(InputError::at_key(
                        format!("{key}.{k}"),
                        format!(
                            "expected a finite{} number, found {v}",
                            if k == "scale" { ", non-zero" } else { "" }
                        ),
                    ));
                }
            }
            keys.push(key);
        }
        check_unique_targets(&targets, &keys)?;
        Ok((identity, targets))
    }
}
