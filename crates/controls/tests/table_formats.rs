//! Compensation table files: round trips of files written by truepos, and errors with line
//! numbers for malformed ones.

mod support;
use support::mutate;

use std::path::Path;

use proptest::prelude::*;
use truepos_controls::linuxcnc::*;
use truepos_controls::siemens::*;
use truepos_controls::table::*;
use truepos_kinematics::table::{CompTable, Direction, Interpolation, Wrap};

fn p() -> &'static Path {
    Path::new("t.comp")
}

#[test]
fn csv_round_trip_and_values() {
    let text = "# X axis pitch error, µm\nposition,value\n0,0\n100,2.5\n250,-1.25\n";
    let t = parse_csv(p(), text, Wrap::Hold, Interpolation::Linear).unwrap();
    // At 50 mm: halfway between 0 and 2.5 µm.
    assert!((t.value(50.0, Direction::Forward) - 1.25).abs() < 1e-12);
    let again = parse_csv(p(), &write_csv(&t), Wrap::Hold, Interpolation::Linear).unwrap();
    assert_eq!(t, again);
    let d = "position,forward,reverse\n0,1,-1\n10,2,-2\n";
    let t = parse_csv(p(), d, Wrap::Hold, Interpolation::Linear).unwrap();
    assert_eq!(t.value(5.0, Direction::Reverse), -1.5);
    assert_eq!(write_csv(&t), d);
}

#[test]
fn csv_errors_name_the_line() {
    let e = parse_csv(
        p(),
        "position,value\n0,0\n10,1\n10,2\n",
        Wrap::Hold,
        Interpolation::Linear,
    )
    .unwrap_err();
    assert_eq!(e.position, Some((4, 1)));
    assert!(e.to_string().contains("strictly increasing"), "{e}");
    let e = parse_csv(
        p(),
        "position,value\n0,zero\n",
        Wrap::Hold,
        Interpolation::Linear,
    )
    .unwrap_err();
    assert_eq!(
        e.to_string(),
        "t.comp:2:3: `value`: expected a finite number, got `zero`"
    );
    let e = parse_csv(p(), "pos,val\n", Wrap::Hold, Interpolation::Linear).unwrap_err();
    assert_eq!(e.position, Some((1, 1)));
}

#[test]
fn linuxcnc_types_mean_positions_and_trims() {
    // Type 0: at nominal 100 the axis reaches 100.002 forward and 99.997 in reverse:
    // errors +2 µm and −3 µm.
    let c = parse_linuxcnc(p(), "0 0 0\n100 100.002 99.997\n", LinuxCncType::Positions).unwrap();
    let t = c.to_table(Interpolation::Linear).unwrap();
    assert!((t.value(100.0, Direction::Forward) - 2.0).abs() < 1e-9);
    assert!((t.value(100.0, Direction::Reverse) + 3.0).abs() < 1e-9);
    // Type 1: the same as trims, as LinuxCNC's loader makes them from type 0:
    // trim = nominal − actual (−0.002 forward, +0.003 in reverse).
    let c = parse_linuxcnc(p(), "0 0 0\n100 -0.002 0.003\n", LinuxCncType::Trims).unwrap();
    let t1 = c.to_table(Interpolation::Linear).unwrap();
    assert!((t1.value(50.0, Direction::Forward) - 1.0).abs() < 1e-9);
    assert!((t1.value(50.0, Direction::Reverse) + 1.5).abs() < 1e-9);
}

#[test]
fn linuxcnc_malformed_files() {
    let e = parse_linuxcnc(p(), "0 0 0\n10 0 0\n5 0 0\n", LinuxCncType::Trims).unwrap_err();
    assert_eq!(e.position, Some((3, 1)));
    assert!(e.to_string().contains("strictly increasing"));
    let big: String = (0..257).map(|i| format!("{i} 0 0\n")).collect();
    let e = parse_linuxcnc(p(), &big, LinuxCncType::Trims).unwrap_err();
    assert_eq!(e.position, Some((257, 1)));
    assert!(e.to_string().contains("at most 256"));
    let ok: String = (0..256).map(|i| format!("{i} 0 0\n")).collect();
    assert!(parse_linuxcnc(p(), &ok, LinuxCncType::Trims).is_ok());
    let e = parse_linuxcnc(p(), "0 0 0\n1 2\n", LinuxCncType::Trims).unwrap_err();
    assert_eq!(e.position, Some((2, 1)));
    let e = parse_linuxcnc(p(), "0 0 0\n1 2 x\n", LinuxCncType::Trims).unwrap_err();
    assert_eq!(e.position, Some((2, 5)));
    let t = CompTable::new(
        (0..300).map(f64::from).collect(),
        vec![0.0; 300],
        Wrap::Hold,
        Interpolation::Linear,
    )
    .unwrap();
    assert!(LinuxCncComp::from_table(&t, LinuxCncType::Trims).is_err());
}

