#!/usr/bin/env bash
# Seed C's loop on a real control (issue 13 item 5): LinuxCNC 2.9 headless, truepos-hal
# compensating a drifted twin with a model fitted on the reference twin, a G-code program that
# probes a block artefact with G38.2 every pass, the harness tripping the probe where the twin's
# true error displaces the block, truepos logging the touches, `truepos reidentify --log` and a
# pulse on truepos.model.reload mid-program; then tests/linuxcnc/probe_check.py judges the
# residual after the switch against the original model's and the applied offset's steps against
# the envelope's rate. Exits non-zero on any failure; never skips (LinuxCNC missing fails).
# Time runs 60 x faster than the twin's day (docs/linuxcnc.md, "The probe loop").
# Usage: bash scripts/linuxcnc_probe_loop.sh [output dir]   (default: target/linuxcnc-probe)
set -euo pipefail
REPO="$(cd "$(dirname "$0")/.." && pwd)"
cd "$REPO"
. scripts/linuxcnc_headless.sh
OUT="${1:-$REPO/target/linuxcnc-probe}"
SPEED=60

bash scripts/install_linuxcnc.sh
echo "== build truepos-hal (release) and truepos"
cargo build --release -p truepos-hal
cargo build -p truepos
TARGET="$(cargo metadata --format-version 1 --no-deps | /usr/bin/python3 -c 'import json,sys; print(json.load(sys.stdin)["target_directory"])')"
export PATH="$TARGET/release:/usr/bin:/bin:/usr/sbin:/sbin:$PATH"
TP="$TARGET/debug/truepos"

rm -rf "$OUT" && mkdir -p "$OUT"
chmod 0777 "$OUT"
for f in probe.ini probe.hal; do
    sed -e "s|@REPO@|$REPO|g" -e "s|@OUT@|$OUT|g" -e "s|@BIN@|$TARGET/debug|g" "tests/linuxcnc/$f.in" > "$OUT/$f"
done
cp tests/linuxcnc/tool.tbl "$OUT/"
: > "$OUT/sim.var"

echo "== the machine, the original model, the drifted day (time compressed $SPEED x)"
PREP=(/usr/bin/python3 tests/linuxcnc/probe_prepare.py)
"${PREP[@]}" machine "$SPEED" examples/twin/machine.toml "$OUT/machine.toml"
# The original model: seed A's all-axes family, fitted on the reference twin's mixed-shift day.
"$TP" sim --scenario mixed-shift --out "$OUT/day_a_sim.csv" > /dev/null
"${PREP[@]}" run "$SPEED" "$OUT/day_a_sim.csv" "$OUT/day_a.csv"
"$TP" fit --machine "$OUT/machine.toml" --run "$OUT/day_a.csv" --target dx_um,dy_um,dz_um \
    --family all-axes --model "$OUT/original.toml" > "$OUT/fit.txt"
cp "$OUT/original.toml" "$OUT/model.toml"
# The machine it runs on: the drifted twin, probed at the artefact every 2 min of its day.
"$TP" sim --twin tests/linuxcnc/probe_twin.toml --scenario tests/linuxcnc/probe_day.toml \
    --out "$OUT/day_sim.csv" > /dev/null
"${PREP[@]}" run "$SPEED" "$OUT/day_sim.csv" "$OUT/day.csv"

run_linuxcnc_headless "$OUT/probe.ini" 480 "$OUT/probe_result.txt" "^probe_loop:|truepos-hal"

echo "== judge: residual after the switch, steps of the applied offset"
/usr/bin/python3 tests/linuxcnc/probe_check.py "$TP" "$OUT"
