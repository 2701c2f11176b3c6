#!/usr/bin/env bash
# The whole test suite. The README names this script; .ci/run calls it.
set -euo pipefail
cd "$(dirname "$0")/.."
# Unit, integration and doc tests of every crate.
cargo test --workspace
