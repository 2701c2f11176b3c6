#!/usr/bin/env python3
"""Writes run.csv: a made-up but plausible 4-hour warm-up of the 3-axis VMC, every 60 s.

The spindle runs at 8000 1/min for 3 h, then stops; the axes sweep their travel; slides warm
underneath (drives and guides) faster than on top; the room warms by 1 K. Deterministic: no
random numbers, so the file is reproducible byte for byte.
"""
import math

SENSORS = [
    "x_slide_top", "x_slide_bottom", "y_slide_top", "y_slide_bottom", "z_slide_front",
    "z_slide_rear", "column_front", "column_rear", "bed_top", "bed_bottom",
    "spindle_front_bearing", "spindle_rear_bearing", "spindle_motor", "head_left", "head_right",
    "ambient",
]
# steady-state rise in K while running, time constant in minutes
RISE = {
    "x_slide_top": (2.0, 50), "x_slide_bottom": (6.0, 35), "y_slide_top": (1.5, 60),
    "y_slide_bottom": (5.0, 40), "z_slide_front": (1.8, 45), "z_slide_rear": (4.5, 35),
    "column_front": (1.0, 90), "column_rear": (2.2, 80), "bed_top": (0.8, 120),
    "bed_bottom": (0.3, 150), "spindle_front_bearing": (14.0, 20),
    "spindle_rear_bearing": (9.0, 25), "spindle_motor": (18.0, 15), "head_left": (4.0, 40),
    "head_right": (3.0, 45), "ambient": (0.0, 1),
}


def main():
    run_s, end_s, step_s = 3 * 3600, 4 * 3600, 60
    with open("run.csv", "w") as f:
        f.write("time_s,X_mm,Y_mm,Z_mm," + ",".join(SENSORS) + ",spindle_rpm,x_feed,y_feed,z_feed\n")
        for t in range(0, end_s + 1, step_s):
            m = t / 60.0
            x = 400.0 + 400.0 * math.sin(2 * math.pi * m / 37.0)
            y = 250.0 + 250.0 * math.sin(2 * math.pi * m / 23.0 + 1.0)
            z = 250.0 + 250.0 * math.cos(2 * math.pi * m / 29.0)
            ambient = 20.0 + 1.0 * (1 - math.exp(-m / 120.0))
            temps = []
            for s in SENSORS:
                rise, tau = RISE[s]
                if t <= run_s:
                    dt = rise * (1 - math.exp(-m / tau))
                else:
                    peak = rise * (1 - math.exp(-run_s / 60.0 / tau))
                    dt = peak * math.exp(-(m - run_s / 60.0) / tau)
                temps.append(ambient + dt)
            rpm = 8000 if t <= run_s else 0
            feeds = (2000, 1500, 1000) if t <= run_s else (0, 0, 0)
            row = [t, x, y, z] + temps + [rpm, *feeds]
            f.write(",".join(f"{v:.4f}" if isinstance(v, float) else str(v) for v in row) + "\n")


if __name__ == "__main__":
    main()
