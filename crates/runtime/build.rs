//! The log links the system's SQLite (see Cargo.toml). Without its development files the build
//! would end in a linker error many lines long; say in one line what to install instead.

use std::path::Path;
use std::process::Command;

fn main() {
    println!("cargo:rerun-if-env-changed=SQLITE3_LIB_DIR");
    if sqlite_is_linkable() {
        return;
    }
    eprintln!(
        "truepos-runtime needs the SQLite library to link against: run `bash scripts/install_system_deps.sh` (Debian: libsqlite3-dev), or set SQLITE3_LIB_DIR"
    );
    std::process::exit(1);
}

/// Whether the linker will find `-lsqlite3`: pkg-config knows it, `SQLITE3_LIB_DIR` names a
/// directory, or a usual library directory holds it.
fn sqlite_is_linkable() -> bool {
    if std::env::var_os("SQLITE3_LIB_DIR").is_some() {
        return true;
    }
    let pkg_config = Command::new("pkg-config")
        .args(["--exists", "sqlite3"])
        .status();
    if pkg_config.is_ok_and(|s| s.success()) {
        return true;
    }
    let dirs = [
        "/usr/lib",
        "/usr/lib64",
        "/usr/local/lib",
        "/usr/lib/x86_64-linux-gnu",
        "/usr/lib/aarch64-linux-gnu",
        "/usr/lib/arm-linux-gnueabihf",
        "/opt/homebrew/opt/sqlite/lib",
        "/usr/local/opt/sqlite/lib",
    ];
    let names = ["libsqlite3.so", "libsqlite3.a", "libsqlite3.dylib"];
    dirs.iter()
        .any(|d| names.iter().any(|n| Path::new(d).join(n).exists()))
}
