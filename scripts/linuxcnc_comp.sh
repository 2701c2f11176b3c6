#!/usr/bin/env bash
# COMP_FILE check against LinuxCNC itself: truepos writes tests/linuxcnc/comp_table.csv as a
# COMP_FILE of type 0 (joint 0, X) and type 1 (joint 1, Y) with `truepos kin table`; one headless
# LinuxCNC 2.9 start loads both, MDI moves both joints forward through the table to 400 mm and
# back (tests/linuxcnc/comp.py) while every servo cycle is recorded; then
# tests/linuxcnc/comp_compare.py compares what motion commanded to the motor with what
# `truepos kin table --eval` predicts from the same files. Bar: 0.1 µm. Fails (never skips) if
# LinuxCNC is missing or anything disagrees.
# Usage: bash scripts/linuxcnc_comp.sh [output dir]   (default: target/linuxcnc-comp)
set -euo pipefail
REPO="$(cd "$(dirname "$0")/.." && pwd)"
cd "$REPO"
. scripts/linuxcnc_headless.sh
OUT="${1:-$REPO/target/linuxcnc-comp}"

bash scripts/install_linuxcnc.sh
cargo build -p truepos
BIN="$(cargo metadata --format-version 1 --no-deps | /usr/bin/python3 -c 'import json,sys; print(json.load(sys.stdin)["target_directory"])')/debug"
export PATH="/usr/bin:/bin:/usr/sbin:/sbin:$PATH"

rm -rf "$OUT" && mkdir -p "$OUT"
chmod 0777 "$OUT"
for f in comp.ini comp.hal; do
    sed -e "s|@REPO@|$REPO|g" -e "s|@OUT@|$OUT|g" "tests/linuxcnc/$f.in" > "$OUT/$f"
done
: > "$OUT/sim.var"
: > "$OUT/tool.tbl"
"$BIN/truepos" kin table --input tests/linuxcnc/comp_table.csv --from csv --to linuxcnc0 --out "$OUT/x.type0.comp"
"$BIN/truepos" kin table --input tests/linuxcnc/comp_table.csv --from csv --to linuxcnc1 --out "$OUT/y.type1.comp"

run_linuxcnc_headless "$OUT/comp.ini" 120 "$OUT/comp_result.txt" "^comp:"

echo "== compare what LinuxCNC commanded to the motors with truepos"
/usr/bin/python3 tests/linuxcnc/comp_compare.py "$BIN/truepos" "$OUT"
