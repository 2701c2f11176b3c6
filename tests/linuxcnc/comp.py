#!/usr/bin/python3
"""The COMP_FILE check's "display" (tests/linuxcnc/comp.ini, run by scripts/linuxcnc_comp.sh):
machine on, home, then MDI moves of X and Y together through the table's support points and
between them, forward to 400 mm and back to 0, while halsampler records every servo cycle into
OUT/comp_samples.txt. Writes OUT/comp_result.txt (PASS/FAIL); the comparison with truepos is
the script's."""
import configparser
import os
import subprocess
import sys
import time

import linuxcnc

import harness


def log(msg):
    print(f"comp: {msg}", flush=True)


ini_path = sys.argv[sys.argv.index("-ini") + 1]
ini = configparser.ConfigParser(strict=False, interpolation=None)
ini.read(ini_path)
out = ini["TRUEPOS"]["OUT"]
s = linuxcnc.stat()
c = linuxcnc.command()


wait = harness.waiter(s, "comp")


def move(x, feed):
    c.mdi(f"G1 X{x} Y{x} F{feed}")
    c.wait_complete()
    wait(f"move to {x}", lambda: s.interp_state == linuxcnc.INTERP_IDLE and s.inpos, 60.0)


# Forward through every support point and between them (the interpolation), a stop at 400,
# then in reverse; a short stop at each target shows what motion holds at standstill.
FORWARD = [20, 40, 70, 100, 145, 180, 215, 250, 290, 330, 365, 400]
REVERSE = [380, 330, 300, 250, 210, 180, 140, 100, 55, 40, 10, 0]
failed = False
sampler = None
try:
    c.state(linuxcnc.STATE_ESTOP_RESET)
    c.state(linuxcnc.STATE_ON)
    wait("machine on", lambda: s.task_state == linuxcnc.STATE_ON)
    c.home(-1)
    wait("homing", lambda: all(s.homed[:2]))
    c.mode(linuxcnc.MODE_MDI)
    c.wait_complete()
    f = open(os.path.join(out, "comp_samples.txt"), "w")
    sampler = (subprocess.Popen(["halsampler", "-t", "-c", "0"], stdout=f), f)
    time.sleep(0.3)
    subprocess.run(["halcmd", "sets", "sample-enable", "1"], check=True)
    started = time.time()
    for x in FORWARD + REVERSE:
        move(x, 3000)
        time.sleep(0.05)
    log(f"moves done in {time.time() - started:.1f} s")
except SystemExit as e:
    print(e, flush=True)
    failed = True
except Exception as e:  # report, then let LinuxCNC shut down
    log(f"error: {e!r}")
    failed = True
finally:
    try:
        subprocess.run(["halcmd", "sets", "sample-enable", "0"], check=True)
    except Exception:
        failed = True
    time.sleep(0.3)
    if sampler:
        sampler[0].terminate()
        sampler[0].wait(5)
        sampler[1].close()
    with open(os.path.join(out, "comp_result.txt"), "w") as r:
        r.write("FAIL\n" if failed else "PASS\n")
    log("FAIL" if failed else "done")
    c.state(linuxcnc.STATE_OFF)
    time.sleep(0.3)
sys.exit(1 if failed else 0)
