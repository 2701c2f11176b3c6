//! ISG leadscrew error compensation lists (`kw.ssfk.*`): the documentation's example layout
//! reads to its values, what truepos writes reads back identically (unilateral, bilateral,
//! equidistant or not), malformed lists get located errors, and no one-character change makes
//! the reader panic.

mod support;
use support::mutate;

use std::path::Path;

use proptest::prelude::*;
use truepos_controls::isg::{parse_isg, IsgSsfk};
use truepos_kinematics::table::{CompTable, Direction, Interpolation, Wrap};

fn p() -> &'static Path {
    Path::new("achskw2.lis")
}

/// Non-equidistant and bilateral, as the documentation's example (shortened to 3 entries).
const LIST: &str = "\
# compensation value list of Y
kopf.achs_nr                        2
kopf.log_achs_name                  Y
kw.ssfk.interval                    0
kw.ssfk.kw_startpos                 -200000
kw.ssfk.kw_nr_max                   3
kw.ssfk.unit                        1   /* metric, 0.1 um */
kw.ssfk.bilateral                   1
kw.ssfk.table[0].setpoint           -200000
kw.ssfk.table[1].setpoint           -199306
kw.ssfk.table[2].setpoint           -198667
kw.ssfk.table[0].pos                0
kw.ssfk.table[1].pos                24
kw.ssfk.table[2].pos                -102
kw.ssfk.table[0].neg                0
kw.ssfk.table[1].neg                67
kw.ssfk.table[2].neg                80
";

#[test]
fn the_documented_layout_reads_to_its_values() {
    let l = parse_isg(p(), LIST).unwrap();
    assert_eq!((l.axis_nr, l.axis_name.as_deref()), (2, Some("Y")));
    let t = l.to_table(Interpolation::Linear).unwrap();
    assert_eq!(t.positions(), &[-20.0, -19.9306, -19.8667]);
    // −102 × 0.1 µm moving positive, +80 × 0.1 µm moving negative at the third point.
    assert!((t.value(-19.8667, Direction::Forward) + 10.2).abs() < 1e-9);
    assert!((t.value(-19.8667, Direction::Reverse) - 8.0).abs() < 1e-9);
    assert_eq!(parse_isg(p(), &l.write()).unwrap(), l);
    // Written from the table: the same list (set-points, bilateral).
    let again = IsgSsfk::from_table(&t, 2, Some("Y")).unwrap();
    assert_eq!(again, l);
}

#[test]
fn malformed_lists_are_located() {
    let cases = [
        (
            "unit",
            LIST.replace(
                "unit                        1",
                "unit                        0",
            ),
            Some((7, 37)),
            "metric lists",
        ),
        (
            "number",
            LIST.replace("pos                24", "pos                2.4"),
            Some((13, 37)),
            "32-bit integer",
        ),
        (
            "unknown",
            LIST.replace("kw.ssfk.bilateral ", "kw.ssfk.bilaterl  "),
            Some((8, 1)),
            "unknown name",
        ),
        (
            "twice",
            LIST.replace("table[2].neg", "table[1].neg"),
            Some((17, 1)),
            "given twice",
        ),
        (
            "field",
            LIST.replace("table[2].neg", "table[2].nag"),
            Some((17, 1)),
            ".pos, .neg or .setpoint",
        ),
        (
            "missing",
            LIST.replace("kw.ssfk.table[1].pos                24\n", ""),
            None,
            "no kw.ssfk.table[1].pos",
        ),
        (
            "order",
            LIST.replace("-199306", "-200001"),
            Some((13, 1)),
            "strictly increasing",
        ),
        (
            "words",
            LIST.replace("kopf.achs_nr                        2", "kopf.achs_nr 2 3"),
            Some((2, 1)),
            "`name value`",
        ),
    ];
    for (what, text, at, msg) in cases {
        let e = parse_isg(p(), &text)
            .and_then(|l| l.to_table(Interpolation::Linear))
            .unwrap_err();
        assert!(e.to_string().contains(msg), "{what}: {e}");
        assert_eq!(e.position, at, "{what}: {e}");
    }
}

proptest! {
    /// Tables on the 0.1 µm grid read back from their list to 0.05 µm (the rounding of the
    /// values), the list itself identically.
    #[test]
    fn written_lists_read_back(
        start in -100_000i64..100_000,
        steps in prop::collection::vec(1i64..50_000, 1..40),
        equal in any::<bool>(),
        values in prop::collection::vec(-300.0f64..300.0, 41),
        reverse in prop::collection::vec(-300.0f64..300.0, 41),
        directional in any::<bool>(),
    ) {
        let mut pos = vec![start as f64 / 1e4];
        let mut at = start;
        for s in &steps {
            at += if equal { steps[0] } else { *s };
            pos.push(at as f64 / 1e4);
        }
        let n = pos.len();
        let t = if directional {
            CompTable::directional(pos, values[..n].to_vec(), reverse[..n].to_vec(), Wrap::Hold, Interpolation::Linear)
        } else {
            CompTable::new(pos, values[..n].to_vec(), Wrap::Hold, Interpolation::Linear)
        }.unwrap();
        let l = IsgSsfk::from_table(&t, 1, Some("X")).unwrap();
        let back = parse_isg(p(), &l.write()).unwrap();
        prop_assert_eq!(&back, &l);
        let t2 = back.to_table(Interpolation::Linear).unwrap();
        for (a, b) in t2.positions().iter().zip(t.positions()) {
            prop_assert!((a - b).abs() < 1e-9);
        }
        for (a, b) in t2.forward().iter().zip(t.forward()) {
            prop_assert!((a - b).abs() <= 0.05 + 1e-9);
        }
    }

    #[test]
    fn mutations_never_panic(
        at in 0usize..10_000,
        with in prop::sample::select(vec!['[', ']', '.', '-', '9', ' ', '\n', '#', '/', '*', 'é']),
        delete in any::<bool>(),
    ) {
        if let Ok(l) = parse_isg(p(), &mutate(LIST, at, with, delete)) {
            if let Ok(t) = l.to_table(Interpolation::Linear) {
                for x in [-1e9, -20.0, -19.9, 0.0, 1e9] {
                    prop_assert!(t.value(x, Direction::Forward).is_finite());
                    prop_assert!(t.value(x, Direction::Reverse).is_finite());
                }
            }
        }
    }
}
