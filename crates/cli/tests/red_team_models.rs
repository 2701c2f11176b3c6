//! The red-team cases about models nobody can vouch for: probe deviations and
//! exported values that no thermal compensation of the machine could carry. Each failed on the
//! landed code (a re-identified model predicting a millimetre at a cold machine; an export of
//! −488 mm with exit 0); the file cases are `red_team.rs`.

mod support;

use std::path::Path;

use support::{command, scratch};
use truepos_sim::{Scenario, Twin};

const TWIN: &str = "examples/twin/machine.toml";

/// A day of the twin with probe events, every measured Z deviation replaced by `dz`.
fn probes_with_dz(dir: &Path, dz: &str) -> std::path::PathBuf {
    let day = Twin::reference()
        .run(&Scenario::builtin("spindle-warmup").unwrap(), 1)
        .unwrap();
    let path = dir.join("probes.csv");
    day.write_csv(std::fs::File::create(&path).unwrap(), false)
        .unwrap();
    let text = std::fs::read_to_string(&path).unwrap();
    let mut lines = text.lines();
    let header = lines.next().unwrap();
    let col = header
        .split(',')
        .position(|h| h == "probe_dz_um")
        .expect("the twin writes probe_dz_um");
    let mut out = vec![header.to_string()];
    for l in lines {
        let mut cells: Vec<&str> = l.split(',').collect();
        if !cells[col].is_empty() {
            cells[col] = dz;
        }
        out.push(cells.join(","));
    }
    std::fs::write(&path, out.join("\n") + "\n").unwrap();
    path
}

#[test]
fn probe_deviations_beyond_the_envelope_are_left_out_by_reidentify() {
    let dir = scratch("red-team-reidentify");
    // A model that predicts nothing: the running error is the probes' deviation.
    let zero = dir.join("zero.toml");
    let machine = truepos_io::machine_file::load(&support::repo(TWIN))
        .unwrap()
        .machine;
    let m = truepos_model::Model::new("zero", &machine, vec![]).unwrap();
    std::fs::write(
        &zero,
        truepos_io::model_file::position::ModelFile::from_model(&m, &machine).to_toml(),
    )
    .unwrap();
    let probes = probes_with_dz(&dir, "999.9");
    let out = dir.join("new.toml");
    let o = command()
        .args(["reidentify", "--machine", TWIN, "--model"])
        .arg(&zero)
        .arg("--run")
        .arg(&probes)
        .arg("--out")
        .arg(&out)
        .arg("--json")
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(matches!(o.status.code(), Some(0 | 3)), "{err}");
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let left_out = v["data"]["beyond_the_envelope"].as_array().unwrap();
    assert!(!left_out.is_empty(), "{v:#}");
    assert!(
        left_out
            .iter()
            .all(|s| s.as_str().unwrap().contains("Z deviation 999.9 µm")),
        "{v:#}"
    );
    if out.exists() {
        // What was written learnt nothing of the millimetre.
        let text = std::fs::read_to_string(&out).unwrap();
        assert!(!text.contains("999"), "{text}");
    }
}

/// The hand-made model of the example machine with its first coefficient set to `k0`.
fn vmc3_model_with_k0(dir: &Path, k0: &str) -> std::path::PathBuf {
    let text = std::fs::read_to_string(support::repo("examples/vmc3/model.toml")).unwrap();
    let wild = text.replacen("k0_um_per_k = 2.0", &format!("k0_um_per_k = {k0}"), 1);
    assert_ne!(wild, text);
    let p = dir.join(format!("k0-{}.toml", k0.replace(['.', '-'], "_")));
    std::fs::write(&p, wild).unwrap();
    p
}

