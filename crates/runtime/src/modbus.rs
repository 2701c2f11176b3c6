//! Modbus TCP temperature modules: a small client for the two read functions such modules
//! answer, the decoding of their register encodings, and a [`Source`] that polls them.
//!
//! References: *MODBUS Application Protocol Specification V1.1b3* (modbus.org, 2012) for the
//! PDUs — function 03 "Read Holding Registers" (§6.3) and 04 "Read Input Registers" (§6.4), 1 to
//! 125 registers per request, exception responses (§7: function code + 0x80 and an exception
//! code) — and *MODBUS Messaging on TCP/IP Implementation Guide V1.0b* (modbus.org, 2006) for the
//! 7-byte MBAP header that precedes a PDU on TCP: transaction id (2 bytes), protocol id (2 bytes,
//! 0 = Modbus), length (2 bytes, the bytes that follow, unit id included) and unit id (1 byte).
//! All 16-bit fields and registers are big-endian.
//!
//! Encodings of a temperature in registers, as modules use them:
//! - `int16-x0.1`: signed 16-bit in tenths of a degree (0x00F1 = 241 → 24.1 °C);
//! - `int16-x0.01`: signed 16-bit in hundredths (0x0929 = 2345 → 23.45 °C);
//! - `uint16`: unsigned 16-bit as is;
//! - `float32`: IEEE 754 single precision over two registers, high word first (Modbus's usual
//!   order, [0x41BC, 0x0000] = 23.5) or low word first ([0x0000, 0x41BC]; many modules swap).
//!
//! Addresses: the protocol carries 0-based register addresses; many module manuals number the
//! registers from 1. With `addressing = "1-based"` register `n` of the manual is protocol
//! address `n − 1`.
//!
//! [`ModbusSource`] polls on its own thread, reading neighbouring registers of a unit in one
//! request (or one by one, if the module refuses such a grouped read with exception 02 because it
//! lacks registers in between). A value is stamped with the service time of the answer that carried it; an
//! exception answer leaves the channels of that request unstamped (reported as bad data, the
//! connection stays); a timeout or a malformed answer ends the connection, and the thread
//! reconnects with backoff ([`crate::reconnect`]) while the stamps stand still.

use std::io::Write;
use std::net::{SocketAddr, TcpStream};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use serde::Deserialize;
use truepos_model::Machine;

use crate::frame::Frame;
use crate::io_traits::{LinkError, SharedChannels, Source};
use crate::reconnect::{
    check_source_config, check_unique_targets, read_exact_until, resolve_address, seconds_since,
    sleep_unless_stopped, stop_thread, Backoff, BackoffConfig, ConfigError, LinkSnapshot,
    LinkStatus, OutageReporter, Target, STOP_LIMIT,
};

/// Which register table a value is read from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum RegisterKind {
    /// Holding registers, function 03.
    Holding,
    /// Input registers, function 04.
    Input,
}

impl RegisterKind {
    /// The function code that reads this table.
    pub fn function_code(self) -> u8 {
        match self {
            Self::Holding => 0x03,
            Self::Input => 0x04,
        }
    }
}

/// How a value is encoded in registers.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
pub enum Encoding {
    /// Signed 16-bit, tenths (`int16-x0.1`).
    #[serde(rename = "int16-x0.1")]
    Int16Tenths,
    /// Signed 16-bit, hundredths (`int16-x0.01`).
    #[serde(rename = "int16-x0.01")]
    Int16Hundredths,
    /// Unsigned 16-bit (`uint16`).
    #[serde(rename = "uint16")]
    Uint16,
    /// IEEE 754 single precision over two registers (`float32`), see [`WordOrder`].
    #[serde(rename = "float32")]
    Float32,
}

impl Encoding {
    /// Number of registers the value occupies.
    pub fn registers(self) -> u16 {
        match self {
            Self::Float32 => 2,
            _ => 1,
        }
    }
}

/// Order of the two registers of a 32-bit value (bytes within a register are always big-endian).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum WordOrder {
    /// The register with the sign and exponent first (`high-first`, "big-endian").
    #[default]
    HighFirst,
    /// The low register first (`low-first`, "word-swapped").
    LowFirst,
}

/// How the configured register numbers count.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
pub enum Addressing {
    /// Register numbers are protocol addresses (`0-based`).
    #[default]
    #[serde(rename = "0-based")]
    ZeroBased,
    /// Register numbers start at 1 as in many manuals (`1-based`): protocol address = n − 1.
    #[serde(rename = "1-based")]
    OneBased,
}

/// Why registers could not be turned into a value.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DecodeError {
    /// The encoding needs another number of registers.
    WrongCount {
        /// Registers the encoding needs.
        expected: usize,
        /// Registers given.
        found: usize,
    },
    /// A float32 that is NaN or infinite (its bits).
    NotFinite {
        /// The 32 bits as assembled.
        bits: u32,
    },
}

impl std::fmt::Display for DecodeError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::WrongCount { expected, found } => {
                write!(
                    f,
                    "expected {expected} register(s) for the encoding, found {found}"
                )
            }
            Self::NotFinite { bits } => {
                write!(
                    f,
                    "expected a finite float32, found 0x{bits:08X} (NaN or infinity)"
                )
            }
        }
    }
}

impl std::error::Error for DecodeError {}

/// Signed 16-bit register in tenths: 0x00F1 → 24.1, 0xFF38 → −20.0.
pub fn decode_int16_tenths(register: u16) -> f64 {
    f64::from(register as i16) / 10.0
}

