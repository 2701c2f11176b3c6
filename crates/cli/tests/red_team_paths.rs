//! The red-team suite's proptest over output paths: every command that writes a
//! file is given, as its output, a symbolic link to a victim, a dangling link, a FIFO, a
//! device, one of its own inputs, a file in a missing directory or a directory. Each must be
//! refused, naming the output, within a deadline, and leave the victim, the input and the path
//! exactly as they were. `run` is here through its CSV sink (whose final file is the output);
//! `report` and `fit --report` write a folder of files, each through the same door
//! (`truepos_files::write`), and are not cases here.

mod support;

use std::os::unix::fs::FileTypeExt;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::OnceLock;
use std::time::{Duration, Instant};

use proptest::prelude::*;
use support::{command, repo, scratch};

const M: &str = "examples/vmc3/machine.toml";
const MODEL: &str = "examples/vmc3/model.toml";
const RUN: &str = "examples/vmc3/run.csv";

/// What the output path is.
#[derive(Debug, Clone, Copy)]
enum Kind {
    LinkToVictim,
    DanglingLink,
    Fifo,
    Device,
    Input,
    MissingDirectory,
    Directory,
}

/// The commands that write a file: each with its input (a copy in the case's directory, so
/// that the output can be it) and the arguments around `OUT`.
const COMMANDS: [&str; 10] = [
    "export",
    "eval",
    "fit",
    "predictions",
    "run",
    "sim",
    "log",
    "reidentify",
    "gcode",
    "table",
];

/// A log, written once for the process, that `truepos log --csv` and `reidentify` read.
fn a_log() -> &'static Path {
    static LOG: OnceLock<PathBuf> = OnceLock::new();
    LOG.get_or_init(|| {
        let d = scratch("rtp-log");
        let log = d.join("log.db");
        let ok = command()
            .args(["run", "--fast", "--duration-s", "1", "--log"])
            .arg(&log)
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .status()
            .unwrap()
            .success();
        assert!(ok);
        log
    })
}

/// The command's input copied into `dir`, and its arguments with `out` as the output.
fn case(cmd: &str, dir: &Path, out: &Path) -> (PathBuf, Vec<String>) {
    let copy = |from: &Path, name: &str| {
        let p = dir.join(name);
        std::fs::copy(from, &p).unwrap();
        p
    };
    let o = out.display().to_string();
    let (input, args): (PathBuf, Vec<&str>) = match cmd {
        "export" => {
            let i = copy(&repo(MODEL), "model.toml");
            let args = vec![
                "export",
                "--to",
                "siemens",
                "--machine",
                M,
                "--run",
                RUN,
                "--model",
            ];
            (i, args)
        }
        "eval" => (
            copy(&repo(RUN), "run.csv"),
            vec!["eval", "--machine", M, "--model", MODEL, "--run"],
        ),
        "fit" => (
            copy(&repo(RUN), "run.csv"),
            vec!["fit", "--inputs", "*bearing", "--target", "X_mm", "--run"],
        ),
        "predictions" => (
            copy(&repo(RUN), "run.csv"),
            vec!["fit", "--inputs", "*bearing", "--target", "X_mm", "--run"],
        ),
        "run" => {
            let i = copy(&repo(RUN), "run.csv");
            let source = format!("replay:{}", i.display());
            let sink = format!("csv:{o}");
            let args = vec!["run", "--fast", "--duration-s", "1", "--source"];
            let mut args: Vec<String> = args.into_iter().map(String::from).collect();
            args.extend([source, "--sink".into(), sink]);
            return (i, args);
        }
        "sim" => (
            copy(&repo("examples/twin/twin.toml"), "twin.toml"),
            vec!["sim", "--scenario", "spindle-warmup", "--twin"],
        ),
        "log" => (copy(a_log(), "log.db"), vec!["log", "--log"]),
        "reidentify" => (
            copy(&repo(MODEL), "model.toml"),
            vec!["reidentify", "--machine", M, "--run", RUN, "--model"],
        ),
        "table" => {
            let p = dir.join("table.csv");
            std::fs::write(&p, "position,forward,reverse\n0,2,-2\n100,3.5,-0.5\n").unwrap();
            (
                p,
                vec!["kin", "table", "--from", "csv", "--to", "csv", "--input"],
            )
        }
        _ => {
            let p = dir.join("prog.ngc");
            std::fs::write(&p, "G0 X10\nM2\n").unwrap();
            let k = "examples/kinematics/head-ac/kinematics.ktab";
            (p, vec!["kin", "gcode", "--kinematics", k, "--input"])
        }
    };
    let mut args: Vec<String> = args.into_iter().map(String::from).collect();
    args.push(input.display().to_string());
    let flag = match cmd {
        "fit" => "--model",
        "predictions" => "--predictions",
        "log" => "--csv",
        "gcode" => "--output",
        _ => "--out",
    };
    args.extend([flag.to_string(), o]);
    (input, args)
}

