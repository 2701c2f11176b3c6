#!/usr/bin/python3
"""Prepares the LinuxCNC probe loop's files in time compressed SPEED times
(scripts/linuxcnc_probe_loop.sh): the loop replays hours of the twin in minutes, so the machine
the component runs must live in the same compressed time — its lagged channels' time constants
divided by SPEED, its temperature rate limit multiplied by SPEED — and so must the runs the
original model is fitted on and the day the harness replays (their time_s divided by SPEED).
Nothing else changes: sensors, differences, travel and envelope are examples/twin/machine.toml's.

usage: probe_prepare.py machine SPEED SRC_MACHINE OUT_MACHINE
       probe_prepare.py run SPEED SRC_CSV OUT_CSV
"""
import csv
import re
import sys


def machine(speed, src, out):
    text = open(src).read()
    blocks = re.split(r"(?m)^(?=\[\[temperature\]\])", text)
    res = []
    for b in blocks:
        if b.startswith("[[temperature]]"):
            if "lag_of" in b:
                b = re.sub(r"(?m)^lag_s = ([0-9.eE+-]+)",
                           lambda m: f"lag_s = {float(m.group(1)) / speed!r}", b)
            else:
                # 2 K/min (the default) in machine time
                b = re.sub(r"(?m)^(valid_range = .*)$",
                           lambda m: f"{m.group(1)}\nmax_rate_k_per_min = {2.0 * speed!r}", b, count=1)
        res.append(b)
    with open(out, "w") as f:
        f.write(f"# examples/twin/machine.toml in time compressed {speed:g} x "
                "(tests/linuxcnc/probe_prepare.py)\n")
        f.write("".join(res))


def run(speed, src, out):
    with open(src, newline="") as fi, open(out, "w", newline="") as fo:
        r = csv.reader(fi)
        w = csv.writer(fo, lineterminator="\n")
        header = next(r)
        w.writerow(header)
        t = header.index("time_s")
        for row in r:
            row[t] = repr(float(row[t]) / speed)
            w.writerow(row)


if __name__ == "__main__":
    kind, speed, src, out = sys.argv[1], float(sys.argv[2]), sys.argv[3], sys.argv[4]
    {"machine": machine, "run": run}[kind](speed, src, out)
