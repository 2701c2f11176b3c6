//! `truepos demo` end to end: the twin's training and test days, both fits, the before/after
//! figures, the model files and the report.

use std::process::Command;

mod support;
use support::repo;

#[test]
fn demo_fits_on_one_day_and_improves_the_other() {
    let dir = std::env::temp_dir().join(format!("truepos-demo-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let out = Command::new(env!("CARGO_BIN_EXE_truepos"))
        .args(["demo", "--json", "--out"])
        .arg(&dir)
        .current_dir(std::env::temp_dir())
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let none = v["uncompensated"]["volume_max_um"].as_f64().unwrap();
    let prior = v["prior_art"]["volume_reduction"].as_f64().unwrap();
    let posdep = v["position_dependent"]["volume_reduction"]
        .as_f64()
        .unwrap();
    // The twin's warm-up moves the tool tens of µm (the realism bar of the twin).
    assert!(none > 20.0, "{v}");
    // Both models help on a day they never saw; the position-dependent one more.
    assert!(prior > 0.5, "{v}");
    assert!(posdep > prior, "{v}");
    // The bar: the position-dependent model cuts the largest error over the working
    // volume on the held-out day by at least 90 % (91 % when this was written; a regression in
    // fitting, lagged channels or the 20 °C inputs shows here first).
    assert!(posdep >= 0.90, "{v}");
    // The models are files `truepos eval` reads with the twin's machine description.
    let model = dir.join("position-dependent.model.toml");
    let machine = truepos_io::machine_file::load(&repo("examples/twin/machine.toml"))
        .unwrap()
        .machine;
    truepos_io::model_file::position::load(&model, &machine).unwrap();
    // One definition of "uncompensated": the headline card and the table below it give the same
    // dz figure (as measured, the reference point of the residual).
    let html = std::fs::read_to_string(dir.join("report/report.html")).unwrap();
    let dz = format!(
        "{:.2}",
        v["uncompensated"]["path_rmse_um"][2].as_f64().unwrap()
    );
    assert!(
        html.matches(&format!("{dz} µm")).count() >= 2,
        "dz {dz} µm once only"
    );
    std::fs::remove_dir_all(&dir).ok();
}
