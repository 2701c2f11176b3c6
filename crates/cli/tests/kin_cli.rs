//! `truepos kin fwd|inv|gcode|chain` end to end through the binary, on the example kinematics
//! files (`examples/kinematics/`) with small point lists and programs written to a temp dir.
//!
//! Golden values are derived by hand from the kinematics files in the comments: frame 0 sits at
//! the TCP with +Z along the tool, each row maps its tool-side frame into its workpiece-side
//! frame (translation along X/Y/Z, right-hand rotation about X/Y/Z = A/B/C), a `MachAxis -A`
//! row rotates by −A.

use std::path::Path;

mod support;
use support::{repo, run as truepos, scratch};

fn ktab(machine: &str) -> String {
    format!("examples/kinematics/{machine}/kinematics.ktab")
}

fn write(dir: &Path, name: &str, text: &str) -> String {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p.to_str().unwrap().to_string()
}

/// A numeric CSV as printed by `kin fwd|inv`: header and rows (a trailing `status` column of
/// `kin inv` is checked to be `ok` and dropped).
fn parse_csv(text: &str) -> (Vec<String>, Vec<Vec<f64>>) {
    let mut lines = text.lines();
    let mut header: Vec<String> = lines
        .next()
        .expect("a header")
        .split(',')
        .map(str::to_string)
        .collect();
    let status = header.last().is_some_and(|h| h == "status");
    if status {
        header.pop();
    }
    let rows = lines
        .map(|l| {
            let mut f: Vec<&str> = l.split(',').collect();
            if status {
                assert_eq!(f.pop(), Some("ok"), "row `{l}`");
            }
            f.iter()
                .map(|v| v.parse().unwrap_or_else(|_| panic!("`{v}` in `{l}`")))
                .collect()
        })
        .collect();
    (header, rows)
}

fn to_csv(header: &[String], rows: &[Vec<f64>]) -> String {
    let mut s = header.join(",") + "\n";
    for r in rows {
        let f: Vec<String> = r.iter().map(|v| format!("{v:.17e}")).collect();
        s += &(f.join(",") + "\n");
    }
    s
}

fn assert_rows_close(got: &[Vec<f64>], want: &[Vec<f64>], tol: f64, what: &str) {
    assert_eq!(got.len(), want.len(), "{what}: number of rows");
    for (i, (g, w)) in got.iter().zip(want).enumerate() {
        assert_eq!(g.len(), w.len(), "{what}: row {i} width");
        for (c, (a, b)) in g.iter().zip(w).enumerate() {
            assert!(
                (a - b).abs() <= tol,
                "{what}: row {i} column {c}: got {a}, want {b} (tolerance {tol})"
            );
        }
    }
}

fn fwd(machine: &str, input: &str, nominal: bool) -> (Vec<String>, Vec<Vec<f64>>) {
    let k = ktab(machine);
    let mut args = vec!["kin", "fwd", "--kinematics", &k, "--input", input];
    if nominal {
        args.push("--nominal");
    }
    let (ok, out, err) = truepos(&args);
    assert!(ok, "kin fwd {machine}: {err}");
    parse_csv(&out)
}

fn inv(machine: &str, input: &str, nominal: bool) -> (Vec<String>, Vec<Vec<f64>>) {
    let k = ktab(machine);
    let mut args = vec!["kin", "inv", "--kinematics", &k, "--input", input];
    if nominal {
        args.push("--nominal");
    }
    let (ok, out, err) = truepos(&args);
    assert!(ok, "kin inv {machine}: {err}");
    parse_csv(&out)
}

