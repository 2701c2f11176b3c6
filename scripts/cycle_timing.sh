#!/usr/bin/env bash
# The runtime's timing benchmark: the service at 1 kHz for DURATION_S seconds (default 600 =
# 10 minutes) on the example machine, replaying the example run and logging to SQLite, paced the
# way the LinuxCNC component paces its cycle (`truepos-hal-check timing`: clock_nanosleep on absolute
# CLOCK_MONOTONIC deadlines, SCHED_FIFO 50, mlockall, bound to the last CPU, no timer slack).
# Beside it a thread samples the hypervisor's steal time (/proc/stat) and the CPU pressure
# (/proc/pressure/cpu) every 5 ms, so every cycle that finished more than 2 ms late is set
# beside what the host did then. Prints the JSON summary (also written to
# target/cycle-timing.json): cycle-time percentiles, wake-up latency, lateness histogram, late
# cycles in total / coinciding with steal / not explained by steal, steal share, CPU share.
#
#   bash scripts/cycle_timing.sh            # 10 minutes (the figure in the README)
#   DURATION_S=10 bash scripts/cycle_timing.sh
#
# Not part of scripts/test.sh or .ci/run (ten minutes, and a figure of the host as much as of
# truepos). Without root or CAP_SYS_NICE it runs at normal priority and says so.
set -euo pipefail
cd "$(dirname "$0")/.."
duration=${DURATION_S:-600}
cargo build --release -q -p truepos-hal-check
target=$(cargo metadata --format-version 1 --no-deps | python3 -c 'import json,sys; print(json.load(sys.stdin)["target_directory"])')
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
"$target/release/truepos-hal-check" timing --duration-s "$duration" --log "$dir/timing.sqlite" \
    | tee "$target/cycle-timing.json"
