//! A Modbus TCP client connection: one transaction at a time, one deadline per whole answer.

use std::io::Write;
use std::net::{SocketAddr, TcpStream};
use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use std::time::{Duration, Instant};

use super::codec::{
    parse_header, parse_read_response, ModbusError, ReadRequest, RegisterKind, MAX_MBAP_LENGTH,
    MBAP_HEADER_BYTES,
};
use truepos_runtime::sources::read_exact_until;

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
