//! `truepos status` for a person (issue 28): clock time, the state and why it is not active
//! (a twin source alone delivers no axis positions), offsets to 0.01 µm, temperatures with
//! units, model names, and `--follow`.

mod support;

use support::{command, repo, scratch};

#[test]
fn status_names_the_missing_positions_and_reads_like_a_person_writes() {
    let dir = scratch("status-person");
    let machine = truepos_io::machine_file::load(&repo("examples/twin/machine.toml"))
        .unwrap()
        .machine;
    let model = dir.join("zero.toml");
    let m = truepos_model::Model::new("twin-zero", &machine, vec![]).unwrap();
    std::fs::write(
        &model,
        truepos_io::model_file::position::ModelFile::from_model(&m, &machine).to_toml(),
    )
    .unwrap();
    let log = dir.join("log.sqlite");
    let run = command()
        .args(["run", "--machine", "examples/twin/machine.toml", "--models"])
        .arg(&model)
        .args([
            "--source",
            "twin:spindle-warmup@60",
            "--fast",
            "--duration-s",
            "5",
        ])
        .arg("--log")
        .arg(&log)
        .output()
        .unwrap();
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let out = command()
        .args(["status", "--log"])
        .arg(&log)
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    println!("{text}");
    assert!(
        text.contains("state: HOLDING") || text.contains("state: NO-MODEL"),
        "{text}"
    );
    assert!(text.contains("why: no axis position for X, Y, Z"), "{text}");
    assert!(text.contains(" UTC"), "a clock time: {text}");
    assert!(
        text.contains("path 1: model none in effect (loaded: twin-zero)"),
        "{text}"
    );
    // Temperatures with their unit, two decimals; offsets to 0.01 µm, never 16 decimals.
    let temps = text
        .lines()
        .find(|l| l.starts_with("temperatures:"))
        .unwrap();
    assert!(temps.contains(" °C"), "{temps}");
    let offsets = text.lines().find(|l| l.starts_with("offsets:")).unwrap();
    assert!(
        offsets.contains("X +0.00 µm") || offsets.contains("X -0.00 µm"),
        "{offsets}"
    );

    let json = command()
        .args(["status", "--json", "--log"])
        .arg(&log)
        .output()
        .unwrap();
    let v: serde_json::Value = serde_json::from_slice(&json.stdout).unwrap();
    assert!(
        v["why"][0].as_str().unwrap().contains("no axis position"),
        "{v}"
    );
    assert!(v["temperatures_c"].as_object().unwrap().len() > 5, "{v}");

    // --follow refreshes (here twice, on a pipe: one snapshot after the other).
    let follow = command()
        .args([
            "status",
            "--follow",
            "--every-s",
            "0.2",
            "--times",
            "2",
            "--log",
        ])
        .arg(&log)
        .output()
        .unwrap();
    let f = String::from_utf8_lossy(&follow.stdout);
    assert_eq!(f.matches("Ctrl-C to leave").count(), 2, "{f}");
    std::fs::remove_dir_all(&dir).ok();
}
