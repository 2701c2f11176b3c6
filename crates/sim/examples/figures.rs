//! The twin's realism figures quoted in docs/twin.md:
//! `cargo run --release -p truepos-sim --example figures`.
//!
//! Prints, for the built-in reference machine, the tool-tip error of the ISO 230-3 style tests
//! along the axes' travel at chosen instants (evaluated from the recorded node temperatures with
//! `Twin::error_um`, the ground truth anywhere in the working volume).

use truepos_sim::{Scenario, SimRun, Twin};

fn row_at(run: &SimRun, t_s: f64) -> usize {
    run.rows
        .iter()
        .position(|r| r.time_s >= t_s - 1e-9)
        .expect("instant inside the run")
}

fn line(twin: &Twin, run: &SimRun, t_h: f64, axis: usize, points: &[f64], base: [f64; 3]) {
    let i = row_at(run, t_h * 3600.0);
    let d = twin.deformation(run.state(i));
    let name = ["X", "Y", "Z"][axis];
    for &p in points {
        let mut pos = base;
        pos[axis] = p;
        let e = d.error_um(pos);
        println!(
            "  t = {t_h:>4.1} h  {name} = {p:>5.0} mm (X {:.0} Y {:.0} Z {:.0}):  dx {:+7.1}  dy {:+7.1}  dz {:+7.1} µm",
            pos[0], pos[1], pos[2], e[0], e[1], e[2]
        );
    }
}

fn main() {
    let twin = Twin::reference();
    println!(
        "reference machine {}: {} thermal nodes, {} sensors",
        twin.name,
        twin.node_count(),
        twin.sensors.len()
    );

    let sc = Scenario::builtin("spindle-warmup").expect("built-in");
    let run = twin.run(&sc, 1).expect("runs");
    let s = run.summary();
    let park = [400.0, 250.0, 250.0];
    println!("\nspindle-warmup (8000 1/min for 4 h, then stopped 4 h), tool at X 400 Y 250 Z 250:");
    for t_h in [0.25, 0.5, 1.0, 2.0, 4.0, 5.0, 6.0, 8.0] {
        let i = row_at(&run, t_h * 3600.0);
        let e = twin.error_um(run.state(i), park);
        println!(
            "  t = {t_h:>4.2} h: dx {:+6.1}  dy {:+6.1}  dz {:+6.1} µm",
            e[0], e[1], e[2]
        );
    }
    println!(
        "  peak dz {:+.1} µm at {:.2} h; dz reaches 63 % of it after {:.0} min",
        s.peak_error[2].0,
        s.peak_error[2].1 / 3600.0,
        s.t63_s[2] / 60.0
    );
    println!("  along Z at the end of the spindle run (column bent by the head's heat, Z tilted):");
    line(
        &twin,
        &run,
        4.0,
        2,
        &[0.0, 125.0, 250.0, 375.0, 500.0],
        park,
    );

    let sc = Scenario::builtin("linear-axis").expect("built-in");
    let run = twin.run(&sc, 1).expect("runs");
    println!("\nlinear-axis (X sweeps its travel at 12 m/min for 4 h, then stands 2 h), along X at Y 250 Z 250:");
    line(
        &twin,
        &run,
        1.0,
        0,
        &[0.0, 200.0, 400.0, 600.0, 800.0],
        park,
    );
    line(
        &twin,
        &run,
        4.0,
        0,
        &[0.0, 200.0, 400.0, 600.0, 800.0],
        park,
    );
    let s = run.summary();
    println!(
        "  dz reaches 63 % of its peak after {:.0} min, dx after {:.0} min",
        s.t63_s[2] / 60.0,
        s.t63_s[0] / 60.0
    );

    let sc = Scenario::builtin("mixed-shift").expect("built-in");
    let run = twin.run(&sc, 1).expect("runs");
    let s = run.summary();
    println!("\nmixed-shift (day A), peak errors over the recorded positions:");
    for (k, d) in ["dx", "dy", "dz"].iter().enumerate() {
        let (v, t, p) = s.peak_error[k];
        println!(
            "  {d} {v:+6.1} µm at {:.2} h, X {:.0} Y {:.0} Z {:.0}",
            t / 3600.0,
            p[0],
            p[1],
            p[2]
        );
    }
    println!("  along Y at 4.5 h (after finishing at 11000 1/min), X 400 Z 50:");
    line(
        &twin,
        &run,
        4.5,
        1,
        &[0.0, 125.0, 250.0, 375.0, 500.0],
        [400.0, 250.0, 50.0],
    );
}