/// head-ac, nominal (L = 100): rows Z −250 · A · X 0.02 · Y −0.015 · C · Z 400 · Z · Y · X.
///   q = 0:                 tip (0,0,−250) → (0.02, −0.015, −250) → +400 → (0.02, −0.015, 150),
///                          direction (0,0,1).
///   X10 Y20 Z30 A90 C0:    Rx(90)·(0,0,−250) = (0, 250, 0), direction Rx(90)·(0,0,1) = (0,−1,0);
///                          + (0.02, −0.015, 0) + (0,0,400) + (10,20,30) = (10.02, 269.985, 430).
///   A90 C90:               Rz(90)·(0.02, 249.985, 0) = (−249.985, 0.02, 0), direction (1,0,0);
///                          + 400 in Z → (−249.985, 0.02, 400).
const HEAD_AC_AXES: &str = "X,Y,Z,A,C\n0,0,0,0,0\n10,20,30,90,0\n0,0,0,90,90\n";
const HEAD_AC_POSES: [[f64; 6]; 3] = [
    [0.02, -0.015, 150.0, 0.0, 0.0, 1.0],
    [10.02, 269.985, 430.0, 0.0, -1.0, 0.0],
    [-249.985, 0.02, 400.0, 1.0, 0.0, 0.0],
];

#[test]
fn fwd_nominal_head_ac_matches_hand_computed_poses() {
    let d = scratch("fwd_head_ac");
    let input = write(&d, "axes.csv", HEAD_AC_AXES);
    let (header, rows) = fwd("head-ac", &input, true);
    assert_eq!(header, ["X", "Y", "Z", "I", "J", "K"]);
    let want: Vec<Vec<f64>> = HEAD_AC_POSES.iter().map(|p| p.to_vec()).collect();
    assert_rows_close(&rows, &want, 1e-9, "head-ac nominal forward");
}

/// table-ac, nominal (L = 100): Z −100 · Z · Y · X · Z −250 · Y 0.03 · −A · Z 80 · −C · Z −20.
///   q = 0:        (0, 0.03, −100 − 250 + 80 − 20) = (0, 0.03, −290), direction (0,0,1).
///   A−90:         (0, 0.03, −350) turned by −A = +90° about X: (0, 350, 0.03), direction
///                 (0,−1,0); + 80 − 20 in Z → (0, 350, 60.03).
///   A−90 C90:     (0, 350, 80.03) turned by −C = −90° about Z: (x, y) → (y, −x) = (350, 0),
///                 direction (−1, 0, 0); − 20 in Z → (350, 0, 60.03).
///   X5 Y−7 Z11:   the spindle axes add to the tool point before any rotation → (5, −6.97, −279).
#[test]
fn fwd_nominal_table_ac_matches_hand_computed_poses() {
    let d = scratch("fwd_table_ac");
    let input = write(
        &d,
        "axes.csv",
        "X,Y,Z,A,C\n0,0,0,0,0\n0,0,0,-90,0\n0,0,0,-90,90\n5,-7,11,0,0\n",
    );
    let (_, rows) = fwd("table-ac", &input, true);
    let want = vec![
        vec![0.0, 0.03, -290.0, 0.0, 0.0, 1.0],
        vec![0.0, 350.0, 60.03, 0.0, -1.0, 0.0],
        vec![350.0, 0.0, 60.03, -1.0, 0.0, 0.0],
        vec![5.0, -6.97, -279.0, 0.0, 0.0, 1.0],
    ];
    assert_rows_close(&rows, &want, 1e-9, "table-ac nominal forward");
}

/// vmc-21, nominal: Z −200 then the three slides, so TCP = (X, Y, Z − 200), tool along +Z.
/// With the 21 error tables the TCP moves by tens of µm, not by nothing and not by a millimetre;
/// the columns may come in any order (named by the header).
#[test]
fn fwd_vmc_21_nominal_exact_and_errors_small() {
    let d = scratch("fwd_vmc");
    let input = write(&d, "axes.csv", "Z,X,Y\n0,0,0\n250,400,300\n500,800,600\n");
    let (_, nominal) = fwd("vmc-21", &input, true);
    let want = vec![
        vec![0.0, 0.0, -200.0, 0.0, 0.0, 1.0],
        vec![400.0, 300.0, 50.0, 0.0, 0.0, 1.0],
        vec![800.0, 600.0, 300.0, 0.0, 0.0, 1.0],
    ];
    assert_rows_close(&nominal, &want, 1e-12, "vmc-21 nominal forward");
    let (_, actual) = fwd("vmc-21", &input, false);
    for (a, n) in actual.iter().zip(&nominal) {
        let dp = (0..3).map(|c| (a[c] - n[c]).powi(2)).sum::<f64>().sqrt();
        assert!(dp > 1e-4 && dp < 0.2, "TCP error {dp} mm: {a:?} vs {n:?}");
    }
}

