#!/usr/bin/env bash
# Issue 13's scale benchmark: a month of logs at 1 s is 2.6 million rows. This fits ROWS rows
# (default 1 000 000) × 17 inputs (16 temperatures, spindle speed) × 5 targets with the default
# automatic selection and prints wall time and peak memory (target: ≤ 10 s, ≤ 500 MB at 1 M rows).
# The run is synthetic (first-order responses to random heat inputs, seeded), written under
# target/fit-scale/; extra arguments go to `truepos fit`.
set -euo pipefail
cd "$(dirname "$0")/.."
ROWS="${ROWS:-1000000}"
OUT=target/fit-scale
mkdir -p "$OUT"
cargo build --quiet --release -p truepos >&2
CSV="$OUT/run-$ROWS.csv"
if [ ! -f "$CSV" ]; then
  /usr/bin/python3 - "$ROWS" "$CSV" <<'PY'
import math, random, sys
rows, path = int(sys.argv[1]), sys.argv[2]
rng = random.Random(13)
temps = [20.0] * 16
taus = [600 + 400 * k for k in range(16)]
ch = [0.0] * 5
power = 0.0
with open(path, "w") as f:
    f.write("time_s," + ",".join(f"t{k + 1}_c" for k in range(16)) + ",spindle_rpm,"
            + ",".join(f"ch{k + 1}_um" for k in range(5)) + "\n")
    for i in range(rows):
        if i % 1800 == 0:
            power = rng.choice([0.0, 0.3, 0.6, 1.0])
        for k in range(16):
            target = 20.0 + 8.0 * power * (1.0 - k / 20.0)
            temps[k] += (target - temps[k]) / taus[k] + rng.gauss(0, 0.01)
        for k in range(5):
            ch[k] = 2.0 * (temps[k] - 20.0) - 1.0 * (temps[k + 8] - 20.0) + rng.gauss(0, 0.3)
        f.write(f"{i}," + ",".join(f"{t:.2f}" for t in temps) + f",{8000 * power:.0f},"
                + ",".join(f"{c:.2f}" for c in ch) + "\n")
PY
fi
/usr/bin/time -f "wall_s=%e peak_rss_mb=%M" -o "$OUT/time.txt" \
  target/release/truepos fit --run "$CSV" --target 'ch*_um' --inputs 't*_c,spindle_rpm' --json "$@" \
  > "$OUT/fit.json"
awk -F'[= ]' '{printf "rows=%s wall_s=%s peak_rss_mb=%.0f\n", '"$ROWS"', $2, $4/1024}' "$OUT/time.txt"
