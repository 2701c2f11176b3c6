//! The kinematics table with error tables on the example machines: forward transform (nominal and
//! through the error tables) and the compensated inverse transform, per point.
//!
//! Run: `cargo bench -p truepos-kinematics --bench kinematics`. Targets: forward ≥ 5 million points
//! per second per core (≤ 200 ns per point); the compensated inverse ≥ 20× the throughput of
//! KDL's `ChainIkSolverPos_NR` (see `scripts/kdl_compare.py`).

use divan::{black_box, Bencher};
use truepos_kinematics::{Chain, Directions, Geometry, Pose};

#[path = "../tests/machines/mod.rs"]
mod machines;

fn main() {
    divan::main();
}

const TOOL: f64 = 100.0;
const POINTS: usize = 1000;

/// Deterministic axis positions inside travel (xorshift, no dependency).
fn positions(chain: &Chain) -> Vec<Vec<f64>> {
    let mut s = 0x2545_f491_4f6c_dd1d_u64;
    let mut next = move || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        (s >> 11) as f64 / (1u64 << 53) as f64
    };
    (0..POINTS)
        .map(|_| {
            chain
                .axes()
                .iter()
                .map(|a| {
                    let (lo, hi) = (a.travel_min.max(-90.0), a.travel_max.min(90.0));
                    let (lo, hi) = if a.kind == truepos_model::AxisKind::Linear {
                        (
                            a.travel_min * 0.7 + a.travel_max * 0.3,
                            a.travel_max * 0.7 + a.travel_min * 0.3,
                        )
                    } else {
                        (lo, hi)
                    };
                    lo + (hi - lo) * next()
                })
                .collect()
        })
        .collect()
}

fn chain(name: &str) -> Chain {
    match name {
        "head-ac" => machines::head_ac(),
        "table-ac" => machines::table_ac(),
        "head-bc" => machines::head_bc(),
        _ => machines::three_axis_21(),
    }
}

const MACHINES: [&str; 4] = ["head-ac", "table-ac", "head-bc", "vmc-21"];

/// 1000 forward transforms of `geometry` per iteration: divide the time by 1000 for one point.
fn forward_1000(bencher: Bencher, name: &str, geometry: Geometry) {
    let c = chain(name);
    let qs = positions(&c);
    bencher.bench_local(|| {
        let mut s = 0.0;
        for q in &qs {
            s += c
                .forward(black_box(q), TOOL, Directions(0), geometry)
                .unwrap()
                .position[0];
        }
        s
    });
}

/// 1000 nominal forward transforms per iteration.
#[divan::bench(args = MACHINES)]
fn forward_nominal_1000(bencher: Bencher, name: &str) {
    forward_1000(bencher, name, Geometry::Nominal);
}

/// 1000 forward transforms through the error tables per iteration.
#[divan::bench(args = MACHINES)]
fn forward_actual_1000(bencher: Bencher, name: &str) {
    forward_1000(bencher, name, Geometry::Actual);
}

fn targets(c: &Chain, geometry: Geometry) -> (Vec<Pose>, Vec<Vec<f64>>) {
    let qs = positions(c);
    let poses = qs
        .iter()
        .map(|q| c.forward(q, TOOL, Directions(0), geometry).unwrap())
        .collect();
    // Previous set-points: the true ones moved by 0.5 mm / 0.5°.
    let prev = qs
        .iter()
        .map(|q| q.iter().map(|v| v + 0.5).collect())
        .collect();
    (poses, prev)
}

/// 1000 inverse transforms of `geometry` with the bencher's clock on the loop only.
fn inverse_1000(bencher: Bencher, name: &str, geometry: Geometry) {
    let c = chain(name);
    let (poses, prev) = targets(&c, geometry);
    let mut out = vec![0.0; c.axes().len()];
    bencher.bench_local(|| {
        let mut s = 0.0;
        for (p, q) in poses.iter().zip(&prev) {
            c.inverse(black_box(p), TOOL, q, Directions(0), geometry, &mut out)
                .unwrap();
            s += out[0];
        }
        s
    });
}

/// 1000 compensated inverse transforms (closed form, error pre-correction, Newton).
#[divan::bench(args = MACHINES)]
fn inverse_actual_1000(bencher: Bencher, name: &str) {
    inverse_1000(bencher, name, Geometry::Actual);
}

/// 1000 nominal inverse transforms (closed form only).
#[divan::bench(args = MACHINES)]
fn inverse_nominal_1000(bencher: Bencher, name: &str) {
    inverse_1000(bencher, name, Geometry::Nominal);
}
