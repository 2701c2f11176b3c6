//! The model file: one format, `truepos-model`, the contract between learning and compensating.
//!
//! Every model file carries `format = "truepos-model"`, a `version` ([`VERSION`], 2, is what
//! this build writes) and its `form`:
//!
//! - `form = "position"` ([`position`], TOML or JSON by extension): a function of this cycle's
//!   values — axis positions and temperature differences;
//! - `form = "filtered"` ([`filtered`], JSON): a model whose filters carry history.
//!
//! Versions that still load: version 1 without `form` — a TOML (or `.json`) file is the position
//! form — and version 1's `"format": "truepos-dynamic-model"` JSON, the filtered form. Both forms
//! may carry the training envelope ([`envelope`]); a file may be signed ([`signature`]).
//!
//! This module is the one loader of a model file, whatever its form: it reads the file once,
//! recognises the form and returns it bound to the machine as the core's [`CompensationModel`],
//! with the axis-combination index the file gives. Every user — `truepos run`, `eval`, `report`,
//! the LinuxCNC component and its check — loads models here.
//!
//! ```
//! use std::path::Path;
//! let machine = r#"
//! [machine]
//! name = "m"
//! [[axis]]
//! name = "Z"
//! kind = "linear"
//! travel = [0.0, 100.0]
//! "#;
//! let machine = truepos_io::machine_file::parse(Path::new("m.toml"), machine)?.machine;
//! let model = r#"
//! format = "truepos-model"
//! version = 2
//! form = "position"
//! name = "s"
//! machine = "m"
//! [inputs]
//! axes = [{ name = "Z", travel = [0.0, 100.0] }]
//! "#;
//! let loaded = truepos_io::model_file::parse(Path::new("s.toml"), model, &machine)?;
//! assert_eq!(loaded.model.name(), "s");
//! assert!(!loaded.model.keeps_state());
//! # Ok::<(), truepos_files::InputError>(())
//! ```

use std::path::{Path, PathBuf};

use truepos_model::config::MachineConfig;
use truepos_model::config::{index_of, ModelEntry};
use truepos_model::{CompensationModel, Machine};

use crate::error::read_text;
use signature::TrustedKeys;
use truepos_files::InputError;

pub mod envelope;
pub mod filtered;
pub mod position;
pub mod signature;

/// The `format` every model file carries, of either form.
pub const FORMAT: &str = "truepos-model";
/// The version this build writes: version 2 says its `form`. Version 1 (no `form`: a
/// position model, or a filtered one under `"format": "truepos-dynamic-model"`) is read as well.
pub const VERSION: u32 = 2;
/// The `form` of a model that is a function of this cycle's values ([`position`]).
pub const FORM_POSITION: &str = "position";
/// The `form` of a model whose filters carry history ([`filtered`]: JSON).
pub const FORM_FILTERED: &str = "filtered";

/// A model file bound to a machine.
#[derive(Debug, Clone)]
pub struct Loaded {
    /// The model.
    pub model: CompensationModel,
    /// The axis-combination index from the file, if it has one.
    pub axis_index: Option<Vec<u32>>,
}

/// Reads a model file of either form and binds it to the machine. A file that cannot be read is
/// an error naming it; every other error names file, line, column and key.
pub fn load(path: &Path, machine: &Machine) -> Result<Loaded, InputError> {
    parse(path, &read_text(path, truepos_files::MODEL)?, machine)
}

/// Loads the model files of a set for the service, in order of preference, bound to the
/// machine. A model whose file carries no axis-combination index serves path 1's axes (the
/// index of the axes whose `path` is 1, by their codes).
pub fn load_set(paths: &[PathBuf], machine: &MachineConfig) -> Result<Vec<ModelEntry>, InputError> {
    load_set_trusted(paths, machine, None)
}

/// [`load_set`] where, with a trust list, every file must carry a signature from one of its
/// keys ([`signature`]); the bytes verified are the bytes parsed.
pub fn load_set_trusted(
    paths: &[PathBuf],
    machine: &MachineConfig,
    trusted: Option<&TrustedKeys>,
) -> Result<Vec<ModelEntry>, InputError> {
    paths
        .iter()
        .map(|path| load_entry_trusted(path, machine, trusted))
        .collect()
}

/// One model file as an entry of the set ([`load_set`] of one file): what a hot reload reads.
pub fn load_entry(path: &Path, machine: &MachineConfig) -> Result<ModelEntry, InputError> {
    load_entry_trusted(path, machine, None)
}

/// [`load_entry`], signed by a trusted key when a trust list is given.
pub fn load_entry_trusted(
    path: &Path,
    machine: &MachineConfig,
    trusted: Option<&TrustedKeys>,
) -> Result<ModelEntry, InputError> {
    entry_of_text(
        path,
        &read_text(path, truepos_files::MODEL)?,
        machine,
        trusted,
    )
}

