//! HEIDENHAIN `.COM` compensation-value tables and `.CMA` assignment tables: what truepos
//! writes reads back identically, a hand-written pair in the manual's layout (Z = F(Z),
//! Y = F(Y) and the sag Z = F(Y)) reads to the values it states, malformed files get located
//! errors, and no one-character change makes the readers panic.

mod support;
use support::mutate;

use std::path::Path;

use proptest::prelude::*;
use truepos_controls::heidenhain::{
    parse_cma, parse_com, read_heidenhain, HeidenhainCma, HeidenhainCom,
};
use truepos_kinematics::table::{CompTable, Direction, Interpolation, Wrap};

fn p() -> &'static Path {
    Path::new("t.COM")
}

/// Y's table: its own pitch error (column Y) and the sag of Z over Y (column Z), in the
/// manual's example ranges (Y from −90 mm); the `.CMA` has a blank cell and an inactive line.
const Y_COM: &str = "\
BEGIN Y.COM MM
NR   AXISPOS   Y         Z
0    -90       0         0.001
1    10        0.002     0.004
2    110       -0.0015   0.0035
3    210       0.001     0
[END]
";

const CMA: &str = "\
BEGIN CONFIG.CMA
NR  X   Y        Z       ACTIVE
0       Y.COM    Z.COM   *
1       OLD.COM
[END]
";

#[test]
fn the_manuals_layout_reads_to_its_values() {
    let com = parse_com(p(), Y_COM).unwrap();
    assert_eq!(com.name, "Y.COM");
    assert_eq!(com.axispos, vec![-90.0, 10.0, 110.0, 210.0]);
    assert_eq!(com.columns[0].0, "Y");
    assert_eq!(com.columns[1].1, vec![0.001, 0.004, 0.0035, 0.0]);
    let lin = Interpolation::Linear;
    // Column Z at Y = 60: halfway between 4 and 3.5 µm.
    let z = com.to_table("Z", Wrap::Hold, lin).unwrap();
    assert!((z.value(60.0, Direction::Forward) - 3.75).abs() < 1e-9);
    let e = com.to_table("X", Wrap::Hold, lin).unwrap_err();
    assert!(
        e.to_string().contains("no column X; it compensates Y, Z"),
        "{e}"
    );

    let cma = parse_cma(Path::new("c.CMA"), CMA).unwrap();
    assert_eq!(cma.axes, vec!["X", "Y", "Z"]);
    assert_eq!(
        cma.lines[0].tables,
        vec![None, Some("Y.COM".into()), Some("Z.COM".into())]
    );
    assert!(cma.lines[0].active && !cma.lines[1].active);
    assert_eq!(
        cma.active_for(Path::new("c.CMA"), "Y").unwrap(),
        ("Y.COM", 3)
    );
    let e = cma.active_for(Path::new("c.CMA"), "X").unwrap_err();
    assert_eq!(e.position, Some((3, 1)));
    assert!(e.to_string().contains("assigns no .COM table to X"), "{e}");
    let e = cma.active_for(Path::new("c.CMA"), "B").unwrap_err();
    assert!(e.to_string().contains("no column B"), "{e}");
    // Written back and read again: the same tables.
    assert_eq!(parse_com(p(), &com.write()).unwrap(), com);
    assert_eq!(parse_cma(Path::new("c.CMA"), &cma.write()).unwrap(), cma);
}

