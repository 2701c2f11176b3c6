//! Rewrite time against rs274 alone, side by side in one run, on a generated program of one
//! million moves (the bar: rewriting costs at most twice what rs274 needs to interpret
//! the same program). `cargo bench -p truepos-gcode --bench rewrite [-- MOVES]`.
//!
//! rs274 alone writes its canonical commands to its output file `/dev/null` (a buffered stream:
//! its fastest way; to standard output it writes unbuffered and is slower); the rewrite runs
//! rs274 on the
//! numbered copy, parses its output as it streams, compensates every point through
//! `examples/kinematics/sample-mill` (21 error tables) and writes the program. Three rounds,
//! alternating, medians reported.

use std::io::Write;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::Instant;

use truepos_gcode::{rewrite_file, Interpreter, Options};

fn main() {
    let moves: usize = std::env::args()
        .skip(1)
        .find_map(|a| a.parse().ok())
        .unwrap_or(1_000_000);
    let repo = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let ex = repo.join("examples/kinematics/sample-mill");
    let k = truepos_io::kinematics_file::load(&ex.join("kinematics.ktab"), None)
        .unwrap_or_else(|e| panic!("{e}"));
    let dir = tempfile::tempdir().unwrap();
    let program = dir.path().join("million.ngc");
    {
        // A raster over 400 × 300 mm with a wavy Z: every line a feed move.
        let mut w = std::io::BufWriter::new(std::fs::File::create(&program).unwrap());
        writeln!(w, "G21 G90 G17 G94\nG0 X0 Y0 Z5\nG1 Z0 F2000").unwrap();
        for i in 0..moves {
            let row = i / 1000;
            let col = i % 1000;
            let x = if row % 2 == 0 { col } else { 999 - col } as f64 * 0.4;
            let y = (row % 750) as f64 * 0.4;
            let z = -1.0 - 0.5 * (x / 40.0).sin() * (y / 30.0).cos();
            writeln!(w, "G1 X{x:.4} Y{y:.4} Z{z:.4}").unwrap();
        }
        writeln!(w, "G0 Z5\nM2").unwrap();
    }
    let tools = ex.join("tool.tbl");
    let mut rs_times = Vec::new();
    let mut rw_times = Vec::new();
    let mut opts = Options::new(k.tool_length_mm);
    opts.interpreter = Interpreter {
        tool_table: Some(tools.clone()),
        ..Interpreter::default()
    };
    for round in 0..3 {
        let work = tempfile::tempdir().unwrap();
        std::fs::copy(&tools, work.path().join("tool.tbl")).unwrap();
        let t = Instant::now();
        let st = Command::new("rs274")
            .args(["-g", "-t", "tool.tbl", "-v", "p.var"])
            .arg(&program)
            .arg("/dev/null")
            .env("HOME", work.path())
            .current_dir(work.path())
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .status()
            .expect("rs274: run scripts/install_linuxcnc.sh");
        assert!(st.success(), "rs274 refused the generated program");
        let rs = t.elapsed().as_secs_f64();
        let out = dir.path().join("million.out.ngc");
        let t = Instant::now();
        let s = rewrite_file(&program, &k.chain, &opts, &out).unwrap_or_else(|e| panic!("{e}"));
        let rw = t.elapsed().as_secs_f64();
        assert_eq!(s.moves as usize, moves + 3);
        println!(
            "round {round}: rs274 alone {rs:.2} s, rewrite {rw:.2} s ({:.2}× rs274; {:.2} µs a move)",
            rw / rs,
            rw / s.moves as f64 * 1e6
        );
        rs_times.push(rs);
        rw_times.push(rw);
    }
    rs_times.sort_by(f64::total_cmp);
    rw_times.sort_by(f64::total_cmp);
    let (rs, rw) = (rs_times[1], rw_times[1]);
    println!(
        "{moves} moves: rs274 alone {rs:.2} s, rewrite {rw:.2} s (medians of 3): {:.2}× rs274 (bar ≤ 2×)",
        rw / rs
    );
}
