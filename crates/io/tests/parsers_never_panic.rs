//! Property tests: whatever bytes arrive, the machine, model and run parsers return a value or
//! an error; they never panic. Inputs are random text and random one-character mutations of the
//! shipped examples (which reach much deeper into the parsers than random text does).

use std::path::Path;

use proptest::prelude::*;
use truepos_io::cycles;
use truepos_io::machine_file;
use truepos_io::model_file::{filtered, position};

mod support;
use support::machine_of;

const MACHINE: &str = include_str!("../../../examples/cross-slide/machine.toml");
const MODEL: &str = include_str!("../../../examples/cross-slide/model.toml");
/// A dynamic model for the cross-slide example's machine (its name, a sensor and an axis are
/// filled in by `dynamic()`).
const DYNAMIC: &str = r#"{
  "format": "truepos-dynamic-model",
  "version": 1,
  "machine": "MACHINE",
  "inputs": [{"name": "SENSOR", "kind": "temperature"}],
  "temperature_rise": true,
  "temperature_taus_s": [900.0, 3600.0],
  "rate_taus_s": [1800.0],
  "operating_taus_s": [],
  "operating_square": false,
  "rise_while_running": false,
  "features": ["rise", "lp900", "lp3600", "rate1800"],
  "outputs": [{"name": "out", "axis": "AXIS", "intercept_um": 0.5, "coefficients": [1.0, 2.0, 3.0, 4.0]}],
  "axis_index": [101],
  "provenance": {"runs": ["a.csv"]},
  "validation": {"rms_um": 1.5}
}"#;
const RUN: &str = include_str!("../../../examples/cross-slide/run.csv");

fn mutate(text: &str, at: usize, with: char, delete: bool) -> String {
    let mut chars: Vec<char> = text.chars().collect();
    let i = at % chars.len();
    if delete {
        chars.remove(i);
    } else {
        chars[i] = with;
    }
    chars.into_iter().collect()
}

fn machine() -> truepos_model::Machine {
    machine_of(MACHINE)
}

fn dynamic(m: &truepos_model::Machine) -> String {
    DYNAMIC
        .replace("MACHINE", &m.name)
        .replace("SENSOR", &m.temperatures[0].id)
        .replace("AXIS", &m.axes[0].name)
}

#[test]
fn the_dynamic_fixture_is_valid() {
    let m = machine();
    filtered::parse(Path::new("d.json"), &dynamic(&m), &m).unwrap();
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(1000))]

    #[test]
    fn machine_parser_never_panics(at in 0..10_000usize, with in any::<char>(), delete in any::<bool>()) {
        let _ = machine_file::parse(Path::new("m.toml"), &mutate(MACHINE, at, with, delete));
    }

    #[test]
    fn model_parser_never_panics(at in 0..10_000usize, with in any::<char>(), delete in any::<bool>()) {
        let m = machine();
        let text = mutate(MODEL, at, with, delete);
        let _ = position::parse(Path::new("k.toml"), &text, &m);
    }

    #[test]
    fn dynamic_model_parser_never_panics_and_names_the_file(at in 0..10_000usize, with in any::<char>(), delete in any::<bool>()) {
        let m = machine();
        let text = mutate(&dynamic(&m), at, with, delete);
        if let Err(e) = filtered::parse(Path::new("d.json"), &text, &m) {
            let e = e.to_string();
            prop_assert!(e.starts_with("d.json:"), "{}", e);
            // Every error of a file that could be read has a line and column.
            let mut parts = e.splitn(4, ':');
            parts.next();
            prop_assert!(parts.next().is_some_and(|l| l.parse::<usize>().is_ok()), "{}", e);
            prop_assert!(parts.next().is_some_and(|c| c.parse::<usize>().is_ok()), "{}", e);
        }
    }

    #[test]
    fn run_reader_never_panics(at in 0..10_000usize, with in any::<char>(), delete in any::<bool>()) {
        let m = machine();
        let text = mutate(RUN, at, with, delete);
        let _ = cycles::read(Path::new("run.csv"), text.as_bytes(), &m, &[0, 1, 6, 7]);
    }

    #[test]
    fn random_text_never_panics(text in "\\PC{0,300}") {
        let m = machine();
        let _ = machine_file::parse(Path::new("m.toml"), &text);
        let _ = position::parse(Path::new("k.toml"), &text, &m);
        let _ = position::parse_json(Path::new("k.json"), &text, &m);
        let _ = filtered::parse(Path::new("d.json"), &text, &m);
        let _ = cycles::read(Path::new("run.csv"), text.as_bytes(), &m, &[]);
    }
}

/// A run table in any of the shapes users have, from arbitrary text: every reader of it returns
/// a value or an error.
fn read_every_way(text: &str, delimiter: truepos_io::table::Delimiter) {
    use truepos_io::run::{self, Shape, Time};
    use truepos_io::table::{self, CsvOptions};
    use truepos_io::units::Role;
    let file = Path::new("run.csv");
    let options = CsvOptions {
        delimiter,
        ..Default::default()
    };
    let Ok(t) = table::parse_csv(file, text.as_bytes(), options) else {
        return;
    };
    let Ok(r) = run::parse_csv(file, text) else {
        return;
    };
    for c in 0..r.columns.len() {
        let _ = r.measured(c);
        let _ = r.numbers_as(c, Role::Temperature);
        let _ = r.time(c);
        let mut formatted = r.clone();
        formatted.time_format = Some("%d/%m/%Y %I:%M %p".into());
        let _ = formatted.time(c);
        if let Ok(runs) = r.clone().split_runs(&r.columns[c]) {
            for run in runs {
                let _ = run.times(&Time::Period(0.5));
                let _ = run.measured(c);
            }
        }
    }
    let m = machine();
    let cycle_options = cycles::Options {
        positions: cycles::Positions::Optional,
        shape: Shape {
            delimiter,
            run_column: None,
            time_format: None,
        },
        time: Some(Time::Period(1.0)),
    };
    let _ = cycles::from_table(&t, &m, &[], &cycle_options);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(1000))]

    /// Arbitrary text of cells, separators, quotes, decimal commas and date-times.
    #[test]
    fn shaped_runs_never_panic(
        text in "[a-z_0-9,;\t\"\n :.TZ+()°µ-]{0,200}",
        d in 0..4usize,
    ) {
        use truepos_io::table::Delimiter;
        let delimiter = [Delimiter::Auto, Delimiter::Comma, Delimiter::Semicolon, Delimiter::Tab][d];
        read_every_way(&text, delimiter);
    }

    /// Mutations of the shipped run rewritten with `;`, decimal commas and ISO times.
    #[test]
    fn semicolon_runs_never_panic(at in 0..10_000usize, with in any::<char>(), delete in any::<bool>()) {
        let semi: String = RUN
            .lines()
            .enumerate()
            .map(|(i, l)| {
                let l = l.replace(',', ";").replace('.', ",");
                if i == 0 { l } else { format!("2024-03-01T08:{:02}:00{}", i % 60, &l[l.find(';').unwrap_or(0)..]) }
            })
            .collect::<Vec<_>>()
            .join("\n");
        read_every_way(&mutate(&semi, at, with, delete), truepos_io::table::Delimiter::Auto);
    }
}
