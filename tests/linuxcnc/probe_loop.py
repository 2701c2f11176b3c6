#!/usr/bin/python3
"""The LinuxCNC probe loop's harness, run by LinuxCNC as the [DISPLAY] of probe.ini (no GUI);
scripts/linuxcnc_probe_loop.sh prepares its files and judges the run (probe_check.py).

The machine is the drifted twin (tests/linuxcnc/probe_twin.toml) on the day probe_day.toml,
replayed 60 x faster (`truepos sim`'s run with its time divided by 60, probe_prepare.py), and
compensated by truepos-hal with a model fitted on the reference twin. This script
- plays the day's temperatures into truepos.temp.* (a HAL component `twin`, interpolated in
  time, the clock starting with the program);
- moves the block artefact of probe.hal.in: its faces, written every few milliseconds, sit where
  the twin's true error at the contact points (the day's probe rows, interpolated in time)
  displaces them, so the servo thread's comparators raise motion.probe-input exactly when the
  tool tip, as the joints place it, meets the displaced block;
- runs probe_loop.ngc and reads every G38.2 touch from LinuxCNC's probed position (where the
  joints stood, the external offset included), takes off the probe's trigger delay at its feed,
  and hands the measured error (nominal face − touched position, the model's sign: actual −
  nominal) to truepos's probe pins with a trigger pulse;
- after REIDENTIFY_AFTER touches runs `truepos reidentify --log` on truepos's log, writes the
  new model over the file the component runs, and pulses truepos.model.reload: the component
  switches mid-program, blending;
- writes OUT/probe_events.json (every touch with the truth) and OUT/probe_result.txt.
Exits non-zero on any failure; LinuxCNC then shuts down (SIGTERM to truepos-hal).
"""
import bisect
import configparser
import csv
import json
import os
import subprocess
import sys
import threading
import time
import tomllib

import hal
import linuxcnc

import harness


def log(msg):
    print(f"probe_loop: {msg}", flush=True)


ini_path = sys.argv[sys.argv.index("-ini") + 1]
ini = configparser.ConfigParser(strict=False, interpolation=None)
ini.read(ini_path)
cfg = ini["TRUEPOS"]
out = cfg["OUT"]
SERVO_PERIOD_S = float(ini["EMCMOT"]["SERVO_PERIOD"]) * 1e-9

# The block's faces (mm), as probe.hal.in describes it, and the contact point of each touch:
# axis -> (face the touch measures, approach direction, contact point).
BLOCK = {"x": (380.0, 420.0), "y": (230.0, 270.0), "z": (60.0, 100.0)}
TOUCH = {
    0: (380.0, +1, (380.0, 250.0, 80.0)),
    1: (230.0, +1, (400.0, 230.0, 80.0)),
    2: (100.0, -1, (400.0, 250.0, 100.0)),
}
PROBE_FEED_MM_MIN = 30.0  # probe_loop.ngc's G38.2 feed
# The input rises in the servo cycle after the joints cross the face and motion latches the
# position of the cycle after that: on average 1.5 cycles of travel past the contact at the
# probing feed (a real probe's trigger delay, which its calibration at that feed removes).
TRIGGER_DELAY_MM = 1.5 * SERVO_PERIOD_S * PROBE_FEED_MM_MIN / 60.0
REIDENTIFY_AFTER = 60  # touches (20 probing cycles, 2 h of the day) before re-identifying
REIDENTIFY_RETRY = 6   # touches more before trying again when the model is kept
AXES = "xyz"

# ---- the day: temperatures and the true error at the contact points, in machine time ----
machine = tomllib.load(open(cfg["MACHINE"], "rb"))
sensors = [t["id"] for t in machine["temperature"] if "lag_of" not in t]
rows = list(csv.DictReader(open(cfg["DAY_CSV"])))
times = [float(r["time_s"]) for r in rows]
temps = [[float(r[s]) for s in sensors] for r in rows]
truth = {a: ([], []) for a in TOUCH}  # axis -> (times, error µm) at that touch's contact point
for r in rows:
    if not r["probe_x_mm"]:
        continue
    p = tuple(float(r[f"probe_{c}_mm"]) for c in AXES)
    for a, (_, _, point) in TOUCH.items():
        if all(abs(p[k] - point[k]) < 1e-6 for k in range(3)):
            truth[a][0].append(float(r["time_s"]))
            truth[a][1].append(float(r[f"probe_d{AXES[a]}_um"]))
if any(len(t[0]) < 2 for t in truth.values()):
    sys.exit("probe_loop: the day has no probe rows at the contact points")


def interp(ts, vs, t):
    i = min(max(bisect.bisect_right(ts, t) - 1, 0), len(ts) - 2)
    w = min(max((t - ts[i]) / (ts[i + 1] - ts[i]), 0.0), 1.0)
    return vs[i] * (1 - w) + vs[i + 1] * w