/// The nominal inverse returns the axis positions the hand-computed poses came from. Each row
/// starts from the previous row's answer: the first pose is the pole (tool along C), where C
/// keeps its previous value 0; the other branch of each later pose (A → −A, C → C + 180°) is
/// farther from the previous set-point. A pose whose tool points straight down cannot be
/// reached (|A| ≤ 110°): the row says so, the error names file and line, the exit is nonzero.
#[test]
fn inv_nominal_head_ac_returns_hand_computed_axes_and_reports_unreachable() {
    let d = scratch("inv_head_ac");
    let mut poses = String::from("X,Y,Z,I,J,K\n");
    for p in HEAD_AC_POSES {
        let f: Vec<String> = p.iter().map(f64::to_string).collect();
        poses += &(f.join(",") + "\n");
    }
    let input = write(&d, "poses.csv", &poses);
    let (header, rows) = inv("head-ac", &input, true);
    assert_eq!(header, ["X", "Y", "Z", "A", "C"]);
    let want = vec![
        vec![0.0, 0.0, 0.0, 0.0, 0.0],
        vec![10.0, 20.0, 30.0, 90.0, 0.0],
        vec![0.0, 0.0, 0.0, 90.0, 90.0],
    ];
    assert_rows_close(&rows, &want, 1e-9, "head-ac nominal inverse");

    let bad = write(&d, "bad.csv", &(poses + "0,0,0,0,0,-1\n"));
    let k = ktab("head-ac");
    // Nominal: with the error tables the pole pose itself is out of reach (a tilt in the
    // plane of A that neither A nor C can undo, see docs/kinematics.md).
    let (ok, out, err) = truepos(&[
        "kin",
        "inv",
        "--kinematics",
        &k,
        "--nominal",
        "--input",
        &bad,
    ]);
    assert!(!ok, "an unreachable pose must fail: {out}");
    assert!(err.contains(&format!("{bad}:5: ")), "{err}");
    assert!(err.contains("outside its travel"), "{err}");
    assert!(err.contains("3 of 4 points converged"), "{err}");
    let last = out.lines().last().unwrap();
    assert!(last.starts_with(",,,,,\""), "failed row: `{last}`");
}

/// A smooth path from near the start set-point (0) for each machine: no branch or turn choice is
/// ambiguous, so inv(fwd(q)) = q through the error tables (the inverse converges to 5e-7 mm; on
/// the heads an angle error ε moves the TCP by ε·250 mm, so 1e-5 mm / 1e-5° is generous).
fn path(machine: &str) -> String {
    let mut s = String::new();
    for k in 0..40 {
        let t = f64::from(k);
        let row = match machine {
            "head-ac" => format!(
                "{},{},{},{},{}",
                -300.0 + 13.0 * t,
                200.0 - 7.5 * t,
                -50.0 + 3.0 * t,
                5.0 + 2.0 * t,
                10.0 + 9.0 * t
            ),
            "head-bc" => format!(
                "{},{},{},{},{}",
                100.0 - 11.0 * t,
                -40.0 + 6.0 * t,
                20.0 - 2.0 * t,
                -3.0 - 2.2 * t,
                -5.0 - 8.0 * t
            ),
            "table-ac" => format!(
                "{},{},{},{},{}",
                50.0 + 4.0 * t,
                -60.0 + 2.5 * t,
                100.0 + 5.0 * t,
                -4.0 - 2.5 * t,
                7.0 + 11.0 * t
            ),
            _ => format!(
                "{},{},{}",
                10.0 + 19.0 * t,
                590.0 - 14.0 * t,
                5.0 + 12.0 * t
            ),
        };
        s += &(row + "\n");
    }
    s
}

