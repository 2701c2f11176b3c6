//! The SHDR line protocol, pure and never panicking: one line into data items or a protocol
//! command, and a byte stream into bounded lines.

/// One line from an adapter.
#[derive(Debug, Clone, PartialEq)]
pub enum ShdrLine<'a> {
    /// Data: the adapter's timestamp (possibly empty) and the items of the line.
    Data {
        /// The first field as sent (ISO 8601 time, possibly with `@duration`, or empty).
        timestamp: &'a str,
        /// `dataItemId|value` pairs in line order.
        items: Vec<ShdrItem<'a>>,
    },
    /// `* PONG <ms>`: the adapter is alive and announces its heartbeat interval in ms.
    Pong {
        /// The announced interval in ms (≥ 1).
        interval_ms: u64,
    },
    /// Any other protocol line, `* name: value` or `* name value` (e.g. `* shdrVersion: 2`).
    Command {
        /// The command's name.
        name: &'a str,
        /// The rest of the line, trimmed (may be empty).
        value: &'a str,
    },
}

/// One `dataItemId|value` pair.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ShdrItem<'a> {
    /// The data item's id (or name) in the adapter's device model.
    pub id: &'a str,
    /// Its value.
    pub value: ShdrValue<'a>,
}

/// The value of a data item.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ShdrValue<'a> {
    /// A finite number (a POSITION in mm, ANGLE in degrees, TEMPERATURE in °C).
    Number(f64),
    /// `UNAVAILABLE`: the adapter does not know the value.
    Unavailable,
    /// Anything else (an event's text, or a number that is not finite), trimmed.
    Text(&'a str),
}

/// Why a line cannot be read.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ShdrError {
    /// The line is empty or only white space.
    Empty,
    /// A data line without any `|`.
    NoItems,
    /// A data item id without a value (the line has an even number of fields).
    MissingValue {
        /// The id left without a value.
        id: String,
    },
    /// An empty data item id.
    EmptyId {
        /// 1-based field number in the line (the timestamp is field 1).
        field: usize,
    },
    /// `* PONG` without a positive whole number of ms.
    BadPong {
        /// What followed `PONG`.
        found: String,
    },
    /// A `*` line without a command name.
    EmptyCommand,
}

impl std::fmt::Display for ShdrError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Empty => write!(f, "empty line; expected timestamp|dataItemId|value…"),
            Self::NoItems => {
                write!(
                    f,
                    "expected timestamp|dataItemId|value…, found no `|` in the line"
                )
            }
            Self::MissingValue { id } => write!(
                f,
                "expected dataItemId|value pairs after the timestamp; data item `{id}` has no value"
            ),
            Self::EmptyId { field } => {
                write!(
                    f,
                    "expected a data item id in field {field}, found an empty field"
                )
            }
            Self::BadPong { found } => write!(
                f,
                "expected `* PONG <interval in ms>` with a whole number ≥ 1, found `{found}`"
            ),
            Self::EmptyCommand => write!(f, "expected a command after `*`, found nothing"),
        }
    }
}

impl std::error::Error for ShdrError {}

/// Reads one SHDR line (with or without its line end). Pure; never panics.
///
/// ```
/// use truepos_protocols::shdr::{parse_line, ShdrLine, ShdrValue};
/// let line = parse_line("2024-05-01T10:00:00.000Z|Xact|125.5|Tspindle|UNAVAILABLE\r\n").unwrap();
/// let ShdrLine::Data { items, .. } = line else { panic!() };
/// assert_eq!(items[0].value, ShdrValue::Number(125.5));
/// assert_eq!(items[1].value, ShdrValue::Unavailable);
/// assert_eq!(parse_line("* PONG 10000").unwrap(), ShdrLine::Pong { interval_ms: 10000 });
/// ```
pub fn parse_line(line: &str) -> Result<ShdrLine<'_>, ShdrError> {
    let line = line.trim_end_matches(['\r', '\n']);
    if line.trim().is_empty() {
        return Err(ShdrError::Empty);
    }
    if let Some(command) = line.strip_prefix('*') {
        return parse_command(command.trim());
    }
    let mut fields = line.split('|');
    // `split` always yields a first field.
    let timestamp = fields.next().unwrap_or_default().trim();
    let mut items = Vec::new();
    let mut field = 1;
    while let Some(id) = fields.next() {
        field += 1;
        let id = id.trim();
        let Some(value) = fields.next() else {
            return Err(ShdrError::MissingValue { id: id.to_string() });
        };
        if id.is_empty() {
            return Err(ShdrError::EmptyId { field });
        }
        field += 1;
        items.push(ShdrItem {
            id,
            value: parse_value(value),
        });
    }
    if items.is_empty() {
        return Err(ShdrError::NoItems);
    }
    Ok(ShdrLine::Data { timestamp, items })
}