#[test]
fn the_active_line_selects_the_table_from_disk() {
    let d = std::env::temp_dir().join(format!("truepos-hh-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    std::fs::write(d.join("Y.COM"), Y_COM).unwrap();
    // The control's own path in the entry is reduced to the file name beside the .CMA.
    let cma = "BEGIN CONFIG.CMA\nNR  X   Y                     Z       ACTIVE\n0       TNC:\\table\\Y.COM      Z.COM   *\n1       OLD.COM\n[END]\n";
    std::fs::write(d.join("c.CMA"), cma).unwrap();
    let lin = Interpolation::Linear;
    let t = read_heidenhain(&d.join("c.CMA"), "Y", "Z", Wrap::Hold, lin).unwrap();
    assert!((t.value(-90.0, Direction::Reverse) - 1.0).abs() < 1e-9);
    let t = read_heidenhain(&d.join("c.CMA"), "Y", "Y", Wrap::Hold, lin).unwrap();
    assert!((t.value(10.0, Direction::Forward) - 2.0).abs() < 1e-9);
    // Activating line 1 too: two active lines are refused at the second.
    let two = cma.replace("OLD.COM", "OLD.COM                       *");
    std::fs::write(d.join("two.CMA"), &two).unwrap();
    let e = read_heidenhain(&d.join("two.CMA"), "Y", "Y", Wrap::Hold, lin).unwrap_err();
    assert!(
        e.to_string().contains("two.CMA:4:1") && e.to_string().contains("2 lines are active"),
        "{e}"
    );
    // A missing .COM is named at the .CMA line that enters it.
    let gone = cma.replace("Y.COM", "Q.COM");
    std::fs::write(d.join("gone.CMA"), &gone).unwrap();
    let e = read_heidenhain(&d.join("gone.CMA"), "Y", "Y", Wrap::Hold, lin).unwrap_err();
    assert!(
        e.to_string().contains("gone.CMA:3:1") && e.to_string().contains("Q.COM"),
        "{e}"
    );
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn malformed_files_are_located() {
    let cases: [(&str, &str, (usize, usize), &str); 8] = [
        (
            "cut short",
            &Y_COM.replace("[END]\n", ""),
            (0, 0),
            "no [END] line",
        ),
        (
            "inch",
            &Y_COM.replace("Y.COM MM", "Y.COM INCH"),
            (1, 13),
            "MM only",
        ),
        (
            "no begin",
            &Y_COM.replace("BEGIN ", "BEGN "),
            (1, 1),
            "expected `BEGIN <name> MM`",
        ),
        (
            "columns",
            &Y_COM.replace("AXISPOS", "POSAXIS"),
            (2, 1),
            "NR AXISPOS",
        ),
        (
            "number",
            &Y_COM.replace("0.004", "0.0x4"),
            (4, 26),
            "finite number",
        ),
        (
            "order",
            &Y_COM.replace("110 ", "5   "),
            (5, 6),
            "strictly increasing",
        ),
        (
            "nr",
            &Y_COM.replace("\n2    ", "\n7    "),
            (5, 1),
            "line number 2",
        ),
        (
            "spill",
            &Y_COM.replace("-0.0015   ", "-0.00151234"),
            (5, 26),
            "runs into column Z",
        ),
    ];
    for (what, text, at, msg) in cases {
        let e = parse_com(p(), text).unwrap_err();
        let s = e.to_string();
        assert!(s.contains(msg), "{what}: {s}");
        if at != (0, 0) {
            assert_eq!(e.position, Some(at), "{what}: {s}");
        }
    }
    // Text after [END], a bad ACTIVE mark, a cell that is no file name.
    let e = parse_com(p(), &format!("{Y_COM}0 1 2 3\n")).unwrap_err();
    assert_eq!(e.position, Some((8, 1)));
    let e = parse_cma(p(), &CMA.replace("Z.COM   *", "Z.COM   x")).unwrap_err();
    assert!(e.to_string().contains("`*` (active) or a blank"), "{e}");
    let e = parse_cma(p(), &CMA.replace("Z.COM   *", "Z=COM   *")).unwrap_err();
    assert_eq!(e.position, Some((3, 18)));
}

#[test]
fn directional_tables_are_refused() {
    let t = CompTable::directional(
        vec![0.0, 10.0],
        vec![1.0, 2.0],
        vec![0.0, 1.0],
        Wrap::Hold,
        Interpolation::Linear,
    )
    .unwrap();
    let e = HeidenhainCom::from_table(&t, "X.COM", "X").unwrap_err();
    assert!(e.to_string().contains("one value per point"), "{e}");
    // Names the table cannot hold: a blank in the BEGIN line's name, an axis no column can be.
    let one = CompTable::new(
        vec![0.0, 10.0],
        vec![1.0, 2.0],
        Wrap::Hold,
        Interpolation::Linear,
    )
    .unwrap();
    let e = HeidenhainCom::from_table(&one, "my X.COM", "X").unwrap_err();
    assert!(e.to_string().contains("without blanks"), "{e}");
    let e = HeidenhainCom::from_table(&one, "X.COM", "X Y").unwrap_err();
    assert!(e.to_string().contains("expected an axis name"), "{e}");
    assert!(HeidenhainCma::single("C.CMA", "X", "a b.COM").is_err());
}

proptest! {
    /// Any table of a linear axis written as `.COM` + `.CMA` reads back identically, and its
    /// values to the last bit (shortest round-trip float form).
    #[test]
    fn written_tables_read_back_identically(
        start in -2000.0f64..2000.0,
        steps in prop::collection::vec(0.001f64..100.0, 1..60),
        values in prop::collection::vec(-500.0f64..500.0, 61),
        axis in prop::sample::select(vec!["X", "Y", "Z", "A", "X1"]),
    ) {
        let mut pos = vec![start];
        for s in &steps {
            pos.push(pos[pos.len() - 1] + s);
        }
        let vals = values[..pos.len()].to_vec();
        let t = CompTable::new(pos, vals, Wrap::Hold, Interpolation::Linear).unwrap();
        let com = HeidenhainCom::from_table(&t, "T.COM", axis).unwrap();
        let back = parse_com(p(), &com.write()).unwrap();
        prop_assert_eq!(&back, &com);
        let t2 = back.to_table(axis, Wrap::Hold, Interpolation::Linear).unwrap();
        prop_assert_eq!(t2.positions(), t.positions());
        for (a, b) in t2.forward().iter().zip(t.forward()) {
            prop_assert!((a - b).abs() <= 1e-12 * (1.0 + b.abs()), "{} vs {}", a, b);
        }
        let cma = HeidenhainCma::single("CONFIG.CMA", axis, "T.COM").unwrap();
        let cback = parse_cma(p(), &cma.write()).unwrap();
        prop_assert_eq!(cback.active_for(p(), axis).unwrap().0, "T.COM");
        prop_assert_eq!(cback, cma);
    }

    /// Whatever one-character change a file gets, the readers return a table or a located
    /// error; never a panic, never a non-finite value.
    #[test]
    fn mutations_never_panic(
        at in 0usize..10_000,
        with in prop::sample::select(vec!['*', ' ', '-', '1', '.', 'e', 'X', '\n', '[', 'é', '\t']),
        delete in any::<bool>(),
        axis in prop::sample::select(vec!["X", "Y", "Z"]),
    ) {
        if let Ok(com) = parse_com(p(), &mutate(Y_COM, at, with, delete)) {
            if let Ok(t) = com.to_table(axis, Wrap::Hold, Interpolation::Linear) {
                for x in [-1e9, -90.0, 0.0, 55.5, 210.0, 1e9] {
                    prop_assert!(t.value(x, Direction::Forward).is_finite());
                }
            }
        }
        if let Ok(cma) = parse_cma(p(), &mutate(CMA, at, with, delete)) {
            let _ = cma.active_for(p(), axis);
        }
    }
}
