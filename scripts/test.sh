#!/usr/bin/env bash
# The whole test suite. The README names this script; .ci/run calls it.
set -euo pipefail
cd "$(dirname "$0")/.."
cargo test --workspace --all-targets
cargo test --workspace --doc
