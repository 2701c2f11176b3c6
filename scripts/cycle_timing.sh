#!/usr/bin/env bash
# The runtime's timing benchmark: the service at 1 kHz for DURATION_S seconds (default 600 =
# 10 minutes) on the example machine, replaying the example run, logging to SQLite; prints the
# JSON summary with the cycle-time percentiles, the histogram of how late each cycle finished
# after its deadline, the overruns and the CPU share of one core.
#
#   bash scripts/cycle_timing.sh            # 10 minutes
#   DURATION_S=60 bash scripts/cycle_timing.sh
#
# Like a control's servo thread, the service runs under SCHED_FIFO (chrt) when it may; without
# it the figures show what the Linux scheduler gives a normal process.
set -euo pipefail
cd "$(dirname "$0")/.."
duration=${DURATION_S:-600}
cargo build --release -q -p truepos
log=$(mktemp -d)/timing.sqlite
cmd=(./target/release/truepos run --period-ms 1 --duration-s "$duration" --log "$log" --json)
if command -v chrt >/dev/null && chrt -f 50 true 2>/dev/null; then
  echo "running under SCHED_FIFO 50 for ${duration} s" >&2
  chrt -f 50 "${cmd[@]}"
else
  echo "running at normal priority for ${duration} s (chrt not permitted)" >&2
  "${cmd[@]}"
fi
rm -rf "$(dirname "$log")"
