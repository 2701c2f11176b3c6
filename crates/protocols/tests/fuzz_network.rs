//! No panic on any input: property-based fuzzing of the SHDR line parser and the Modbus
//! decoding (answers and register encodings).
//!
//! In release builds the properties below run 1,100,000 cases in total (`.ci/run` runs
//! `cargo test --release -p truepos-protocols --test fuzz_network`); the normal (debug) suite runs
//! a hundredth of that. `TRUEPOS_FUZZ_SCALE` overrides the divisor (1 = full count).

use proptest::prelude::*;
use proptest::test_runner::Config;

use truepos_protocols::modbus::{
    decode, parse_header, parse_response_adu, Encoding, ModbusError, ReadRequest, RegisterKind,
    WordOrder, MBAP_HEADER_BYTES,
};
use truepos_protocols::shdr::{parse_line, LineBuffer, ShdrLine, ShdrValue};

/// Cases for a property that runs `full` cases in a release build.
fn cases(full: u32) -> Config {
    let divisor = std::env::var("TRUEPOS_FUZZ_SCALE")
        .ok()
        .and_then(|s| s.parse::<u32>().ok())
        .filter(|&d| d >= 1)
        .unwrap_or(if cfg!(debug_assertions) { 100 } else { 1 });
    Config {
        cases: (full / divisor).max(100),
        failure_persistence: None,
        ..Config::default()
    }
}

/// Checks what every successful parse must satisfy.
fn check_shdr(line: &str) {
    match parse_line(line) {
        Ok(ShdrLine::Data { items, timestamp }) => {
            assert!(!items.is_empty());
            assert!(!timestamp.contains('|'));
            for item in items {
                assert!(!item.id.is_empty() && !item.id.contains('|'));
                if let ShdrValue::Number(x) = item.value {
                    assert!(x.is_finite());
                }
            }
        }
        Ok(ShdrLine::Pong { interval_ms }) => assert!(interval_ms >= 1),
        Ok(ShdrLine::Command { name, .. }) => assert!(!name.is_empty()),
        Err(e) => assert!(!e.to_string().is_empty()),
    }
}

fn kind() -> impl Strategy<Value = RegisterKind> {
    prop_oneof![Just(RegisterKind::Holding), Just(RegisterKind::Input)]
}

fn request() -> impl Strategy<Value = ReadRequest> {
    (any::<u16>(), any::<u8>(), kind(), any::<u16>(), 1u16..=125).prop_map(
        |(transaction, unit, kind, address, count)| ReadRequest {
            transaction,
            unit,
            kind,
            address,
            count,
        },
    )
}

fn encoding() -> impl Strategy<Value = Encoding> {
    prop_oneof![
        Just(Encoding::Int16Tenths),
        Just(Encoding::Int16Hundredths),
        Just(Encoding::Uint16),
        Just(Encoding::Float32)
    ]
}

fn order() -> impl Strategy<Value = WordOrder> {
    prop_oneof![Just(WordOrder::HighFirst), Just(WordOrder::LowFirst)]
}

/// A correct answer to `r` carrying `values`.
fn answer(r: &ReadRequest, values: &[u16]) -> Vec<u8> {
    let mut out = r.transaction.to_be_bytes().to_vec();
    out.extend_from_slice(&[0, 0]);
    out.extend_from_slice(&(3 + 2 * values.len() as u16).to_be_bytes());
    out.extend_from_slice(&[r.unit, r.kind.function_code(), (2 * values.len()) as u8]);
    for v in values {
        out.extend_from_slice(&v.to_be_bytes());
    }
    out
}

proptest! {
    #![proptest_config(cases(250_000))]
    /// Any text at all.
    #[test]
    fn shdr_any_text(line in any::<String>()) {
        check_shdr(&line);
    }
}

proptest! {
    #![proptest_config(cases(250_000))]
    /// Text made of SHDR's own characters, so that most lines come close to valid ones.
    #[test]
    fn shdr_like_text(line in "[*|:. 0-9eE+\\-aPINGOUVLBnfTXZ\r\n\t]{0,60}") {
        check_shdr(&line);
    }
}

proptest! {
    #![proptest_config(cases(100_000))]
    /// Well-formed lines read back exactly.
    #[test]
    fn shdr_round_trip(
        timestamp in "[0-9T:.Z\\-]{0,26}",
        items in prop::collection::vec(
            ("[A-Za-z][A-Za-z0-9_]{0,8}", prop::option::of(any::<f64>().prop_filter("finite", |x| x.is_finite()))),
            1..6,
        ),
    ) {
        let mut line = timestamp.clone();
        for (id, value) in &items {
            match value {
                Some(x) => line.push_str(&format!("|{id}|{x}")),
                None => line.push_str(&format!("|{id}|UNAVAILABLE")),
            }
        }
        line.push_str("\r\n");
        let ShdrLine::Data { timestamp: t, items: got } = parse_line(&line).unwrap() else {
            panic!("not data: {line}");
        };
        prop_assert_eq!(t, timestamp.as_str());
        prop_assert_eq!(got.len(), items.len());
        for (g, (id, value)) in got.iter().zip(&items) {
            prop_assert_eq!(g.id, id.as_str());
            let want = match value {
                Some(x) => ShdrValue::Number(*x),
                None => ShdrValue::Unavailable,
            };
            prop_assert_eq!(g.value, want);
        }
    }
}

