//! A minimal MQTT 3.1.1 client for one job: publish at QoS 1 and learn which packets the
//! broker acknowledged. Synchronous, on the publisher's thread (std `TcpStream`, no async
//! runtime beside the control's cycle). Written here rather than taken from a client crate
//! because store-and-forward needs exactly two things a general client hides: the cursor
//! advances on the PUBACK of *our* packet id, and nothing is re-sent by the client itself
//! after a reconnect (the publisher replays from the log, marked historical, with a new
//! Sparkplug session). It sends CONNECT (clean session, with a will), PUBLISH, PINGREQ and
//! DISCONNECT and reads CONNACK, PUBACK and PINGRESP; anything else the broker sends, or bytes
//! that are no packet, end the connection with an error, never a panic.

use std::io::{ErrorKind, Read, Write};
use std::net::{TcpStream, ToSocketAddrs};
use std::time::Duration;

/// Largest packet accepted from the broker by a publisher: a broker sends it only 2-5 byte
/// packets, so anything longer is not ours and ends the connection rather than buffering it.
pub const MAX_ACK: usize = 1024;

/// A broker's address, from `mqtt://HOST[:PORT]` or `tcp://HOST[:PORT]` (port 1883 unless given).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct BrokerUrl {
    /// Host name or address.
    pub host: String,
    /// TCP port.
    pub port: u16,
}

impl BrokerUrl {
    /// Parses a broker URL; the error says what is wrong in a sentence.
    pub fn parse(url: &str) -> Result<Self, String> {
        let rest = url
            .strip_prefix("mqtt://")
            .or_else(|| url.strip_prefix("tcp://"))
            .ok_or_else(|| {
                format!("broker `{url}`: give mqtt://HOST[:PORT] (TLS is not supported yet)")
            })?;
        let rest = rest.trim_end_matches('/');
        if rest.contains('@') || rest.contains('/') {
            return Err(format!(
                "broker `{url}`: user names and paths are not supported: give mqtt://HOST[:PORT]"
            ));
        }
        let (host, port) = match rest.rsplit_once(':') {
            Some((h, p)) if !h.ends_with(']') || h.starts_with('[') => (
                h,
                p.parse::<u16>()
                    .ok()
                    .filter(|p| *p > 0)
                    .ok_or_else(|| format!("broker `{url}`: port `{p}` is not 1-65535"))?,
            ),
            _ => (rest, 1883),
        };
        let host = host.trim_start_matches('[').trim_end_matches(']');
        if host.is_empty() {
            return Err(format!("broker `{url}`: no host"));
        }
        Ok(BrokerUrl {
            host: host.to_string(),
            port,
        })
    }
}

impl std::fmt::Display for BrokerUrl {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if self.host.contains(':') {
            write!(f, "mqtt://[{}]:{}", self.host, self.port)
        } else {
            write!(f, "mqtt://{}:{}", self.host, self.port)
        }
    }
}

/// The will: the message the broker publishes when the connection ends without DISCONNECT.
pub struct Will<'a> {
    /// Topic.
    pub topic: &'a str,
    /// Payload.
    pub payload: &'a [u8],
}

/// What the broker sent.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Incoming {
    /// PUBACK of a packet id.
    PubAck(u16),
    /// PINGRESP.
    PingResp,
    /// SUBACK of a packet id with the granted QoS (0x80: refused).
    SubAck(u16, u8),
    /// A message on a subscribed topic (`packet_id` for QoS 1 and 2, which must be acknowledged).
    Publish {
        /// Its topic (invalid UTF-8 replaced).
        topic: String,
        /// The packet id to acknowledge, `None` at QoS 0.
        packet_id: Option<u16>,
        /// Its payload.
        payload: Vec<u8>,
    },
}

/// One connection to a broker.
pub struct Connection {
    stream: TcpStream,
    buf: Vec<u8>,
    max_incoming: usize,
}

fn push_str(out: &mut Vec<u8>, s: &[u8]) {
    // MQTT strings and binary fields carry a two-byte length; ours are bounded far below it.
    let n = s.len().min(usize::from(u16::MAX));
    out.extend_from_slice(&(n as u16).to_be_bytes());
    out.extend_from_slice(&s[..n]);
}

fn packet(first: u8, body: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(body.len() + 5);
    out.push(first);
    let mut n = body.len();
    loop {
        let mut b = (n % 128) as u8;
        n /= 128;
        if n > 0 {
            b |= 0x80;
        }
        out.push(b);
        if n == 0 {
            break;
        }
    }
    out.extend_from_slice(body);
    out
}