#[test]
fn an_export_beyond_the_envelope_is_refused_for_every_control_even_forced() {
    let dir = scratch("red-team-export");
    for k0 in ["1e6", "1e300", "-1.7e308"] {
        let model = vmc3_model_with_k0(&dir, k0);
        for to in [
            "siemens",
            "heidenhain9231",
            "heidenhain-tempcomp",
            "isg",
            "fanuc",
        ] {
            for force in [false, true] {
                let out = dir.join(format!("{to}.out"));
                let mut c = command();
                c.args([
                    "export",
                    "--to",
                    to,
                    "--machine",
                    "examples/vmc3/machine.toml",
                ])
                .arg("--model")
                .arg(&model)
                .args(["--run", "examples/vmc3/run.csv", "--out"])
                .arg(&out);
                if force {
                    c.arg("--force");
                }
                let o = c.output().unwrap();
                let err = String::from_utf8_lossy(&o.stderr);
                assert_eq!(o.status.code(), Some(1), "{k0} {to} force={force}: {err}");
                assert!(
                    err.contains("beyond the axis' envelope")
                        || err.contains("not a finite number")
                        || err.contains("overflow"),
                    "{k0} {to} force={force}: {err}"
                );
                assert!(!out.exists(), "{k0} {to}: {}", out.display());
            }
        }
    }
    // The model as shipped still exports.
    let o = command()
        .args([
            "export",
            "--to",
            "siemens",
            "--machine",
            "examples/vmc3/machine.toml",
        ])
        .args([
            "--model",
            "examples/vmc3/model.toml",
            "--run",
            "examples/vmc3/run.csv",
        ])
        .arg("--out")
        .arg(dir.join("ok.spf"))
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

/// A model file written in two steps, the first of which is valid TOML on its own: the loader
/// (every command and the hot reload) refuses it by its checksum instead of taking half a model.
#[test]
fn a_model_file_written_in_part_is_refused_by_its_checksum() {
    let dir = scratch("red-team-half");
    let machine = truepos_io::machine_file::load(&support::repo("examples/vmc3/machine.toml"))
        .unwrap()
        .machine;
    let model = truepos_io::model_file::position::load(
        &support::repo("examples/vmc3/model.toml"),
        &machine,
    )
    .unwrap();
    let text = truepos_io::model_file::position::ModelFile::from_model(&model, &machine).to_toml();
    assert!(text.starts_with("# sha256 "), "{text}");
    // The first write: everything before the last part.
    let cut = text.rfind("[[part]]").unwrap();
    let half = &text[..cut];
    let path = |name: &str, body: &str| {
        let p = dir.join(name);
        std::fs::write(&p, body).unwrap();
        p
    };
    let eval = |p: &Path| {
        command()
            .args(["eval", "--machine", "examples/vmc3/machine.toml", "--run"])
            .arg("examples/vmc3/run.csv")
            .arg("--model")
            .arg(p)
            .output()
            .unwrap()
    };
    let o = eval(&path("half.toml", half));
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.contains("half.toml:1:1") && err.contains("checksum"),
        "{err}"
    );
    // The whole file loads; so does one edited by hand without the checksum line.
    assert!(eval(&path("whole.toml", &text)).status.success());
    let edited = text.split_once('\n').unwrap().1.replace("2.0", "2.5");
    assert!(eval(&path("edited.toml", &edited)).status.success());
}

/// Red team item 6: a model no machine has is refused at start, and a hot reload to it leaves
/// the running model (the log says why) instead of pinning every axis at the envelope.
#[test]
fn an_implausible_model_is_refused_at_start_and_at_hot_reload() {
    let dir = scratch("red-team-admission");
    for k0 in ["1e6", "1e300", "-1.7e308"] {
        let wild = vmc3_model_with_k0(&dir, k0);
        let out = command()
            .args(["run", "--fast", "--duration-s", "1", "--models"])
            .arg(&wild)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{k0}: started");
        assert!(
            err.contains("one kelvin on sensor") && err.contains("max_offset_um"),
            "{k0}: {err}"
        );
    }

    let model = dir.join("model.toml");
    std::fs::copy(support::repo("examples/vmc3/model.toml"), &model).unwrap();
    let log = dir.join("log.db");
    let mut child = command()
        .args(["run", "--duration-s", "3", "--reload-on-change", "--json"])
        .arg("--models")
        .arg(&model)
        .arg("--log")
        .arg(&log)
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    std::thread::sleep(std::time::Duration::from_millis(800));
    std::fs::rename(vmc3_model_with_k0(&dir, "1e6"), &model).unwrap();
    let start = std::time::Instant::now();
    while child.try_wait().unwrap().is_none() {
        assert!(start.elapsed().as_secs() < 30, "the run did not end");
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
    let events = truepos_runtime::log::read_events(&log).unwrap();
    let failed: Vec<_> = events
        .iter()
        .filter(|e| e.kind == "model-reload-failed")
        .collect();
    assert!(
        failed
            .iter()
            .any(|e| e.detail.contains("one kelvin on sensor")),
        "{events:?}"
    );
    assert!(
        !events.iter().any(|e| e.kind == "model-reloaded"),
        "{events:?}"
    );
}

/// `eval` says, as `run` does, when the model predicts beyond an axis' envelope on the run, and
/// names the key to change (fit, demo, eval and run all tell it at start).
#[test]
fn eval_says_when_the_model_predicts_beyond_the_envelope() {
    let dir = scratch("red-team-eval-envelope");
    let strong = vmc3_model_with_k0(&dir, "60.0");
    let out = command()
        .args(["eval", "--json", "--model"])
        .arg(&strong)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(
        err.contains("beyond the axis' safety envelope of 100 µm")
            && err.contains("raise `max_offset_um` in axis Z's `[[axis]]` table"),
        "{err}"
    );
}