/// Signed 16-bit register in hundredths: 0x0929 → 23.45, 0xF830 → −20.0.
pub fn decode_int16_hundredths(register: u16) -> f64 {
    f64::from(register as i16) / 100.0
}

/// Unsigned 16-bit register: 0x1234 → 4660.
pub fn decode_uint16(register: u16) -> f64 {
    f64::from(register)
}

/// IEEE 754 single precision from two registers in the given word order:
/// [0x41BC, 0x0000] high-first = [0x0000, 0x41BC] low-first = 23.5.
pub fn decode_float32(registers: [u16; 2], order: WordOrder) -> Result<f64, DecodeError> {
    let (high, low) = match order {
        WordOrder::HighFirst => (registers[0], registers[1]),
        WordOrder::LowFirst => (registers[1], registers[0]),
    };
    let bits = (u32::from(high) << 16) | u32::from(low);
    let x = f32::from_bits(bits);
    if x.is_finite() {
        Ok(f64::from(x))
    } else {
        Err(DecodeError::NotFinite { bits })
    }
}

/// Decodes one value from exactly [`Encoding::registers`] registers. Pure; never panics.
pub fn decode(encoding: Encoding, order: WordOrder, registers: &[u16]) -> Result<f64, DecodeError> {
    let expected = usize::from(encoding.registers());
    if registers.len() != expected {
        return Err(DecodeError::WrongCount {
            expected,
            found: registers.len(),
        });
    }
    Ok(match encoding {
        Encoding::Int16Tenths => decode_int16_tenths(registers[0]),
        Encoding::Int16Hundredths => decode_int16_hundredths(registers[0]),
        Encoding::Uint16 => decode_uint16(registers[0]),
        Encoding::Float32 => decode_float32([registers[0], registers[1]], order)?,
    })
}

/// The most registers one read may ask for (spec V1.1b3 §6.3, §6.4: 1 to 125 = 0x7D).
pub const MAX_READ_REGISTERS: u16 = 125;

/// Length of the MBAP header in bytes.
pub const MBAP_HEADER_BYTES: usize = 7;

/// Largest value of the MBAP length field: unit id + the largest PDU (253 bytes), so that an ADU
/// is at most 260 bytes.
pub const MAX_MBAP_LENGTH: u16 = 254;

/// Why a Modbus exchange failed.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ModbusError {
    /// The server answered with an exception (spec V1.1b3 §7).
    Exception {
        /// The function code of the request.
        function: u8,
        /// The exception code.
        code: u8,
    },
    /// The answer does not follow the protocol or does not match the request.
    Protocol(String),
    /// The request cannot be made (count out of 1–125, address range beyond 65535).
    Request(String),
    /// The connection failed or timed out.
    Io(String),
}

impl ModbusError {
    /// Whether the connection is still usable after this error (only after an exception, which
    /// is a complete, well-formed answer).
    pub fn keeps_connection(&self) -> bool {
        matches!(self, Self::Exception { .. } | Self::Request(_))
    }
}

/// The name of an exception code (spec V1.1b3 §7).
pub fn exception_name(code: u8) -> &'static str {
    match code {
        0x01 => "illegal function",
        0x02 => "illegal data address",
        0x03 => "illegal data value",
        0x04 => "server device failure",
        0x05 => "acknowledge",
        0x06 => "server device busy",
        0x08 => "memory parity error",
        0x0A => "gateway path unavailable",
        0x0B => "gateway target device failed to respond",
        _ => "unknown exception",
    }
}

impl std::fmt::Display for ModbusError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Exception { function, code } => write!(
                f,
                "exception {code:02X} ({}) to function {function:02X}",
                exception_name(*code)
            ),
            Self::Protocol(why) | Self::Request(why) | Self::Io(why) => write!(f, "{why}"),
        }
    }
}

impl std::error::Error for ModbusError {}

/// A read of `count` registers from `address` (protocol address, 0-based) of one unit.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ReadRequest {
    /// MBAP transaction id, echoed by the server.
    pub transaction: u16,
    /// Unit identifier (the module's address behind a gateway; 1 or 255 for a plain module).
    pub unit: u8,
    /// Holding (03) or input (04) registers.
    pub kind: RegisterKind,
    /// First register's protocol address.
    pub address: u16,
    /// Number of registers, 1–125.
    pub count: u16,
}

impl ReadRequest {
    /// The 12 bytes of the request ADU: MBAP header (length 6) + function, address, count.
    pub fn encode(&self) -> Result<[u8; 12], ModbusError> {
        if self.count == 0 || self.count > MAX_READ_REGISTERS {
            return Err(ModbusError::Request(format!(
                "expected 1 to {MAX_READ_REGISTERS} registers per read, asked for {}",
                self.count
            )));
        }
        if u32::from(self.address) + u32::from(self.count) > 0x1_0000 {
            return Err(ModbusError::Request(format!(
                "expected registers within addresses 0–65535, asked for {} from {}",
                self.count, self.address
            )));
        }
        let [t0, t1] = self.transaction.to_be_bytes();
        let [a0, a1] = self.address.to_be_bytes();
        let [c0, c1] = self.count.to_be_bytes();
        Ok([
            t0,
            t1,
            0,
            0,
            0,
            6,
            self.unit,
            self.kind.function_code(),
            a0,
            a1,
            c0,
            c1,
        ])
    }
}

/// The MBAP header of an answer.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MbapHeader {
    /// Transaction id.
    pub transaction: u16,
    /// Bytes that follow the length field (unit id + PDU).
    pub length: u16,
    /// Unit identifier.
    pub unit: u8,
}

