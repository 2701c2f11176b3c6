//! Sparkplug B 3.0 payloads, protobuf-encoded by hand: the subset a node sends (NBIRTH, NDATA,
//! NDEATH with metrics of scalar types). Written here rather than generated because it is five
//! field kinds of one message (`Payload`, `Payload.Metric` of `sparkplug_b.proto`) and needs
//! no protoc, no build script and no generated code; tests decode it with the Eclipse
//! definition through PyPI's `pysparkplug` (crates/cli/tests/fleet_mqtt.rs).

/// A Sparkplug message type of an edge node (the topic's third level).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MessageType {
    /// Node birth: every metric the node will send, with its type.
    NBirth,
    /// Node data.
    NData,
    /// Node death: the MQTT will, or sent before a clean disconnect.
    NDeath,
}

/// The topic of a node's message: `spBv1.0/<group>/<type>/<edge node>`.
pub fn topic(group: &str, kind: MessageType, node: &str) -> String {
    let t = match kind {
        MessageType::NBirth => "NBIRTH",
        MessageType::NData => "NDATA",
        MessageType::NDeath => "NDEATH",
    };
    format!("spBv1.0/{group}/{t}/{node}")
}

/// An id a person gives (`--mqtt-node`, `--mqtt-group`) checked as it is, rather than changed
/// behind their back as a machine's name is ([`sanitize_id`]): the store and `fleet follow`
/// are then given the same id the service publishes under.
pub fn check_id(what: &str, id: &str) -> Result<(), String> {
    if id.is_empty()
        || id
            .chars()
            .any(|c| c == '/' || c == '+' || c == '#' || c.is_control())
    {
        return Err(format!(
            "{what} `{id}`: a Sparkplug id may not be empty nor hold `/`, `+`, `#` or a control character"
        ));
    }
    Ok(())
}

/// An id usable as a Sparkplug group or edge node id: the characters MQTT gives a meaning in
/// topics (`/`, `+`, `#`) and control characters become `_`; empty becomes `_`.
pub fn sanitize_id(id: &str) -> String {
    let s: String = id
        .chars()
        .map(|c| {
            if c == '/' || c == '+' || c == '#' || c.is_control() {
                '_'
            } else {
                c
            }
        })
        .collect();
    if s.is_empty() {
        "_".into()
    } else {
        s
    }
}

/// A metric's value with its Sparkplug data type.
#[derive(Debug, Clone, PartialEq)]
pub enum Value {
    /// `UInt32` (datatype 7), sent as `int_value`.
    UInt32(u32),
    /// `UInt64` (8), `long_value`.
    UInt64(u64),
    /// `Double` (10), `double_value`.
    Double(f64),
    /// `Boolean` (11), `boolean_value`.
    Boolean(bool),
    /// `String` (12), `string_value`.
    String(String),
    /// No value (`is_null`) of the given Sparkplug datatype.
    Null(u32),
}

/// Sparkplug datatype `Double`.
pub const DOUBLE: u32 = 10;
/// Sparkplug datatype `String`.
pub const STRING: u32 = 12;

impl Value {
    fn datatype(&self) -> u32 {
        match self {
            Value::UInt32(_) => 7,
            Value::UInt64(_) => 8,
            Value::Double(_) => DOUBLE,
            Value::Boolean(_) => 11,
            Value::String(_) => STRING,
            Value::Null(t) => *t,
        }
    }
}

/// One metric.
#[derive(Debug, Clone, PartialEq)]
pub struct Metric {
    /// Its name; empty in NDATA, where the alias alone names it.
    pub name: String,
    /// Its alias: declared beside the name in NBIRTH, alone in NDATA (a third of the bytes).
    pub alias: Option<u64>,
    /// When the value was true, ms since the Unix epoch.
    pub timestamp_ms: Option<u64>,
    /// The value.
    pub value: Value,
    /// Sent late, from the store (store-and-forward after an outage).
    pub historical: bool,
}

impl Metric {
    /// A current metric without a timestamp of its own.
    pub fn new(name: impl Into<String>, value: Value) -> Self {
        Metric {
            name: name.into(),
            alias: None,
            timestamp_ms: None,
            value,
            historical: false,
        }
    }
}

/// A payload: the message's time, its sequence number (none in NDEATH) and metrics.
#[derive(Debug, Clone, PartialEq)]
pub struct Payload {
    /// When the message was made, ms since the Unix epoch.
    pub timestamp_ms: u64,
    /// `seq`: 0 in NBIRTH, then 1, 2, … 255, 0, … per MQTT session; `None` in NDEATH.
    pub seq: Option<u64>,
    /// The metrics.
    pub metrics: Vec<Metric>,
}

// Protobuf wire types.
const VARINT: u8 = 0;
const FIXED64: u8 = 1;
const LEN: u8 = 2;

fn key(out: &mut Vec<u8>, field: u32, wire: u8) {
    varint(out, (u64::from(field) << 3) | u64::from(wire));
}