def temperatures_at(t):
    i = min(max(bisect.bisect_right(times, t) - 1, 0), len(times) - 2)
    w = min(max((t - times[i]) / (times[i + 1] - times[i]), 0.0), 1.0)
    return [a * (1 - w) + b * w for a, b in zip(temps[i], temps[i + 1])]


def true_error_um(axis, t):
    return interp(truth[axis][0], truth[axis][1], t)


# ---- HAL: the twin's temperatures, the artefact's faces, the probe pins of truepos ----
twin = hal.component("twin")
for s in sensors:
    twin.newpin(s, hal.HAL_FLOAT, hal.HAL_OUT)
for a in AXES:
    for side in ("lo", "hi"):
        twin.newpin(f"face-{a}-{side}", hal.HAL_FLOAT, hal.HAL_OUT)
twin.newpin("probe-trigger", hal.HAL_BIT, hal.HAL_OUT)
for n in range(3):
    twin.newpin(f"probe-pos-{n}", hal.HAL_FLOAT, hal.HAL_OUT)
    twin.newpin(f"probe-dev-{n}", hal.HAL_FLOAT, hal.HAL_OUT)
    twin.newpin(f"probe-measured-{n}", hal.HAL_BIT, hal.HAL_OUT)
twin.newpin("model-reload", hal.HAL_BIT, hal.HAL_OUT)
twin.ready()

clock = {"t0": None, "stop": False}


def machine_time():
    t0 = clock["t0"]
    return 0.0 if t0 is None else time.monotonic() - t0


def place(t):
    """Writes the temperatures and the displaced faces for machine time t."""
    for s, v in zip(sensors, temperatures_at(t)):
        twin[s] = v
    for a in TOUCH:
        e_mm = true_error_um(a, t) / 1000.0
        lo, hi = BLOCK[AXES[a]]
        twin[f"face-{AXES[a]}-lo"] = lo - e_mm
        twin[f"face-{AXES[a]}-hi"] = hi - e_mm


place(0.0)
for s in sensors:
    hal.new_sig(f"tp-t-{s}", hal.HAL_FLOAT)
    hal.connect(f"twin.{s}", f"tp-t-{s}")
    hal.connect(f"truepos.temp.{s}", f"tp-t-{s}")
for a in AXES:
    for side in ("lo", "hi"):
        hal.connect(f"twin.face-{a}-{side}", f"tp-face-{a}-{side}")
for pin, target in [("probe-trigger", "probe.trigger"), ("model-reload", "model.reload")] + [
    (f"probe-{k}-{n}", f"probe.{k}-{n}") for n in range(3) for k in ("pos", "dev", "measured")
]:
    sig = f"tp-{pin}"
    hal.new_sig(sig, hal.HAL_BIT if ("trigger" in pin or "measured" in pin or "reload" in pin)
                else hal.HAL_FLOAT)
    hal.connect(f"twin.{pin}", sig)
    hal.connect(f"truepos.{target}", sig)


def feeder():
    while not clock["stop"]:
        place(machine_time())
        time.sleep(0.002)


threading.Thread(target=feeder, daemon=True).start()

s = linuxcnc.stat()
c = linuxcnc.command()
harness.realtime_priority(log)


wait = harness.waiter(s, "probe_loop")


def pulse(pin):
    twin[pin] = True
    time.sleep(0.02)  # 20 cycles of the component: it sees the rising edge
    twin[pin] = False
    time.sleep(0.02)


def hand_to_truepos(axis, position, dev_um):
    for n in range(3):
        twin[f"probe-pos-{n}"] = position[n]
        twin[f"probe-dev-{n}"] = dev_um if n == axis else 0.0
        twin[f"probe-measured-{n}"] = n == axis
    time.sleep(0.005)
    pulse("probe-trigger")


reid = {"runs": [], "thread": None, "reload_wall": None, "next_at": REIDENTIFY_AFTER}


def reidentify(touches):
    time.sleep(0.6)  # the log commits every 250 ms: the last touch is in the file
    cmd = [cfg["TRUEPOS"], "reidentify", "--machine", cfg["MACHINE"], "--model",
           cfg["ORIGINAL"], "--log", os.path.join(out, "truepos.sqlite"), "--out",
           cfg["MODEL"], "--json"]
    started = time.monotonic()
    p = subprocess.run(cmd, capture_output=True, text=True)
    run = {"touches": touches, "exit": p.returncode, "seconds": time.monotonic() - started,
           "machine_time_s": machine_time()}
    try:
        run["result"] = json.loads(p.stdout)
    except ValueError:
        run["stdout"], run["stderr"] = p.stdout, p.stderr
    reid["runs"].append(run)
    log(f"reidentify after {touches} touches: exit {p.returncode} in {run['seconds']:.1f} s "
        f"{p.stderr.strip()}")
    if p.returncode == 0:
        pulse("model-reload")
        reid["reload_wall"] = time.monotonic()
        reid["reload_machine_time_s"] = machine_time()
        log(f"model.reload pulsed at machine time {reid['reload_machine_time_s']:.1f} s")
    elif p.returncode == 3:
        reid["next_at"] = touches + REIDENTIFY_RETRY