fn parse_command(command: &str) -> Result<ShdrLine<'_>, ShdrError> {
    let (name, value) = match command.find([':', ' ', '\t']) {
        Some(i) => (&command[..i], command[i + 1..].trim()),
        None => (command, ""),
    };
    let name = name.trim();
    if name.is_empty() {
        return Err(ShdrError::EmptyCommand);
    }
    if name == "PONG" {
        return match value.parse::<u64>() {
            Ok(ms) if ms >= 1 => Ok(ShdrLine::Pong { interval_ms: ms }),
            _ => Err(ShdrError::BadPong {
                found: value.to_string(),
            }),
        };
    }
    Ok(ShdrLine::Command { name, value })
}

/// A value field: `UNAVAILABLE`, a finite number, or text.
pub fn parse_value(field: &str) -> ShdrValue<'_> {
    let text = field.trim();
    if text == "UNAVAILABLE" {
        return ShdrValue::Unavailable;
    }
    match text.parse::<f64>() {
        Ok(x) if x.is_finite() => ShdrValue::Number(x),
        _ => ShdrValue::Text(text),
    }
}

/// The longest line the client accepts, in bytes; a longer one is a protocol error and ends the
/// connection.
pub const MAX_LINE_BYTES: usize = 64 * 1024;

/// Splits a byte stream into lines (`\n`, with an optional `\r`), across reads.
#[derive(Debug, Default)]
pub struct LineBuffer {
    pending: Vec<u8>,
}

impl LineBuffer {
    /// Appends received bytes and calls `line` for each complete line (as bytes, without its
    /// end). Fails when a line exceeds [`MAX_LINE_BYTES`]; the buffer is then cleared.
    pub fn push(&mut self, bytes: &[u8], mut line: impl FnMut(&[u8])) -> Result<(), String> {
        self.pending.extend_from_slice(bytes);
        let mut start = 0;
        while let Some(n) = self.pending[start..].iter().position(|&b| b == b'\n') {
            let end = start + n;
            let body = &self.pending[start..end];
            line(body.strip_suffix(b"\r").unwrap_or(body));
            start = end + 1;
        }
        self.pending.drain(..start);
        if self.pending.len() > MAX_LINE_BYTES {
            let n = self.pending.len();
            self.pending.clear();
            return Err(format!(
                "expected lines of at most {MAX_LINE_BYTES} bytes, found {n} bytes without a line end"
            ));
        }
        Ok(())
    }

    /// Bytes of the line under way (received, no line end yet).
    pub fn pending_len(&self) -> usize {
        self.pending.len()
    }

    /// Bytes the buffer holds room for (bounded: about [`MAX_LINE_BYTES`] plus one read).
    pub fn capacity(&self) -> usize {
        self.pending.capacity()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn data(line: &str) -> Vec<ShdrItem<'_>> {
        match parse_line(line) {
            Ok(ShdrLine::Data { items, .. }) => items,
            other => panic!("expected data from {line:?}, got {other:?}"),
        }
    }