const SIEMENS: &str = "\
%_N_AX_EEC_INI
CHANDATA(1)
; X ball screw, measured 2026-11-02
$AA_ENC_COMP[0,0,AX1]=0.0
$AA_ENC_COMP[0,1,AX1]=0.003
$AA_ENC_COMP[0,2,AX1]=0.0045
$AA_ENC_COMP_STEP[0,AX1]=100.0
$AA_ENC_COMP_MIN[0,AX1]=0.0
$AA_ENC_COMP_MAX[0,AX1]=200.0
$AA_ENC_COMP_IS_MODULO[0,AX1]=0
$AN_CEC[1,0]=0
$AN_CEC[1,1]=-0.01
$AN_CEC_INPUT_AXIS[1]=AX1
$AN_CEC_OUTPUT_AXIS[1]=AX3
$AN_CEC_STEP[1]=400
$AN_CEC_MIN[1]=0
$AN_CEC_MAX[1]=400
$AN_CEC_DIRECTION[1]=0
$AN_CEC_MULT_BY_TABLE[1]=0
$AN_CEC_IS_MODULO[1]=0
M17
";

#[test]
fn siemens_reads_both_kinds() {
    let tables = parse_siemens(p(), SIEMENS, None).unwrap();
    assert_eq!(tables.len(), 2);
    let enc = &tables[0];
    assert_eq!(
        enc.kind,
        SiemensKind::Encoder {
            encoder: 0,
            axis: "AX1".into()
        }
    );
    // 0.003 mm at 100 mm, 0.0045 mm at 200 mm: 3.75 µm at 150 mm.
    let t = enc.to_table(Interpolation::Linear).unwrap();
    assert!((t.value(150.0, Direction::Forward) - 3.75).abs() < 1e-9);
    let cec = &tables[1];
    assert_eq!(cec.output_axis.as_deref(), Some("AX3"));
    assert_eq!(cec.values, vec![0.0, -0.01]);
    // Written by truepos, read back identically.
    let text = write_siemens(&tables);
    assert_eq!(parse_siemens(p(), &text, None).unwrap(), tables);
}

#[test]
fn siemens_malformed_files() {
    let no_step = SIEMENS.replace("$AA_ENC_COMP_STEP[0,AX1]=100.0\n", "");
    let e = parse_siemens(p(), &no_step, None).unwrap_err();
    assert_eq!(e.position, Some((4, 1)));
    assert!(e.to_string().contains("_STEP"), "{e}");
    // An axis the machine does not have.
    let e = parse_siemens(p(), SIEMENS, Some(&["AX1", "AX2"])).unwrap_err();
    assert_eq!(e.position, Some((14, 1)));
    assert!(e.to_string().contains("unknown axis `AX3`"), "{e}");
    // Not an axis name at all.
    let bad = SIEMENS.replace("$AA_ENC_COMP_MIN[0,AX1]", "$AA_ENC_COMP_MIN[0,1X]");
    let e = parse_siemens(p(), &bad, None).unwrap_err();
    assert_eq!(e.position, Some((8, 1)));
    // The MIN belongs to another axis: the AX1 table lacks _MIN.
    let other = SIEMENS.replace("$AA_ENC_COMP_MIN[0,AX1]", "$AA_ENC_COMP_MIN[0,AX2]");
    let e = parse_siemens(p(), &other, None).unwrap_err();
    assert!(
        e.to_string().contains("_MIN") || e.to_string().contains("_STEP"),
        "{e}"
    );
    // A gap in the support points.
    let gap = SIEMENS.replace("$AA_ENC_COMP[0,1,AX1]", "$AA_ENC_COMP[0,5,AX1]");
    let e = parse_siemens(p(), &gap, None).unwrap_err();
    assert!(e.to_string().contains("without gaps"), "{e}");
    let e = parse_siemens(p(), "$AN_CEC[0,0]=abc\n", None).unwrap_err();
    assert_eq!(e.position, Some((1, 1)));
    // Non-equidistant tables cannot be written for Siemens.
    let t = CompTable::new(
        vec![0.0, 1.0, 3.0],
        vec![0.0; 3],
        Wrap::Hold,
        Interpolation::Linear,
    )
    .unwrap();
    assert!(SiemensTable::from_table(&t, SiemensKind::Cec { table: 0 }).is_err());
}

