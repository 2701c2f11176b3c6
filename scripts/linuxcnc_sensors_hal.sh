#!/usr/bin/env bash
# The worked HAL file for real sensors (tests/linuxcnc/sensors.hal.in, shown in docs/linuxcnc.md)
# loaded for real by halcmd under halrun: motion, mb2hal, scale and truepos-hal as on a machine,
# only the hardware stood in for — a Modbus TCP server on 127.0.0.1 in place of the temperature
# module (tests/linuxcnc/modbus_temperatures.py) and a component with the Mesa card's pin names in
# place of its analog inputs (tests/linuxcnc/sensors_stand_ins.py). Then every truepos.temp.* pin
# must read its sensor's value in °C and the spindle speed must reach truepos.operating.spindle_rpm.
# A pin name wrong in the file, a component that does not load or a value that does not arrive
# fails. Needs LinuxCNC (scripts/install_linuxcnc.sh) and truepos-hal on PATH (linuxcnc_e2e.sh
# builds it and runs this).
# Usage: bash scripts/linuxcnc_sensors_hal.sh [output dir]   (default: target/linuxcnc-sensors)
set -euo pipefail
REPO="$(cd "$(dirname "$0")/.." && pwd)"
cd "$REPO"
. scripts/linuxcnc_headless.sh
OUT="${1:-$REPO/target/linuxcnc-sensors}"
command -v truepos-hal >/dev/null || { echo "FAIL: truepos-hal is not on PATH"; exit 1; }
rm -rf "$OUT" && mkdir -p "$OUT"

# What the stand-ins give: 12 registers of 0.1 °C (20.1 … 21.2 °C), 4 transmitters' volts.
REGISTERS=201,202,203,204,205,206,207,208,209,210,211,212
VOLTS=2.25,2.5,2.75,2.15
PORT="$(/usr/bin/python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])')"
/usr/bin/python3 tests/linuxcnc/modbus_temperatures.py "$PORT" "$REGISTERS" > "$OUT/modbus.log" 2>&1 &
SERVER=$!
trap 'kill "$SERVER" 2>/dev/null || true' EXIT

sed -e "s|@MODBUS_IP@|127.0.0.1|" -e "s|@MODBUS_PORT@|$PORT|" \
    tests/linuxcnc/sensors_mb2hal.ini.in > "$OUT/sensors_mb2hal.ini"
sed -e "s|@MB2HAL_INI@|$OUT/sensors_mb2hal.ini|" tests/linuxcnc/sensors.hal.in > "$OUT/sensors.hal"
cat > "$OUT/harness.hal" <<HAL
# What the machine's own HAL file and LinuxCNC's launcher load before sensors.hal: motion (with
# its homing and trajectory modules, which give spindle.0.* and the servo thread), the Mesa card
# (here its stand-in) and truepos-hal.
loadrt trivkins coordinates=xyz
loadrt homemod
loadrt tpmod
loadrt motmod servo_period_nsec=1000000 num_joints=3
loadusr -Wn hm2_7i92.0 /usr/bin/python3 $REPO/tests/linuxcnc/sensors_stand_ins.py $VOLTS
loadusr -Wn truepos truepos-hal run --machine $REPO/examples/vmc3/machine.toml --model $REPO/examples/vmc3/model.toml
source $OUT/sensors.hal
start
# mb2hal reads twice a second: wait for a few reads, then show what truepos sees.
loadusr -w sleep 2
show pin truepos.temp
show sig tp-spindle-rpm
HAL

if [ "$(id -u)" -eq 0 ]; then
    id truepos-ci >/dev/null 2>&1 || useradd --system --no-create-home --shell /usr/sbin/nologin truepos-ci
    export RTAPI_UID="$(id -u truepos-ci)"
    export HOME="$OUT/home"
    mkdir -p "$HOME" && chown truepos-ci "$HOME"
fi
[ -e "$LINUXCNC_LOCK" ] || (umask 0 && : >>"$LINUXCNC_LOCK")
exec {lock_fd}<"$LINUXCNC_LOCK"
flock -w 900 "$lock_fd" || { echo "FAIL: another LinuxCNC test run held $LINUXCNC_LOCK for 900 s"; exit 1; }
linuxcnc_ended_within 30 || { echo "FAIL: LinuxCNC programs are still running"; exit 1; }
remove_orphan_linuxcnc_memory
echo "== load tests/linuxcnc/sensors.hal.in with halcmd (halrun), hardware stood in for"
status=0
timeout 120 halrun -f "$OUT/harness.hal" > "$OUT/halrun.log" 2>&1 {lock_fd}>&- || status=$?
halrun -U >/dev/null 2>&1 {lock_fd}>&- || true
linuxcnc_ended_within 30 || echo "warning: LinuxCNC programs left 30 s after the run"
exec {lock_fd}>&-
if [ "$status" -ne 0 ]; then
    echo "FAIL: halrun exited $status"
    cat "$OUT/halrun.log"
    exit 1
fi

echo "== every temperature pin reads its sensor in °C; the spindle speed is connected"
/usr/bin/python3 - "$OUT/halrun.log" "$REGISTERS" "$VOLTS" <<'PY'
import re, sys
log = open(sys.argv[1]).read()
modbus = ["x_slide_top", "x_slide_bottom", "y_slide_top", "y_slide_bottom", "z_slide_front",
          "z_slide_rear", "column_front", "column_rear", "bed_top", "bed_bottom", "head_left",
          "head_right"]
analog = ["spindle_front_bearing", "spindle_rear_bearing", "spindle_motor", "ambient"]
expected = {i: 0.1 * int(r) for i, r in zip(modbus, sys.argv[2].split(","))}
expected.update({i: 10.0 * float(v) for i, v in zip(analog, sys.argv[3].split(","))})
seen = {m.group(2): float(m.group(1))
        for m in re.finditer(r"float\s+IN\s+(\S+)\s+truepos\.temp\.(\S+)", log)}
bad = [f"truepos.temp.{i}: {seen.get(i)} (expected {v:.2f} °C)"
       for i, v in expected.items() if i not in seen or abs(seen[i] - v) > 1e-6]
if not re.search(r"<==\s*spindle\.0\.speed-out-abs", log) or \
        not re.search(r"==>\s*truepos\.operating\.spindle_rpm", log):
    bad.append("tp-spindle-rpm does not join spindle.0.speed-out-abs to truepos.operating.spindle_rpm")
for b in bad:
    print("FAIL:", b)
print(f"{len(expected) - len([b for b in bad if 'temp' in b])} of {len(expected)} temperatures arrive in °C")
sys.exit(1 if bad else 0)
PY
echo "linuxcnc_sensors_hal: PASS"