fn varint(out: &mut Vec<u8>, mut v: u64) {
    while v >= 0x80 {
        out.push((v as u8) | 0x80);
        v >>= 7;
    }
    out.push(v as u8);
}

fn bytes_field(out: &mut Vec<u8>, field: u32, b: &[u8]) {
    key(out, field, LEN);
    varint(out, b.len() as u64);
    out.extend_from_slice(b);
}

fn varint_field(out: &mut Vec<u8>, field: u32, v: u64) {
    key(out, field, VARINT);
    varint(out, v);
}

impl Metric {
    fn encode(&self, out: &mut Vec<u8>) {
        // Field numbers of `Payload.Metric` in sparkplug_b.proto. A metric sent by its alias
        // alone carries neither name nor datatype: the NBIRTH declared both.
        if !self.name.is_empty() {
            bytes_field(out, 1, self.name.as_bytes());
        }
        if let Some(a) = self.alias {
            varint_field(out, 2, a);
        }
        if let Some(t) = self.timestamp_ms {
            varint_field(out, 3, t);
        }
        if !self.name.is_empty() {
            varint_field(out, 4, u64::from(self.value.datatype()));
        }
        if self.historical {
            varint_field(out, 5, 1);
        }
        match &self.value {
            Value::Null(_) => varint_field(out, 7, 1),
            Value::UInt32(v) => varint_field(out, 10, u64::from(*v)),
            Value::UInt64(v) => varint_field(out, 11, *v),
            Value::Double(v) => {
                key(out, 13, FIXED64);
                out.extend_from_slice(&v.to_le_bytes());
            }
            Value::Boolean(v) => varint_field(out, 14, u64::from(*v)),
            Value::String(s) => bytes_field(out, 15, s.as_bytes()),
        }
    }
}

impl Payload {
    /// The protobuf bytes of `Payload` (fields timestamp 1, metrics 2, seq 3).
    pub fn encode(&self) -> Vec<u8> {
        let mut out = Vec::with_capacity(64 + 48 * self.metrics.len());
        varint_field(&mut out, 1, self.timestamp_ms);
        let mut m = Vec::with_capacity(64);
        for metric in &self.metrics {
            m.clear();
            metric.encode(&mut m);
            bytes_field(&mut out, 2, &m);
        }
        if let Some(s) = self.seq {
            varint_field(&mut out, 3, s);
        }
        out
    }
}

/// Reads protobuf fields from a byte string; every read is checked, nothing panics.
struct Reader<'a> {
    b: &'a [u8],
}

/// One field's value as its wire type carries it.
enum Field<'a> {
    Varint(u64),
    Fixed64([u8; 8]),
    Fixed32([u8; 4]),
    Bytes(&'a [u8]),
}

impl<'a> Reader<'a> {
    fn varint(&mut self) -> Result<u64, String> {
        let mut v = 0u64;
        for i in 0..10 {
            let (&b, rest) = self.b.split_first().ok_or("a varint cut short")?;
            self.b = rest;
            v |= u64::from(b & 0x7f) << (7 * i);
            if b & 0x80 == 0 {
                return Ok(v);
            }
        }
        Err("a varint longer than 10 bytes".into())
    }

    fn take(&mut self, n: usize) -> Result<&'a [u8], String> {
        if n > self.b.len() {
            return Err(format!(
                "a field of {n} bytes where {} are left",
                self.b.len()
            ));
        }
        let (a, rest) = self.b.split_at(n);
        self.b = rest;
        Ok(a)
    }

    /// The next field, `None` at the end.
    fn field(&mut self) -> Result<Option<(u64, Field<'a>)>, String> {
        if self.b.is_empty() {
            return Ok(None);
        }
        let key = self.varint()?;
        let f = match key & 7 {
            0 => Field::Varint(self.varint()?),
            1 => Field::Fixed64(self.take(8)?.try_into().map_err(|_| "fixed64")?),
            2 => {
                let n = usize::try_from(self.varint()?).map_err(|_| "a length beyond memory")?;
                Field::Bytes(self.take(n)?)
            }
            5 => Field::Fixed32(self.take(4)?.try_into().map_err(|_| "fixed32")?),
            w => return Err(format!("wire type {w} (groups are not Sparkplug)")),
        };
        Ok(Some((key >> 3, f)))
    }
}

impl Metric {
    fn decode(b: &[u8]) -> Result<Self, String> {
        let mut r = Reader { b };
        let mut m = Metric::new("", Value::Null(0));
        let mut datatype = 0u32;
        let mut null = false;
        while let Some((n, f)) = r.field()? {
            m.value = match (n, f) {
                (1, Field::Bytes(x)) => {
                    m.name = String::from_utf8_lossy(x).into_owned();
                    continue;
                }
                (2, Field::Varint(v)) => {
                    m.alias = Some(v);
                    continue;
                }
                (3, Field::Varint(v)) => {
                    m.timestamp_ms = Some(v);
                    continue;
                }
                (4, Field::Varint(v)) => {
                    datatype = u32::try_from(v).unwrap_or(0);
                    continue;
                }
                (5, Field::Varint(v)) => {
                    m.historical = v != 0;
                    continue;
                }
                (7, Field::Varint(v)) => {
                    null = v != 0;
                    continue;
                }
                (10, Field::Varint(v)) => Value::UInt32(v as u32),
                (11, Field::Varint(v)) => Value::UInt64(v),
                (12, Field::Fixed32(x)) => Value::Double(f64::from(f32::from_le_bytes(x))),
                (13, Field::Fixed64(x)) => Value::Double(f64::from_le_bytes(x)),
                (14, Field::Varint(v)) => Value::Boolean(v != 0),
                (15, Field::Bytes(x)) => Value::String(String::from_utf8_lossy(x).into_owned()),
                // Fields this node never sends (metadata, properties, data sets): skipped.
                _ => continue,
            };
        }
        if null {
            m.value = Value::Null(datatype);
        }
        Ok(m)
    }
}

