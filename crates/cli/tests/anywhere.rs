//! The commands that default to the example machine work from any directory, not only from a
//! checkout's root (`truepos eval` without arguments once failed outside the repository,
//! which is where an installed `truepos` runs).

mod support;

use support::{command, scratch};

#[test]
fn eval_and_run_find_their_examples_from_another_directory() {
    let elsewhere = scratch("anywhere");
    for args in [
        vec!["eval", "--json"],
        vec!["run", "--fast", "--duration-s", "1", "--json"],
    ] {
        let out = command()
            .current_dir(&elsewhere)
            .args(&args)
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{args:?}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
    let _ = std::fs::remove_dir_all(&elsewhere);
}
