"""What the display programs of the headless LinuxCNC tests share (e2e.py, probe_loop.py,
comp.py; each started by scripts/linuxcnc_headless.sh): real-time priority for the simulator's
threads, and waiting on LinuxCNC's status with a deadline."""

import subprocess
import time


def realtime_priority(log):
    """Without a PREEMPT_RT kernel LinuxCNC's uspace servo thread runs with normal scheduling
    ("POSIX non-realtime") and catches up in bursts after the host holds it up: give the
    simulator's threads SCHED_FIFO 60 like a real control has (truepos-hal takes priority 50)."""
    rtapi = subprocess.run(["pgrep", "-x", "rtapi_app"], capture_output=True,
                           text=True).stdout.split()
    for pid in rtapi:
        if subprocess.run(["chrt", "-a", "-f", "-p", "60", pid]).returncode == 0:
            log(f"rtapi_app {pid}: SCHED_FIFO 60")


def waiter(stat, name, period_s=0.01):
    """`wait(what, cond, timeout)`: polls `stat` every `period_s` until `cond()` holds; past the
    timeout the test ends with `<name>: timeout waiting for <what>`."""
    def wait(what, cond, timeout=30.0):
        end = time.time() + timeout
        while time.time() < end:
            stat.poll()
            if cond():
                return
            time.sleep(period_s)
        raise SystemExit(f"{name}: timeout waiting for {what}")
    return wait
