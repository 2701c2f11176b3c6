//! FANUC pitch error compensation tapes: a table by hand to the tape the parameter manual's
//! rules give, the quantisation and the magnification it needs reported, every written tape
//! read back to the table within the reported loss, located errors, and no panic whatever a
//! one-character change does to a tape.

mod support;
use support::mutate;

use std::path::Path;

use proptest::prelude::*;
use truepos_controls::fanuc::{parse_fanuc, FanucGrid, FanucPitch};
use truepos_kinematics::table::{CompTable, Direction, Interpolation, Wrap};

fn p() -> &'static Path {
    Path::new("x.prm")
}

fn grid(reference: u32) -> FanucGrid {
    FanucGrid {
        axis: 1,
        reference,
        interval: None,
        magnification: None,
        detection_unit: 0.001,
        max_step: 7,
    }
}

fn table(pos: Vec<f64>, err: Vec<f64>) -> CompTable {
    CompTable::new(pos, err, Wrap::Hold, Interpolation::Linear).unwrap()
}

/// Error 0, 2, 5, 4, 9 µm at 0…400 mm: compensation −error; point k holds the step from
/// point k − 1 to k in 1 µm detection units.
const TAPE: &str = "%
N03620A1P40;
N03621A1P40;
N03622A1P44;
N03623A1P1;
N03624A1P100.0;
N10040P0;
N10041P-2;
N10042P-3;
N10043P1;
N10044P-5;
%
";

#[test]
fn a_table_by_hand_gives_the_manuals_tape() {
    let t = table(
        vec![0.0, 100.0, 200.0, 300.0, 400.0],
        vec![0.0, 2.0, 5.0, 4.0, 9.0],
    );
    let (tape, loss) = FanucPitch::from_table(&t, &grid(40)).unwrap();
    assert_eq!(tape.write(), TAPE);
    assert_eq!(loss.magnification, 1);
    assert_eq!(loss.quantisation_um, 0.0);
    let back = parse_fanuc(p(), TAPE).unwrap();
    assert_eq!(back, tape);
    let t2 = back.to_table(p(), 1, 0.001, Interpolation::Linear).unwrap();
    for x in [0.0, 50.0, 100.0, 250.0, 400.0] {
        let (a, b) = (
            t2.value(x, Direction::Forward),
            t.value(x, Direction::Forward),
        );
        assert!((a - b).abs() < 1e-9, "{x}: {a} vs {b}");
    }
    // No axis 2 on the tape; a detection unit of 0.01 mm reads ten times the error.
    let e = back
        .to_table(p(), 2, 0.001, Interpolation::Linear)
        .unwrap_err();
    assert!(
        e.to_string()
            .contains("no pitch error parameters 3620–3624 for axis A2; the tape has A1"),
        "{e}"
    );
    let t10 = back.to_table(p(), 1, 0.01, Interpolation::Linear).unwrap();
    assert!((t10.value(400.0, Direction::Forward) - 90.0).abs() < 1e-9);
}

#[test]
fn quantisation_magnification_and_the_reference_are_reported() {
    // 20 µm per 100 mm interval: more than 7 units of 1 µm, so magnification 3 (6.7 units).
    let t = table(vec![-200.0, 0.0, 200.0], vec![-40.0, 0.3, 40.6]);
    let g100 = |reference| FanucGrid {
        interval: Some(100.0),
        ..grid(reference)
    };
    let (tape, loss) = FanucPitch::from_table(&t, &g100(100)).unwrap();
    assert_eq!(loss.magnification, 3);
    assert_eq!(tape.axes[&1].magnification, 3);
    // The error at the reference position (0.3 µm) is not carried; the rest to ±1.5 µm.
    assert!((loss.at_reference_um - 0.3).abs() < 1e-12);
    assert!(
        loss.quantisation_um <= 1.5 + 1e-9 && loss.quantisation_um > 0.0,
        "{loss:?}"
    );
    // The grid starts one point below the table (the first point's value is the section
    // before it) and covers the reference position.
    assert_eq!((tape.axes[&1].negative, tape.axes[&1].positive), (98, 102));
    // A fixed magnification too small for a step is refused, naming the limit.
    let mut g = g100(100);
    g.magnification = Some(1);
    let e = FanucPitch::from_table(&t, &g).unwrap_err();
    assert!(
        e.to_string().contains("exceeds ±7 at magnification 1"),
        "{e}"
    );
    // Points beyond 0 … 1023 and unequal spacing without an interval are refused.
    let e = FanucPitch::from_table(&t, &g100(1)).unwrap_err();
    assert!(e.to_string().contains("needs points -2 to 3"), "{e}");
    let uneven = table(vec![0.0, 10.0, 30.0], vec![0.0, 1.0, 2.0]);
    let e = FanucPitch::from_table(&uneven, &grid(10)).unwrap_err();
    assert!(e.to_string().contains("not equidistant"), "{e}");
    let mut g = grid(10);
    g.interval = Some(10.0);
    let (tape, _) = FanucPitch::from_table(&uneven, &g).unwrap();
    assert_eq!(tape.points.len(), 4);
    let dir = CompTable::directional(
        vec![0.0, 10.0],
        vec![0.0, 1.0],
        vec![1.0, 2.0],
        Wrap::Hold,
        Interpolation::Linear,
    )
    .unwrap();
    let e = FanucPitch::from_table(&dir, &grid(10)).unwrap_err();
    assert!(e.to_string().contains("bidirectional"), "{e}");
    // A detection unit or range that makes no tape is refused, writing and reading.
    let e = FanucPitch::from_table(
        &uneven,
        &FanucGrid {
            detection_unit: 0.0,
            ..g
        },
    )
    .unwrap_err();
    assert!(e.to_string().contains("detection unit"), "{e}");
    let e = FanucPitch::from_table(&uneven, &FanucGrid { max_step: 0, ..g }).unwrap_err();
    assert!(e.to_string().contains("at least 1"), "{e}");
    let e = tape
        .to_table(p(), 1, f64::NAN, Interpolation::Linear)
        .unwrap_err();
    assert!(e.to_string().contains("detection unit NaN"), "{e}");
}