impl MbapHeader {
    /// Bytes of PDU that follow the header.
    pub fn pdu_bytes(&self) -> usize {
        usize::from(self.length).saturating_sub(1)
    }
}

/// Reads an MBAP header: protocol id 0 and a length of 2–254 (unit id + at least a function
/// code; at most a 253-byte PDU). Pure; never panics.
pub fn parse_header(bytes: &[u8]) -> Result<MbapHeader, ModbusError> {
    let Some(h) = bytes.get(..MBAP_HEADER_BYTES) else {
        return Err(ModbusError::Protocol(format!(
            "expected a {MBAP_HEADER_BYTES}-byte MBAP header, found {} bytes",
            bytes.len()
        )));
    };
    let protocol = u16::from_be_bytes([h[2], h[3]]);
    if protocol != 0 {
        return Err(ModbusError::Protocol(format!(
            "expected protocol id 0 (Modbus) in the MBAP header, found {protocol}"
        )));
    }
    let length = u16::from_be_bytes([h[4], h[5]]);
    if !(2..=MAX_MBAP_LENGTH).contains(&length) {
        return Err(ModbusError::Protocol(format!(
            "expected an MBAP length of 2 to {MAX_MBAP_LENGTH}, found {length}"
        )));
    }
    Ok(MbapHeader {
        transaction: u16::from_be_bytes([h[0], h[1]]),
        length,
        unit: h[6],
    })
}

/// Checks an answer's PDU against its request and returns the registers. Pure; never panics.
pub fn parse_read_response(
    request: &ReadRequest,
    header: &MbapHeader,
    pdu: &[u8],
) -> Result<Vec<u16>, ModbusError> {
    if header.transaction != request.transaction {
        return Err(ModbusError::Protocol(format!(
            "expected transaction {}, found {}",
            request.transaction, header.transaction
        )));
    }
    if header.unit != request.unit {
        return Err(ModbusError::Protocol(format!(
            "expected an answer from unit {}, found unit {}",
            request.unit, header.unit
        )));
    }
    if pdu.len() != header.pdu_bytes() {
        return Err(ModbusError::Protocol(format!(
            "expected {} PDU bytes as the MBAP length says, found {}",
            header.pdu_bytes(),
            pdu.len()
        )));
    }
    let function = request.kind.function_code();
    match pdu.first() {
        Some(&f) if f == function | 0x80 => {
            return match pdu {
                [_, code] => Err(ModbusError::Exception {
                    function,
                    code: *code,
                }),
                _ => Err(ModbusError::Protocol(format!(
                    "expected a 2-byte exception PDU, found {} bytes",
                    pdu.len()
                ))),
            };
        }
        Some(&f) if f == function => {}
        Some(&f) => {
            return Err(ModbusError::Protocol(format!(
                "expected function {function:02X} in the answer, found {f:02X}"
            )))
        }
        None => return Err(ModbusError::Protocol("expected a PDU, found none".into())),
    }
    let want = usize::from(request.count) * 2;
    let Some(&byte_count) = pdu.get(1) else {
        return Err(ModbusError::Protocol(
            "expected a byte count after the function code".into(),
        ));
    };
    if usize::from(byte_count) != want || pdu.len() != 2 + want {
        return Err(ModbusError::Protocol(format!(
            "expected {want} data bytes for {} registers, found byte count {byte_count} and {} bytes",
            request.count,
            pdu.len().saturating_sub(2)
        )));
    }
    Ok(pdu[2..]
        .chunks_exact(2)
        .map(|b| u16::from_be_bytes([b[0], b[1]]))
        .collect())
}

/// Checks a whole answer ADU (header + PDU) against its request. Pure; never panics.
pub fn parse_response_adu(request: &ReadRequest, adu: &[u8]) -> Result<Vec<u16>, ModbusError> {
    let header = parse_header(adu)?;
    parse_read_response(request, &header, &adu[MBAP_HEADER_BYTES..])
}

/// A Modbus TCP client connection (one request at a time).
#[derive(Debug)]
pub struct ModbusClient {
    stream: TcpStream,
    transaction: u16,
    timeout: Duration,
    stop: Arc<AtomicBool>,
}

impl ModbusClient {
    /// Connects, with `timeout` for the connection and for every whole answer (header and PDU
    /// together, however slowly the server sends them).
    pub fn connect(peer: SocketAddr, timeout: Duration) -> Result<Self, ModbusError> {
        let stream = TcpStream::connect_timeout(&peer, timeout)
            .map_err(|e| ModbusError::Io(format!("cannot connect to Modbus server {peer}: {e}")))?;
        stream
            .set_write_timeout(Some(timeout))
            .and_then(|_| stream.set_nodelay(true))
            .map_err(|e| ModbusError::Io(format!("cannot set up the connection to {peer}: {e}")))?;
        Ok(Self {
            stream,
            transaction: 0,
            timeout,
            stop: Arc::new(AtomicBool::new(false)),
        })
    }

    /// Gives up a pending answer (with an `Io` error) within about 20 ms of `stop` being set.
    pub fn stop_on(mut self, stop: Arc<AtomicBool>) -> Self {
        self.stop = stop;
        self
    }

