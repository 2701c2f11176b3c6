#!/usr/bin/python3
"""Judges the LinuxCNC probe loop (scripts/linuxcnc_probe_loop.sh) after LinuxCNC has run:

- the residual, true error − applied compensation, at the probe touches after the switch
  (from the end of the blend, reload + --blend-s + 1 s, to the end of the program) must be at
  least 70 % below the original model's residual at the same touches: the truth is the twin's
  error at the contact point at the touch's machine time; the applied compensation is the
  external offset LinuxCNC held at the touch; the original model's prediction there comes from
  `truepos eval` of the original model on the day's temperatures at the contact point;
- no cycle-to-cycle step of the applied offset (axis.<a>.eoffset, every servo cycle) exceeds
  the envelope's rate over the real time since the offset could last have moved, plus one
  cycle of the component, plus two counts of quantisation (0.02 µm) — the rule
  truepos-hal-check's output invariant applies to the end-to-end test: the time spans the
  cycles in which the offset stood still and the PIPELINE_CYCLES before them, each at its real
  length (the two run on different clocks; after a servo cycle the host held up come catch-up
  cycles a few µs long, in which the component's step over the whole hold lands);
- the re-identification switched, the component took the model (truepos.model.reloads 1), and
  the log holds every touch as an accepted probe event.
Prints the figures and writes OUT/probe_check.json; exits non-zero on any failure.

usage: probe_check.py TRUEPOS_BINARY OUT_DIR
"""
import bisect
import csv
import json
import math
import os
import sqlite3
import statistics
import subprocess
import sys
import tomllib

BLEND_S = 2.0  # probe.hal.in: --blend-s 2
MIN_REDUCTION = 0.70
MIN_WINDOW_TOUCHES = 15
# LinuxCNC applies a request a cycle or more after the component wrote it (as truepos-hal-check).
PIPELINE_CYCLES = 3
AXES = "XYZ"

tp, out = sys.argv[1], sys.argv[2]
ev = json.load(open(os.path.join(out, "probe_events.json")))
events = ev["events"]
machine = tomllib.load(open(os.path.join(out, "machine.toml"), "rb"))
rate_um_s = [a.get("max_rate_um_per_s", 50.0) for a in machine["axis"]]
failures = []


def fail(msg):
    failures.append(msg)
    print(f"FAIL: {msg}")


def rms(v):
    return math.sqrt(sum(x * x for x in v) / len(v)) if v else float("nan")


# ---- the original model at each contact point over the day (truepos eval) ----
rows = list(csv.DictReader(open(os.path.join(out, "day.csv"))))
header = list(rows[0].keys())
original = {}
for a in range(3):
    point = next(e["point_mm"] for e in events if e["axis"] == a)
    run = os.path.join(out, f"contact_{AXES[a]}.csv")
    with open(run, "w", newline="") as f:
        w = csv.writer(f, lineterminator="\n")
        w.writerow(header)
        for r in rows:
            r = dict(r, X_mm=point[0], Y_mm=point[1], Z_mm=point[2])
            w.writerow([r[k] for k in header])
    pred = os.path.join(out, f"contact_{AXES[a]}_original.csv")
    subprocess.run([tp, "eval", "--machine", os.path.join(out, "machine.toml"), "--model",
                    os.path.join(out, "original.toml"), "--run", run, "--out", pred],
                   check=True, stdout=subprocess.DEVNULL)
    p = list(csv.DictReader(open(pred)))
    original[a] = ([float(r["time_s"]) for r in p], [float(r[f"{AXES[a]}_error_um"]) for r in p])


def original_um(a, t):
    ts, vs = original[a]
    i = min(max(bisect.bisect_right(ts, t) - 1, 0), len(ts) - 2)
    w = min(max((t - ts[i]) / (ts[i + 1] - ts[i]), 0.0), 1.0)
    return vs[i] * (1 - w) + vs[i + 1] * w


# The truth ends with the day: a touch after its last probe row would be judged on a frozen twin.
day_end = max(float(r["time_s"]) for r in rows if r["probe_x_mm"])
late = [e for e in events if e["machine_time_s"] > day_end]
if late:
    fail(f"{len(late)} touches after the day's last probe row ({day_end:.1f} s): lengthen the day")

