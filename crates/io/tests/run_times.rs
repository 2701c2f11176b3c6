//! The time column of a run CSV: every row's time is finite and strictly increasing, the first
//! and the last row included; anything else is an error naming file:line:column and the
//! expectation (issue 11: a NaN or −∞ first time or an ∞ last time used to pass).

use std::path::Path;

use proptest::prelude::*;
use truepos_io::cycles;

mod support;
use support::machine_of;

const MACHINE: &str = include_str!("../../../examples/cross-slide/machine.toml");
const ROW: &str = "150,750,23,20,21,22,21,22,26,20,2000";
const HEADER: &str = "time_s,X_mm,Z_mm,bed_top,bed_bottom,carriage_top,carriage_bottom,x_slide_top,x_slide_bottom,spindle_bearing,ambient,spindle_rpm";

fn csv(times: &[String]) -> String {
    let mut s = format!("{HEADER}\n");
    for t in times {
        s.push_str(&format!("{t},{ROW}\n"));
    }
    s
}

fn load(times: &[&str]) -> Result<cycles::Cycles, String> {
    let m = machine_of(MACHINE);
    let times: Vec<String> = times.iter().map(|t| t.to_string()).collect();
    cycles::read(Path::new("run.csv"), csv(&times).as_bytes(), &m, &[]).map_err(|e| e.to_string())
}

#[test]
fn a_nan_first_time_is_refused_at_its_place() {
    let e = load(&["NaN", "60", "120"]).unwrap_err();
    assert_eq!(
        e,
        "run.csv:2:1: `time_s`: expected a finite time in s, got NaN"
    );
}

#[test]
fn a_minus_infinite_first_time_is_refused() {
    let e = load(&["-inf", "60", "120"]).unwrap_err();
    assert!(
        e.starts_with("run.csv:2:1: `time_s`: expected a finite time"),
        "{e}"
    );
}

#[test]
fn an_infinite_last_time_is_refused() {
    let e = load(&["0", "60", "inf"]).unwrap_err();
    assert!(
        e.starts_with("run.csv:4:1: `time_s`: expected a finite time"),
        "{e}"
    );
}

#[test]
fn a_repeated_time_is_refused() {
    let e = load(&["0", "60", "60"]).unwrap_err();
    assert!(
        e.starts_with("run.csv:4:1: `time_s`: expected time to increase"),
        "{e}"
    );
}

fn time_text() -> impl Strategy<Value = String> {
    prop_oneof![
        6 => (-1e6f64..1e6).prop_map(|v| v.to_string()),
        1 => Just("NaN".to_string()),
        1 => Just("inf".to_string()),
        1 => Just("-inf".to_string()),
        1 => Just("1e400".to_string()),
        1 => Just("0".to_string()),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(500))]

    /// A run is accepted exactly when every time is finite and larger than the one before; then
    /// the times are those of the file; else the error names the first bad row's line.
    #[test]
    fn times_are_accepted_iff_finite_and_strictly_increasing(times in prop::collection::vec(time_text(), 1..8)) {
        let values: Vec<f64> = times.iter().map(|t| t.parse().unwrap()).collect();
        let bad = (0..values.len()).find(|&i| {
            !values[i].is_finite() || (i > 0 && values[i] <= values[i - 1])
        });
        let refs: Vec<&str> = times.iter().map(String::as_str).collect();
        match (load(&refs), bad) {
            (Ok(run), None) => prop_assert_eq!(run.run.time_s, values),
            (Err(e), Some(i)) => {
                let place = format!("run.csv:{}:1: `time_s`: expected", i + 2);
                prop_assert!(e.starts_with(&place), "{} (bad row {})", e, i);
            }
            (Ok(_), Some(i)) => prop_assert!(false, "row {} accepted: {:?}", i, times),
            (Err(e), None) => prop_assert!(false, "refused: {} for {:?}", e, times),
        }
    }
}
