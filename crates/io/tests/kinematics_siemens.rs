//! A kinematics file's Siemens tables: the table a row reads must be declared for the row's
//! axis (`_INPUT_AXIS`, or the axis of `$AA_ENC_COMP`), under the control's name of the axis
//! (`siemens-axis=`); a file of several tables gives each row its own (`siemens-table=`); a
//! CEC table's `_OUTPUT_AXIS` must be the axis the row corrects (`siemens-output-axis=`).

use std::path::PathBuf;

use truepos_io::kinematics_file::load;
use truepos_kinematics::table::Direction;

/// Table 1 reads AX2 (Y on this control), table 2 reads AX1 (X); both correct AX3 (Z).
const CEC: &str = "\
$AN_CEC[1,0]=0
$AN_CEC[1,1]=0.004
$AN_CEC_INPUT_AXIS[1]=(AX2)
$AN_CEC_OUTPUT_AXIS[1]=(AX3)
$AN_CEC_STEP[1]=400
$AN_CEC_MIN[1]=0
$AN_CEC_MAX[1]=400
$AN_CEC[2,0]=0.001
$AN_CEC[2,1]=0.003
$AN_CEC_INPUT_AXIS[2]=(AX1)
$AN_CEC_OUTPUT_AXIS[2]=(AX3)
$AN_CEC_STEP[2]=400
$AN_CEC_MIN[2]=0
$AN_CEC_MAX[2]=400
M17
";

fn dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("truepos-kin-siemens-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    std::fs::write(d.join("cec.ini"), CEC).unwrap();
    d
}

fn ktab(name: &str, table_line: &str) -> Result<f64, String> {
    let d = dir(name);
    let text = format!(
        "axis X linear 0 400\naxis Y linear 0 400\naxis Z linear 0 400\n{table_line}\n\
         0 Trans Z 0 EZ\n1 MachAxis Z - -\n2 MachAxis Y - -\n3 MachAxis X - -\n"
    );
    let path = d.join("k.ktab");
    std::fs::write(&path, text).unwrap();
    let r = load(&path, None).map_err(|e| e.to_string());
    let _ = std::fs::remove_dir_all(&d);
    let k = r?;
    Ok(k.chain.tables()[0].table.value(200.0, Direction::Forward))
}

#[test]
fn a_table_reads_only_the_axis_it_is_declared_for() {
    // The row's axis is X; without saying that X is AX1 on the control, no table reads X.
    let e = ktab(
        "none",
        "table EZ axis=X unit=um file=cec.ini format=siemens",
    )
    .unwrap_err();
    assert!(e.contains("no table reads axis X"), "{e}");
    // X is AX1: table 2 (1 µm at 0, 3 µm at 400: 2 µm at 200), not table 1.
    let v = ktab(
        "ax1",
        "table EZ axis=X unit=um file=cec.ini format=siemens siemens-axis=AX1 siemens-output-axis=AX3",
    )
    .unwrap();
    assert!((v - 2.0).abs() < 1e-9, "{v}");
    // Y is AX2: table 1.
    let v = ktab(
        "ax2",
        "table EZ axis=Y unit=um file=cec.ini format=siemens siemens-axis=AX2 siemens-output-axis=AX3",
    )
    .unwrap();
    assert!((v - 2.0).abs() < 1e-9, "{v}");
    // Table 1 asked for by number on X (AX1): refused at its line, naming both axes.
    let e = ktab(
        "wrong",
        "table EZ axis=X unit=um file=cec.ini format=siemens siemens-axis=AX1 siemens-table=1",
    )
    .unwrap_err();
    assert!(e.contains("cec.ini:1:1:"), "{e}");
    assert!(e.contains("input axis AX2, not AX1"), "{e}");
    // The Siemens keys belong to Siemens tables; a bad number is located on the table line.
    let e = ktab(
        "csv",
        "table EZ axis=X unit=um file=cec.ini siemens-axis=AX1",
    )
    .unwrap_err();
    assert!(e.contains("need format=siemens"), "{e}");
    // Both tables correct AX3 (Z): applied as X's own error (siemens-output-axis defaults to
    // siemens-axis) or to AX2, table 2 is refused at its first line, naming both axes.
    let e = ktab(
        "own",
        "table EZ axis=X unit=um file=cec.ini format=siemens siemens-axis=AX1",
    )
    .unwrap_err();
    assert!(e.contains("cec.ini:8:1:"), "{e}");
    assert!(e.contains("output axis AX3 (_OUTPUT_AXIS), not AX1"), "{e}");
    let e = ktab(
        "out2",
        "table EZ axis=X unit=um file=cec.ini format=siemens siemens-axis=AX1 siemens-output-axis=AX2",
    )
    .unwrap_err();
    assert!(e.contains("not AX2"), "{e}");
    let e = ktab(
        "num",
        "table EZ axis=X unit=um file=cec.ini format=siemens siemens-table=x",
    )
    .unwrap_err();
    assert!(e.contains("k.ktab:4:"), "{e}");
    assert!(e.contains("expected the number of an $AN_CEC table"), "{e}");
}