impl Payload {
    /// Decodes a Sparkplug B payload; bytes that are not one are an error, never a panic.
    /// Values come back by their protobuf field (`int_value` as `UInt32`, `float_value` as
    /// `Double`); a metric by alias alone has an empty name.
    pub fn decode(bytes: &[u8]) -> Result<Self, String> {
        let mut r = Reader { b: bytes };
        let mut p = Payload {
            timestamp_ms: 0,
            seq: None,
            metrics: Vec::new(),
        };
        let mut has_timestamp = false;
        while let Some((n, f)) = r.field()? {
            match (n, f) {
                (1, Field::Varint(v)) => {
                    p.timestamp_ms = v;
                    has_timestamp = true;
                }
                (2, Field::Bytes(m)) => p.metrics.push(Metric::decode(m)?),
                (3, Field::Varint(v)) => p.seq = Some(v),
                _ => {}
            }
        }
        if !has_timestamp {
            return Err("no timestamp: not a Sparkplug B payload".into());
        }
        Ok(p)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_payload_has_the_bytes_protobuf_gives_it() {
        // Worked by hand from the protobuf encoding rules: field 1 varint 1000 = 08 e8 07;
        // metric (field 2, length 11): name "a" = 0a 01 61, datatype 10 = 20 0a,
        // double 1.0 = 69 + 8 bytes; seq (field 3) 0 = 18 00.
        let p = Payload {
            timestamp_ms: 1000,
            seq: Some(0),
            metrics: vec![Metric::new("a", Value::Double(1.0))],
        };
        let mut want = vec![
            0x08, 0xe8, 0x07, 0x12, 14, 0x0a, 0x01, b'a', 0x20, 0x0a, 0x69,
        ];
        want.extend_from_slice(&1.0f64.to_le_bytes());
        want.extend_from_slice(&[0x18, 0x00]);
        assert_eq!(p.encode(), want);
    }

    #[test]
    fn a_metric_by_alias_carries_no_name_and_no_datatype() {
        let m = Metric {
            alias: Some(300),
            timestamp_ms: Some(1),
            ..Metric::new("", Value::UInt32(5))
        };
        let mut out = Vec::new();
        m.encode(&mut out);
        // alias 300 = 10 ac 02, timestamp 1 = 18 01, int_value 5 = 50 05.
        assert_eq!(out, [0x10, 0xac, 0x02, 0x18, 0x01, 0x50, 0x05]);
    }

    #[test]
    fn what_is_encoded_decodes_and_what_is_not_a_payload_is_refused() {
        let p = Payload {
            timestamp_ms: 1_764_000_000_000,
            seq: Some(7),
            metrics: vec![
                Metric::new("a", Value::Double(-1.5)),
                Metric {
                    alias: Some(9),
                    timestamp_ms: Some(5),
                    historical: true,
                    ..Metric::new("", Value::UInt32(3))
                },
                Metric::new("s", Value::String("x y".into())),
                Metric::new("n", Value::Null(DOUBLE)),
                Metric::new("b", Value::Boolean(true)),
                Metric::new("l", Value::UInt64(u64::MAX)),
            ],
        };
        assert_eq!(Payload::decode(&p.encode()), Ok(p.clone()));
        let bytes = p.encode();
        for cut in 0..bytes.len() {
            let _ = Payload::decode(&bytes[..cut]);
        }
        assert!(Payload::decode(b"").is_err());
        assert!(Payload::decode(b"{\"json\": true}").is_err());
        assert!(Payload::decode(&[0x08, 0xff, 0xff]).is_err());
        assert!(Payload::decode(&[0x12, 0xff, 0xff, 0xff, 0xff, 0x0f]).is_err());
        for a in 0..=255u8 {
            for b in [0u8, 1, 2, 0x7f, 0x80, 0xff] {
                let _ = Payload::decode(&[a, b, a, b, 0x0a, a]);
            }
        }
    }

    #[test]
    fn ids_cannot_break_the_topic() {
        assert_eq!(sanitize_id("vmc/3+#"), "vmc_3__");
        assert_eq!(sanitize_id(""), "_");
        assert_eq!(topic("g", MessageType::NData, "n"), "spBv1.0/g/NDATA/n");
    }
}