proptest! {
    #[test]
    fn linuxcnc_written_files_read_back_identically(
        steps in proptest::collection::vec(0.001f64..50.0, 1..255),
        start in -500.0f64..500.0,
        errs in proptest::collection::vec(-20.0f64..20.0, 256),
        type0 in any::<bool>(),
    ) {
        let mut pos = vec![start];
        for s in &steps { let last = *pos.last().unwrap(); pos.push(last + s); }
        prop_assume!(pos.windows(2).all(|w| w[1] > w[0]));
        let n = pos.len();
        let fwd = errs[..n].to_vec();
        let rev: Vec<f64> = errs[..n].iter().map(|e| e - 3.0).collect();
        let t = CompTable::directional(pos, fwd, rev, Wrap::Hold, Interpolation::Linear).unwrap();
        let ty = if type0 { LinuxCncType::Positions } else { LinuxCncType::Trims };
        let comp = LinuxCncComp::from_table(&t, ty).unwrap();
        let back = parse_linuxcnc(p(), &comp.write(), ty).unwrap();
        prop_assert_eq!(&back, &comp);
        let t2 = back.to_table(Interpolation::Linear).unwrap();
        for (a, b) in t.forward().iter().zip(t2.forward()) {
            // Type 0 stores nominal + error in mm: the error survives to ~1e-13 mm · 1000.
            prop_assert!((a - b).abs() < 1e-6);
        }
    }

    #[test]
    fn siemens_written_files_read_back_identically(
        values in proptest::collection::vec(-20.0f64..20.0, 2..100),
        min in -500.0f64..0.0,
        step in 0.5f64..20.0,
        modulo in any::<bool>(),
    ) {
        let n = values.len();
        let (min, step) = if modulo { (0.0, 360.0 / n as f64) } else { (min, step) };
        let pos: Vec<f64> = (0..n).map(|i| min + step * i as f64).collect();
        let wrap = if modulo { Wrap::Rotary } else { Wrap::Hold };
        let t = CompTable::new(pos, values, wrap, Interpolation::Linear).unwrap();
        let mut s = SiemensTable::from_table(&t, SiemensKind::Cec { table: 3 }).unwrap();
        s.input_axis = Some("AX4".into());
        s.output_axis = Some("AX2".into());
        let enc = SiemensTable::from_table(&t, SiemensKind::Encoder { encoder: 1, axis: "X1".into() }).unwrap();
        let tables = vec![enc, s];
        let back = parse_siemens(p(), &write_siemens(&tables), None).unwrap();
        prop_assert_eq!(back, tables);
    }
}

