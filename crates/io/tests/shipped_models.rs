//! Every model file the repository ships — the examples and the LinuxCNC tests' models, of
//! either form — loads through the one door for the machine it names, and steps to finite
//! errors at mid-travel; a position model written again in this build's version reads back to
//! the same errors. A moved or renamed loader that stopped reading one of
//! them fails here, whichever file it is.

mod support;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use support::repo;
use truepos_io::{machine_file, model_file};
use truepos_model::config::MachineConfig;
use truepos_model::CycleInput;

/// Files below `dir` (recursively) whose name ends in one of `ends`.
fn files(dir: &Path, ends: &[&str], out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            files(&path, ends, out);
        } else if ends.iter().any(|e| path.to_string_lossy().ends_with(e)) {
            out.push(path);
        }
    }
}

/// The machine files of the examples, by the machine's name.
fn machines() -> BTreeMap<String, MachineConfig> {
    let mut found = Vec::new();
    files(&repo("examples"), &["machine.toml"], &mut found);
    found
        .iter()
        .filter_map(|p| machine_file::load(p).ok())
        .map(|m| (m.machine.name.clone(), m))
        .collect()
}

/// The machine a model file names (`machine = "…"` or `"machine": "…"`).
fn named_machine(text: &str) -> Option<String> {
    text.lines().find_map(|line| {
        let line = line.trim().trim_end_matches(',');
        let rest = line
            .strip_prefix("machine =")
            .or_else(|| line.strip_prefix("\"machine\":"))?;
        Some(rest.trim().trim_matches('"').to_string())
    })
}

#[test]
fn every_shipped_model_loads_through_the_one_door() {
    let machines = machines();
    let mut candidates = Vec::new();
    for dir in ["examples", "tests"] {
        files(&repo(dir), &[".toml", ".json"], &mut candidates);
    }
    let mut loaded = Vec::new();
    for path in candidates {
        let text = std::fs::read_to_string(&path).unwrap();
        if !text.contains("\"truepos-model\"") && !text.contains("\"truepos-dynamic-model\"") {
            continue; // a machine, scenario or configuration file
        }
        let name = named_machine(&text).unwrap_or_else(|| panic!("{}: no machine", path.display()));
        let machine = machines
            .get(&name)
            .unwrap_or_else(|| panic!("{}: machine {name} is no example", path.display()));
        let entry = model_file::load_entry(&path, machine)
            .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        let mut model = model_file::load(&path, &machine.machine)
            .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
            .model;
        let m = &machine.machine;
        let temperatures = vec![22.0; m.temperatures.len()];
        let positions: Vec<f64> = m
            .axes
            .iter()
            .map(|a| (a.travel_min + a.travel_max) / 2.0)
            .collect();
        let operating = vec![0.0; m.operating.len()];
        let input = CycleInput {
            temperatures_c: &temperatures,
            positions: &positions,
            operating: &operating,
        };
        let error = model
            .step(1.0, &input)
            .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        assert!(error.iter().all(|e| e.is_finite()), "{}", path.display());
        // A position model written again in this build's version reads back to the same errors.
        if let Some(position) = model.as_static() {
            let text = model_file::position::ModelFile::from_model(position, m).to_toml();
            assert!(text.contains(&format!("version = {}", model_file::VERSION)));
            let mut again = model_file::parse(Path::new("again.toml"), &text, m)
                .unwrap_or_else(|e| panic!("{} written again: {e}", path.display()))
                .model;
            let error_again = again.step(1.0, &input).unwrap();
            assert_eq!(error, error_again, "{}", path.display());
        }
        loaded.push((path, entry.model.axis_count()));
    }
    // The examples' two position models and the LinuxCNC test's three (two position, one
    // filtered): a walk that found fewer would check nothing.
    assert!(loaded.len() >= 5, "{loaded:?}");
    assert!(
        loaded
            .iter()
            .any(|(p, _)| p.extension().is_some_and(|e| e == "json")),
        "no filtered model among {loaded:?}"
    );
}