fn round_trip(machine: &str, header: &str) {
    let d = scratch(&format!("round_trip_{machine}"));
    let axes = write(
        &d,
        "axes.csv",
        &(header.to_string() + "\n" + &path(machine)),
    );
    let (h, q) = parse_csv(&std::fs::read_to_string(&axes).unwrap());
    for nominal in [true, false] {
        let (_, poses) = fwd(machine, &axes, nominal);
        let poses_csv = write(
            &d,
            "poses.csv",
            &to_csv(&["X", "Y", "Z", "I", "J", "K"].map(String::from), &poses),
        );
        let (h2, back) = inv(machine, &poses_csv, nominal);
        assert_eq!(h2, h);
        let what = format!("{machine} inv(fwd(q)), nominal = {nominal}");
        assert_rows_close(&back, &q, 1e-5, &what);
        if nominal {
            // The nominal chain has no errors to iterate away: the closed form is exact.
            assert_rows_close(&back, &q, 1e-9, &what);
        }
    }
}

#[test]
fn inv_of_fwd_is_identity_head_ac() {
    round_trip("head-ac", "X,Y,Z,A,C");
}

#[test]
fn inv_of_fwd_is_identity_head_bc() {
    round_trip("head-bc", "X,Y,Z,B,C");
}

#[test]
fn inv_of_fwd_is_identity_table_ac() {
    round_trip("table-ac", "X,Y,Z,A,C");
}

#[test]
fn inv_of_fwd_is_identity_vmc_21() {
    round_trip("vmc-21", "X,Y,Z");
}

/// On the example's own axis samples (far apart, any branch may be chosen) the compensated
/// inverse lands the real tool on the pose: fwd(inv(p)) = p within 1e-6 mm and 1e-6 in the
/// direction's components.
#[test]
fn fwd_of_inv_reaches_the_pose_on_example_samples() {
    for machine in ["head-ac", "table-ac", "head-bc"] {
        let d = scratch(&format!("fwd_inv_{machine}"));
        let all = std::fs::read_to_string(repo(&format!("examples/kinematics/{machine}/axes.csv")))
            .unwrap();
        let some: Vec<&str> = all.lines().take(60).collect();
        let axes = write(&d, "axes.csv", &(some.join("\n") + "\n"));
        let (_, poses) = fwd(machine, &axes, false);
        let header = ["X", "Y", "Z", "I", "J", "K"].map(String::from);
        let poses_csv = write(&d, "poses.csv", &to_csv(&header, &poses));
        let (h, q) = inv(machine, &poses_csv, false);
        let q_csv = write(&d, "q.csv", &to_csv(&h, &q));
        let (_, again) = fwd(machine, &q_csv, false);
        assert_rows_close(&again, &poses, 1e-6, &format!("{machine} fwd(inv(p))"));
    }
}

/// Malformed point lists: every error names file, line and column, and the exit is nonzero.
#[test]
fn malformed_csv_gives_located_errors() {
    let d = scratch("malformed");
    let k = ktab("head-ac");
    let cases = [
        // (file content, expected part of the message)
        (
            "X,Y,Z,A,C\n0,0,0,0,0\n1,2,x,4,5\n",
            ":3:5: `Z`: expected a finite number, got `x`",
        ),
        ("X,Y,Z,A,C\n1,2,3,4\n", ":2:1: "),
        ("X,Y,Z,A,Q\n1,2,3,4,5\n", ":1:5: `Q`: unknown column"),
        ("X,Y,Z,A\n1,2,3,4\n", "`C`: missing column"),
        (
            "X,Y,Z,A,C\n1,2,3,4,inf\n",
            ":2:9: `C`: expected a finite number",
        ),
        ("", "empty file"),
    ];
    for (i, (text, want)) in cases.iter().enumerate() {
        let input = write(&d, &format!("bad{i}.csv"), text);
        let (ok, out, err) = truepos(&["kin", "fwd", "--kinematics", &k, "--input", &input]);
        assert!(!ok, "case {i} must fail: {out}");
        assert!(out.is_empty(), "case {i}: no partial output: {out}");
        assert!(err.contains(&input), "case {i} names the file: {err}");
        assert!(err.contains(want), "case {i}: want `{want}` in `{err}`");
    }
    // A pose list needs X,Y,Z,I,J,K.
    let input = write(&d, "axes_for_inv.csv", "X,Y,Z,A,C\n0,0,0,0,0\n");
    let (ok, _, err) = truepos(&["kin", "inv", "--kinematics", &k, "--input", &input]);
    assert!(!ok);
    assert!(
        err.contains(&format!("{input}:1:4: `A`: unknown column")),
        "{err}"
    );
}