#[test]
fn conversion_errors_name_the_line_and_the_table() {
    // A modulo table whose ends (0° and 360°, the same position) disagree: the joint is the
    // last support point's line.
    let text = "$AN_CEC[1,0]=0\n$AN_CEC[1,1]=0.001\n$AN_CEC[1,2]=0.002\n\
        $AN_CEC_INPUT_AXIS[1]=AX4\n$AN_CEC_OUTPUT_AXIS[1]=AX4\n$AN_CEC_STEP[1]=180\n\
        $AN_CEC_MIN[1]=0\n$AN_CEC_MAX[1]=360\n$AN_CEC_IS_MODULO[1]=1\n";
    let tables = parse_siemens(p(), text, None).unwrap();
    let e = tables[0].to_table(Interpolation::Linear).unwrap_err();
    assert_eq!(e.position, Some((3, 1)));
    assert_eq!(e.key.as_deref(), Some("$AN_CEC[1,…]"));
    // LinuxCNC type 0: a position of 1e306 mm is no number in µm.
    let c = parse_linuxcnc(p(), "0 0 0\n10 1e306 10\n", LinuxCncType::Positions).unwrap();
    let e = c.to_table(Interpolation::Linear).unwrap_err();
    assert_eq!(
        (e.position, e.key.as_deref()),
        (Some((2, 1)), Some("forward"))
    );
    assert!(e.to_string().starts_with("t.comp:2:1: `forward`: "), "{e}");
    // A table built in memory says so instead of naming a file.
    let t = CompTable::new(
        vec![0.0, 1.0],
        vec![0.0; 2],
        Wrap::Hold,
        Interpolation::Linear,
    )
    .unwrap();
    let mut comp = LinuxCncComp::from_table(&t, LinuxCncType::Trims).unwrap();
    comp.forward[1] = f64::INFINITY;
    let e = comp.to_table(Interpolation::Linear).unwrap_err();
    assert_eq!(e.file, Path::new("(table built in memory)"));
    // Exports fail with what the format cannot hold.
    let e = SiemensTable::directional_pair(&t, 3, "AX1", "AX1").unwrap_err();
    assert_eq!(e, ExportError::OneDirection);
}

/// Two sag/cross tables in one file, in the manual's syntax (axes in parentheses), each with
/// its own metadata: table 1 reads AX2 and corrects AX3, table 2 reads AX1 and corrects AX1.
const TWO_CEC: &str = "\
%_N_NC_CEC_INI
CHANDATA(1)
$AN_CEC[1,0]=0
$AN_CEC[1,1]=0.004
$AN_CEC[1,2]=0.002
$AN_CEC_INPUT_AXIS[1]=(AX2)
$AN_CEC_OUTPUT_AXIS[1]=(AX3)
$AN_CEC_STEP[1]=100
$AN_CEC_MIN[1]=0
$AN_CEC_MAX[1]=200
$AN_CEC_DIRECTION[1]=0
$AN_CEC_MULT_BY_TABLE[1]=0
$AN_CEC_IS_MODULO[1]=0
$AN_CEC[2,0]=-0.001
$AN_CEC[2,1]=0.001
$AN_CEC_INPUT_AXIS[2]=( AX1 )
$AN_CEC_OUTPUT_AXIS[2]=AX1
$AN_CEC_STEP[2]=400
$AN_CEC_MIN[2]=0
$AN_CEC_MAX[2]=400
M17
";

#[test]
fn siemens_manual_syntax_and_two_tables_with_their_own_axes() {
    let tables = parse_siemens(p(), TWO_CEC, None).unwrap();
    assert_eq!(tables.len(), 2);
    assert_eq!(tables[0].kind, SiemensKind::Cec { table: 1 });
    assert_eq!(tables[0].input_axis.as_deref(), Some("AX2"));
    assert_eq!(tables[0].output_axis.as_deref(), Some("AX3"));
    assert_eq!(tables[0].values, vec![0.0, 0.004, 0.002]);
    assert_eq!(tables[1].input_axis.as_deref(), Some("AX1"));
    assert_eq!(tables[1].output_axis.as_deref(), Some("AX1"));
    assert_eq!(
        (tables[1].min, tables[1].max, tables[1].step),
        (0.0, 400.0, 400.0)
    );
    // Written back in the manual's syntax, read back the same.
    let text = write_siemens(&tables);
    assert!(text.contains("$AN_CEC_INPUT_AXIS[1]=(AX2)\n"), "{text}");
    assert_eq!(parse_siemens(p(), &text, None).unwrap(), tables);
    // A bare name reads the same as the parenthesised one.
    let bare = TWO_CEC.replace("=(AX2)", "=AX2");
    assert_eq!(parse_siemens(p(), &bare, None).unwrap(), tables);

    let lin = Interpolation::Linear;
    // Each axis gets its own table: AX2 reads table 1 (4 µm at 100 mm), AX1 table 2.
    let t = select_siemens(p(), &tables, Some("AX2"), Some("AX3"), None, lin).unwrap();
    assert!((t.value(100.0, Direction::Forward) - 4.0).abs() < 1e-9);
    let t = select_siemens(p(), &tables, Some("AX1"), None, None, lin).unwrap();
    assert!((t.value(200.0, Direction::Forward) - 0.0).abs() < 1e-9);
    // A table declared for AX2 is never applied to another axis: chosen by number for AX1,
    // it is refused at its first support point's line, naming both axes.
    let e = select_siemens(p(), &tables, Some("AX1"), None, Some(1), lin).unwrap_err();
    assert_eq!(e.position, Some((3, 1)));
    assert_eq!(e.key.as_deref(), Some("$AN_CEC[1,…]"));
    assert!(e.to_string().contains("input axis AX2, not AX1"), "{e}");
    // No table reads X: refused, listing what the file holds.
    let e = select_siemens(p(), &tables, Some("X"), None, None, lin).unwrap_err();
    assert!(e.to_string().contains("no table reads axis X"), "{e}");
    assert!(
        e.to_string()
            .contains("$AN_CEC[1,…] (input AX2, output AX3"),
        "{e}"
    );
    // Without an axis, two unrelated tables are ambiguous; a number chooses.
    let e = select_siemens(p(), &tables, None, None, None, lin).unwrap_err();
    assert!(e.to_string().contains("2 tables apply"), "{e}");
    assert!(select_siemens(p(), &tables, None, None, Some(2), lin).is_ok());
    let e = select_siemens(p(), &tables, None, None, Some(7), lin).unwrap_err();
    assert!(e.to_string().contains("no $AN_CEC table 7"), "{e}");
}

