//! Compensation table files: round trips of files written by truepos, and errors with line
//! numbers for malformed ones.

use std::path::Path;

use proptest::prelude::*;
use truepos_io::comp_table::*;
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
