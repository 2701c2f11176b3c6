#!/usr/bin/env bash
# FL_THERMAL in the shapes users have (docs/formats.md "Runs"): the real run rewritten as a
# `;`-separated file with decimal commas, ISO 8601 times and temperatures in °F, and as a sparse
# run whose errors were measured every 60th row (every 15 min) only. Prints the test RMSE of
# each fit beside the plain CSV's (scripts/fl_thermal_bench.sh). The files are written under
# target/, never into the repository.
set -euo pipefail
cd "$(dirname "$0")/.."
DATA="${FL_THERMAL:-../shared/data/fl_thermal/fl_thermal.csv}"
[ -f "$DATA" ] || { echo "FL_THERMAL data not found at $DATA (set FL_THERMAL=…)" >&2; exit 1; }
OUT="${CARGO_TARGET_DIR:-target}/fl-shapes"
mkdir -p "$OUT"
cargo build --quiet --release -p truepos >&2
BIN="${CARGO_TARGET_DIR:-target}/release/truepos"
python3 - "$DATA" "$OUT" <<'PY'
import csv, datetime, sys
src, out = sys.argv[1], sys.argv[2]
rows = list(csv.reader(open(src)))
h = rows[0]
targets = [i for i, c in enumerate(h) if c.endswith("_um")]
with open(f"{out}/sparse.csv", "w", newline="") as f:
    w = csv.writer(f)
    w.writerow(h)
    for k, r in enumerate(rows[1:]):
        w.writerow(r if k % 60 == 0 else ["" if i in targets else v for i, v in enumerate(r)])
temp = lambda c: c.startswith("t") and c.endswith("_c")
with open(f"{out}/semicolon.csv", "w") as f:
    f.write(";".join(["time"] + [c[:-2] + " (°F)" if temp(c) else c for c in h[1:]]) + "\n")
    t0 = datetime.datetime(2024, 3, 1, 8, 0, 0)
    for r in rows[1:]:
        cells = [(t0 + datetime.timedelta(seconds=float(r[0]))).isoformat(sep=" ")]
        for c, v in zip(h[1:], r[1:]):
            cells.append((repr(float(v) * 1.8 + 32) if temp(c) else v).replace(".", ","))
        f.write(";".join(cells) + "\n")
PY
fit() { "$BIN" fit --target 'ch*_um' --split chrono:0.6 --machine-name fl-thermal --json "$@"; }
show() {
  python3 -c '
import json, sys
r = json.load(sys.stdin)
m = r["validation"]["metrics"]
print(sys.argv[1] + ": test RMSE " + " / ".join("%.2f" % x["rmse_um"] for x in m)
      + " µm on %d measured test rows per channel" % m[0]["samples"]
      + "; rows measured: " + ", ".join("%d of %d" % (x["measured"], x["samples"]) for x in r["runs"]))
' "$1"
}
fit --run "$DATA" --inputs 't*_c,spindle_rpm' | show "plain CSV           "
fit --run "$OUT/semicolon.csv" --inputs 't* (°F),spindle_rpm' --time time | show "; decimal comma ISO °F"
fit --run "$OUT/sparse.csv" --inputs 't*_c,spindle_rpm' | show "errors every 15 min "