    /// Reads `count` registers from protocol address `address` of `unit`.
    pub fn read_registers(
        &mut self,
        unit: u8,
        kind: RegisterKind,
        address: u16,
        count: u16,
    ) -> Result<Vec<u16>, ModbusError> {
        self.transaction = self.transaction.wrapping_add(1);
        let request = ReadRequest {
            transaction: self.transaction,
            unit,
            kind,
            address,
            count,
        };
        let bytes = request.encode()?;
        self.stream
            .write_all(&bytes)
            .map_err(|e| ModbusError::Io(format!("cannot send the request: {e}")))?;
        // One deadline for the whole answer: a server dripping bytes cannot stretch it.
        let deadline = Instant::now() + self.timeout;
        let ms = self.timeout.as_millis();
        let mut filled = 0;
        let mut head = [0u8; MBAP_HEADER_BYTES];
        read_exact_until(
            &mut self.stream,
            &mut head,
            deadline,
            &self.stop,
            &mut filled,
        )
        .map_err(|e| answer_error(&e, ms, filled, None))?;
        let header = parse_header(&head)?;
        let mut pdu = [0u8; MAX_MBAP_LENGTH as usize];
        let pdu = &mut pdu[..header.pdu_bytes()];
        read_exact_until(&mut self.stream, pdu, deadline, &self.stop, &mut filled).map_err(
            |e| {
                let whole = MBAP_HEADER_BYTES + pdu.len();
                answer_error(&e, ms, MBAP_HEADER_BYTES + filled, Some(whole))
            },
        )?;
        parse_read_response(&request, &header, pdu)
    }
}

/// Why an answer did not come whole: `got` bytes of `whole` (unknown before the header is in).
fn answer_error(e: &std::io::Error, ms: u128, got: usize, whole: Option<usize>) -> ModbusError {
    use std::io::ErrorKind;
    let of = match whole {
        Some(n) => format!("{got} of {n} bytes"),
        None => format!("{got} of {MBAP_HEADER_BYTES} header bytes"),
    };
    ModbusError::Io(match e.kind() {
        ErrorKind::TimedOut if got == 0 => format!("no answer within {ms} ms (timeout)"),
        ErrorKind::TimedOut => format!("answer incomplete after {ms} ms (timeout; {of})"),
        ErrorKind::UnexpectedEof => format!("the server closed the connection ({of})"),
        ErrorKind::Interrupted => "stopped while waiting for an answer".to_string(),
        _ => format!("reading the answer: {e} ({of})"),
    })
}

/// One Modbus register feeding one machine channel (configuration, TOML). Give exactly one of
/// `temperature`, `axis` or `operating`.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ModbusChannelConfig {
    /// Machine temperature channel id (°C).
    #[serde(default)]
    pub temperature: Option<String>,
    /// Machine axis name.
    #[serde(default)]
    pub axis: Option<String>,
    /// Machine operating channel id.
    #[serde(default)]
    pub operating: Option<String>,
    /// Unit identifier (default 1).
    #[serde(default = "default_unit")]
    pub unit: u8,
    /// `holding` (function 03, default) or `input` (function 04).
    #[serde(default = "default_function")]
    pub function: RegisterKind,
    /// Register number, counted as `addressing` says.
    pub register: u32,
    /// `int16-x0.1`, `int16-x0.01`, `uint16` or `float32`.
    pub encoding: Encoding,
    /// For `float32`: `high-first` (default) or `low-first`.
    #[serde(default)]
    pub word_order: WordOrder,
}

fn default_unit() -> u8 {
    1
}
fn default_function() -> RegisterKind {
    RegisterKind::Holding
}

/// A Modbus TCP source (configuration, TOML).
///
/// ```toml
/// address = "192.168.0.20:502"
/// poll_ms = 100
/// addressing = "1-based"
/// [[channel]]
/// temperature = "x_slide_bottom"
/// function = "input"
/// register = 1
/// encoding = "int16-x0.1"
/// ```
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ModbusConfig {
    /// The server's `host:port` (Modbus TCP's port is 502).
    pub address: String,
    /// Poll period in ms (default 100).
    #[serde(default = "default_poll_ms")]
    pub poll_ms: u64,
    /// Longest wait for a connection or an answer in ms (default 500).
    #[serde(default = "default_timeout_ms")]
    pub timeout_ms: u64,
    /// `0-based` (default) or `1-based` register numbers.
    #[serde(default)]
    pub addressing: Addressing,
    /// Reconnection waits.
    #[serde(default)]
    pub backoff: BackoffConfig,
    /// Which register feeds which machine channel.
    #[serde(rename = "channel")]
    pub channels: Vec<ModbusChannelConfig>,
}

fn default_poll_ms() -> u64 {
    100
}
fn default_timeout_ms() -> u64 {
    500
}

/// Neighbouring registers of one unit and table, read in one request.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ReadBlock {
    /// Unit identifier.
    pub unit: u8,
    /// Register table.
    pub kind: RegisterKind,
    /// First protocol address.
    pub address: u16,
    /// Number of registers (≤ 125).
    pub count: u16,
    /// The channels it serves: (channel index, offset of its first register in the block).
    pub members: Vec<(usize, u16)>,
}

/// The largest gap of unused registers that is still read through rather than split into two
/// requests.
pub const MAX_GAP_REGISTERS: u16 = 16;

/// A channel's place: (unit, table, protocol address, registers).
pub type RegisterSpan = (u8, RegisterKind, u16, u16);