reload_t = ev["reload_machine_time_s"]
if reload_t is None:
    fail("the component never took a re-identified model")
    reload_t = float("inf")
window_from = reload_t + BLEND_S + 1.0
figures = {"touches": len(events), "reload_machine_time_s": reload_t,
           "window_from_machine_time_s": window_from}

# ---- the probe's readings against the truth; the applied compensation before the switch ----
reading = [e["measured_um"] - e["true_um"] for e in events]
figures["probe_reading_minus_truth_um"] = {
    "mean": statistics.fmean(reading), "max_abs": max(abs(x) for x in reading)}
before = [e for e in events if e["machine_time_s"] < reload_t]
applied_vs_original = [e["eoffset_mm"][e["axis"]] * 1000.0 + original_um(e["axis"],
                       e["machine_time_s"]) for e in before]
figures["before_switch_applied_plus_original_prediction_um_max_abs"] = max(
    (abs(x) for x in applied_vs_original), default=float("nan"))

# ---- the residuals in the window after the switch ----
window = [e for e in events if e["machine_time_s"] >= window_from]
res_new = {a: [] for a in range(3)}
res_orig = {a: [] for a in range(3)}
for e in window:
    a, t = e["axis"], e["machine_time_s"]
    res_new[a].append(e["true_um"] + e["eoffset_mm"][a] * 1000.0)
    res_orig[a].append(e["true_um"] - original_um(a, t))
pooled_new = [x for a in range(3) for x in res_new[a]]
pooled_orig = [x for a in range(3) for x in res_orig[a]]
figures["window_touches"] = len(window)
figures["residual_rms_um"] = {
    "original": rms(pooled_orig), "applied": rms(pooled_new),
    "per_axis": {AXES[a]: {"original": rms(res_orig[a]), "applied": rms(res_new[a]),
                           "touches": len(res_new[a])} for a in range(3)}}
figures["residual_max_abs_um"] = {
    "original": max((abs(x) for x in pooled_orig), default=float("nan")),
    "applied": max((abs(x) for x in pooled_new), default=float("nan"))}
reduction = 1.0 - rms(pooled_new) / rms(pooled_orig) if pooled_orig else float("nan")
figures["reduction"] = reduction
if len(window) < MIN_WINDOW_TOUCHES:
    fail(f"only {len(window)} touches after the switch (at least {MIN_WINDOW_TOUCHES})")
if not reduction >= MIN_REDUCTION:
    fail(f"the residual after the switch is {100 * reduction:.1f} % below the original "
         f"model's (at least {100 * MIN_REDUCTION:.0f} %)")

# ---- steps of the applied offset, cycle to cycle ----
samples = []
for line in open(os.path.join(out, "motion.txt")):
    v = line.split()
    if len(v) == 14:
        samples.append([float(x) for x in v[1:]])
if len(samples) < 10000:
    fail(f"only {len(samples)} servo cycles recorded")
clocks = statistics.median(s[12] for s in samples if s[12] > 0)
period = ev["servo_period_s"]
worst = [0.0, 0.0, 0.0]
worst_share = [0.0, 0.0, 0.0]
worst_50ms = [0.0, 0.0, 0.0]
# Real time (s) up to the end of each servo cycle, from its clock counts.
elapsed = [0.0]
for smp in samples:
    elapsed.append(elapsed[-1] + smp[12] / clocks * period)
last_change = [0, 0, 0]
for k in range(1, len(samples)):
    for a in range(3):
        step = abs(samples[k][3 + a] - samples[k - 1][3 + a]) * 1000.0
        # Since the cycle the offset last changed in, and the pipeline's cycles before it.
        start = max(0, last_change[a] - PIPELINE_CYCLES)
        dt = elapsed[k + 1] - elapsed[start + 1]
        allowance = rate_um_s[a] * (dt + period) + 0.02
        worst[a] = max(worst[a], step)
        worst_share[a] = max(worst_share[a], step / allowance)
        if step > 0.0:
            last_change[a] = k