/// Makes `out` what `kind` says; `None` when this process may not (a device without root).
fn plant(kind: Kind, out: &Path, victim: &Path) -> Option<()> {
    match kind {
        Kind::LinkToVictim => std::os::unix::fs::symlink(victim, out).unwrap(),
        Kind::DanglingLink => std::os::unix::fs::symlink(out.with_extension("gone"), out).unwrap(),
        Kind::Fifo => {
            assert!(Command::new("mkfifo").arg(out).status().unwrap().success());
        }
        Kind::Device => {
            let made = Command::new("mknod")
                .arg(out)
                .args(["c", "1", "7"])
                .output()
                .unwrap();
            if !made.status.success() {
                eprintln!("skipped a device case: mknod needs root");
                return None;
            }
        }
        Kind::Directory => std::fs::create_dir(out).unwrap(),
        Kind::Input | Kind::MissingDirectory => {}
    }
    Some(())
}

fn file_type(p: &Path) -> Option<std::fs::FileType> {
    std::fs::symlink_metadata(p).ok().map(|m| m.file_type())
}

fn check(cmd: &str, kind: Kind, n: u32) {
    let dir = scratch(&format!("rtp-{cmd}-{n}"));
    let victim = dir.join("victim.txt");
    std::fs::write(&victim, "precious").unwrap();
    let planned = match kind {
        Kind::MissingDirectory => dir.join("missing").join("out.csv"),
        _ => dir.join("out.csv"),
    };
    let (input, mut args) = case(cmd, &dir, &planned);
    let out = if matches!(kind, Kind::Input) {
        let last = args.len() - 1;
        let prefix = if args[last].starts_with("csv:") {
            "csv:"
        } else {
            ""
        };
        args[last] = format!("{prefix}{}", input.display());
        input.clone()
    } else {
        planned
    };
    if plant(kind, &out, &victim).is_none() {
        return;
    }
    let before_type =
        file_type(&out).map(|t| (t.is_symlink(), t.is_fifo(), t.is_char_device(), t.is_dir()));
    let input_before = std::fs::read(&input).unwrap();
    let mut child = command()
        .args(&args)
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let start = Instant::now();
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        if start.elapsed() > Duration::from_secs(60) {
            let _ = child.kill();
            let _ = child.wait();
            panic!("{cmd} with a {kind:?} output still ran after 60 s");
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    let mut err = String::new();
    std::io::Read::read_to_string(child.stderr.as_mut().unwrap(), &mut err).unwrap();
    assert!(!status.success(), "{cmd} wrote to a {kind:?}: {err}");
    assert!(
        err.contains(&out.display().to_string()),
        "{cmd}, {kind:?}: {err}"
    );
    assert_eq!(
        std::fs::read_to_string(&victim).unwrap(),
        "precious",
        "{cmd}, {kind:?}"
    );
    assert_eq!(
        std::fs::read(&input).unwrap(),
        input_before,
        "{cmd}, {kind:?}: input changed"
    );
    let after_type =
        file_type(&out).map(|t| (t.is_symlink(), t.is_fifo(), t.is_char_device(), t.is_dir()));
    assert_eq!(
        before_type, after_type,
        "{cmd}, {kind:?}: the output path changed"
    );
    let left: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".tmp") || n.ends_with(".partial"))
        .collect();
    assert!(left.is_empty(), "{cmd}, {kind:?}: left {left:?}");
    let _ = std::fs::remove_dir_all(&dir);
}

fn kind() -> impl Strategy<Value = Kind> {
    prop_oneof![
        Just(Kind::LinkToVictim),
        Just(Kind::DanglingLink),
        Just(Kind::Fifo),
        Just(Kind::Device),
        Just(Kind::Input),
        Just(Kind::MissingDirectory),
        Just(Kind::Directory),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 24, failure_persistence: None, ..ProptestConfig::default() })]

    #[test]
    fn no_command_writes_through_a_hostile_output(cmd in 0..COMMANDS.len(), kind in kind(), n in 0u32..1_000_000) {
        check(COMMANDS[cmd], kind, n);
    }
}

/// Every command against every kind once, so no pair is left to chance.
#[test]
fn every_command_refuses_every_hostile_output() {
    let kinds = [
        Kind::LinkToVictim,
        Kind::DanglingLink,
        Kind::Fifo,
        Kind::Device,
        Kind::Input,
        Kind::MissingDirectory,
        Kind::Directory,
    ];
    for cmd in COMMANDS {
        for (i, kind) in kinds.iter().enumerate() {
            check(cmd, *kind, 2_000_000 + i as u32);
        }
    }
}