#[test]
fn siemens_cec_output_axis_must_be_the_corrected_axis() {
    let lin = Interpolation::Linear;
    let tables = parse_siemens(p(), TWO_CEC, None).unwrap();
    // Table 1 reads AX2 and corrects AX3: applied to AX3 it is taken.
    let t = select_siemens(p(), &tables, Some("AX2"), Some("AX3"), None, lin).unwrap();
    assert!((t.value(100.0, Direction::Forward) - 4.0).abs() < 1e-9);
    // Applied to AX2 (as AX2's own error) it is refused at its first line, naming both axes.
    let e = select_siemens(p(), &tables, Some("AX2"), Some("AX2"), None, lin).unwrap_err();
    assert_eq!(e.position, Some((3, 1)));
    assert_eq!(e.key.as_deref(), Some("$AN_CEC[1,…]"));
    let msg = e.to_string();
    assert!(
        msg.contains("output axis AX3 (_OUTPUT_AXIS), not AX2"),
        "{msg}"
    );
    // Table 2 reads and corrects AX1: its own error.
    assert!(select_siemens(p(), &tables, Some("AX1"), Some("AX1"), None, lin).is_ok());
    // A directional pair: both halves are checked.
    let pair = CompTable::directional(
        vec![0.0, 50.0, 100.0],
        vec![1.0, 2.0, 3.0],
        vec![-1.0, -2.0, -3.0],
        Wrap::Hold,
        lin,
    )
    .unwrap();
    let both = SiemensTable::directional_pair(&pair, 5, "AX1", "AX3").unwrap();
    let back = parse_siemens(p(), &write_siemens(&both), None).unwrap();
    assert!(select_siemens(p(), &back, Some("AX1"), Some("AX3"), None, lin).is_ok());
    let e = select_siemens(p(), &back, Some("AX1"), Some("AX1"), None, lin).unwrap_err();
    assert!(e.to_string().contains("not AX1"), "{e}");
    // An encoder table corrects its own axis; there is no _OUTPUT_AXIS to check.
    let enc = parse_siemens(p(), SIEMENS, None).unwrap();
    assert!(select_siemens(p(), &enc[..1], Some("AX1"), Some("AX1"), None, lin).is_ok());
}

