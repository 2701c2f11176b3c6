//! The Modbus TCP codec, pure and never panicking: register tables and value encodings (with the
//! word order of 32-bit values), read requests and the MBAP framing of answers.

use serde::Deserialize;

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
}