/// [`load_entry_trusted`] on a file's text already read: what a caller that keeps the bytes
/// (the fleet store registers exactly the bytes it verified and parsed) loads through.
pub fn entry_of_text(
    path: &Path,
    text: &str,
    machine: &MachineConfig,
    trusted: Option<&TrustedKeys>,
) -> Result<ModelEntry, InputError> {
    if let Some(keys) = trusted {
        keys.verify(path, text.as_bytes())?;
    }
    let loaded = parse(path, text, &machine.machine)?;
    let index = match &loaded.axis_index {
        Some(b) => index_of(b.iter().copied()),
        None => index_of(
            machine
                .axes
                .iter()
                .filter(|a| a.path == 1)
                .map(|a| a.code()),
        ),
    };
    Ok(ModelEntry {
        name: loaded.model.name().to_string(),
        index,
        model: loaded.model,
    })
}

/// [`load`] on a file's text; `path` names it in errors and, by its extension, tells JSON from
/// TOML for a position-dependent model.
pub fn parse(path: &Path, text: &str, machine: &Machine) -> Result<Loaded, InputError> {
    if is_dynamic(path, text) {
        let (bound, axis_index) = filtered::parse_entry(path, text, machine)?;
        return Ok(Loaded {
            model: bound.into(),
            axis_index,
        });
    }
    let loaded = position::parse_entry(path, text, machine)?;
    Ok(Loaded {
        model: loaded.model.into(),
        axis_index: loaded.axis_index,
    })
}

/// Whether the text is a dynamic model file: JSON whose `format` says so, or — so that a broken
/// one gets the dynamic parser's error, not the static one's — a `.json` file naming that format.
fn is_dynamic(path: &Path, text: &str) -> bool {
    let json = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("json"));
    filtered::is_dynamic(text)
        || (json
            && [filtered::LEGACY_FORMAT, filtered::FORM_FILTERED]
                .iter()
                .any(|f| text.contains(&format!("\"{f}\""))))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn machine() -> Machine {
        let text = "[machine]\nname = \"m\"\n[[axis]]\nname = \"Z\"\nkind = \"linear\"\ntravel = [0.0, 100.0]\n[[temperature]]\nid = \"t\"\nvalid_range = [0.0, 80.0]\n";
        crate::machine_file::parse(Path::new("m.toml"), text)
            .unwrap()
            .machine
    }

    const DYNAMIC: &str = r#"{
  "format": "truepos-dynamic-model", "version": 1, "machine": "m",
  "inputs": [{"name": "t", "kind": "temperature"}],
  "temperature_rise": true, "temperature_taus_s": [], "rate_taus_s": [],
  "operating_taus_s": [], "operating_square": false,
  "features": ["rise(t)"],
  "outputs": [{"name": "dz_um", "intercept_um": 0.5, "coefficients": [2.0]}],
  "axis_index": [101],
  "provenance": {}, "validation": {}
}"#;

    #[test]
    fn both_forms_come_through_one_door() {
        let m = machine();
        let d = parse(Path::new("d.json"), DYNAMIC, &m).unwrap();
        assert!(d.model.keeps_state());
        assert_eq!(d.model.name(), "d");
        assert_eq!(d.axis_index, Some(vec![101]));
        let s = parse(
            Path::new("s.toml"),
            "format = \"truepos-model\"\nversion = 1\nname = \"s\"\nmachine = \"m\"\naxis_index = [101]\n[inputs]\naxes = [{ name = \"Z\", travel = [0.0, 100.0] }]\n",
            &m,
        )
        .unwrap();
        assert!(!s.model.keeps_state());
        assert_eq!(s.model.name(), "s");
        assert_eq!(s.axis_index, Some(vec![101]));
    }

    #[test]
    fn errors_name_the_file() {
        let m = machine();
        let missing = load(Path::new("/nonexistent/x.toml"), &m).unwrap_err();
        assert!(
            missing
                .to_string()
                .starts_with("/nonexistent/x.toml: cannot read"),
            "{missing}"
        );
        // A broken dynamic file gets the dynamic parser's error, at line and column.
        let broken = DYNAMIC.replace("\"version\": 1,", "\"version\": 1");
        let e = parse(Path::new("d.json"), &broken, &m)
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("d.json:2:"), "{e}");
        let other = DYNAMIC.replace("\"machine\": \"m\"", "\"machine\": \"lathe\"");
        let e = parse(Path::new("d.json"), &other, &m)
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("d.json:2:") && e.contains("`machine`"), "{e}");
    }
}