    #[test]
    fn data_lines() {
        let items = data("2024-05-01T10:00:00.123456Z|Xact|125.500|Tspindle|24.1\n");
        assert_eq!(items.len(), 2);
        assert_eq!(
            items[0],
            ShdrItem {
                id: "Xact",
                value: ShdrValue::Number(125.5)
            }
        );
        assert_eq!(
            items[1],
            ShdrItem {
                id: "Tspindle",
                value: ShdrValue::Number(24.1)
            }
        );
        // Empty timestamp, CRLF, spaces around fields, negative and exponent numbers.
        let items = data("| Zact | -3.5e1 |exec|ACTIVE|T1|UNAVAILABLE\r\n");
        assert_eq!(items[0].value, ShdrValue::Number(-35.0));
        assert_eq!(items[1].value, ShdrValue::Text("ACTIVE"));
        assert_eq!(items[2].value, ShdrValue::Unavailable);
        // An empty value is text, not a number; non-finite numbers are text too.
        assert_eq!(data("t|a|")[0].value, ShdrValue::Text(""));
        assert_eq!(data("t|a|NaN|b|inf")[0].value, ShdrValue::Text("NaN"));
        assert_eq!(data("t|a|NaN|b|inf")[1].value, ShdrValue::Text("inf"));
        match parse_line("2024-05-01T10:00:00Z@100.0|x|1").unwrap() {
            ShdrLine::Data { timestamp, .. } => assert_eq!(timestamp, "2024-05-01T10:00:00Z@100.0"),
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn protocol_lines() {
        assert_eq!(
            parse_line("* PONG 10000\r\n"),
            Ok(ShdrLine::Pong { interval_ms: 10000 })
        );
        assert_eq!(
            parse_line("*PONG 250"),
            Ok(ShdrLine::Pong { interval_ms: 250 })
        );
        assert_eq!(
            parse_line("* shdrVersion: 2"),
            Ok(ShdrLine::Command {
                name: "shdrVersion",
                value: "2"
            })
        );
        assert_eq!(
            parse_line("* PING"),
            Ok(ShdrLine::Command {
                name: "PING",
                value: ""
            })
        );
    }

    #[test]
    fn malformed_lines_are_errors_naming_the_problem() {
        assert_eq!(parse_line(""), Err(ShdrError::Empty));
        assert_eq!(parse_line(" \r\n"), Err(ShdrError::Empty));
        assert_eq!(parse_line("2024-05-01T10:00:00Z"), Err(ShdrError::NoItems));
        assert_eq!(
            parse_line("t|Xact|1|Yact"),
            Err(ShdrError::MissingValue { id: "Yact".into() })
        );
        assert_eq!(parse_line("t||1"), Err(ShdrError::EmptyId { field: 2 }));
        assert_eq!(
            parse_line("t|a|1| |2"),
            Err(ShdrError::EmptyId { field: 4 })
        );
        assert_eq!(
            parse_line("* PONG"),
            Err(ShdrError::BadPong { found: "".into() })
        );
        assert_eq!(
            parse_line("* PONG 0"),
            Err(ShdrError::BadPong { found: "0".into() })
        );
        assert_eq!(
            parse_line("* PONG -5"),
            Err(ShdrError::BadPong { found: "-5".into() })
        );
        assert_eq!(parse_line("*  "), Err(ShdrError::EmptyCommand));
        assert_eq!(
            ShdrError::MissingValue { id: "Yact".into() }.to_string(),
            "expected dataItemId|value pairs after the timestamp; data item `Yact` has no value"
        );
    }

    #[test]
    fn line_buffer_splits_across_reads() {
        let mut b = LineBuffer::default();
        let mut got: Vec<String> = Vec::new();
        b.push(b"t|a|1\r\nt|b", |l| {
            got.push(String::from_utf8_lossy(l).into())
        })
        .unwrap();
        assert_eq!(got, ["t|a|1"]);
        b.push(b"|2\n\n* PONG 5\n", |l| {
            got.push(String::from_utf8_lossy(l).into())
        })
        .unwrap();
        assert_eq!(got, ["t|a|1", "t|b|2", "", "* PONG 5"]);
        let long = vec![b'x'; MAX_LINE_BYTES + 1];
        assert!(b.push(&long, |_| {}).is_err());
        b.push(b"ok\n", |l| assert_eq!(l, b"ok")).unwrap();
    }
}
