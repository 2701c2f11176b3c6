//! Property tests: whatever bytes arrive, the machine, model and run parsers return a value or
//! an error; they never panic. Inputs are random text and random one-character mutations of the
//! shipped examples (which reach much deeper into the parsers than random text does).

use std::path::Path;

use proptest::prelude::*;
use truepos_io::{cycles, machine_file, model_file};

const MACHINE: &str = include_str!("../../../examples/cross-slide/machine.toml");
const MODEL: &str = include_str!("../../../examples/cross-slide/model.toml");
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
    machine_file::parse(Path::new("m.toml"), MACHINE)
        .unwrap()
        .machine
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
        let _ = model_file::parse(Path::new("k.toml"), &text, &m);
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
        let _ = model_file::parse(Path::new("k.toml"), &text, &m);
        let _ = model_file::parse_json(Path::new("k.json"), &text, &m);
        let _ = cycles::read(Path::new("run.csv"), text.as_bytes(), &m, &[]);
    }
}
