#!/usr/bin/env bash
# End-to-end test of truepos on a real LinuxCNC 2.9 (simulated machine, no hardware):
# runs tests/linuxcnc/vmc3.ini headless, whose display is tests/linuxcnc/e2e.py, with the truepos
# HAL component compensating through external offsets; then `truepos-hal-check check` compares what
# LinuxCNC applied with the model and the envelope; then loads the worked HAL file for real
# sensors (scripts/linuxcnc_sensors_hal.sh). Exits non-zero on any failure; never skips.
# Usage: bash scripts/linuxcnc_e2e.sh [output dir]   (default: target/linuxcnc-e2e)
set -euo pipefail
REPO="$(cd "$(dirname "$0")/.." && pwd)"
cd "$REPO"
. scripts/linuxcnc_headless.sh
OUT="${1:-$REPO/target/linuxcnc-e2e}"

bash scripts/install_linuxcnc.sh
echo "== build truepos-hal and its judge truepos-hal-check (release)"
cargo build --release -p truepos-hal -p truepos-hal-check
BIN="$(cargo metadata --format-version 1 --no-deps | /usr/bin/python3 -c 'import json,sys; print(json.load(sys.stdin)["target_directory"])')/release"
# Debian's python modules live in the system interpreter; truepos-hal must be on PATH for loadusr.
export PATH="$BIN:/usr/bin:/bin:/usr/sbin:/sbin:$PATH"

rm -rf "$OUT" && mkdir -p "$OUT"
chmod 0777 "$OUT"
# The component serves its live view during the run (docs/live_view.md) on HTTP=ADDR, by default
# a free loopback port; a poller reads its state and metrics as a person's browser would.
HTTP="${HTTP:-127.0.0.1:$(python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')}"
http_sed="s|--stats \(.*\)stats.json|--stats \1stats.json --http $HTTP|"
for f in vmc3.ini vmc3.hal; do
    sed -e "s|@REPO@|$REPO|g" -e "s|@OUT@|$OUT|g" -e "$http_sed" "tests/linuxcnc/$f.in" > "$OUT/$f"
done
cp tests/linuxcnc/tool.tbl "$OUT/"
: > "$OUT/sim.var"

python3 - "$HTTP" "$OUT/live_view.json" <<'PY' &
import json, sys, time, urllib.request
addr, out = sys.argv[1:3]
seen = {"states": [], "metrics": False}
while True:  # until killed when LinuxCNC has run (however long it waited for its lock)
    try:
        s = json.load(urllib.request.urlopen(f"http://{addr}/api/state", timeout=2))
        m = urllib.request.urlopen(f"http://{addr}/metrics", timeout=2).read().decode()
    except Exception:
        time.sleep(0.5)
        continue
    seen["states"] = sorted(set(seen["states"]) | {s.get("state")})
    seen["metrics"] = seen["metrics"] or ("truepos_cycles_total" in m and "truepos_model_generation" in m)
    with open(out + ".tmp", "w") as f:
        json.dump(seen, f)
    import os; os.replace(out + ".tmp", out)
    time.sleep(1)
PY
poller=$!
trap 'kill "$poller" 2>/dev/null || true' EXIT
run_linuxcnc_headless "$OUT/vmc3.ini" 300 "$OUT/e2e_result.txt" "^e2e:|truepos-hal"
kill "$poller" 2>/dev/null || true

echo "== compare what LinuxCNC applied with the models; the events in the log"
fail=0
CHECK=(--machine examples/vmc3/machine.toml --model examples/vmc3/model.toml
       --model tests/linuxcnc/model_b.toml --model tests/linuxcnc/model_c.toml --model tests/linuxcnc/model_d.json
       --motion "$OUT/motion.txt" --temperatures "$OUT/temperatures.txt" --log "$OUT/truepos.sqlite"
       --expect-event "sensor-fault:x_slide_bottom" --expect-event "sensor-recovered:x_slide_bottom"
       --expect-event "sensor-fault:x_slide_top" --expect-event "sensor-recovered:x_slide_top"
       --expect-event "holding:path 1" --expect-event "model-selected:path 1:vmc3-e2e-alternative"
       --expect-event "axis-switch" --expect-event "model-selected:path 1:vmc3-e2e-xy"
       --expect-event "model-selected:path 1:model_d" --expect-event "extrapolating:path 1")
truepos-hal-check check "${CHECK[@]}" || fail=1
truepos-hal-check check --json "${CHECK[@]}" > "$OUT/check.json" || true

echo "== the live view served by the component during the run"
python3 - "$OUT/live_view.json" <<'PY' || fail=1
import json, sys
try:
    seen = json.load(open(sys.argv[1]))
except OSError:
    sys.exit("FAIL: the live view never answered")
print(f"live view: states seen {seen['states']}, metrics {'ok' if seen['metrics'] else 'missing'}")
if "active" not in seen["states"] or not seen["metrics"]:
    sys.exit("FAIL: the live view did not show an active compensation with its metrics")
PY

echo "== the worked HAL file for real sensors of docs/linuxcnc.md, loaded by halcmd"
bash scripts/linuxcnc_sensors_hal.sh "$OUT/sensors" || fail=1

echo "== component timing"
cat "$OUT/stats.json" || { echo "FAIL: truepos-hal wrote no stats (did it get SIGTERM?)"; fail=1; }
if [ "$fail" -ne 0 ]; then
    echo "linuxcnc_e2e: FAIL"
    exit 1
fi
echo "linuxcnc_e2e: PASS"