#[test]
fn siemens_directions_and_products() {
    let lin = Interpolation::Linear;
    // A table for one direction only corrects that direction: zero the other way.
    let one = TWO_CEC.replace("$AN_CEC_DIRECTION[1]=0", "$AN_CEC_DIRECTION[1]=-1");
    let tables = parse_siemens(p(), &one, None).unwrap();
    let t = select_siemens(p(), &tables, Some("AX2"), Some("AX3"), None, lin).unwrap();
    assert_eq!(t.value(100.0, Direction::Forward), 0.0);
    assert!((t.value(100.0, Direction::Reverse) - 4.0).abs() < 1e-9);
    // A pair with _DIRECTION 1 and -1 for the same axes is one directional table.
    let pair = CompTable::directional(
        vec![0.0, 50.0, 100.0],
        vec![1.0, 2.0, 3.0],
        vec![-1.0, -2.0, -3.0],
        Wrap::Hold,
        lin,
    )
    .unwrap();
    let mut all = SiemensTable::directional_pair(&pair, 5, "AX1", "AX1")
        .unwrap()
        .to_vec();
    all.extend(parse_siemens(p(), TWO_CEC, None).unwrap());
    let text = write_siemens(&all);
    let back = parse_siemens(p(), &text, None).unwrap();
    // Read in table order: 1, 2, then the pair 5, 6.
    let t = select_siemens(p(), &back[2..], Some("AX1"), None, None, lin).unwrap();
    assert!((t.value(50.0, Direction::Reverse) + 2.0).abs() < 1e-9);
    // Among four tables, AX1 has the pair and table 2: ambiguous, a number picks one.
    let e = select_siemens(p(), &back, Some("AX1"), None, None, lin).unwrap_err();
    assert!(e.to_string().contains("3 tables apply"), "{e}");
    let t = select_siemens(p(), &back, Some("AX1"), None, Some(5), lin).unwrap();
    assert_eq!(t.value(50.0, Direction::Reverse), 0.0);
    // A table multiplied by another cannot be evaluated alone.
    let mult = TWO_CEC.replace("$AN_CEC_MULT_BY_TABLE[1]=0", "$AN_CEC_MULT_BY_TABLE[1]=2");
    let tables = parse_siemens(p(), &mult, None).unwrap();
    let e = select_siemens(p(), &tables, Some("AX2"), Some("AX3"), None, lin).unwrap_err();
    assert!(e.to_string().contains("_MULT_BY_TABLE"), "{e}");
}

#[test]
fn siemens_malformed_axes_are_located() {
    let bad = TWO_CEC.replace("=(AX2)", "=(AX2");
    let e = parse_siemens(p(), &bad, None).unwrap_err();
    assert_eq!(e.position, Some((6, 1)));
    assert!(e.to_string().contains("closing parenthesis"), "{e}");
    let bad = TWO_CEC.replace("=(AX2)", "=()");
    let e = parse_siemens(p(), &bad, None).unwrap_err();
    assert_eq!(e.position, Some((6, 1)));
    assert!(e.to_string().contains("expected an axis name"), "{e}");
    // An axis the machine does not have, in parentheses.
    let e = parse_siemens(p(), TWO_CEC, Some(&["AX1", "AX2"])).unwrap_err();
    assert_eq!(e.position, Some((7, 1)));
    assert!(e.to_string().contains("unknown axis `AX3`"), "{e}");
}

proptest! {
    /// Whatever one-character change a file gets, reading it and choosing a table return a
    /// value or a located error; never a panic, never a non-finite value.
    #[test]
    fn siemens_and_linuxcnc_mutations_never_panic(
        at in 0usize..10_000,
        with in prop::sample::select(vec!['(', ')', '=', ',', '[', ']', '-', '1', '9', 'X', ' ', ';', '\n', 'e', '.']),
        delete in any::<bool>(),
        axis in prop::sample::select(vec![None, Some("AX1"), Some("AX2"), Some("X")]),
        number in prop::option::of(0u32..4),
        output in prop::sample::select(vec![None, Some("AX1"), Some("AX3")]),
    ) {
        let text = mutate(TWO_CEC, at, with, delete);
        if let Ok(tables) = parse_siemens(p(), &text, None) {
            if let Ok(t) = select_siemens(p(), &tables, axis, output, number, Interpolation::Linear) {
                for x in [-10.0, 0.0, 55.5, 400.0, 1e9] {
                    prop_assert!(t.value(x, Direction::Forward).is_finite());
                    prop_assert!(t.value(x, Direction::Reverse).is_finite());
                }
            }
        } else {
            let e = parse_siemens(p(), &text, None).unwrap_err();
            prop_assert!(e.file == p());
        }
        let comp = "0 0.002 -0.004\n40 40.0035 39.9975\n100 100.00725 100.00125\n";
        for ty in [LinuxCncType::Positions, LinuxCncType::Trims] {
            if let Ok(c) = parse_linuxcnc(p(), &mutate(comp, at, with, delete), ty) {
                let _ = c.to_table(Interpolation::Linear);
            }
        }
    }
}