/// Groups channels into as few reads as possible: same unit and table, at most 125 registers,
/// gaps of at most [`MAX_GAP_REGISTERS`]. Spans must lie within 0–65535.
pub fn plan_reads(spans: &[RegisterSpan]) -> Vec<ReadBlock> {
    let mut order: Vec<usize> = (0..spans.len()).collect();
    order.sort_by_key(|&i| (spans[i].0, spans[i].1, spans[i].2, i));
    let mut blocks: Vec<ReadBlock> = Vec::new();
    for i in order {
        let (unit, kind, address, n) = spans[i];
        let end = u32::from(address) + u32::from(n);
        if let Some(b) = blocks.last_mut() {
            let b_end = u32::from(b.address) + u32::from(b.count);
            if b.unit == unit
                && b.kind == kind
                && u32::from(address) <= b_end + u32::from(MAX_GAP_REGISTERS)
                && end.max(b_end) - u32::from(b.address) <= u32::from(MAX_READ_REGISTERS)
            {
                b.count = (end.max(b_end) - u32::from(b.address)) as u16;
                b.members.push((i, address - b.address));
                continue;
            }
        }
        blocks.push(ReadBlock {
            unit,
            kind,
            address,
            count: n,
            members: vec![(i, 0)],
        });
    }
    blocks
}

/// Replaces the blocks at `indices` by one block per channel (its own registers only).
pub fn split_blocks(
    blocks: &[ReadBlock],
    indices: &[usize],
    decoders: &[(Encoding, WordOrder)],
) -> Vec<ReadBlock> {
    let mut out = Vec::with_capacity(blocks.len());
    for (b, block) in blocks.iter().enumerate() {
        if !indices.contains(&b) {
            out.push(block.clone());
            continue;
        }
        for &(k, offset) in &block.members {
            let count = decoders.get(k).map_or(1, |(e, _)| e.registers());
            out.push(ReadBlock {
                unit: block.unit,
                kind: block.kind,
                address: block.address.saturating_add(offset),
                count,
                members: vec![(k, 0)],
            });
        }
    }
    out
}

impl ModbusConfig {
    /// Reads the configuration from TOML text (a table with the fields above).
    pub fn from_toml(text: &str) -> Result<Self, ConfigError> {
        toml::from_str(text).map_err(|e| ConfigError::new("modbus", e.to_string()))
    }

    /// Reads the configuration from a TOML file; errors name the file (and, for TOML mistakes,
    /// the line and column).
    pub fn load(path: &std::path::Path) -> Result<Self, ConfigError> {
        let file = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|e| {
            ConfigError::new(
                &file,
                format!("cannot read the Modbus source configuration: {e}"),
            )
        })?;
        toml::from_str(&text).map_err(|e| ConfigError::new(file, e.to_string()))
    }

    /// Checks the bounds and resolves the channels against the machine: their targets and
    /// register spans (protocol addresses).
    pub fn resolve(
        &self,
        machine: &Machine,
    ) -> Result<(Vec<Target>, Vec<RegisterSpan>), ConfigError> {
        let keys = check_source_config(
            "modbus",
            &self.address,
            &[("poll_ms", self.poll_ms), ("timeout_ms", self.timeout_ms)],
            &self.backoff,
            self.channels.len(),
            "a register",
        )?;
        let mut targets = Vec::with_capacity(self.channels.len());
        let mut spans = Vec::with_capacity(self.channels.len());
        for (c, key) in self.channels.iter().zip(&keys) {
            targets.push(Target::resolve(
                machine,
                key,
                c.temperature.as_deref(),
                c.axis.as_deref(),
                c.operating.as_deref(),
            )?);
            let n = c.encoding.registers();
            let address = match self.addressing {
                Addressing::ZeroBased => Some(c.register),
                Addressing::OneBased => c.register.checked_sub(1),
            };
            let last = 0xFFFF - u32::from(n - 1);
            let address = address.filter(|&a| a <= last).ok_or_else(|| {
                let (lo, hi, how) = match self.addressing {
                    Addressing::ZeroBased => (0, last, "0-based"),
                    Addressing::OneBased => (1, last + 1, "1-based"),
                };
                ConfigError::new(
                    format!("{key}.register"),
                    format!(
                        "expected a register number from {lo} to {hi} ({how} addressing, {n} register(s)), found {}",
                        c.register
                    ),
                )
            })?;
            spans.push((c.unit, c.function, address as u16, n));
        }
        check_unique_targets(&targets, &keys)?;
        Ok((targets, spans))
    }
}

/// A Modbus TCP source: a polling thread and the cycle's view of its values.
#[derive(Debug)]
pub struct ModbusSource {
    name: String,
    targets: Vec<Target>,
    channels: Arc<SharedChannels>,
    status: Arc<LinkStatus>,
    stop: Arc<AtomicBool>,
    outage: OutageReporter,
    thread: Option<JoinHandle<()>>,
}

impl ModbusSource {
    /// Starts the polling thread for a checked configuration. `epoch` is the service clock's
    /// zero: stamps are seconds since it.
    pub fn start(
        config: &ModbusConfig,
        machine: &Machine,
        epoch: Instant,
    ) -> Result<Self, ConfigError> {
        let (targets, spans) = config.resolve(machine)?;
        let peer = resolve_address(&config.address, "modbus.address")?;
        let channels = SharedChannels::new(targets.len());
        let status = Arc::new(LinkStatus::default());
        let stop = Arc::new(AtomicBool::new(false));
        let poller = Poller {
            peer,
            poll: Duration::from_millis(config.poll_ms),
            timeout: Duration::from_millis(config.timeout_ms),
            backoff: config.backoff,
            blocks: plan_reads(&spans),
            decoders: config
                .channels
                .iter()
                .map(|c| (c.encoding, c.word_order))
                .collect(),
            channels: Arc::clone(&channels),
            status: Arc::clone(&status),
            stop: Arc::clone(&stop),
            epoch,
        };
        let name = format!("modbus {}", config.address);
        let thread = std::thread::Builder::new()
            .name(name.clone())
            .spawn(move || poller.run())
            .map_err(|e| {
                ConfigError::new("modbus", format!("cannot start the polling thread: {e}"))
            })?;
        Ok(Self {
            name,
            targets,
            channels,
            status,
            stop,
            outage: OutageReporter::default(),
            thread: Some(thread),
        })
    }

