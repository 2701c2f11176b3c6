//! The example files that commands default to (`examples/vmc3/…`), found from any directory: a
//! relative path under `examples/` that does not exist from the working directory is looked up
//! in the repository this binary was built from (`cargo install --path crates/cli` keeps that
//! path), so `truepos eval` without arguments works outside a checkout too. A path that exists
//! as given, or one found nowhere, is left as it is (a missing file's error then names it).

use std::path::{Path, PathBuf};

/// `path`, or the same example in the repository the binary was built from.
pub fn find(path: PathBuf) -> PathBuf {
    if path.is_absolute() || path.exists() || !path.starts_with("examples") {
        return path;
    }
    let built = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../..")
        .join(&path);
    if built.exists() {
        built
    } else {
        path
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_example_is_found_from_another_directory_and_other_paths_stay() {
        let here = std::env::current_dir().unwrap();
        // Tests run in crates/cli, where `examples/` does not exist.
        assert!(!here.join("examples/vmc3/model.toml").exists());
        let found = find(PathBuf::from("examples/vmc3/model.toml"));
        assert!(found.is_file(), "{}", found.display());
        for stays in ["examples/none.toml", "model.toml", "/abs/examples/x"] {
            assert_eq!(find(PathBuf::from(stays)), PathBuf::from(stays));
        }
    }
}
