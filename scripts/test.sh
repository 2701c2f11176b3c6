#!/usr/bin/env bash
# The whole test suite, as the README gives it and as .ci/run calls it. It installs what the
# tests need (idempotent, from Debian and PyPI), then runs every test for real: nothing skips
# because something is missing — a missing piece fails the run.
set -euo pipefail
cd "$(dirname "$0")/.."

echo "== what the tests need"
bash scripts/install_system_deps.sh   # SQLite headers, the Mosquitto MQTT broker (Debian)
bash scripts/setup_python.sh          # .venv with pymodbus, asyncua and pysparkplug, for the Modbus, OPC UA and MQTT tests
bash scripts/install_linuxcnc.sh      # LinuxCNC 2.9 (Debian), for the HAL component
bash scripts/install_chromium.sh      # Chromium (Debian), to render the HTML reports in a real browser
bash scripts/install_prometheus.sh    # promtool (Debian `prometheus`), to check the live view's /metrics

echo "== unit, integration and doc tests of every crate"
# Among them the fleet's, against Mosquitto and PostgreSQL 15 started on loopback by the tests:
# crates/cli/tests/fleet_mqtt.rs (telemetry, store), fleet_models.rs (models, fleet status) and
# fleet_follow.rs (a service's models shadowed, activated and rolled back by fleet follow),
# fleet_refit.rs (probe events into the store, a model refitted from it, signed, registered).
cargo test --workspace

echo "== fault campaign: 10 000 random fault schedules, the output invariant checked every cycle (release)"
PROPTEST_CASES=10000 cargo test --release -p truepos-runtime --test fault_campaign

echo "== network-source fuzzing, 1.1 million inputs (release)"
cargo test --release -p truepos-protocols --test fuzz_network

echo "== kinematics side by side with Orocos KDL"
bash scripts/kdl_check.sh

# The host can hold the component or LinuxCNC's servo thread for seconds (this VM's hypervisor
# steals time, the kernel has no PREEMPT_RT: one run saw a 7 s stall). A run that failed during
# such a stall (the component's longest cycle interval > 100 ms, in its stats.json) says nothing
# about truepos and runs again, at most three times in all; a failure without one fails at once.
#   with_stall_retry NAME OUT_DIR SCRIPT
with_stall_retry() {
  local name="$1" out="$2" script="$3" attempt stall_ms
  for attempt in 1 2 3; do
    if bash "$script"; then return 0; fi
    stall_ms=$(/usr/bin/python3 -c "import json; print(json.load(open('$out/stats.json'))['max_interval_ms'])" 2>/dev/null || echo 0)
    if ! /usr/bin/python3 -c "import sys; sys.exit(0 if float('$stall_ms') > 100 else 1)"; then
      break
    fi
    echo "$name: attempt $attempt failed during a host stall of $stall_ms ms; running it again"
  done
  echo "$name: FAIL"
  exit 1
}

echo "== LinuxCNC end to end (real control, headless simulated machine)"
with_stall_retry linuxcnc_e2e target/linuxcnc-e2e scripts/linuxcnc_e2e.sh

echo "== LinuxCNC probe loop: G38.2 on a drifted twin, re-identification, a hot switch mid-program"
with_stall_retry linuxcnc_probe_loop target/linuxcnc-probe scripts/linuxcnc_probe_loop.sh

echo "== LinuxCNC COMP_FILE types 0 and 1: truepos-written tables loaded into LinuxCNC itself"
bash scripts/linuxcnc_comp.sh

echo "== FL_THERMAL benchmark (real measured run; prints its figures)"
bash scripts/fl_thermal_bench.sh
echo "== FL_THERMAL benchmark, rolling-origin selection (docs/fitting.md: why it is not the default)"
bash scripts/fl_thermal_bench.sh --inner-cv rolling
echo "== live view benchmark: first paint of 24 h of history in Chromium, the view's CPU with a page"
echo "   streaming at 1 kHz (figures printed; a figure of the host, no bar asserted: docs/benchmarks.md)"
D=15 STREAMS="0 1" bash scripts/live_view_bench.sh
echo "== fleet benchmark, short: 50 simulated machines at 1 Hz for 10 s into Mosquitto, fleet ingest"
echo "   and PostgreSQL 15 (every message stored, none failed, p99 < 2 s; the full run: docs/benchmarks.md)"
FLEET_BENCH_CHECK=1 bash scripts/fleet_bench.sh 50 10
echo "== a fleet on a laptop: broker, PostgreSQL, fleet ingest and three machines for 15 s; fleet"
echo "   status must show the three online (docs/fleet.md)"
DURATION=15 CHECK=1 bash scripts/fleet_laptop.sh
echo "== twin population: issue 14's development benchmark at the ci size, its bars asserted"
echo "   (median reduction >= 85 %, no run made worse, median inner/test within 1.5; the full size"
echo "   meets them too: docs/fitting.md)"
bash scripts/fit_population.sh --size ci --assert
echo "== development gate: the defaults against the simple baseline, paired per run with a bootstrap interval,"
echo "   on a twin population drawn from this commit's own seed range (docs/fitting.md, 'The development gate')"
draw=$(( 0x$(git rev-parse --short=7 HEAD 2>/dev/null || echo 1) % 9999 + 1 ))
bash scripts/fit_gate.sh --size ci --draw "$draw"