/// Encodes a QoS 1 PUBLISH (not retained).
pub fn publish_packet(topic: &str, packet_id: u16, payload: &[u8]) -> Vec<u8> {
    let mut body = Vec::with_capacity(topic.len() + payload.len() + 4);
    push_str(&mut body, topic.as_bytes());
    body.extend_from_slice(&packet_id.to_be_bytes());
    body.extend_from_slice(payload);
    packet(0x32, &body)
}

/// Decodes one packet from the start of `buf`: `Ok(None)` when it is not complete yet,
/// otherwise the packet and its length. A packet longer than `max`, of a type a client does
/// not receive, or malformed inside is an error (never a panic).
pub fn decode(buf: &[u8], max: usize) -> Result<Option<(Incoming, usize)>, String> {
    let Some(&first) = buf.first() else {
        return Ok(None);
    };
    let mut len = 0usize;
    let mut i = 1;
    loop {
        let Some(&b) = buf.get(i) else {
            return Ok(None);
        };
        len |= usize::from(b & 0x7f) << (7 * (i - 1));
        i += 1;
        if b & 0x80 == 0 {
            break;
        }
        if i > 4 {
            return Err("a packet length longer than 4 bytes".into());
        }
    }
    if len > max {
        return Err(format!("a packet of {len} bytes from the broker"));
    }
    if buf.len() < i + len {
        return Ok(None);
    }
    let body = &buf[i..i + len];
    let p = match (first, len) {
        (0x40, 2) => Incoming::PubAck(u16::from_be_bytes([body[0], body[1]])),
        (0xd0, 0) => Incoming::PingResp,
        (0x90, 3) => Incoming::SubAck(u16::from_be_bytes([body[0], body[1]]), body[2]),
        (f, _) if f & 0xf0 == 0x30 => publish(f, body)?,
        _ => {
            return Err(format!(
                "an unexpected packet from the broker (type {}, {len} bytes)",
                first >> 4
            ))
        }
    };
    Ok(Some((p, i + len)))
}

/// The body of an incoming PUBLISH.
fn publish(first: u8, body: &[u8]) -> Result<Incoming, String> {
    let qos = (first >> 1) & 3;
    if qos == 3 {
        return Err("a PUBLISH with QoS 3".into());
    }
    let short = || "a PUBLISH shorter than its header".to_string();
    let n = usize::from(u16::from_be_bytes([
        *body.first().ok_or_else(short)?,
        *body.get(1).ok_or_else(short)?,
    ]));
    let topic = body.get(2..2 + n).ok_or_else(short)?;
    let mut rest = 2 + n;
    let packet_id = if qos > 0 {
        let id = body.get(rest..rest + 2).ok_or_else(short)?;
        rest += 2;
        Some(u16::from_be_bytes([id[0], id[1]]))
    } else {
        None
    };
    Ok(Incoming::Publish {
        topic: String::from_utf8_lossy(topic).into_owned(),
        packet_id,
        payload: body[rest..].to_vec(),
    })
}

impl Connection {
    /// Connects (TCP, then CONNECT with a clean session and the will) and waits for CONNACK,
    /// each within `timeout`.
    pub fn connect(
        url: &BrokerUrl,
        client_id: &str,
        keep_alive_s: u16,
        will: Will<'_>,
        timeout: Duration,
    ) -> Result<Self, String> {
        Self::open(url, client_id, keep_alive_s, Some(will), timeout)
    }

    /// Connects a subscriber: no will and a persistent session (clean session off), so that
    /// the broker keeps its subscriptions and queues QoS 1 messages while it is away.
    pub fn connect_subscriber(
        url: &BrokerUrl,
        client_id: &str,
        keep_alive_s: u16,
        timeout: Duration,
    ) -> Result<Self, String> {
        Self::open(url, client_id, keep_alive_s, None, timeout)
    }

    fn open(
        url: &BrokerUrl,
        client_id: &str,
        keep_alive_s: u16,
        will: Option<Will<'_>>,
        timeout: Duration,
    ) -> Result<Self, String> {
        let addrs = (url.host.as_str(), url.port)
            .to_socket_addrs()
            .map_err(|e| format!("{url}: {e}"))?;
        let mut last = format!("{url}: no address");
        for addr in addrs {
            match TcpStream::connect_timeout(&addr, timeout) {
                Ok(stream) => {
                    return Self::handshake(stream, client_id, keep_alive_s, will, timeout)
                }
                Err(e) => last = format!("{url}: {e}"),
            }
        }
        Err(last)
    }

