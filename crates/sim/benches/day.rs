//! 24 simulated hours at 1 s steps on the reference machine (84 thermal nodes): the whole run,
//! from building the integrator to the recorded rows (sampled every 10 s, ground-truth error
//! evaluated at each row).

use truepos_sim::{Scenario, Twin};

fn main() {
    divan::main();
}

/// The `environment` scenario: 24 h, 86 400 steps, sampled every 30 s.
#[divan::bench(sample_count = 10)]
fn day_environment_24h(bencher: divan::Bencher) {
    let twin = Twin::reference();
    let sc = Scenario::builtin("environment").expect("built-in");
    bencher.bench(|| twin.run(divan::black_box(&sc), 1).expect("runs"));
}

/// Days A and B back to back with their busy schedules stretched to 24 h: 86 400 steps at 1 s,
/// axes moving, probing, sampled every 10 s.
#[divan::bench(sample_count = 10)]
fn day_mixed_24h(bencher: divan::Bencher) {
    let twin = Twin::reference();
    let mut sc = Scenario::builtin("mixed-shift").expect("built-in");
    let b = Scenario::builtin("mixed-shift-b").expect("built-in");
    sc.phases.extend(b.phases);
    let total: f64 = sc.duration_s();
    let last = sc.phases.len() - 1;
    sc.phases[last].duration_s += 86_400.0 - total;
    assert_eq!(sc.duration_s(), 86_400.0);
    bencher.bench(|| twin.run(divan::black_box(&sc), 1).expect("runs"));
}

/// One integrator step alone (84 nodes).
#[divan::bench]
fn network_step(bencher: divan::Bencher) {
    let twin = Twin::reference();
    let mut st = twin.stepper(1.0);
    let mut temps = vec![20.0; twin.node_count()];
    let powers = [(0usize, 10.0), (70, 100.0)];
    bencher.bench_local(|| st.step(divan::black_box(&mut temps), &powers, 20.0));
}