# Over windows of at least 50 ms of real time (catch-up cycles a few µs long would make a
# window of 50 cycles a fraction of a millisecond).
j = 0
for k in range(1, len(samples), 10):
    while j + 1 < k and elapsed[k + 1] - elapsed[j + 2] >= 0.05:
        j += 1
    dt = elapsed[k + 1] - elapsed[j + 1]
    if dt < 0.05:
        continue
    for a in range(3):
        worst_50ms[a] = max(worst_50ms[a],
                            abs(samples[k][3 + a] - samples[j][3 + a]) * 1000.0 / dt)
figures["servo_cycles"] = len(samples)
figures["largest_step_um"] = dict(zip(AXES, worst))
figures["largest_step_share_of_allowance"] = dict(zip(AXES, worst_share))
figures["largest_rate_over_50ms_um_s"] = dict(zip(AXES, worst_50ms))
figures["envelope_rate_um_s"] = dict(zip(AXES, rate_um_s))
for a in range(3):
    if worst_share[a] > 1.0:
        fail(f"axis {AXES[a]}: a one-cycle step of {worst[a]:.3f} µm exceeds the envelope's rate")
nonfinite = sum(1 for s in samples for x in s[3:9] if not math.isfinite(x))
if nonfinite:
    fail(f"{nonfinite} non-finite offsets recorded")
reloads = max(int(s[10]) for s in samples)
figures["model_reloads"] = reloads
if reloads != 1:
    fail(f"truepos.model.reloads reached {reloads}, expected 1")
figures["largest_offset_um"] = dict(zip(AXES, [max(abs(s[3 + a]) for s in samples) * 1000.0
                                               for a in range(3)]))

# ---- re-identification and the log ----
switched = [r for r in ev["reidentify"] if r["exit"] == 0]
if not switched:
    fail("no re-identification switched")
else:
    r = switched[0]["result"]
    figures["reidentify"] = {"touches": switched[0]["touches"], "seconds": switched[0]["seconds"],
                             "window": r.get("window"), "status": r.get("status")}
db = sqlite3.connect(f"file:{os.path.join(out, 'truepos.sqlite')}?mode=ro", uri=True)
counts = dict(db.execute("SELECT status, COUNT(*) FROM probes GROUP BY status").fetchall())
figures["log_probes"] = counts
if counts.get("accepted", 0) != len(events) or counts.get("rejected", 0):
    fail(f"the log holds {counts} probe events for {len(events)} touches")

json.dump(figures, open(os.path.join(out, "probe_check.json"), "w"), indent=1)
f = figures
print(f"touches {f['touches']}, re-identified after {f.get('reidentify', {}).get('touches')}, "
      f"model taken at machine time {reload_t:.1f} s; window from {window_from:.1f} s: "
      f"{f['window_touches']} touches")
print(f"residual RMS (true − applied) in the window: {f['residual_rms_um']['applied']:.2f} µm; "
      f"original model's there: {f['residual_rms_um']['original']:.2f} µm; "
      f"reduction {100 * reduction:.1f} % (bar {100 * MIN_REDUCTION:.0f} %)")
for a in AXES:
    p = f["residual_rms_um"]["per_axis"][a]
    print(f"  {a}: {p['touches']} touches, original {p['original']:.2f} µm, "
          f"applied {p['applied']:.2f} µm")
print(f"probe reading − truth: mean {f['probe_reading_minus_truth_um']['mean']:+.3f} µm, "
      f"max |.| {f['probe_reading_minus_truth_um']['max_abs']:.3f} µm; before the switch, "
      f"applied + original prediction max |.| "
      f"{f['before_switch_applied_plus_original_prediction_um_max_abs']:.3f} µm")
print("largest one-cycle step of the applied offset: " + ", ".join(
    f"{a} {f['largest_step_um'][a]:.3f} µm ({f['largest_step_share_of_allowance'][a]:.2f} of "
    f"the allowance)" for a in AXES))
print("largest rate over 50 ms: " + ", ".join(
    f"{a} {f['largest_rate_over_50ms_um_s'][a]:.1f} µm/s" for a in AXES) +
      f" (envelope {rate_um_s[0]:g} µm/s); servo cycles {len(samples)}")
print(f"log: probe events {counts}")
if failures:
    print("linuxcnc_probe_loop: FAIL")
    sys.exit(1)
print("linuxcnc_probe_loop: PASS")