    /// The link's state for the status line.
    pub fn status(&self) -> LinkSnapshot {
        self.status.snapshot()
    }

    /// The link's state, including its events to drain (off the cycle).
    pub fn link(&self) -> &LinkStatus {
        &self.status
    }

    /// The machine channels this source feeds, in configuration order.
    pub fn targets(&self) -> &[Target] {
        &self.targets
    }
}

impl Source for ModbusSource {
    fn name(&self) -> &str {
        &self.name
    }

    /// Copies the latest values with the time of the answer that carried them (atomics only, no
    /// allocation). A value that arrived after the frame's clock reading is stamped with the
    /// frame's time: stamps never lie after `frame.time_s`.
    fn read(&mut self, frame: &mut Frame) -> Result<(), LinkError> {
        for (k, target) in self.targets.iter().enumerate() {
            let (value, stamp) = self.channels.get(k);
            target.write(frame, value, stamp.min(frame.time_s));
        }
        self.outage.check(&self.status)
    }
}

impl Drop for ModbusSource {
    fn drop(&mut self) {
        if let Some(t) = self.thread.take() {
            stop_thread(&self.stop, t, STOP_LIMIT);
        }
    }
}

/// The polling thread.
struct Poller {
    peer: SocketAddr,
    poll: Duration,
    timeout: Duration,
    backoff: BackoffConfig,
    blocks: Vec<ReadBlock>,
    decoders: Vec<(Encoding, WordOrder)>,
    channels: Arc<SharedChannels>,
    status: Arc<LinkStatus>,
    stop: Arc<AtomicBool>,
    epoch: Instant,
}

impl Poller {
    fn run(mut self) {
        let mut backoff = Backoff::new(self.backoff);
        // The last problem reported per block and per channel, so that a lasting one is reported
        // once, not at every poll.
        let mut block_problem: Vec<Option<String>> = vec![None; self.blocks.len()];
        let mut value_problem: Vec<Option<DecodeError>> = vec![None; self.decoders.len()];
        while !self.stop.load(Ordering::Acquire) {
            match ModbusClient::connect(self.peer, self.timeout) {
                Ok(client) => {
                    let mut client = client.stop_on(Arc::clone(&self.stop));
                    backoff.reset();
                    self.status.set_connected(
                        seconds_since(self.epoch),
                        format!("connected to Modbus server {}", self.peer),
                    );
                    match self.poll_until_lost(&mut client, &mut block_problem, &mut value_problem)
                    {
                        None => return,
                        Some(why) => self.status.set_lost(seconds_since(self.epoch), why),
                    }
                }
                Err(e) => self
                    .status
                    .set_lost(seconds_since(self.epoch), e.to_string()),
            }
            if !sleep_unless_stopped(backoff.next_delay(), &self.stop) {
                return;
            }
        }
    }

