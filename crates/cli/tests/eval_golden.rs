//! `truepos eval` reproduces document A's golden cases from files, end to end through the binary.

mod support;
use support::run as truepos;

/// The cross-slide example: embodiment 6 on X, document C's form on Z (see the model file).
///   ΔA_X = ΔT_bed·[2 + 4·KFA_Z − 2·r_X]·KFA_Z,  ΔA_Z = 1.5·(T_spindle − T_ambient)
///   row 1: ΔT = 3, KFA = 0.5, r = 0.5 → 3·3·0.5 = 4.5;      Z: 1.5·6 = 9
///   row 2: Z in the middle, KFA = 0 → 0;                     Z: 9
///   row 3: KFA = −1 → 3·(2 − 4 − 1)·(−1) = 9;                Z: 9
///   row 4: ΔT = 2, KFA = 1, r = 0 → 2·6·1 = 12;              Z: 1.5·4 = 6
///   row 5: ΔT = 2, KFA = 1, r = 1 → 2·4·1 = 8;               Z: 0
#[test]
fn eval_reproduces_embodiment_6_from_files() {
    let (ok, stdout, stderr) = truepos(&[
        "eval",
        "--machine",
        "examples/cross-slide/machine.toml",
        "--model",
        "examples/cross-slide/model.toml",
        "--run",
        "examples/cross-slide/run.csv",
    ]);
    assert!(ok, "{stderr}");
    let expected = "\
time_s,X_error_um,X_comp_um,Z_error_um,Z_comp_um,status
0,4.500000,-4.500000,9.000000,-9.000000,ok
60,0.000000,0.000000,9.000000,-9.000000,ok
120,9.000000,-9.000000,9.000000,-9.000000,ok
180,12.000000,-12.000000,6.000000,-6.000000,ok
240,8.000000,-8.000000,0.000000,0.000000,ok
";
    assert_eq!(stdout, expected);
}

#[test]
fn eval_json_summary() {
    let (ok, stdout, stderr) = truepos(&[
        "eval",
        "--machine",
        "examples/cross-slide/machine.toml",
        "--model",
        "examples/cross-slide/model.toml",
        "--run",
        "examples/cross-slide/run.csv",
        "--json",
    ]);
    assert!(ok, "{stderr}");
    let v: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    assert_eq!(v["cycles"], 5);
    assert_eq!(v["failed_cycles"], 0);
    assert_eq!(v["axes"][0]["axis"], "X");
    assert_eq!(v["axes"][0]["max_abs_error_um"], 12.0);
    assert_eq!(v["axes"][1]["max_abs_error_um"], 9.0);
}

/// A NaN temperature in a run gives a failed cycle with a named reason and no number.
#[test]
fn eval_never_writes_a_number_for_a_bad_cycle() {
    let dir = std::env::temp_dir().join(format!("truepos-eval-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let run = dir.join("run.csv");
    std::fs::write(
        &run,
        "time_s,X_mm,Z_mm,bed_top,bed_bottom,spindle_bearing,ambient\n\
         0,150,750,23,20,26,20\n\
         1,150,750,NaN,20,26,20\n\
         2,150,750,23,20,26,99\n",
    )
    .unwrap();
    let (ok, stdout, stderr) = truepos(&[
        "eval",
        "--machine",
        "examples/cross-slide/machine.toml",
        "--model",
        "examples/cross-slide/model.toml",
        "--run",
        run.to_str().unwrap(),
    ]);
    assert!(ok, "{stderr}");
    let lines: Vec<&str> = stdout.lines().collect();
    assert_eq!(lines[1], "0,4.500000,-4.500000,9.000000,-9.000000,ok");
    assert_eq!(
        lines[2],
        "1,,,,,error: temperature `bed_top` is not a number"
    );
    assert_eq!(
        lines[3],
        // Quoted: the reason holds a comma.
        "2,,,,,\"error: temperature `ambient` reads 99 °C, outside its valid range [0, 45]\""
    );
    assert!(!stdout.to_lowercase().contains("nan,"));
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn eval_reports_a_model_for_another_machine() {
    let (ok, _, stderr) = truepos(&[
        "eval",
        "--machine",
        "examples/cross-slide/machine.toml",
        "--model",
        "examples/vmc3/model.toml",
        "--run",
        "examples/cross-slide/run.csv",
    ]);
    assert!(!ok);
    assert!(
        stderr.contains("model.toml:7:11: `machine`: the model was made for machine `vmc-3axis`, but the machine description is `cross-slide-on-bed`"),
        "{stderr}"
    );
}

#[test]
fn update_period_reproduces_the_timing_argument() {
    let (ok, stdout, stderr) = truepos(&[
        "update-period",
        "--feed-m-min",
        "100",
        "--period-ms",
        "4",
        "--length-mm",
        "500",
        "--json",
    ]);
    assert!(ok, "{stderr}");
    let v: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    let pct = v["worst_error_percent"]["ratio"].as_f64().unwrap();
    assert_eq!(format!("{pct:.1}"), "1.3");
    assert!((v["travel_per_update_mm"].as_f64().unwrap() - 6.6667).abs() < 1e-3);
}