/// A program that cannot be compensated — here a move beyond the travel of head-ac's X axis
/// after two good ones — is refused with its file and line and leaves no output: neither a new
/// file nor a change to one that was there (issue 15: a failed rewrite used to write its
/// output, with moves the original never had).
#[test]
fn gcode_refuses_with_file_and_line_and_writes_nothing() {
    let d = scratch("gcode");
    let program = "\
%
(a test program)
N10 G90 G21 G17
N20 G0 X10 Y20 Z100 A15 C30 ; above the part
N30 G1 X12.5 F800 (modal move)
N40 G1 X5000
N50 M30
%
";
    let input = write(&d, "prog.nc", program);
    let k = ktab("head-ac");
    let fresh = d.join("fresh.ngc");
    let (ok, _, err) = truepos(&[
        "kin",
        "gcode",
        "--kinematics",
        &k,
        "--input",
        &input,
        "--output",
        fresh.to_str().unwrap(),
    ]);
    assert!(!ok, "a move beyond travel must fail the command: {err}");
    assert!(
        err.contains(&format!("{input}:6: the program moves X to 5000.0000"))
            && err.contains("outside its travel"),
        "{err}"
    );
    assert!(
        !fresh.exists(),
        "a refused program left {}",
        fresh.display()
    );
    let kept = write(&d, "kept.ngc", "(an earlier result)\n");
    let (ok, _, err) = truepos(&[
        "kin",
        "gcode",
        "--kinematics",
        &k,
        "--input",
        &input,
        "--output",
        &kept,
    ]);
    assert!(!ok, "{err}");
    assert_eq!(
        std::fs::read_to_string(&kept).unwrap(),
        "(an earlier result)\n"
    );
    let leftovers: Vec<_> = std::fs::read_dir(&d)
        .unwrap()
        .filter_map(|e| e.ok())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with(".truepos-gcode-"))
        .collect();
    assert!(leftovers.is_empty(), "temporary files left: {leftovers:?}");
    // An interpreter error names the line rs274 stopped at.
    let bad = write(&d, "bad.nc", "G0 X1\nG1 X2 F100\nG1 X3 Q\nM2\n");
    let (ok, _, err) = truepos(&["kin", "gcode", "--kinematics", &k, "--input", &bad]);
    assert!(!ok);
    assert!(
        err.contains(&format!(
            "{bad}:3: LinuxCNC's interpreter refused the program"
        )),
        "{err}"
    );
}

