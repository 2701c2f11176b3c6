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
//! reconnects with backoff ([`truepos_runtime::sources`]) while the stamps stand still.
//!
//! [`Source`]: truepos_runtime::Source

mod client;
mod codec;
mod config;
mod plan;
mod source;

pub use client::ModbusClient;
pub use codec::{
    decode, decode_float32, decode_int16_hundredths, decode_int16_tenths, decode_uint16,
    exception_name, parse_header, parse_read_response, parse_response_adu, DecodeError, Encoding,
    MbapHeader, ModbusError, ReadRequest, RegisterKind, WordOrder, MAX_MBAP_LENGTH,
    MAX_READ_REGISTERS, MBAP_HEADER_BYTES,
};
pub use config::{Addressing, ModbusChannelConfig, ModbusConfig};
pub use plan::{plan_reads, split_blocks, ReadBlock, RegisterSpan, MAX_GAP_REGISTERS};
pub use source::ModbusSource;