    /// Polls until the connection is lost (returns why) or the source stops (returns `None`).
    /// A round in which the server refuses a request (an exception) makes the source fail with
    /// that reason until a round is answered in full.
    fn poll_until_lost(
        &mut self,
        client: &mut ModbusClient,
        block_problem: &mut Vec<Option<String>>,
        value_problem: &mut [Option<DecodeError>],
    ) -> Option<String> {
        let mut next = Instant::now();
        let mut failing: Option<String> = None;
        loop {
            let mut split = Vec::new();
            let mut refused: Option<String> = None;
            for (b, block) in self.blocks.iter().enumerate() {
                if self.stop.load(Ordering::Acquire) {
                    return None;
                }
                // The source's name carries the server's address.
                let what = format!(
                    "unit {} function {:02X} registers {}–{}",
                    block.unit,
                    block.kind.function_code(),
                    block.address,
                    u32::from(block.address) + u32::from(block.count) - 1
                );
                match client.read_registers(block.unit, block.kind, block.address, block.count) {
                    Ok(registers) => {
                        let now = seconds_since(self.epoch);
                        block_problem[b] = None;
                        for &(k, offset) in &block.members {
                            let (encoding, order) = self.decoders[k];
                            let start = usize::from(offset);
                            let end = start + usize::from(encoding.registers());
                            let value = registers
                                .get(start..end)
                                .ok_or(DecodeError::WrongCount {
                                    expected: end,
                                    found: registers.len(),
                                })
                                .and_then(|r| decode(encoding, order, r));
                            match value {
                                Ok(x) => {
                                    value_problem[k] = None;
                                    self.channels.publish(k, x, now);
                                }
                                Err(e) => {
                                    // An invalid value is published as NaN so that validation
                                    // rejects it, and reported once while it lasts.
                                    self.channels.publish(k, f64::NAN, now);
                                    if value_problem[k] != Some(e) {
                                        value_problem[k] = Some(e);
                                        self.status.bad_data(
                                            now,
                                            format!(
                                                "Modbus server {} unit {} register {}: {e}",
                                                self.peer,
                                                block.unit,
                                                u32::from(block.address) + u32::from(offset)
                                            ),
                                        );
                                    }
                                }
                            }
                        }
                    }
                    // A module may refuse a read that spans registers it does not have (between
                    // the ones configured): read the channels of that block one by one.
                    Err(ModbusError::Exception { code: 0x02, .. }) if block.members.len() > 1 => {
                        split.push(b);
                        self.status.bad_data(
                            seconds_since(self.epoch),
                            format!(
                                "Modbus server {} unit {} function {:02X} registers {}–{}: exception 02 \
                                 (illegal data address) to a grouped read; reading its {} channels one by one",
                                self.peer,
                                block.unit,
                                block.kind.function_code(),
                                block.address,
                                u32::from(block.address) + u32::from(block.count) - 1,
                                block.members.len()
                            ),
                        );
                    }
                    Err(e) if e.keeps_connection() => {
                        let why = format!("{what}: {e}");
                        if block_problem[b].as_deref() != Some(why.as_str()) {
                            self.status.bad_data(seconds_since(self.epoch), why.clone());
                            block_problem[b] = Some(why.clone());
                        }
                        refused.get_or_insert(why);
                    }
                    Err(e) => return Some(format!("{what}: {e}")),
                }
            }
            match refused {
                Some(why) if failing.as_deref() != Some(why.as_str()) => {
                    self.status
                        .set_failing(seconds_since(self.epoch), why.clone());
                    failing = Some(why);
                }
                None if failing.is_some() => {
                    failing = None;
                    self.status.set_delivering(
                        seconds_since(self.epoch),
                        format!("Modbus server {} answers every request again", self.peer),
                    );
                }
                _ => {}
            }
            if !split.is_empty() {
                self.blocks = split_blocks(&self.blocks, &split, &self.decoders);
                block_problem.clear();
                block_problem.resize(self.blocks.len(), None);
            }
            next += self.poll;
            let now = Instant::now();
            if next < now {
                next = now; // a slow server: poll again at once, without catching up
            }
            if !sleep_unless_stopped(next - now, &self.stop) {
                return None;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hand_computed_register_values() {
        // 0x00F1 = 241 → 24.1 °C; 0xFF38 = −200 (two's complement) → −20.0 °C.
        assert_eq!(decode_int16_tenths(0x00F1), 24.1);
        assert_eq!(decode_int16_tenths(0xFF38), -20.0);
        // 0x0929 = 2345 → 23.45; 0xF830 = 63536 − 65536 = −2000 → −20.00.
        assert_eq!(decode_int16_hundredths(0x0929), 23.45);
        assert_eq!(decode_int16_hundredths(0xF830), -20.0);
        // Extremes: 0x7FFF = 32767 → 3276.7; 0x8000 = −32768 → −3276.8.
        assert_eq!(decode_int16_tenths(0x7FFF), 3276.7);
        assert_eq!(decode_int16_tenths(0x8000), -3276.8);
        assert_eq!(decode_uint16(0x1234), 4660.0);
        assert_eq!(decode_uint16(0xFFFF), 65535.0);
        // 23.5 = 1.46875 · 2^4: sign 0, exponent 127 + 4 = 0x83, mantissa .46875 = 0x3C0000
        // → 0x41BC0000.
        assert_eq!(
            decode_float32([0x41BC, 0x0000], WordOrder::HighFirst),
            Ok(23.5)
        );
        assert_eq!(
            decode_float32([0x0000, 0x41BC], WordOrder::LowFirst),
            Ok(23.5)
        );
        // The wrong order reads 0x000041BC, a subnormal ≈ 2.4e-41, not 23.5.
        assert!(decode_float32([0x0000, 0x41BC], WordOrder::HighFirst).unwrap() < 1e-30);
        // −20.0 = −1.25 · 2^4: 0xC1A00000.
        assert_eq!(
            decode_float32([0xC1A0, 0x0000], WordOrder::HighFirst),
            Ok(-20.0)
        );
        assert_eq!(
            decode_float32([0x7FC0, 0x0000], WordOrder::HighFirst),
            Err(DecodeError::NotFinite { bits: 0x7FC0_0000 })
        );
        assert_eq!(
            decode_float32([0x0000, 0x7F80], WordOrder::LowFirst),
            Err(DecodeError::NotFinite { bits: 0x7F80_0000 })
        );
    }

    #[test]
    fn decode_checks_the_register_count() {
        assert_eq!(
            decode(Encoding::Int16Tenths, WordOrder::HighFirst, &[0x00F1]),
            Ok(24.1)
        );
        assert_eq!(
            decode(Encoding::Float32, WordOrder::LowFirst, &[0, 0x41BC]),
            Ok(23.5)
        );
        assert_eq!(
            decode(Encoding::Float32, WordOrder::HighFirst, &[0x41BC]),
            Err(DecodeError::WrongCount {
                expected: 2,
                found: 1
            })
        );
        assert_eq!(
            decode(Encoding::Uint16, WordOrder::HighFirst, &[]),
            Err(DecodeError::WrongCount {
                expected: 1,
                found: 0
            })
        );
    }

    #[test]
    fn request_bytes() {
        // Spec V1.1b3 §6.3 example: read holding registers 108–110 = address 0x006B, count 3.
        let r = ReadRequest {
            transaction: 0x0102,
            unit: 0x11,
            kind: RegisterKind::Holding,
            address: 0x006B,
            count: 3,
        };
        assert_eq!(
            r.encode().unwrap(),
            [0x01, 0x02, 0x00, 0x00, 0x00, 0x06, 0x11, 0x03, 0x00, 0x6B, 0x00, 0x03]
        );
        let r = ReadRequest {
            kind: RegisterKind::Input,
            count: 125,
            ..r
        };
        assert_eq!(r.encode().unwrap()[7], 0x04);
        assert!(ReadRequest { count: 0, ..r }.encode().is_err());
        assert!(ReadRequest { count: 126, ..r }.encode().is_err());
        assert!(ReadRequest {
            address: 0xFFFF,
            count: 2,
            ..r
        }
        .encode()
        .is_err());
        assert!(ReadRequest {
            address: 0xFFFF,
            count: 1,
            ..r
        }
        .encode()
        .is_ok());
    }

    #[test]
    fn answers() {
        let r = ReadRequest {
            transaction: 7,
            unit: 1,
            kind: RegisterKind::Holding,
            address: 0,
            count: 2,
        };
        // Spec §6.3 answer: function, byte count 4, registers 0x00F1, 0xFF38.
        let ok = [0, 7, 0, 0, 0, 7, 1, 0x03, 4, 0x00, 0xF1, 0xFF, 0x38];
        assert_eq!(parse_response_adu(&r, &ok), Ok(vec![0x00F1, 0xFF38]));
        // Exception 02, illegal data address (§7).
        let ex = [0, 7, 0, 0, 0, 3, 1, 0x83, 0x02];
        let e = parse_response_adu(&r, &ex).unwrap_err();
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
        assert!(e.keeps_connection());
        // Mismatches and malformed answers.
        let mut bad = ok;
        bad[1] = 8;
        assert_eq!(
            parse_response_adu(&r, &bad),
            Err(ModbusError::Protocol(
                "expected transaction 7, found 8".into()
            ))
        );
        let mut bad = ok;
        bad[3] = 1;
        assert!(parse_response_adu(&r, &bad)
            .unwrap_err()
            .to_string()
            .contains("protocol id 0"));
        let mut bad = ok;
        bad[6] = 2;
        assert!(parse_response_adu(&r, &bad)
            .unwrap_err()
            .to_string()
            .contains("unit 1"));
        let mut bad = ok;
        bad[7] = 0x04;
        assert!(parse_response_adu(&r, &bad)
            .unwrap_err()
            .to_string()
            .contains("function 03"));
        let mut bad = ok;
        bad[8] = 2;
        assert!(!parse_response_adu(&r, &bad).unwrap_err().keeps_connection());
        assert!(parse_response_adu(&r, &ok[..12]).is_err());
        assert!(parse_response_adu(&r, &ok[..3]).is_err());
        assert!(parse_header(&[0, 0, 0, 0, 0x01, 0x00, 1]).is_err()); // length 256
        assert!(parse_header(&[0, 0, 0, 0, 0, 1, 1]).is_err()); // length 1
    }

    #[test]
    fn reads_are_grouped() {
        use RegisterKind::*;
        let spans = [
            (1, Holding, 10, 1),
            (1, Holding, 0, 2),
            (1, Input, 0, 1),
            (2, Holding, 0, 1),
            (1, Holding, 11, 2),
            (1, Holding, 200, 1),
        ];
        let blocks = plan_reads(&spans);
        assert_eq!(blocks.len(), 4);
        assert_eq!(
            blocks[0],
            ReadBlock {
                unit: 1,
                kind: Holding,
                address: 0,
                count: 13,
                members: vec![(1, 0), (0, 10), (4, 11)]
            }
        );
        assert_eq!(
            blocks[1],
            ReadBlock {
                unit: 1,
                kind: Holding,
                address: 200,
                count: 1,
                members: vec![(5, 0)]
            }
        );
        assert_eq!(blocks[2].kind, Input);
        assert_eq!(blocks[3].unit, 2);
        // 125 registers at most per read.
        let spans: Vec<RegisterSpan> = (0..130).map(|a| (1, Holding, a, 1)).collect();
        let blocks = plan_reads(&spans);
        assert_eq!(
            (blocks[0].count, blocks[1].address, blocks[1].count),
            (125, 125, 5)
        );
    }

    #[test]
    fn refused_blocks_are_split_per_channel() {
        use RegisterKind::*;
        let spans = [(1, Input, 0, 1), (1, Input, 10, 2), (1, Holding, 0, 1)];
        let decoders = [
            (Encoding::Int16Tenths, WordOrder::HighFirst),
            (Encoding::Float32, WordOrder::LowFirst),
            (Encoding::Uint16, WordOrder::HighFirst),
        ];
        let blocks = plan_reads(&spans);
        assert_eq!(blocks.len(), 2); // holding 0; input 0–11
        let split = split_blocks(&blocks, &[1], &decoders);
        assert_eq!(split.len(), 3);
        assert_eq!(split[0], blocks[0]);
        assert_eq!(
            split[1],
            ReadBlock {
                unit: 1,
                kind: Input,
                address: 0,
                count: 1,
                members: vec![(0, 0)]
            }
        );
        assert_eq!(
            split[2],
            ReadBlock {
                unit: 1,
                kind: Input,
                address: 10,
                count: 2,
                members: vec![(1, 0)]
            }
        );
    }

    #[test]
    fn config_reads_toml() {
        let c = ModbusConfig::from_toml(
            "address = \"127.0.0.1:502\"\naddressing = \"1-based\"\n[[channel]]\ntemperature = \"t\"\n\
             function = \"input\"\nregister = 1\nencoding = \"float32\"\nword_order = \"low-first\"\n",
        )
        .unwrap();
        assert_eq!(c.addressing, Addressing::OneBased);
        assert_eq!((c.poll_ms, c.timeout_ms), (100, 500));
        let ch = &c.channels[0];
        assert_eq!(
            (ch.unit, ch.function, ch.encoding, ch.word_order),
            (
                1,
                RegisterKind::Input,
                Encoding::Float32,
                WordOrder::LowFirst
            )
        );
        let e = ModbusConfig::from_toml(
            "address = \"a\"\n[[channel]]\nregister = 1\nencoding = \"int32\"\n",
        )
        .unwrap_err();
        assert!(e.message.contains("int16-x0.1"), "{e}");
    }
}
