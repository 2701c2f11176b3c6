#!/usr/bin/python3
"""Stand-in for the Mesa card in scripts/linuxcnc_sensors_hal.sh: a HAL component named
hm2_7i92.0 whose pins carry the real driver's names (hm2_7i92.0.7i76.0.0.analogin0…3, volts), so
that tests/linuxcnc/sensors.hal.in loads unchanged without the hardware. The volts are given on
the command line; the component holds them until it is unloaded."""
import sys
import time

import hal

volts = [float(v) for v in sys.argv[1].split(",")]
c = hal.component("hm2_7i92.0")
for k in range(len(volts)):
    c.newpin(f"7i76.0.0.analogin{k}", hal.HAL_FLOAT, hal.HAL_OUT)
c.ready()
for k, v in enumerate(volts):
    c[f"7i76.0.0.analogin{k}"] = v
try:
    while True:
        time.sleep(0.2)
except KeyboardInterrupt:
    pass