    fn handshake(
        mut stream: TcpStream,
        client_id: &str,
        keep_alive_s: u16,
        will: Option<Will<'_>>,
        timeout: Duration,
    ) -> Result<Self, String> {
        let _ = stream.set_nodelay(true);
        stream
            .set_write_timeout(Some(timeout))
            .and_then(|()| stream.set_read_timeout(Some(timeout)))
            .map_err(|e| e.to_string())?;
        let mut body = Vec::with_capacity(64 + will.as_ref().map_or(0, |w| w.payload.len()));
        push_str(&mut body, b"MQTT");
        // Protocol level 4: MQTT 3.1.1.
        body.push(4);
        // A publisher: clean session (0x02), will (0x04) at QoS 1 (0x08), not retained:
        // Sparkplug's NDEATH. A subscriber: a persistent session and no will.
        body.push(if will.is_some() {
            0x02 | 0x04 | 0x08
        } else {
            0
        });
        body.extend_from_slice(&keep_alive_s.to_be_bytes());
        push_str(&mut body, client_id.as_bytes());
        if let Some(will) = &will {
            push_str(&mut body, will.topic.as_bytes());
            push_str(&mut body, will.payload);
        }
        stream
            .write_all(&packet(0x10, &body))
            .map_err(|e| format!("CONNECT: {e}"))?;
        let mut ack = [0u8; 4];
        stream
            .read_exact(&mut ack)
            .map_err(|e| format!("no CONNACK: {e}"))?;
        if ack[0] != 0x20 || ack[1] != 2 {
            return Err(format!("not a CONNACK: {ack:02x?}"));
        }
        if ack[3] != 0 {
            let why = match ack[3] {
                1 => "unacceptable protocol version",
                2 => "client id rejected",
                3 => "server unavailable",
                4 => "bad user name or password",
                5 => "not authorised",
                _ => "unknown reason",
            };
            return Err(format!("connection refused: {why} ({})", ack[3]));
        }
        Ok(Connection {
            stream,
            buf: Vec::with_capacity(64),
            max_incoming: MAX_ACK,
        })
    }

    /// Sends bytes (a packet made by this module).
    pub fn send(&mut self, bytes: &[u8]) -> Result<(), String> {
        self.stream.write_all(bytes).map_err(|e| e.to_string())
    }

    /// Sends a QoS 1 PUBLISH.
    pub fn publish(&mut self, topic: &str, packet_id: u16, payload: &[u8]) -> Result<(), String> {
        self.send(&publish_packet(topic, packet_id, payload))
    }

    /// Accepts packets from the broker up to `bytes` (a subscriber receives messages).
    pub fn set_max_incoming(&mut self, bytes: usize) {
        self.max_incoming = bytes;
    }

    /// Subscribes to a topic filter at QoS 1 (packet id `id`); SUBACK comes through [`Self::poll`].
    pub fn subscribe(&mut self, id: u16, filter: &str) -> Result<(), String> {
        let mut body = Vec::with_capacity(filter.len() + 5);
        body.extend_from_slice(&id.to_be_bytes());
        push_str(&mut body, filter.as_bytes());
        body.push(1);
        self.send(&packet(0x82, &body))
    }

    /// Acknowledges a QoS 1 message.
    pub fn puback(&mut self, id: u16) -> Result<(), String> {
        let [a, b] = id.to_be_bytes();
        self.send(&[0x40, 2, a, b])
    }

    /// Acknowledges QoS 1 messages, all in one write (one TCP segment for a batch, rather than
    /// one each).
    pub fn pubacks(&mut self, ids: &[u16]) -> Result<(), String> {
        let mut out = Vec::with_capacity(4 * ids.len());
        for id in ids {
            let [a, b] = id.to_be_bytes();
            out.extend_from_slice(&[0x40, 2, a, b]);
        }
        self.send(&out)
    }

    /// Sends PINGREQ.
    pub fn ping(&mut self) -> Result<(), String> {
        self.send(&[0xc0, 0])
    }

    /// Sends DISCONNECT: the broker then drops the will.
    pub fn disconnect(mut self) {
        let _ = self.send(&[0xe0, 0]);
        let _ = self.stream.shutdown(std::net::Shutdown::Both);
    }

