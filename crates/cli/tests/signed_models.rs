//! Signed models: with `--trusted-keys`, a service loads only a model whose signature
//! (`MODEL.sig`, `truepos sign`) verifies under a key of its list over the model's exact bytes —
//! at start and at every hot reload; an unsigned, changed or foreign-signed model is refused
//! and a reload to one keeps the running model with `model-reload-failed` until its signature
//! arrives.

mod support;

use std::path::{Path, PathBuf};
use std::process::Output;

use support::{command, scratch};

fn sign(args: &[&std::ffi::OsStr]) -> Output {
    let out = command().arg("sign").args(args).output().unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

fn new_key(dir: &Path, name: &str) -> PathBuf {
    let key = dir.join(name);
    let out = sign(&["--new-key".as_ref(), key.as_os_str()]);
    let public = String::from_utf8(out.stdout).unwrap();
    assert_eq!(public.trim().len(), 64, "{public}");
    assert_eq!(
        std::fs::read_to_string(dir.join(format!("{name}.pub"))).unwrap(),
        public
    );
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        let mode = std::fs::metadata(&key).unwrap().permissions().mode();
        assert_eq!(
            mode & 0o077,
            0,
            "the secret key is readable by others: {mode:o}"
        );
    }
    key
}

fn start(model: &Path, trusted: &Path) -> (bool, String) {
    let out = command()
        .args(["run", "--fast", "--duration-s", "1", "--models"])
        .arg(model)
        .arg("--trusted-keys")
        .arg(trusted)
        .output()
        .unwrap();
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stderr).to_string(),
    )
}

#[test]
fn only_a_model_signed_by_a_trusted_key_is_loaded() {
    let dir = scratch("signed-models");
    let key = new_key(&dir, "builder.key");
    let foreign = new_key(&dir, "someone.key");
    let trusted = dir.join("builder.key.pub");
    let model = dir.join("model.toml");
    std::fs::copy(support::repo("examples/vmc3/model.toml"), &model).unwrap();

    let (ok, err) = start(&model, &trusted);
    assert!(!ok && err.contains("no signature readable"), "{err}");

    sign(&["--key".as_ref(), key.as_os_str(), model.as_os_str()]);
    let (ok, err) = start(&model, &trusted);
    assert!(ok, "{err}");

    // One byte more (a comment) after signing.
    let text = std::fs::read_to_string(&model).unwrap();
    std::fs::write(&model, format!("{text}#\n")).unwrap();
    let (ok, err) = start(&model, &trusted);
    assert!(!ok && err.contains("does not match the file"), "{err}");

    std::fs::write(&model, &text).unwrap();
    sign(&["--key".as_ref(), foreign.as_os_str(), model.as_os_str()]);
    let (ok, err) = start(&model, &trusted);
    assert!(!ok && err.contains("not in the trust list"), "{err}");

    // A trust list that is not one.
    let bad = dir.join("bad.pub");
    std::fs::write(&bad, "# keys\nnot-a-key\n").unwrap();
    let (ok, err) = start(&model, &bad);
    assert!(
        !ok && err.contains("bad.pub:2:1") && err.contains("64 hex digits"),
        "{err}"
    );
}

#[test]
fn a_reload_to_a_changed_model_waits_for_its_signature() {
    let dir = scratch("signed-models-reload");
    let key = new_key(&dir, "builder.key");
    let model = dir.join("model.toml");
    std::fs::copy(support::repo("examples/vmc3/model.toml"), &model).unwrap();
    sign(&["--key".as_ref(), key.as_os_str(), model.as_os_str()]);
    let log = dir.join("log.db");
    let mut child = command()
        .args(["run", "--duration-s", "3", "--reload-on-change", "--json"])
        .arg("--models")
        .arg(&model)
        .arg("--trusted-keys")
        .arg(dir.join("builder.key.pub"))
        .arg("--log")
        .arg(&log)
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    std::thread::sleep(std::time::Duration::from_millis(800));
    // The same model with a coefficient changed, its old signature beside it.
    let text = std::fs::read_to_string(&model).unwrap();
    let changed = dir.join("changed.toml");
    std::fs::write(
        &changed,
        text.replacen("k0_um_per_k = 2.0", "k0_um_per_k = 2.5", 1),
    )
    .unwrap();
    std::fs::rename(&changed, &model).unwrap();
    // Its signature comes later (rsync writes `model.toml` before `model.toml.sig`): the reload
    // watches the signature too and reads the model again.
    std::thread::sleep(std::time::Duration::from_millis(800));
    sign(&["--key".as_ref(), key.as_os_str(), model.as_os_str()]);
    let start = std::time::Instant::now();
    while child.try_wait().unwrap().is_none() {
        assert!(start.elapsed().as_secs() < 30, "the run did not end");
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
    let events = truepos_runtime::log::read_events(&log).unwrap();
    assert!(
        events
            .iter()
            .any(|e| e.kind == "model-reload-failed" && e.detail.contains("does not match")),
        "{events:?}"
    );
    let failed = events
        .iter()
        .position(|e| e.kind == "model-reload-failed")
        .unwrap();
    assert!(
        events[failed..].iter().any(|e| e.kind == "model-reloaded"),
        "{events:?}"
    );
}
