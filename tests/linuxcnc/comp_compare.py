#!/usr/bin/python3
"""Compares what LinuxCNC commanded to the motors (OUT/comp_samples.txt, recorded by comp.py
every servo cycle) with what truepos predicts from the same COMP_FILEs
(`truepos kin table --eval`). Usage: comp_compare.py TRUEPOS OUT. Exits non-zero on failure.

Per joint (0: type 0 file, 1: type 1 file) and every servo cycle from the first move on, the
direction of travel the sign of vel-cmd, or at standstill that of the last move (motion keeps
the last direction's correction, control.c: "not moving, use whatever was there before"):
backlash-corr, the correction motion computes from the table, must
equal truepos' compensation at pos-cmd within 0.1 µm; where motion applies it in full
(backlash-filt = backlash-corr: not slewing after a reversal), so must motor-pos-cmd − pos-cmd."""
import csv
import io
import subprocess
import sys

BAR_UM = 0.1
truepos, out = sys.argv[1], sys.argv[2]
rows = []
for line in open(f"{out}/comp_samples.txt"):
    f = line.split()
    if len(f) == 11:
        rows.append([float(v) for v in f[1:]])
if len(rows) < 5000:
    sys.exit(f"comp_compare: FAIL: only {len(rows)} servo cycles recorded")

failed = False
for joint, (fmt, path) in enumerate([("linuxcnc0", "x.type0.comp"), ("linuxcnc1", "y.type1.comp")]):
    cols = [r[5 * joint:5 * joint + 5] for r in rows]  # pos, vel, applied, corr, filt
    moving, direction, last = [], [], 0
    for c in cols:
        last = (1 if c[1] > 0 else -1) if c[1] != 0.0 else last
        if last:
            moving.append(c)
            direction.append(last)
    query = "position,direction\n" + "".join(
        f"{c[0]!r},{d}\n" for c, d in zip(moving, direction))
    with open(f"{out}/eval_{joint}.csv", "w") as q:
        q.write(query)
    res = subprocess.run([truepos, "kin", "table", "--input", f"{out}/{path}", "--from", fmt,
                          "--eval", f"{out}/eval_{joint}.csv"],
                         capture_output=True, text=True, check=True).stdout
    predicted = [float(r["compensation_um"]) for r in csv.DictReader(io.StringIO(res))]
    assert len(predicted) == len(moving)
    corr_dev = max(abs(c[3] - p) for c, p in zip(moving, predicted))
    settled = [(c, p) for c, p in zip(moving, predicted) if abs(c[4] - c[3]) < 1e-6]
    applied_dev = max(abs(c[2] - p) for c, p in settled)
    fwd = [c[0] for c in moving if c[1] > 0]
    rev = [c[0] for c in moving if c[1] < 0]
    span = (min(fwd), max(fwd), min(rev), max(rev))
    still = [c for c in moving if c[1] == 0.0]
    print(f"joint {joint} ({path}, COMP_FILE_TYPE {joint}): {len(fwd)} forward and {len(rev)} "
          f"reverse servo cycles over {span[0]:.1f}-{span[1]:.1f} / {span[2]:.1f}-{span[3]:.1f} mm and {len(still)} standstill "
          f"cycles between moves; "
          f"max |backlash-corr - truepos| = {corr_dev:.2e} um; max |motor-pos-cmd - pos-cmd - "
          f"truepos| = {applied_dev:.2e} um over {len(settled)} cycles applied in full "
          f"({len(moving) - len(settled)} slewing a step of the correction left out)")
    if corr_dev > BAR_UM or applied_dev > BAR_UM:
        print(f"comp_compare: FAIL: joint {joint} disagrees with truepos by more than {BAR_UM} um")
        failed = True
    if len(fwd) < 2000 or len(rev) < 2000 or span[0] > 5 or span[1] < 395 or span[2] > 5 \
            or span[3] < 395 or len(settled) < 0.9 * len(moving):
        print(f"comp_compare: FAIL: joint {joint}: the moves did not cover the table")
        failed = True
print("linuxcnc_comp: FAIL" if failed else "linuxcnc_comp: PASS")
sys.exit(1 if failed else 0)
