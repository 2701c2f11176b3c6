//! Bad input gives a clear error naming its place, never a hang, a panic or an output file:
//! binary garbage, a 50 MB comment, 4 million words on one line (generated here into a temp
//! dir), a program that never ends, an interpreter that is not there, an interpreter error.

mod common;

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use common::*;
use truepos_gcode::{rewrite_file, Error, Interpreter, Options};

fn refuse(input: &Path, opts: &Options, within: Duration) -> Error {
    let k = example("sample-mill");
    let out = input.with_extension("out.ngc");
    let start = Instant::now();
    let e = rewrite_file(input, &k.chain, opts, &out).expect_err("must be refused");
    let took = start.elapsed();
    assert!(took < within, "{}: took {took:?}", input.display());
    assert!(
        !out.exists(),
        "{}: refused but wrote {}",
        input.display(),
        out.display()
    );
    let left: Vec<PathBuf> = std::fs::read_dir(input.parent().unwrap())
        .unwrap()
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            p.file_name()
                .unwrap()
                .to_string_lossy()
                .starts_with(".truepos")
        })
        .collect();
    assert!(left.is_empty(), "temporary files left: {left:?}");
    e
}

fn opts() -> Options {
    let mut o = Options::new(100.0);
    o.interpreter = interpreter();
    o
}

#[test]
fn binary_garbage_is_refused_at_its_first_control_character() {
    require_rs274();
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("garbage.ngc");
    // Deterministic pseudo-random bytes after two good lines.
    let mut bytes = b"G21 G90\nG0 X1\n".to_vec();
    let mut x: u32 = 0x1234_5678;
    for _ in 0..100_000 {
        x ^= x << 13;
        x ^= x >> 17;
        x ^= x << 5;
        bytes.push((x >> 24) as u8);
    }
    std::fs::write(&p, &bytes).unwrap();
    let e = refuse(&p, &opts(), Duration::from_secs(5));
    let msg = e.to_string();
    assert!(msg.starts_with(&format!("{}:3:", p.display())), "{msg}");
    assert!(
        msg.contains("control character") || msg.contains("longer than 252"),
        "{msg}"
    );
    // A NUL byte in an otherwise good line.
    std::fs::write(&p, b"G21\nG0 X1 (a\0b)\nM2\n").unwrap();
    let msg = refuse(&p, &opts(), Duration::from_secs(5)).to_string();
    assert!(
        msg.starts_with(&format!("{}:2:9: control character 0x00", p.display())),
        "{msg}"
    );
}

#[test]
fn a_50_mb_comment_is_refused_without_reading_it() {
    require_rs274();
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("comment.ngc");
    let mut text = String::from("G21 G90\nG0 X1 (");
    text.push_str(&"x".repeat(50 << 20));
    text.push_str(")\nM2\n");
    std::fs::write(&p, text).unwrap();
    let msg = refuse(&p, &opts(), Duration::from_secs(5)).to_string();
    assert!(
        msg.starts_with(&format!(
            "{}:2:253: line longer than 252 characters",
            p.display()
        )),
        "{msg}"
    );
}

#[test]
fn four_million_words_on_one_line_are_refused() {
    require_rs274();
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("words.ngc");
    let mut text = String::from("G21 G90\nG1 F100");
    for i in 0..4_000_000 {
        text.push_str(if i % 2 == 0 { " X1" } else { " Y2" });
    }
    text.push_str("\nM2\n");
    std::fs::write(&p, text).unwrap();
    let msg = refuse(&p, &opts(), Duration::from_secs(5)).to_string();
    assert!(msg.starts_with(&format!("{}:2:253:", p.display())), "{msg}");
}

#[test]
fn a_program_that_never_ends_is_stopped_at_the_time_limit() {
    require_rs274();
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("forever.ngc");
    std::fs::write(
        &p,
        "#1 = 0\no100 while [1]\n#1 = [#1 + 1]\no100 endwhile\nM2\n",
    )
    .unwrap();
    let mut o = opts();
    o.interpreter.time_limit = Duration::from_secs(2);
    let e = refuse(&p, &o, Duration::from_secs(10));
    assert!(matches!(e, Error::TimedOut { .. }), "{e}");
    assert!(e.to_string().contains("did not finish within 2 s"), "{e}");
}

#[test]
fn a_missing_interpreter_names_the_install_script() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("p.ngc");
    std::fs::write(&p, "G0 X1\nM2\n").unwrap();
    let mut o = opts();
    o.interpreter = Interpreter {
        rs274: PathBuf::from("/nonexistent/rs274"),
        ..Interpreter::default()
    };
    let msg = refuse(&p, &o, Duration::from_secs(5)).to_string();
    assert!(msg.contains("scripts/install_linuxcnc.sh"), "{msg}");
}

#[test]
fn interpreter_errors_name_the_line_and_what_rs274_said() {
    require_rs274();
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("bad.ngc");
    std::fs::write(&p, "G21 G90\nN10 G0 X1\n  G1 X2 (no feed)\nM2\n").unwrap();
    let msg = refuse(&p, &opts(), Duration::from_secs(5)).to_string();
    assert_eq!(
        msg,
        format!("{}:3: LinuxCNC's interpreter refused the program: Cannot do g1 with zero feed rate (at `  G1 X2 (no feed)`)", p.display())
    );
    // No program end: rs274 refuses at the end of the file.
    std::fs::write(&p, "G0 X1\n").unwrap();
    let msg = refuse(&p, &opts(), Duration::from_secs(5)).to_string();
    assert!(
        msg.contains("File ended with no percent sign or program end"),
        "{msg}"
    );
    // An empty file.
    std::fs::write(&p, "").unwrap();
    let msg = refuse(&p, &opts(), Duration::from_secs(5)).to_string();
    assert!(msg.contains("interpreter refused"), "{msg}");
}

/// The output path is never touched by a refusal: an earlier file there stays as it was.
#[test]
fn a_refusal_keeps_an_earlier_output() {
    require_rs274();
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("travel.ngc");
    std::fs::write(&p, "G21 G90\nG0 X10\nG0 X2000\nM2\n").unwrap();
    let out = dir.path().join("travel.out.ngc");
    std::fs::write(&out, "(earlier)\n").unwrap();
    let k = example("sample-mill");
    let e = rewrite_file(&p, &k.chain, &opts(), &out).unwrap_err();
    assert!(
        e.to_string().starts_with(&format!(
            "{}:3: the program moves X to 2000.0000",
            p.display()
        )),
        "{e}"
    );
    assert_eq!(std::fs::read_to_string(&out).unwrap(), "(earlier)\n");
}
