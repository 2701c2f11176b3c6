#!/usr/bin/env bash
# truepos's least-squares solver against numpy.linalg.lstsq on the same 1,000,000 × 100 matrix.
# Installs numpy into a virtual environment (target/lstsq-venv), builds the Rust side in release
# mode, and prints one JSON object: both times (best of 3), their ratio, and the largest relative
# difference between the two coefficient vectors. Usage: scripts/lstsq_vs_numpy.sh [ROWS [COLS]]
set -euo pipefail
cd "$(dirname "$0")/.."
ROWS="${1:-1000000}"
COLS="${2:-100}"
DIR="${TMPDIR:-/tmp}/truepos-lstsq"
VENV="target/lstsq-venv"
if [ ! -x "$VENV/bin/python" ]; then
  python3 -m venv "$VENV" >&2
  "$VENV/bin/pip" install --quiet numpy >&2
fi
cargo build --quiet --release -p truepos-fit --example lstsq_bench >&2
BIN=target/release/examples/lstsq_bench
"$BIN" gen "$DIR" "$ROWS" "$COLS"
NUMPY_JSON="$("$VENV/bin/python" - "$DIR" <<'PY'
import json, sys, time
import numpy as np
d = sys.argv[1]
A = np.load(f"{d}/A.npy"); b = np.load(f"{d}/b.npy")
best = float("inf")
for _ in range(3):
    t0 = time.perf_counter()
    x, *_ = np.linalg.lstsq(A, b, rcond=None)
    best = min(best, time.perf_counter() - t0)
np.save(f"{d}/x_numpy.npy", x)
# An accuracy reference (not timed): numpy on the column-scaled matrix, which removes the
# 1e-3 … 1e3 spread of column scales that costs the unscaled solve digits.
norms = np.linalg.norm(A, axis=0)
A /= norms
xs, *_ = np.linalg.lstsq(A, b, rcond=None)
np.save(f"{d}/x_reference.npy", xs / norms)
print(json.dumps({"numpy_seconds": best, "numpy_version": np.__version__}))
PY
)"
RUST_JSON="$("$BIN" solve "$DIR")"
"$VENV/bin/python" - "$DIR" "$NUMPY_JSON" "$RUST_JSON" <<'PY'
import json, sys
import numpy as np
d, nj, rj = sys.argv[1], json.loads(sys.argv[2]), json.loads(sys.argv[3])
xn = np.load(f"{d}/x_numpy.npy"); xr = np.load(f"{d}/x_truepos.npy")
xref = np.load(f"{d}/x_reference.npy")
rel = float(np.max(np.abs(xr - xn) / np.abs(xn)))
rel_t = float(np.max(np.abs(xr - xref) / np.abs(xref)))
rel_n = float(np.max(np.abs(xn - xref) / np.abs(xref)))
out = {**rj, **nj,
       "speed_ratio_numpy_over_truepos": nj["numpy_seconds"] / rj["truepos_seconds"],
       "max_relative_coefficient_difference": rel,
       "coefficients_equal_1e-8": rel <= 1e-8,
       "truepos_vs_scaled_reference": rel_t,
       "numpy_vs_scaled_reference": rel_n,
       "at_least_as_fast_as_numpy": rj["truepos_seconds"] <= nj["numpy_seconds"]}
print(json.dumps(out))
PY
rm -f "$DIR"/A.npy "$DIR"/b.npy