/// Through the error tables: the compensated set-points put the real tool where the nominal
/// machine puts it at the programmed positions (checked with `kin fwd`), and they differ from
/// the programmed ones by µm / µrad-sized amounts, not by nothing. Every move is a G53 block
/// whose N word is its source line.
#[test]
fn gcode_compensation_lands_the_real_tool_on_the_nominal_pose() {
    let d = scratch("gcode_comp");
    let program =
        "G1 X10 Y20 Z30 A15 C30 F1000\nX-40 A-35.5 C-100 (tilted)\nY55 Z-12 A60 C250\nM2\n";
    let input = write(&d, "prog.nc", program);
    let output = d.join("out.ngc");
    let k = ktab("head-ac");
    let (ok, summary, err) = truepos(&[
        "kin",
        "gcode",
        "--kinematics",
        &k,
        "--input",
        &input,
        "--output",
        output.to_str().unwrap(),
    ]);
    assert!(ok, "{err}");
    assert!(summary.contains("3 moves written"), "{summary}");
    let out = std::fs::read_to_string(&output).unwrap();
    let words = |line: &str| -> Vec<f64> {
        ['X', 'Y', 'Z', 'A', 'C']
            .iter()
            .map(|l| {
                let w = line
                    .split_whitespace()
                    .find(|w| w.starts_with(*l))
                    .unwrap_or_else(|| panic!("{l} in `{line}`"));
                w[1..].parse().unwrap()
            })
            .collect()
    };
    let programmed = [
        vec![10.0, 20.0, 30.0, 15.0, 30.0],
        vec![-40.0, 20.0, 30.0, -35.5, -100.0],
        vec![-40.0, 55.0, -12.0, 60.0, 250.0],
    ];
    let lines: Vec<&str> = out.lines().filter(|l| l.contains(" G53 G")).collect();
    assert_eq!(lines.len(), 3, "{out}");
    assert!(
        lines[0].starts_with("N1 G53 G1 X") && lines[0].ends_with(" F1000"),
        "{}",
        lines[0]
    );
    assert!(lines[1].starts_with("N2 G53 G1 X"), "{}", lines[1]);
    assert!(lines[2].starts_with("N3 G53 G1 X"), "{}", lines[2]);
    assert!(out.contains("N2 (tilted)"), "{out}");
    let rewritten: Vec<Vec<f64>> = lines.iter().map(|l| words(l)).collect();
    for (r, p) in rewritten.iter().zip(&programmed) {
        let moved = r
            .iter()
            .zip(p)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(moved > 1e-4 && moved < 0.05, "{r:?} vs {p:?}");
    }
    let header = ["X", "Y", "Z", "A", "C"].map(String::from);
    let nominal_in = write(&d, "programmed.csv", &to_csv(&header, &programmed));
    let actual_in = write(&d, "rewritten.csv", &to_csv(&header, &rewritten));
    let (_, want) = fwd("head-ac", &nominal_in, true);
    let (_, got) = fwd("head-ac", &actual_in, false);
    // The program carries 7 decimals (mm) and 8 (degrees): 1e-8° at 250 mm is 4.4e-8 mm.
    assert_rows_close(&got, &want, 1e-6, "real pose of the rewritten program");
}

/// `kin chain` prints the resolved chain: axes with travel, rows in file order with the tool
/// length row, error rows naming their tables, table axes with sign −1, and the closed form.
#[test]
fn chain_prints_the_resolved_rows() {
    let k = ktab("table-ac");
    let (ok, out, err) = truepos(&["kin", "chain", "--kinematics", &k]);
    assert!(ok, "{err}");
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert_eq!(v["name"], "table-ac");
    assert_eq!(v["layout"], "5-axis");
    assert_eq!(v["tool_length_mm"], 100.0);
    let axes: Vec<&str> = v["axes"]
        .as_array()
        .unwrap()
        .iter()
        .map(|a| a["name"].as_str().unwrap())
        .collect();
    assert_eq!(axes, ["X", "Y", "Z", "A", "C"]);
    assert_eq!(v["axes"][3]["travel"], serde_json::json!([-120.0, 30.0]));
    assert_eq!(v["axes"][3]["kind"], "rotary");
    let rows = v["rows"].as_array().unwrap();
    assert_eq!(rows.len(), 14);
    assert_eq!(rows[0]["key"], "tool");
    assert_eq!(
        rows[5],
        serde_json::json!({"key": "fixed", "dof": "Y", "value": 0.03})
    );
    assert_eq!(
        rows[6],
        serde_json::json!({"key": "axis", "dof": "A", "axis": 3, "sign": -1.0})
    );
    assert_eq!(rows[8]["table"], "F_A_B");
    assert_eq!(rows[8]["dof"], "B");

    let k = ktab("vmc-21");
    let (ok, out, _) = truepos(&["kin", "chain", "--kinematics", &k]);
    assert!(ok);
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert_eq!(v["layout"], "3-axis");
    let tables = v["rows"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|r| r["key"] == "error")
        .count();
    assert_eq!(tables, 21);
}