proptest! {
    #![proptest_config(cases(50_000))]
    /// The line splitter gives the same lines however the stream is cut into reads.
    #[test]
    fn line_buffer_any_chunking(
        bytes in prop::collection::vec(prop_oneof![Just(b'\n'), Just(b'\r'), any::<u8>()], 0..300),
        cuts in prop::collection::vec(0usize..300, 0..10),
    ) {
        let mut whole = Vec::new();
        LineBuffer::default().push(&bytes, |l| whole.push(l.to_vec())).unwrap();
        let mut cuts: Vec<usize> = cuts.into_iter().map(|c| c.min(bytes.len())).collect();
        cuts.push(0);
        cuts.push(bytes.len());
        cuts.sort_unstable();
        let mut pieces = Vec::new();
        let mut buffer = LineBuffer::default();
        for w in cuts.windows(2) {
            buffer.push(&bytes[w[0]..w[1]], |l| pieces.push(l.to_vec())).unwrap();
        }
        prop_assert_eq!(pieces, whole);
    }
}

proptest! {
    #![proptest_config(cases(150_000))]
    /// Any bytes as an answer to any request.
    #[test]
    fn modbus_any_answer(r in request(), adu in prop::collection::vec(any::<u8>(), 0..300)) {
        match parse_response_adu(&r, &adu) {
            Ok(registers) => prop_assert_eq!(registers.len(), usize::from(r.count)),
            Err(ModbusError::Exception { function, .. }) => {
                prop_assert_eq!(function, r.kind.function_code())
            }
            Err(e) => prop_assert!(!e.to_string().is_empty()),
        }
        if adu.len() >= MBAP_HEADER_BYTES {
            if let Ok(h) = parse_header(&adu) {
                prop_assert!((2..=254).contains(&h.length));
            }
        }
    }
}

proptest! {
    #![proptest_config(cases(100_000))]
    /// A correct answer with one byte changed (or cut short) is read or refused, never a panic;
    /// unchanged, it reads back its registers.
    #[test]
    fn modbus_mutated_answer(
        r in request().prop_map(|r| ReadRequest { count: r.count.min(20), ..r }),
        values in prop::collection::vec(any::<u16>(), 20),
        at in any::<prop::sample::Index>(),
        byte in any::<u8>(),
        cut in any::<prop::sample::Index>(),
    ) {
        let good = answer(&r, &values[..usize::from(r.count)]);
        prop_assert_eq!(parse_response_adu(&r, &good).unwrap(), &values[..usize::from(r.count)]);
        let mut bad = good.clone();
        let i = at.index(bad.len());
        bad[i] = byte;
        if let Ok(registers) = parse_response_adu(&r, &bad) {
            prop_assert_eq!(registers.len(), usize::from(r.count));
        }
        let short = &good[..cut.index(good.len())];
        prop_assert!(parse_response_adu(&r, short).is_err());
    }
}

proptest! {
    #![proptest_config(cases(150_000))]
    /// Any registers in any encoding: a finite value or an error, never a panic or a NaN.
    #[test]
    fn modbus_decode_any_registers(
        e in encoding(),
        o in order(),
        registers in prop::collection::vec(any::<u16>(), 0..4),
    ) {
        match decode(e, o, &registers) {
            Ok(x) => {
                prop_assert!(x.is_finite());
                prop_assert_eq!(registers.len(), usize::from(e.registers()));
            }
            Err(err) => prop_assert!(!err.to_string().is_empty()),
        }
    }
}

proptest! {
    #![proptest_config(cases(50_000))]
    /// Values written the way a module writes them decode to themselves.
    #[test]
    fn modbus_decode_round_trip(t in any::<i16>(), u in any::<u16>(), f in any::<f32>()) {
        let r = t as u16;
        prop_assert_eq!(decode(Encoding::Int16Tenths, WordOrder::HighFirst, &[r]), Ok(f64::from(t) / 10.0));
        prop_assert_eq!(decode(Encoding::Int16Hundredths, WordOrder::LowFirst, &[r]), Ok(f64::from(t) / 100.0));
        prop_assert_eq!(decode(Encoding::Uint16, WordOrder::HighFirst, &[u]), Ok(f64::from(u)));
        let bits = f.to_bits();
        let (high, low) = ((bits >> 16) as u16, bits as u16);
        let hf = decode(Encoding::Float32, WordOrder::HighFirst, &[high, low]);
        let lf = decode(Encoding::Float32, WordOrder::LowFirst, &[low, high]);
        prop_assert_eq!(hf, lf);
        if f.is_finite() {
            prop_assert_eq!(hf, Ok(f64::from(f)));
        } else {
            prop_assert!(hf.is_err());
        }
    }
}