    /// Reads what the broker sent within `wait`, appending every complete packet to `out`.
    pub fn poll(&mut self, wait: Duration, out: &mut Vec<Incoming>) -> Result<(), String> {
        self.stream
            .set_read_timeout(Some(wait.max(Duration::from_millis(1))))
            .map_err(|e| e.to_string())?;
        // A read takes what the socket holds, up to a quarter of the largest packet accepted:
        // 4 kB for a publisher (acknowledgements), 1 MB for the ingester, so that one poll
        // brings as many messages as the broker has in flight (~650 of a service's NDATA).
        let chunk = (self.max_incoming / 4).clamp(4 * 1024, 1024 * 1024);
        let old = self.buf.len();
        self.buf.resize(old + chunk, 0);
        let read = self.stream.read(&mut self.buf[old..]);
        self.buf.truncate(old + *read.as_ref().unwrap_or(&0));
        match read {
            Ok(0) => return Err("the broker closed the connection".into()),
            Ok(_) => {}
            Err(e) if matches!(e.kind(), ErrorKind::WouldBlock | ErrorKind::TimedOut) => {}
            Err(e) => return Err(e.to_string()),
        }
        let mut used = 0;
        while let Some((p, n)) = decode(&self.buf[used..], self.max_incoming)? {
            out.push(p);
            used += n;
        }
        self.buf.drain(..used);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn broker_urls() {
        let u = BrokerUrl::parse("mqtt://127.0.0.1:1884").unwrap();
        assert_eq!((u.host.as_str(), u.port), ("127.0.0.1", 1884));
        assert_eq!(BrokerUrl::parse("tcp://broker").unwrap().port, 1883);
        assert_eq!(BrokerUrl::parse("mqtt://[::1]:9").unwrap().host, "::1");
        for bad in [
            "http://x",
            "mqtt://",
            "mqtt://h:0",
            "mqtt://h:x",
            "mqtt://u@h",
            "mqtts://h",
        ] {
            assert!(BrokerUrl::parse(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn a_publish_packet_is_laid_out_as_the_standard_says() {
        let p = publish_packet("a/b", 0x0102, b"xy");
        assert_eq!(p, [0x32, 9, 0, 3, b'a', b'/', b'b', 1, 2, b'x', b'y']);
        // A body of 200 bytes takes two length bytes (200 = 0xc8 0x01).
        let long = publish_packet("t", 1, &[0; 195]);
        assert_eq!(&long[..3], &[0x32, 0xc8, 0x01]);
    }

    #[test]
    fn what_the_broker_sends_is_decoded_or_refused_never_a_panic() {
        let d = |b: &[u8]| decode(b, MAX_ACK);
        assert_eq!(d(&[0x40, 2, 0, 7]), Ok(Some((Incoming::PubAck(7), 4))));
        assert_eq!(d(&[0xd0, 0]), Ok(Some((Incoming::PingResp, 2))));
        assert_eq!(
            d(&[0x90, 3, 0, 1, 1]),
            Ok(Some((Incoming::SubAck(1, 1), 5)))
        );
        assert_eq!(d(&[0x40, 2, 0]), Ok(None));
        assert_eq!(d(&[0x40]), Ok(None));
        assert!(d(&[0x20, 2, 0, 0]).is_err());
        assert!(d(&[0x40, 0xff, 0xff, 0xff, 0xff, 1]).is_err());
        assert!(d(&[0x40, 0xff, 0xff, 0x7f]).is_err());
        // Every short byte string: decoded, incomplete or refused.
        for a in 0..=255u8 {
            for b in [0u8, 1, 2, 3, 4, 5, 0x7f, 0x80, 0xff] {
                let _ = d(&[a, b, a, b, a]);
                let _ = d(&[a, b, 0, b, a, 0, 0]);
            }
        }
    }

    #[test]
    fn an_incoming_publish_is_taken_apart() {
        let p = publish_packet("a/b", 9, b"xy");
        assert_eq!(
            decode(&p, MAX_ACK),
            Ok(Some((
                Incoming::Publish {
                    topic: "a/b".into(),
                    packet_id: Some(9),
                    payload: b"xy".to_vec()
                },
                p.len()
            )))
        );
        // QoS 0: no packet id; QoS 3 and a topic longer than the packet: refused.
        assert_eq!(
            decode(&[0x30, 4, 0, 1, b't', b'z'], MAX_ACK),
            Ok(Some((
                Incoming::Publish {
                    topic: "t".into(),
                    packet_id: None,
                    payload: b"z".to_vec()
                },
                6
            )))
        );
        assert!(decode(&[0x36, 3, 0, 1, b't'], MAX_ACK).is_err());
        assert!(decode(&[0x32, 3, 0, 9, b't'], MAX_ACK).is_err());
        assert!(decode(&[0x32, 4, 0, 1, b't', 0], MAX_ACK).is_err());
        assert!(decode(&p, 4).is_err(), "longer than allowed");
    }
}