events = []
failed = False
samplers = []
try:
    c.state(linuxcnc.STATE_ESTOP_RESET)
    c.state(linuxcnc.STATE_ON)
    wait("machine on", lambda: s.task_state == linuxcnc.STATE_ON)
    c.home(-1)
    wait("homing", lambda: all(s.homed[:3]))
    wait("truepos active", lambda: hal.get_value("truepos.status") == 1, 10.0)
    f = open(os.path.join(out, "motion.txt"), "w")
    samplers.append((subprocess.Popen(["halsampler", "-t", "-c", "0"], stdout=f), f))
    time.sleep(0.5)
    subprocess.run(["halcmd", "sets", "sample-enable", "1"], check=True)
    time.sleep(1.0)

    c.mode(linuxcnc.MODE_AUTO)
    c.wait_complete()
    c.program_open(cfg["PROGRAM"])
    clock["t0"] = time.monotonic()
    c.auto(linuxcnc.AUTO_RUN, 0)
    log("program running; the twin's clock started")
    wait("program start", lambda: s.interp_state != linuxcnc.INTERP_IDLE, 5.0)
    last = tuple(s.probed_position[:3])
    while True:
        s.poll()
        if s.task_state != linuxcnc.STATE_ON:
            raise SystemExit("probe_loop: machine went off during the program")
        probed = tuple(s.probed_position[:3])
        if probed != last and s.probe_tripped:
            last = probed
            t = machine_time()
            axis = min(TOUCH, key=lambda a: abs(probed[a] - TOUCH[a][0]))
            face, direction, point = TOUCH[axis]
            eoffset = [hal.get_value(f"axis.{a}.eoffset") for a in AXES]
            # LinuxCNC latches where the joints stood, external offset included (measured:
            # adding the offset again misses the truth by the offset), one trigger delay past
            # the contact.
            touched = probed[axis] - direction * TRIGGER_DELAY_MM
            measured_um = (face - touched) * 1000.0
            position = list(point)
            position[axis] = probed[axis]
            hand_to_truepos(axis, position, measured_um)
            events.append({
                "machine_time_s": t, "wall_s": time.monotonic() - clock["t0"], "axis": axis,
                "probed_mm": probed, "eoffset_mm": eoffset, "measured_um": measured_um,
                "true_um": true_error_um(axis, t), "point_mm": point,
                "offset_um": [hal.get_value(f"truepos.axis.{a}.offset-um") for a in AXES],
            })
            n = len(events)
            if n >= reid["next_at"] and reid["reload_wall"] is None and (
                    reid["thread"] is None or not reid["thread"].is_alive()):
                if len(reid["runs"]) >= 3:
                    raise SystemExit("probe_loop: three re-identifications kept the model")
                reid["next_at"] = 10**9
                reid["thread"] = threading.Thread(target=reidentify, args=(n,))
                reid["thread"].start()
        if s.interp_state == linuxcnc.INTERP_IDLE and time.monotonic() - clock["t0"] > 2.0:
            break
        if time.monotonic() - clock["t0"] > 400:
            raise SystemExit("probe_loop: program did not finish in 400 s")
        time.sleep(0.002)
    log(f"program finished after {machine_time():.1f} s; {len(events)} touches")
    if reid["thread"] is not None:
        reid["thread"].join(60)
    if reid["reload_wall"] is None:
        log("no re-identified model was taken")
        failed = True
    if s.task_state != linuxcnc.STATE_ON or len(events) == 0:
        failed = True
    time.sleep(1.0)
except SystemExit as e:
    print(e, flush=True)
    failed = True
except KeyboardInterrupt:  # LinuxCNC shutting down under us (another instance started)
    log("interrupted")
    failed = True
except Exception as e:  # report, then let LinuxCNC shut down
    log(f"error: {e!r}")
    failed = True
finally:
    try:
        subprocess.run(["halcmd", "sets", "sample-enable", "0"], check=True)
    except Exception:
        pass
    time.sleep(0.5)
    for p, f in samplers:
        p.terminate()
        p.wait(5)
        f.close()
    clock["stop"] = True
    with open(os.path.join(out, "probe_events.json"), "w") as fo:
        json.dump({"events": events, "reidentify": reid["runs"],
                   "reload_machine_time_s": reid.get("reload_machine_time_s"),
                   "trigger_delay_mm": TRIGGER_DELAY_MM,
                   "servo_period_s": SERVO_PERIOD_S}, fo, indent=1)
    with open(os.path.join(out, "probe_result.txt"), "w") as r:
        r.write("FAIL\n" if failed else "PASS\n")
    log("FAIL" if failed else "done")
    c.state(linuxcnc.STATE_OFF)
    time.sleep(0.5)
sys.exit(1 if failed else 0)
