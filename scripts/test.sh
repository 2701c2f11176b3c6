#!/usr/bin/env bash
# The whole test suite, as the README gives it and as .ci/run calls it. It installs what the
# tests need (idempotent, from Debian and PyPI), then runs every test for real: nothing skips
# because something is missing — a missing piece fails the run.
set -euo pipefail
cd "$(dirname "$0")/.."

echo "== what the tests need"
bash scripts/install_system_deps.sh   # SQLite headers (Debian)
bash scripts/setup_python.sh          # .venv with pymodbus, for the Modbus source tests
bash scripts/install_linuxcnc.sh      # LinuxCNC 2.9 (Debian), for the HAL component

echo "== unit, integration and doc tests of every crate"
cargo test --workspace

echo "== network-source fuzzing, 1.1 million inputs (release)"
cargo test --release -p truepos-runtime --test fuzz_network

echo "== kinematics side by side with Orocos KDL"
bash scripts/kdl_check.sh

echo "== LinuxCNC end to end (real control, headless simulated machine)"
bash scripts/linuxcnc_e2e.sh

echo "== FL_THERMAL benchmark (real measured run; prints its figures)"
bash scripts/fl_thermal_bench.sh
echo "== FL_THERMAL benchmark, rolling-origin selection (docs/fitting.md: why it is not the default)"
bash scripts/fl_thermal_bench.sh --inner-cv rolling
