//! What the io tests share: repository paths and machines from the examples or from text.
#![allow(dead_code)] // each test file uses a part

use std::path::{Path, PathBuf};

use truepos_io::machine_file;
use truepos_model::Machine;

/// A path in the repository.
pub fn repo(path: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../..")
        .join(path)
}

/// The example machine `examples/vmc3`.
pub fn vmc() -> Machine {
    machine_file::load(&repo("examples/vmc3/machine.toml"))
        .unwrap()
        .machine
}

/// The machine of a machine file's text, which the test knows to be valid.
pub fn machine_of(text: &str) -> Machine {
    machine_file::parse(Path::new("m.toml"), text)
        .unwrap()
        .machine
}
