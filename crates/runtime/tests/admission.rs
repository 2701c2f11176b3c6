//! A model implausible for its machine is refused at every load, naming the model, the axis,
//! the figure and the limit (red team: coefficients of 10⁶ and 10³⁰⁰ µm/K
//! pinned every axis at the envelope while the state said `active`; −1.7·10³⁰⁸ held without
//! saying the correction overflows). Every model the repository ships passes.

mod support;

use support::{repo, vmc};
use truepos_io::model_file::load_set;
use truepos_runtime::admission;
use truepos_runtime::MachineConfig;

fn machine(path: &str) -> MachineConfig {
    truepos_io::machine_file::load(&repo(path)).unwrap()
}

/// `examples/vmc3/model.toml` with one of its lines replaced, loaded as the service loads it.
fn vmc3_with(from: &str, to: &str) -> truepos_runtime::model_set::ModelEntry {
    let text = std::fs::read_to_string(repo("examples/vmc3/model.toml")).unwrap();
    assert!(text.contains(from));
    let dir = std::env::temp_dir().join(format!("admission-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(format!("m{}.toml", to.len() + from.len()));
    std::fs::write(&path, text.replacen(from, to, 1)).unwrap();
    load_set(&[path], &vmc()).unwrap().remove(0)
}

#[test]
fn every_model_the_repository_ships_is_admitted() {
    let cases = [
        ("examples/vmc3/machine.toml", "examples/vmc3/model.toml"),
        (
            "examples/cross-slide/machine.toml",
            "examples/cross-slide/model.toml",
        ),
        ("examples/vmc3/machine.toml", "tests/linuxcnc/model_b.toml"),
        ("examples/vmc3/machine.toml", "tests/linuxcnc/model_c.toml"),
        ("examples/vmc3/machine.toml", "tests/linuxcnc/model_d.json"),
    ];
    for (m, model) in cases {
        let m = machine(m);
        let entry = load_set(&[repo(model)], &m).unwrap().remove(0);
        admission::admit(&entry, &m, 1e-3).unwrap_or_else(|e| panic!("{model}: {e}"));
    }
}

#[test]
fn a_kelvin_that_moves_an_axis_beyond_its_envelope_is_refused() {
    for k0 in ["1e6", "1e300"] {
        let entry = vmc3_with("k0_um_per_k = 2.0", &format!("k0_um_per_k = {k0}"));
        let err = admission::admit(&entry, &vmc(), 1e-3).unwrap_err();
        assert!(
            err.contains("one kelvin on sensor `x_slide_top` moves axis Z by")
                && err.contains("envelope of 100 µm (`max_offset_um`)"),
            "{k0}: {err}"
        );
    }
    // 24 µm/K at the far end of X (k0 + k·r = 20 + 4) is a strong machine, not an absurd one.
    let entry = vmc3_with("k0_um_per_k = 2.0", "k0_um_per_k = 20.0");
    let strong = admission::plausible(&entry.model, &vmc());
    assert!(strong.is_ok(), "{strong:?}");
}

#[test]
fn a_correction_beyond_the_envelope_on_a_cold_machine_is_refused() {
    let entry = vmc3_with("constant_um = 0.0", "constant_um = 1e9");
    let err = admission::admit(&entry, &vmc(), 1e-3).unwrap_err();
    assert!(
        err.contains("asks a correction of 1.00e9 µm on axis Z of a cold machine"),
        "{err}"
    );
}

#[test]
fn a_correction_that_overflows_is_refused_with_its_reason() {
    let entry = vmc3_with("k_um_per_k = 3.1", "k_um_per_k = -1.7e308");
    let err = admission::admit(&entry, &vmc(), 1e-3).unwrap_err();
    assert!(
        err.contains("one kelvin on sensor `spindle_front_bearing` moves axis Z by -1.70e308 µm"),
        "{err}"
    );
    // Two such terms on one sensor overflow: the evaluation's own reason is given.
    let text = std::fs::read_to_string(repo("examples/vmc3/model.toml")).unwrap();
    let both = text
        .replacen("k_um_per_k = 3.1", "k_um_per_k = 1.7e308", 1)
        .replacen("k_um_per_k = -0.9", "k_um_per_k = 1.7e308", 1)
        .replacen("k0_um_per_k = 2.0", "k0_um_per_k = 1.7e308", 1);
    let dir = std::env::temp_dir().join(format!("admission-o-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("overflow.toml");
    std::fs::write(&path, both).unwrap();
    let entry = load_set(&[path], &vmc()).unwrap().remove(0);
    let err = admission::admit(&entry, &vmc(), 1e-3).unwrap_err();
    assert!(err.starts_with("model `vmc3-example`"), "{err}");
}

#[test]
fn a_filtered_model_scaled_a_thousandfold_is_refused() {
    let text = std::fs::read_to_string(repo("tests/linuxcnc/model_d.json")).unwrap();
    let mut json: serde_json::Value = serde_json::from_str(&text).unwrap();
    let mut scaled = 0;
    scale(&mut json, &mut scaled);
    assert!(scaled > 0);
    let dir = std::env::temp_dir().join(format!("admission-d-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("model_d.json");
    std::fs::write(&path, json.to_string()).unwrap();
    let entry = load_set(&[path], &vmc()).unwrap().remove(0);
    let err = admission::plausible(&entry.model, &vmc()).unwrap_err();
    assert!(err.contains("one kelvin on sensor"), "{err}");
}

/// Multiplies every `coefficients` array's numbers by 1000.
fn scale(v: &mut serde_json::Value, n: &mut usize) {
    match v {
        serde_json::Value::Object(map) => {
            for (k, x) in map.iter_mut() {
                if k == "coefficients" {
                    mul(x, n);
                } else {
                    scale(x, n);
                }
            }
        }
        serde_json::Value::Array(a) => a.iter_mut().for_each(|x| scale(x, n)),
        _ => {}
    }
}

fn mul(v: &mut serde_json::Value, n: &mut usize) {
    match v {
        serde_json::Value::Number(x) => {
            *v = serde_json::json!(x.as_f64().unwrap() * 1000.0);
            *n += 1;
        }
        serde_json::Value::Array(a) => a.iter_mut().for_each(|x| mul(x, n)),
        _ => {}
    }
}

/// The host admits every model itself, whatever its caller forgot: at start, and every model
/// its reload loader returns (here a loader that checks nothing).
#[test]
fn the_host_refuses_an_implausible_model_at_start_and_at_reload() {
    use truepos_runtime::host::ReloadSetup;
    use truepos_runtime::{ServiceHost, StartError};

    let absurd = vmc3_with("k0_um_per_k = 2.0", "k0_um_per_k = 1e6");
    let refused = ServiceHost::new(vmc(), vec![absurd.clone()]).start();
    match refused {
        Err(StartError::Refused(why)) => assert!(why.contains("one kelvin"), "{why}"),
        Err(e) => panic!("refused for another reason: {e}"),
        Ok(_) => panic!("an implausible model started"),
    }

    let sound = load_set(&[repo("examples/vmc3/model.toml")], &vmc())
        .unwrap()
        .remove(0);
    let setup = ReloadSetup {
        files: vec![repo("examples/vmc3/model.toml")],
        loader: Box::new(move |_| Ok(absurd.clone())),
        watch: false,
    };
    let mut running = ServiceHost::new(vmc(), vec![sound])
        .reload(Some(setup))
        .start()
        .unwrap();
    running.request_reload();
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(20);
    let report = loop {
        if let Some(r) = running.poll_reload() {
            break r;
        }
        assert!(std::time::Instant::now() < deadline, "no reload answer");
        std::thread::sleep(std::time::Duration::from_millis(10));
    };
    assert!(report.reloaded.is_empty(), "{report:?}");
    assert!(report.failed[0].1.contains("one kelvin"), "{report:?}");
    assert_eq!(running.model_generations(), &[1]);
}
