//! The red-team suite of issue 32, kept as tests that a later campaign extends: each case is
//! what a careless or hostile user did to the landed code, and each failed on it (data
//! destroyed, a read that never ends or exhausts memory, an input taken that nobody named).
//! Every command runs under a deadline, so a case that hangs fails in seconds instead of
//! hanging the suite. The proptest over output paths is `red_team_paths.rs`.

mod support;

use std::os::unix::fs::FileTypeExt;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use support::{command, repo, scratch};

const M: &str = "examples/vmc3/machine.toml";
const MODEL: &str = "examples/vmc3/model.toml";
const RUN: &str = "examples/vmc3/run.csv";

/// Runs the binary with a deadline: (success, stderr). A command still running at the
/// deadline is killed and the test fails naming it.
fn within(secs: u64, args: &[&str]) -> (bool, String) {
    let mut child = command()
        .args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let start = Instant::now();
    loop {
        if let Some(status) = child.try_wait().unwrap() {
            let mut err = String::new();
            std::io::Read::read_to_string(child.stderr.as_mut().unwrap(), &mut err).unwrap();
            return (status.success(), err);
        }
        if start.elapsed() > Duration::from_secs(secs) {
            let _ = child.kill();
            let _ = child.wait();
            panic!("`truepos {}` still ran after {secs} s", args.join(" "));
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

fn mkfifo(p: &Path) {
    assert!(Command::new("mkfifo").arg(p).status().unwrap().success());
}

/// A character device like `/dev/full` (1:7) in a scratch directory; `None` (and why) where
/// the test does not run as root.
fn mknod_full(p: &Path) -> Option<()> {
    let out = Command::new("mknod")
        .arg(p)
        .args(["c", "1", "7"])
        .output()
        .unwrap();
    if out.status.success() {
        Some(())
    } else {
        eprintln!(
            "skipped the device case: mknod needs root ({})",
            String::from_utf8_lossy(&out.stderr).trim()
        );
        None
    }
}

fn export(out: &Path, model: &str) -> (bool, String) {
    within(
        60,
        &[
            "export",
            "--to",
            "siemens",
            "--machine",
            M,
            "--model",
            model,
            "--run",
            RUN,
            "--out",
            s(out),
        ],
    )
}

/// A run with two temperatures and a measured error linear in them (and not in time).
fn small_run(dir: &Path) -> PathBuf {
    let mut text = String::from("time_s,t1_c,t2_c,dz_um\n");
    for i in 0..400 {
        let t1 = 20.0 + 5.0 * (1.0 - (-(i as f64) / 80.0).exp());
        let t2 = 20.0 + 2.0 * ((i as f64) / 50.0).sin();
        let dz = 3.0 * (t1 - 20.0) - 1.5 * (t2 - 20.0);
        text.push_str(&format!("{},{t1:.4},{t2:.4},{dz:.4}\n", i * 60));
    }
    let p = dir.join("run.csv");
    std::fs::write(&p, text).unwrap();
    p
}

#[test]
fn a_planted_link_at_the_temporary_name_is_not_followed() {
    let d = scratch("rt-planted");
    let victim = d.join("victim.txt");
    std::fs::write(&victim, "precious").unwrap();
    let out = d.join("out.spf");
    std::os::unix::fs::symlink(&victim, d.join("out.spf.partial")).unwrap();
    let (ok, err) = export(&out, MODEL);
    assert!(ok, "{err}");
    assert_eq!(std::fs::read_to_string(&victim).unwrap(), "precious");
}

#[test]
fn an_output_that_is_a_link_is_refused_and_kept() {
    let d = scratch("rt-link");
    let victim = d.join("victim.txt");
    std::fs::write(&victim, "precious").unwrap();
    let out = d.join("out.spf");
    std::os::unix::fs::symlink(&victim, &out).unwrap();
    let (ok, err) = export(&out, MODEL);
    assert!(!ok && err.contains("is a symbolic link"), "{err}");
    assert!(std::fs::symlink_metadata(&out)
        .unwrap()
        .file_type()
        .is_symlink());
    assert_eq!(std::fs::read_to_string(&victim).unwrap(), "precious");
}

#[test]
fn an_output_that_is_a_device_is_refused_and_the_node_kept() {
    let d = scratch("rt-device");
    let out = d.join("full");
    if mknod_full(&out).is_none() {
        let (ok, err) = export(Path::new("/dev/null"), MODEL);
        assert!(!ok && err.contains("is a character device"), "{err}");
        return;
    }
    let (ok, err) = export(&out, MODEL);
    assert!(!ok && err.contains("is a character device"), "{err}");
    assert!(std::fs::symlink_metadata(&out)
        .unwrap()
        .file_type()
        .is_char_device());
}

#[test]
fn an_output_that_is_a_fifo_is_refused_and_kept() {
    let d = scratch("rt-fifo-out");
    let out = d.join("out.csv");
    mkfifo(&out);
    let (ok, err) = export(&out, MODEL);
    assert!(!ok && err.contains("is a FIFO"), "{err}");
    let (ok, err) = within(
        60,
        &["sim", "--scenario", "spindle-warmup", "--out", s(&out)],
    );
    assert!(!ok && err.contains("is a FIFO"), "{err}");
    // The CSV sink, which opened a FIFO with no reader and waited for ever.
    let sink = format!("csv:{}", s(&out));
    let (ok, err) = within(30, &["run", "--fast", "--duration-s", "1", "--sink", &sink]);
    assert!(!ok && err.contains("is a FIFO"), "{err}");
    assert!(std::fs::symlink_metadata(&out)
        .unwrap()
        .file_type()
        .is_fifo());
}

#[test]
fn an_output_that_is_an_input_is_refused_and_the_input_kept() {
    let d = scratch("rt-same");
    let model = d.join("model.toml");
    std::fs::copy(repo(MODEL), &model).unwrap();
    let before = std::fs::read(&model).unwrap();
    let (ok, err) = export(&model, s(&model));
    assert!(
        !ok && err.contains("is also this command's input --model"),
        "{err}"
    );
    assert_eq!(std::fs::read(&model).unwrap(), before);

    let run = small_run(&d);
    let run_before = std::fs::read(&run).unwrap();
    let fit = [
        "fit",
        "--run",
        s(&run),
        "--inputs",
        "t*",
        "--target",
        "dz_um",
        "--model",
        s(&run),
    ];
    let (ok, err) = within(120, &fit);
    assert!(
        !ok && err.contains("is also this command's input --run"),
        "{err}"
    );
    assert_eq!(std::fs::read(&run).unwrap(), run_before);

    let eval = [
        "eval",
        "--machine",
        M,
        "--model",
        s(&model),
        "--run",
        s(&run),
        "--out",
        s(&run),
    ];
    let (ok, err) = within(60, &eval);
    assert!(
        !ok && err.contains("is also this command's input --run"),
        "{err}"
    );
    assert_eq!(std::fs::read(&run).unwrap(), run_before);

    let program = d.join("prog.ngc");
    std::fs::write(&program, "G0 X10\nM2\n").unwrap();
    let ktab = "examples/kinematics/head-ac/kinematics.ktab";
    let gcode = [
        "kin",
        "gcode",
        "--kinematics",
        ktab,
        "--input",
        s(&program),
        "--output",
        s(&program),
    ];
    let (ok, err) = within(60, &gcode);
    assert!(
        !ok && err.contains("is also this command's input --input"),
        "{err}"
    );
    assert_eq!(std::fs::read_to_string(&program).unwrap(), "G0 X10\nM2\n");

    // A CSV sink over the run the service replays.
    let replay = d.join("replay.csv");
    std::fs::copy(repo(RUN), &replay).unwrap();
    let source = format!("replay:{}", s(&replay));
    let sink = format!("csv:{}", s(&replay));
    let (ok, err) = within(
        60,
        &[
            "run",
            "--fast",
            "--duration-s",
            "1",
            "--source",
            &source,
            "--sink",
            &sink,
        ],
    );
    assert!(
        !ok && err.contains("is also this command's input --source"),
        "{err}"
    );
    assert_eq!(
        std::fs::read(&replay).unwrap(),
        std::fs::read(repo(RUN)).unwrap()
    );
}

#[test]
fn devices_and_fifos_are_refused_as_inputs_at_once() {
    let d = scratch("rt-inputs");
    let cases: [(&str, Vec<&str>); 5] = [
        ("/dev/zero", vec!["status", "--log", "/dev/zero"]),
        ("/dev/zero", vec!["log", "--log", "/dev/zero"]),
        (
            "/dev/zero",
            vec![
                "run",
                "--fast",
                "--duration-s",
                "1",
                "--models",
                "/dev/zero",
            ],
        ),
        (
            "/dev/zero",
            vec![
                "eval",
                "--machine",
                "/dev/zero",
                "--model",
                MODEL,
                "--run",
                RUN,
            ],
        ),
        (
            "/dev/urandom",
            vec![
                "eval",
                "--machine",
                M,
                "--model",
                MODEL,
                "--run",
                "/dev/urandom",
            ],
        ),
    ];
    for (file, args) in cases {
        let (ok, err) = within(10, &args);
        assert!(
            !ok && err.contains(&format!(
                "{file}: is a character device, not a regular file"
            )),
            "{err}"
        );
    }
    let fifo = d.join("model.toml");
    mkfifo(&fifo);
    let (ok, err) = within(
        10,
        &["eval", "--machine", M, "--model", s(&fifo), "--run", RUN],
    );
    assert!(
        !ok && err.contains("is a FIFO (named pipe), not a regular file"),
        "{err}"
    );
    // The campaign's second round: a log that is a FIFO or a directory, named as such (a FIFO
    // opened by SQLite would wait for a writer; a directory gave "disk I/O error").
    for (what, log) in [
        ("a FIFO (named pipe)", fifo.clone()),
        ("a directory", d.clone()),
    ] {
        let (ok, err) = within(10, &["log", "--log", s(&log)]);
        assert!(
            !ok && err.contains(&format!("is {what}, not a regular file")),
            "{err}"
        );
    }
}

#[test]
fn a_model_of_500_mb_is_refused_by_its_size() {
    let d = scratch("rt-huge-model");
    let model = d.join("model.toml");
    std::fs::copy(repo(MODEL), &model).unwrap();
    // Sparse: the size is what the door looks at, before reading a byte of it.
    let f = std::fs::OpenOptions::new()
        .write(true)
        .open(&model)
        .unwrap();
    f.set_len(500 << 20).unwrap();
    let t = Instant::now();
    let (ok, err) = within(
        10,
        &["eval", "--machine", M, "--model", s(&model), "--run", RUN],
    );
    assert!(
        !ok && err
            .contains("is 524288000 bytes, more than the 16777216 bytes a model file may have"),
        "{err}"
    );
    assert!(t.elapsed() < Duration::from_secs(5));
}

/// A FIFO renamed over the model file of a running service: the reload thread must not block
/// on it (the run ends on time), the running model stays, and the log says why.
#[test]
fn a_fifo_moved_over_the_model_never_blocks_the_reload() {
    let d = scratch("rt-reload-fifo");
    let model = d.join("model.toml");
    std::fs::copy(repo(MODEL), &model).unwrap();
    let log = d.join("log.db");
    let mut child = command()
        .args([
            "run",
            "--duration-s",
            "3",
            "--reload-on-change",
            "--json",
            "--models",
        ])
        .arg(&model)
        .arg("--log")
        .arg(&log)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    std::thread::sleep(Duration::from_millis(800));
    let fifo = d.join("fifo");
    mkfifo(&fifo);
    std::fs::rename(&fifo, &model).unwrap();
    let start = Instant::now();
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        if start.elapsed() > Duration::from_secs(20) {
            let _ = child.kill();
            let _ = child.wait();
            panic!("the run did not end: its reload thread blocks on the FIFO");
        }
        std::thread::sleep(Duration::from_millis(50));
    };
    // The run itself may end non-zero (its model file is gone); what matters is that it ended.
    let _ = status;
    let rows = truepos_runtime::log::read_events(&log).unwrap();
    let failed: Vec<_> = rows
        .iter()
        .filter(|e| e.kind == "model-reload-failed")
        .collect();
    assert!(!failed.is_empty(), "no model-reload-failed event: {rows:?}");
    assert!(failed[0].detail.contains("FIFO"), "{:?}", failed[0]);
}

#[test]
fn a_glob_of_inputs_takes_neither_time_nor_positions() {
    let d = scratch("rt-glob");
    let run = small_run(&d);
    let (ok, err) = within(
        120,
        &[
            "fit",
            "--run",
            s(&run),
            "--inputs",
            "t*",
            "--target",
            "dz_um",
            "--json",
        ],
    );
    assert!(ok, "{err}");
    let out = command()
        .args([
            "fit",
            "--run",
            s(&run),
            "--inputs",
            "t*",
            "--target",
            "dz_um",
            "--json",
        ])
        .output()
        .unwrap();
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["inputs"], serde_json::json!(["t1_c", "t2_c"]));
    // Only the time column matches: an error that says so.
    let (ok, err) = within(
        60,
        &[
            "fit",
            "--run",
            s(&run),
            "--inputs",
            "time*",
            "--target",
            "dz_um",
        ],
    );
    assert!(
        !ok && err.contains("matches only time_s, the time or position columns"),
        "{err}"
    );
}

#[test]
fn a_fit_beyond_its_budget_names_inputs_and_rows() {
    let d = scratch("rt-budget");
    let n = 300;
    let mut text = String::from("time_s");
    for k in 0..n {
        text.push_str(&format!(",t{k}_c"));
    }
    text.push_str(",dz_um\n");
    for i in 0..20 {
        text.push_str(&format!("{}", i * 60));
        for k in 0..n {
            text.push_str(&format!(",{}", 20.0 + ((i * k) % 7) as f64 * 0.1));
        }
        text.push_str(",1.0\n");
    }
    let run = d.join("wide.csv");
    std::fs::write(&run, text).unwrap();
    let (ok, err) = within(
        60,
        &[
            "fit",
            "--run",
            s(&run),
            "--inputs",
            "t*",
            "--target",
            "dz_um",
        ],
    );
    assert!(
        !ok && err.contains("300 inputs × 20 rows: more than the 256 inputs one fit takes"),
        "{err}"
    );
}

#[test]
fn a_line_of_unbounded_length_is_refused_at_its_line() {
    let d = scratch("rt-long-line");
    let run = d.join("long.csv");
    let mut text = String::from("time_s,t1_c,dz_um\n0,20,0\n");
    text.push_str(&"x".repeat(3 << 20));
    text.push('\n');
    std::fs::write(&run, text).unwrap();
    let (ok, err) = within(
        30,
        &[
            "fit",
            "--run",
            s(&run),
            "--inputs",
            "t*",
            "--target",
            "dz_um",
        ],
    );
    assert!(
        !ok && err.contains(&format!(
            "{}:3:1048577: the line is longer than 1048576 bytes",
            s(&run)
        )),
        "{err}"
    );
}

/// Unmounts on drop, so a failing test leaves no mount behind.
struct Mounted(PathBuf);

impl Drop for Mounted {
    fn drop(&mut self) {
        let _ = Command::new("umount").arg(&self.0).status();
    }
}

/// A log in a directory its reader cannot write: `status` and `log` read it. Root may write any
/// directory whatever its mode, so the directory is a read-only bind mount (the file system
/// itself refuses writes, for root too); where mounting is not allowed the test says so and
/// checks only that the log reads through the immutable fallback (runtime unit test
/// `a_log_opened_immutable_reads_every_commit`).
#[test]
fn a_log_in_a_read_only_directory_is_read() {
    let d = scratch("rt-ro-log");
    let (rw, ro) = (d.join("rw"), d.join("ro"));
    std::fs::create_dir_all(&rw).unwrap();
    std::fs::create_dir_all(&ro).unwrap();
    let log = rw.join("log.db");
    let (ok, err) = within(
        60,
        &["run", "--fast", "--duration-s", "2", "--log", s(&log)],
    );
    assert!(ok, "{err}");
    let bind = Command::new("mount")
        .arg("--bind")
        .arg(&rw)
        .arg(&ro)
        .output()
        .unwrap();
    if !bind.status.success() {
        eprintln!(
            "skipped: cannot bind-mount a read-only directory here ({})",
            String::from_utf8_lossy(&bind.stderr).trim()
        );
        return;
    }
    let _m = Mounted(ro.clone());
    let remount = Command::new("mount")
        .args(["-o", "remount,ro,bind"])
        .arg(&ro)
        .output()
        .unwrap();
    assert!(remount.status.success());
    assert!(
        std::fs::write(ro.join("probe"), "x").is_err(),
        "the mount is not read-only"
    );
    let ro_log = ro.join("log.db");
    let (ok, err) = within(20, &["status", "--log", s(&ro_log)]);
    assert!(ok, "status: {err}");
    let (ok, err) = within(20, &["log", "--log", s(&ro_log)]);
    assert!(ok, "log: {err}");
}

/// `fit --model` on a full disk: the earlier model stays whole and no temporary file is left
/// (it was left truncated at 4 096 bytes). The full disk is a 64 KiB tmpfs filled up, which
/// needs root; elsewhere the test says why it skips.
#[test]
fn a_full_disk_leaves_the_earlier_model_whole() {
    let d = scratch("rt-full-disk");
    let run = small_run(&d);
    let disk = d.join("disk");
    std::fs::create_dir_all(&disk).unwrap();
    let mounted = Command::new("mount")
        .args(["-t", "tmpfs", "-o", "size=64k", "tmpfs"])
        .arg(&disk)
        .output()
        .unwrap();
    if !mounted.status.success() {
        eprintln!(
            "skipped: cannot mount a small tmpfs here ({})",
            String::from_utf8_lossy(&mounted.stderr).trim()
        );
        return;
    }
    let _m = Mounted(disk.clone());
    let model = disk.join("model.json");
    std::fs::write(&model, "{\"earlier\": true}\n").unwrap();
    // Fill what is left, in small pieces so that the last one takes the last block.
    let mut filler = std::fs::File::create(disk.join("filler")).unwrap();
    while std::io::Write::write_all(&mut filler, &[b'x'; 512]).is_ok() {}
    drop(filler);
    let (ok, err) = within(
        120,
        &[
            "fit",
            "--run",
            s(&run),
            "--inputs",
            "t*",
            "--target",
            "dz_um",
            "--model",
            s(&model),
        ],
    );
    assert!(!ok, "the fit wrote on a full disk: {err}");
    assert!(err.contains(s(&model)), "{err}");
    assert_eq!(
        std::fs::read_to_string(&model).unwrap(),
        "{\"earlier\": true}\n"
    );
    let left: Vec<_> = std::fs::read_dir(&disk)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".tmp"))
        .collect();
    assert!(left.is_empty(), "{left:?}");
}
