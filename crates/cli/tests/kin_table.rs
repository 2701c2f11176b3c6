//! `truepos kin table` end to end: every format it writes reads back to the same table (by
//! `--eval` at points between and beyond the support points), a table a format cannot hold
//! leaves no file, and the Siemens axis metadata is checked when reading.

use std::path::Path;

mod support;
use support::{run as truepos, scratch};

/// Equidistant (so Siemens can hold it) and directional: 4 µm of backlash.
const TABLE: &str = "position,forward,reverse\n0,2,-2\n100,3.5,-0.5\n200,5,1\n300,-1.25,-5.25\n";
const EVAL: &str = "position,direction\n-10,1\n0,1\n50,1\n50,-1\n150,-1\n299.5,1\n450,-1\n";

fn eval(table: &str, from: &str, extra: &[&str], points: &str) -> Vec<(f64, f64)> {
    let mut args = vec![
        "kin", "table", "--input", table, "--from", from, "--eval", points,
    ];
    args.extend_from_slice(extra);
    let (ok, out, err) = truepos(&args);
    assert!(ok, "{err}");
    out.lines()
        .skip(1)
        .map(|l| {
            let f: Vec<f64> = l.split(',').map(|x| x.parse().unwrap()).collect();
            assert_eq!(f[3], -f[2], "compensation = -error");
            (f[0], f[2])
        })
        .collect()
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

#[test]
fn every_writer_reads_back_the_same_table() {
    let d = scratch("kin-table");
    // The CSV writer writes `t.csv`: the input has another name, since an output that is the
    // input is refused.
    let (csv, points) = (d.join("input.csv"), d.join("eval.csv"));
    std::fs::write(&csv, TABLE).unwrap();
    std::fs::write(&points, EVAL).unwrap();
    let want = eval(s(&csv), "csv", &[], s(&points));
    // By hand: 2.75 µm at 50 forward, -1.25 in reverse; held beyond the ends.
    assert_eq!(want[0], (-10.0, 2.0));
    assert!((want[2].1 - 2.75).abs() < 1e-12 && (want[3].1 + 1.25).abs() < 1e-12);
    assert_eq!(want[6], (450.0, -5.25));
    for (to, from, write_extra, read_extra) in [
        ("csv", "csv", &[][..], &[][..]),
        ("linuxcnc0", "linuxcnc0", &[], &[]),
        ("linuxcnc1", "linuxcnc1", &[], &[]),
        // A bilateral ISG list (kw.ssfk.table[i].pos / .neg).
        (
            "isg",
            "isg",
            &["--isg-axis", "3", "--isg-axis-name", "Z"],
            &[],
        ),
        // Two CEC tables (_DIRECTION 1 and -1) that read AX1, read back for AX1.
        (
            "siemens-cec",
            "siemens",
            &["--siemens-axis", "AX1"],
            &["--siemens-axis", "AX1"],
        ),
    ] {
        let out = d.join(format!("t.{to}"));
        let mut args = vec!["kin", "table", "--input", s(&csv), "--from", "csv"];
        args.extend_from_slice(&["--to", to, "--out", s(&out)]);
        args.extend_from_slice(write_extra);
        let (ok, _, err) = truepos(&args);
        assert!(ok, "{to}: {err}");
        let got = eval(s(&out), from, read_extra, s(&points));
        // ISG lists hold whole 0.1 µm: the values round by at most 0.05 µm.
        let tolerance = if to == "isg" { 0.05 + 1e-9 } else { 1e-9 };
        for ((p, a), (_, b)) in want.iter().zip(&got) {
            assert!((a - b).abs() <= tolerance, "{to} at {p}: {a} vs {b}");
        }
    }
    // The CEC pair read for another axis is refused: it is declared for AX1.
    let (ok, _, err) = truepos(&[
        "kin",
        "table",
        "--input",
        s(&d.join("t.siemens-cec")),
        "--from",
        "siemens",
        "--siemens-axis",
        "AX2",
        "--eval",
        s(&points),
    ]);
    assert!(!ok);
    assert!(err.contains("no table reads axis AX2"), "{err}");
    // A cross table (reads AX1, corrects AX3) is AX3's correction, not AX1's own error:
    // refused unless --siemens-output-axis says the values go to AX3.
    let cross = d.join("cross.ini");
    let (ok, _, err) = truepos(&[
        "kin",
        "table",
        "--input",
        s(&csv),
        "--from",
        "csv",
        "--to",
        "siemens-cec",
        "--siemens-axis",
        "AX1",
        "--siemens-output-axis",
        "AX3",
        "--out",
        s(&cross),
    ]);
    assert!(ok, "{err}");
    let read = |extra: &[&str]| {
        let mut args = vec!["kin", "table", "--input", s(&cross), "--from", "siemens"];
        args.extend_from_slice(extra);
        args.extend_from_slice(&["--eval", s(&points)]);
        truepos(&args)
    };
    let (ok, _, err) = read(&["--siemens-axis", "AX1"]);
    assert!(!ok, "applied to AX1");
    assert!(
        err.contains("cross.ini:3:1") && err.contains("output axis AX3 (_OUTPUT_AXIS), not AX1"),
        "{err}"
    );
    let (ok, _, err) = read(&[]);
    assert!(!ok && err.contains("not AX1"), "{err}");
    let (ok, out, err) = read(&["--siemens-axis", "AX1", "--siemens-output-axis", "AX3"]);
    assert!(ok, "{err}");
    assert_eq!(out.lines().count(), EVAL.lines().count());
    // One direction fits $AA_ENC_COMP; read back by its axis.
    let one = d.join("one.csv");
    std::fs::write(&one, "position,value\n0,1\n50,-1\n100,4\n").unwrap();
    let enc = d.join("one.ini");
    let (ok, _, err) = truepos(&[
        "kin",
        "table",
        "--input",
        s(&one),
        "--from",
        "csv",
        "--to",
        "siemens-enc",
        "--siemens-axis",
        "X1",
        "--out",
        s(&enc),
    ]);
    assert!(ok, "{err}");
    assert!(std::fs::read_to_string(&enc)
        .unwrap()
        .contains("$AA_ENC_COMP[0,2,X1]=0.004\n"));
    let got = eval(s(&enc), "siemens", &["--siemens-axis", "X1"], s(&points));
    assert!((got[2].1 + 1.0).abs() < 1e-9, "{got:?}");
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn a_table_the_format_cannot_hold_leaves_no_file() {
    let d = scratch("kin-table-refused");
    let csv = d.join("t.csv");
    std::fs::write(&csv, TABLE).unwrap();
    // Directional: $AA_ENC_COMP has no direction of travel.
    let out = d.join("enc.ini");
    let (ok, _, err) = truepos(&[
        "kin",
        "table",
        "--input",
        s(&csv),
        "--from",
        "csv",
        "--to",
        "siemens-enc",
        "--siemens-axis",
        "AX1",
        "--out",
        s(&out),
    ]);
    assert!(!ok);
    assert!(err.contains("no direction of travel"), "{err}");
    assert!(!out.exists() && !d.join("enc.ini.partial").exists());
    // Unequal spacing for Siemens; a Siemens table without its axis.
    let uneven = d.join("u.csv");
    std::fs::write(&uneven, "position,value\n0,1\n10,2\n30,3\n").unwrap();
    let (ok, _, err) = truepos(&[
        "kin",
        "table",
        "--input",
        s(&uneven),
        "--from",
        "csv",
        "--to",
        "siemens-cec",
        "--siemens-axis",
        "AX1",
        "--out",
        s(&out),
    ]);
    assert!(!ok && err.contains("equidistant"), "{err}");
    let (ok, _, err) = truepos(&[
        "kin",
        "table",
        "--input",
        s(&csv),
        "--from",
        "csv",
        "--to",
        "siemens-cec",
        "--out",
        s(&out),
    ]);
    assert!(!ok && err.contains("--siemens-axis"), "{err}");
    assert!(!out.exists());
    // A malformed input is located; a bad direction in the points too.
    std::fs::write(&csv, "position,value\n0,1\n10,x\n").unwrap();
    let (ok, _, err) = truepos(&[
        "kin",
        "table",
        "--input",
        s(&csv),
        "--from",
        "csv",
        "--to",
        "linuxcnc1",
        "--out",
        s(&out),
    ]);
    assert!(!ok && err.contains("t.csv:3:4"), "{err}");
    assert!(!out.exists());
    std::fs::write(&csv, TABLE).unwrap();
    let points = d.join("p.csv");
    std::fs::write(&points, "position,direction\n0,1\n5,0\n").unwrap();
    let (ok, _, err) = truepos(&[
        "kin",
        "table",
        "--input",
        s(&csv),
        "--from",
        "csv",
        "--eval",
        s(&points),
    ]);
    assert!(
        !ok && err.contains("p.csv:3:1") && err.contains("expected 1 (forward) or -1"),
        "{err}"
    );
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn heidenhain_com_and_cma_are_written_together_and_read_back() {
    let d = scratch("kin-table-heidenhain");
    let (one, points) = (d.join("one.csv"), d.join("eval.csv"));
    std::fs::write(&one, "position,value\n-90,1\n10,-1.5\n110,4\n300,0.25\n").unwrap();
    std::fs::write(&points, EVAL).unwrap();
    let want = eval(s(&one), "csv", &[], s(&points));
    // Y's sag of Z: the .COM's column is Z, the .CMA enters it in column Y.
    let com = d.join("Y.COM");
    let (ok, _, err) = truepos(&[
        "kin",
        "table",
        "--input",
        s(&one),
        "--from",
        "csv",
        "--to",
        "heidenhain-com",
        "--heidenhain-axis",
        "Y",
        "--heidenhain-output-axis",
        "Z",
        "--out",
        s(&com),
    ]);
    assert!(ok, "{err}");
    let cma = std::fs::read_to_string(d.join("Y.CMA")).unwrap();
    assert!(
        cma.starts_with("BEGIN Y.CMA\nNR  Y      ACTIVE\n0   Y.COM  *\n[END]"),
        "{cma}"
    );
    let text = std::fs::read_to_string(&com).unwrap();
    assert!(
        text.starts_with("BEGIN Y.COM MM\nNR  AXISPOS  Z\n0   -90      0.001\n"),
        "{text}"
    );
    // Read through the .CMA (Y's table, column Z) and from the .COM itself: the same values.
    let via_cma = eval(
        s(&d.join("Y.CMA")),
        "heidenhain",
        &["--heidenhain-axis", "Y", "--heidenhain-output-axis", "Z"],
        s(&points),
    );
    let via_com = eval(s(&com), "heidenhain", &[], s(&points));
    for got in [via_cma, via_com] {
        for ((p, a), (_, b)) in want.iter().zip(&got) {
            assert!((a - b).abs() < 1e-9, "at {p}: {a} vs {b}");
        }
    }
    // Y's own error is not in the table: refused, naming the column it has.
    let cma_path = d.join("Y.CMA");
    let mut args = vec![
        "kin",
        "table",
        "--input",
        s(&cma_path),
        "--from",
        "heidenhain",
    ];
    args.extend_from_slice(&["--heidenhain-axis", "Y", "--eval", s(&points)]);
    let (ok, _, err) = truepos(&args);
    assert!(
        !ok && err.contains("no column Y; it compensates Z"),
        "{err}"
    );
    // A directional table does not fit a .COM column: neither file is written.
    let csv = d.join("dir.csv");
    std::fs::write(&csv, TABLE).unwrap();
    let out = d.join("X.COM");
    let (ok, _, err) = truepos(&[
        "kin",
        "table",
        "--input",
        s(&csv),
        "--from",
        "csv",
        "--to",
        "heidenhain-com",
        "--heidenhain-axis",
        "X",
        "--out",
        s(&out),
    ]);
    assert!(!ok && err.contains("one value per point"), "{err}");
    assert!(!out.exists() && !d.join("X.CMA").exists());
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn fanuc_tape_round_trip_and_quantisation_refusal() {
    let d = scratch("kin-table-fanuc");
    let (one, points) = (d.join("one.csv"), d.join("eval.csv"));
    // Zero at the reference position (0 mm), whole µm: the tape carries it exactly.
    std::fs::write(&one, "position,value\n-100,3\n0,0\n100,-2\n200,4\n300,6\n").unwrap();
    std::fs::write(&points, EVAL).unwrap();
    let want = eval(s(&one), "csv", &[], s(&points));
    let tape = d.join("x.prm");
    let write = |extra: &[&str]| {
        let mut args = vec!["kin", "table", "--input", s(&one), "--from", "csv"];
        args.extend_from_slice(&["--to", "fanuc", "--out", s(&tape), "--fanuc-axis", "2"]);
        args.extend_from_slice(extra);
        truepos(&args)
    };
    let (ok, _, err) = write(&["--fanuc-ref-point", "20"]);
    assert!(ok, "{err}");
    assert!(
        err.contains("FANUC A2: magnification 1, quantisation 0.000 µm"),
        "{err}"
    );
    let text = std::fs::read_to_string(&tape).unwrap();
    assert!(
        text.starts_with("%\nN03620A2P20;\nN03621A2P19;\nN03622A2P23;\n"),
        "{text}"
    );
    let got = eval(s(&tape), "fanuc", &["--fanuc-axis", "2"], s(&points));
    for ((p, a), (_, b)) in want.iter().zip(&got) {
        assert!((a - b).abs() < 1e-9, "at {p}: {a} vs {b}");
    }
    // A 10 µm detection unit quantises by up to 5 µm: refused without a file, then forced.
    std::fs::remove_file(&tape).unwrap();
    let coarse = ["--fanuc-ref-point", "20", "--fanuc-detection-unit", "0.01"];
    let (ok, _, err) = write(&coarse);
    assert!(!ok && err.contains("more than --max-error-um 1"), "{err}");
    assert!(!tape.exists());
    let mut forced = coarse.to_vec();
    forced.push("--force");
    let (ok, _, err) = write(&forced);
    assert!(
        ok && err.contains("warning: the quantisation loses"),
        "{err}"
    );
    assert!(tape.exists());
    // No reference point: refused by name.
    let (ok, _, err) = write(&[]);
    assert!(!ok && err.contains("--fanuc-ref-point"), "{err}");
    let _ = std::fs::remove_dir_all(&d);
}