#[test]
fn malformed_tapes_are_located() {
    type Case<'a> = (&'a str, String, Option<(usize, usize)>, &'a str);
    let cases: [Case; 8] = [
        (
            "cut short",
            TAPE.replace("N10044P-5;\n%\n", "N10044P-5;\n"),
            None,
            "no closing `%`",
        ),
        (
            "no semicolon",
            TAPE.replace("N10042P-3;", "N10042P-3"),
            Some((9, 10)),
            "expected `;`",
        ),
        (
            "letter",
            TAPE.replace("N10042P-3;", "N10042X-3;"),
            Some((9, 1)),
            "N1xxxxP",
        ),
        (
            "parameter",
            TAPE.replace("N03623", "N03633"),
            Some((5, 2)),
            "parameter 3633",
        ),
        (
            "value",
            TAPE.replace("N10043P1;", "N10043P1.5;"),
            Some((10, 8)),
            "integer compensation value",
        ),
        (
            "interval",
            TAPE.replace("P100.0", "P-100.0"),
            Some((6, 10)),
            "positive interval",
        ),
        (
            "twice",
            TAPE.replace("N10043P1;", "N10042P1;"),
            Some((10, 1)),
            "given twice",
        ),
        (
            "after",
            format!("{TAPE}N1P1;\n"),
            Some((13, 1)),
            "after the closing",
        ),
    ];
    for (what, text, at, msg) in cases {
        let e = parse_fanuc(p(), &text).unwrap_err();
        assert!(e.to_string().contains(msg), "{what}: {e}");
        assert_eq!(e.position, at, "{what}: {e}");
    }
    // A parameter missing for an axis, a point missing in the data: named.
    let e = parse_fanuc(p(), &TAPE.replace("N03623A1P1;\n", "")).unwrap_err();
    assert!(e.to_string().contains("A1 has no parameter 3623"), "{e}");
    let tape = parse_fanuc(p(), &TAPE.replace("N10042P-3;\n", "")).unwrap();
    let e = tape
        .to_table(p(), 1, 0.001, Interpolation::Linear)
        .unwrap_err();
    assert!(
        e.to_string().contains("no data for point 42 (N10042)"),
        "{e}"
    );
}

proptest! {
    /// Any equidistant table on the grid reads back from its tape within the reported
    /// quantisation, relative to the reference position.
    #[test]
    fn written_tapes_read_back_within_the_reported_loss(
        first in -20i32..5,
        steps in 1usize..40,
        interval in prop::sample::select(vec![5.0, 10.0, 25.0, 50.0]),
        values in prop::collection::vec(-30.0f64..30.0, 41),
        unit in prop::sample::select(vec![0.001, 0.0001, 0.01]),
    ) {
        let pos: Vec<f64> = (0..=steps).map(|i| (first + i as i32) as f64 * interval).collect();
        let t = table(pos.clone(), values[..pos.len()].to_vec());
        let mut g = grid(500);
        g.detection_unit = unit;
        let Ok((tape, loss)) = FanucPitch::from_table(&t, &g) else {
            // Only a step beyond ±7 at every magnification may refuse it.
            let unit_um = unit * 1000.0 * 100.0;
            prop_assert!(values.windows(2).any(|w| (w[1] - w[0]).abs() > 6.0 * unit_um));
            return Ok(());
        };
        let back = parse_fanuc(p(), &tape.write()).unwrap();
        prop_assert_eq!(&back, &tape);
        let t2 = back.to_table(p(), 1, unit, Interpolation::Linear).unwrap();
        for &x in &pos {
            let want = t.value(x, Direction::Forward) - loss.at_reference_um;
            let got = t2.value(x, Direction::Forward);
            prop_assert!((got - want).abs() <= loss.quantisation_um + 1e-9, "{} µm vs {} at {}", got, want, x);
        }
    }

    /// Whatever one-character change a tape gets, reading it returns a table or a located
    /// error; never a panic, never a non-finite value.
    #[test]
    fn mutations_never_panic(
        at in 0usize..10_000,
        with in prop::sample::select(vec!['%', ';', 'N', 'A', 'P', '-', '9', '.', 'e', ' ', '\n', 'é']),
        delete in any::<bool>(),
    ) {
        if let Ok(tape) = parse_fanuc(p(), &mutate(TAPE, at, with, delete)) {
            for axis in [1, 2, 9] {
                if let Ok(t) = tape.to_table(p(), axis, 0.001, Interpolation::Linear) {
                    for x in [-1e9, -5.0, 0.0, 123.0, 1e9] {
                        prop_assert!(t.value(x, Direction::Forward).is_finite());
                    }
                }
            }
        }
    }
}
