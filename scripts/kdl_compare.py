#!/usr/bin/python3
"""truepos's kinematics side by side with Orocos KDL (python3-pykdl).

For each example machine the script
1. builds the same nominal chain in KDL from `truepos kin chain --json`,
2. draws random axis positions inside travel and checks that truepos's forward transform
   (`truepos kin fwd --nominal`) and KDL's ChainFkSolverPos_recursive agree within 1e-9 mm
   (TCP) and 1e-12 (tool direction),
3. times KDL's ChainIkSolverPos_NR (with ChainIkSolverVel_pinv, 100 iterations, eps 1e-6)
   on the nominal poses of those samples, seeded 0.5 mm / 0.5° away from the true set-points,
   and truepos's compensated inverse transform (`truepos kin inv`: closed form + Newton through
   every error table to 5e-7 mm / 5e-7 rad, no seed: each row starts from the previous row's
   result) on the poses the real chain reaches at the same samples. Throughputs are the median
   over chunks of 1000 targets (robust to other processes), and both sides are timed --repeats
   times, alternately, the fastest repeat of each side counting, as `timeit` does: on a shared
   machine interference only ever slows a run down, and truepos's solve lasts ~50 ms, so one busy
   moment would otherwise decide the ratio. Every repeat's rate is in the --json output; the
   total-time ratio is reported too.

Usage: /usr/bin/python3 scripts/kdl_compare.py [--points N] [--truepos PATH] [--json]
          [--min-ratio R] [--repeats N]
Exit status 1 if forward results disagree, a truepos target does not converge, or the
throughput ratio is below --min-ratio (default 0: report only).
"""

import argparse
import json
import math
import os
import random
import subprocess
import sys
import tempfile
import time

import PyKDL as K

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
MACHINES = ["head-ac", "table-ac", "head-bc", "vmc-21"]
TOOL = 100.0


def unit(dof):
    return {"X": K.Vector(1, 0, 0), "Y": K.Vector(0, 1, 0), "Z": K.Vector(0, 0, 1),
            "A": K.Vector(1, 0, 0), "B": K.Vector(0, 1, 0), "C": K.Vector(0, 0, 1)}[dof]


def fixed_frame(dof, value):
    """A fixed row: translation in mm or rotation in degrees."""
    if dof in "XYZ":
        return K.Frame(unit(dof) * value)
    rot = {"A": K.Rotation.RotX, "B": K.Rotation.RotY, "C": K.Rotation.RotZ}[dof]
    return K.Frame(rot(math.radians(value)))


def build_chain(desc):
    """truepos rows map frame i (tool side) to i+1; the pose is M_{n-1}...M_0. KDL multiplies
    segments from the base: segment k is row n-1-k. Returns the chain and, per KDL joint, the
    truepos axis index."""
    chain = K.Chain()
    joint_axes = []
    joint_type = {"X": K.Joint.TransX, "Y": K.Joint.TransY, "Z": K.Joint.TransZ,
                  "A": K.Joint.RotX, "B": K.Joint.RotY, "C": K.Joint.RotZ}
    for row in reversed(desc["rows"]):
        key, dof = row["key"], row["dof"]
        if key == "axis":
            chain.addSegment(K.Segment(K.Joint(joint_type[dof], row["sign"]), K.Frame.Identity()))
            joint_axes.append(row["axis"])
        elif key == "tool":
            chain.addSegment(K.Segment(K.Joint(K.Joint.Fixed),
                                       fixed_frame(dof, row["sign"] * TOOL + row["offset"])))
        else:  # fixed, or an error row's nominal part
            chain.addSegment(K.Segment(K.Joint(K.Joint.Fixed), fixed_frame(dof, row["value"])))
    return chain, joint_axes


def run(cmd):
    out = subprocess.run(cmd, capture_output=True, text=True)
    if out.returncode != 0:
        sys.exit(f"{' '.join(cmd)} failed:\n{out.stdout}\n{out.stderr}")
    return out.stdout


def sample(desc, rng):
    q = []
    for a in desc["axes"]:
        lo, hi = a["travel"]
        if a["kind"] == "linear":
            lo, hi = 0.7 * lo + 0.3 * hi, 0.7 * hi + 0.3 * lo
        else:
            lo, hi = max(lo, -90.0), min(hi, 90.0)
        q.append(rng.uniform(lo, hi))
    return q


def median(values):
    v = sorted(values)
    return v[len(v) // 2]


def compare(machine, points, truepos, tmp, repeats):
    d = os.path.join(ROOT, "examples", "kinematics", machine)
    ktab = os.path.join(d, "kinematics.ktab")
    desc = json.loads(run([truepos, "kin", "chain", "--kinematics", ktab]))
    chain, joint_axes = build_chain(desc)
    names = [a["name"] for a in desc["axes"]]
    rotary = [a["kind"] == "rotary" for a in desc["axes"]]
    rng = random.Random(20261121)
    qs = [sample(desc, rng) for _ in range(points)]
    axes_csv = os.path.join(tmp, f"{machine}.axes.csv")
    with open(axes_csv, "w") as f:
        f.write(",".join(names) + "\n")
        for q in qs:
            f.write(",".join(repr(v) for v in q) + "\n")

    # 1. Forward, nominal: truepos vs KDL.
    poses_csv = os.path.join(tmp, f"{machine}.poses.csv")
    fwd = json.loads(run([truepos, "kin", "fwd", "--kinematics", ktab, "--nominal",
                          "--tool-length", str(TOOL), "--input", axes_csv,
                          "--output", poses_csv, "--json"]))
    with open(poses_csv) as f:
        next(f)
        tp = [list(map(float, line.split(","))) for line in f]
    fk = K.ChainFkSolverPos_recursive(chain)
    nj = chain.getNrOfJoints()

    def kdl_q(q):
        j = K.JntArray(nj)
        for k, ax in enumerate(joint_axes):
            j[k] = math.radians(q[ax]) if rotary[ax] else q[ax]
        return j

    frames = []
    max_dp = max_dd = 0.0
    for q, p in zip(qs, tp):
        fr = K.Frame()
        fk.JntToCart(kdl_q(q), fr)
        frames.append(fr)
        z = fr.M.UnitZ()
        max_dp = max(max_dp, max(abs(fr.p[i] - p[i]) for i in range(3)))
        max_dd = max(max_dd, max(abs(z[i] - p[3 + i]) for i in range(3)))

    # 2. KDL inverse (nominal chain), seeded near the true set-points.
    ikv = K.ChainIkSolverVel_pinv(chain)
    ik = K.ChainIkSolverPos_NR(chain, fk, ikv, 100, 1e-6)
    seeds = []
    for q in qs:
        seeds.append(kdl_q([v + 0.5 for v in q]))
    out = K.JntArray(nj)

    def time_kdl():
        # Total time, and the rate of every chunk of 1000 targets: the median chunk is robust
        # to other processes taking the core for a while (truepos reports the same statistic).
        ok = 0
        rates = []
        t0 = time.perf_counter()
        tc = t0
        for i, (fr, seed) in enumerate(zip(frames, seeds)):
            if i > 0 and i % 1000 == 0:
                now = time.perf_counter()
                rates.append(1000 / (now - tc))
                tc = now
            if ik.CartToJnt(seed, fr, out) >= 0:
                ok += 1
        total = time.perf_counter() - t0
        return ok, total, median(rates) if rates else points / total

    # 3. truepos inverse through every error table. Its targets are the poses the real
    # (erroneous) chain reaches at the same axis samples: a nominal pose can lie a few µrad
    # outside what the real machine can reach (at the pole, a tilt in the plane of the swivel
    # axis cannot be undone), which would test reachability rather than the solver.
    actual_csv = os.path.join(tmp, f"{machine}.actual.csv")
    run([truepos, "kin", "fwd", "--kinematics", ktab, "--tool-length", str(TOOL),
         "--input", axes_csv, "--output", actual_csv, "--json"])

    def time_truepos():
        return json.loads(run([truepos, "kin", "inv", "--kinematics", ktab,
                               "--tool-length", str(TOOL), "--input", actual_csv,
                               "--output", os.path.join(tmp, f"{machine}.inv.csv"), "--json"]))

    # Both sides alternately, `repeats` times; the fastest repeat of each side counts.
    kdl_runs, inv_runs = [], []
    for _ in range(max(1, repeats)):
        kdl_runs.append(time_kdl())
        inv_runs.append(time_truepos())
    kdl_ok = min(r[0] for r in kdl_runs)
    kdl_s = min(r[1] for r in kdl_runs)
    kdl_median = max(r[2] for r in kdl_runs)
    inv = max(inv_runs, key=lambda r: r["median_chunk_points_per_second"])
    inv_converged = min(r["converged"] for r in inv_runs)
    return {
        "machine": machine,
        "points": points,
        "forward_max_tcp_difference_mm": max_dp,
        "forward_max_direction_difference": max_dd,
        "truepos_forward_points_per_second": fwd["points_per_second"],
        "kdl_ik_seconds": kdl_s,
        "kdl_ik_points_per_second": points / kdl_s,
        "kdl_ik_converged": kdl_ok,
        "truepos_inverse_seconds": inv["solve_seconds"],
        "truepos_inverse_points_per_second": inv["points_per_second"],
        "truepos_inverse_converged": inv_converged,
        "repeats": len(inv_runs),
        "kdl_ik_median_chunk_points_per_second_each_repeat": [r[2] for r in kdl_runs],
        "truepos_inverse_median_chunk_points_per_second_each_repeat": [
            r["median_chunk_points_per_second"] for r in inv_runs],
        "truepos_max_position_residual_mm": inv["max_position_residual_mm"],
        "truepos_max_direction_residual_rad": inv["max_direction_residual_rad"],
        "kdl_ik_median_chunk_points_per_second": kdl_median,
        "truepos_inverse_median_chunk_points_per_second": inv["median_chunk_points_per_second"],
        "throughput_ratio_total": (points / inv["solve_seconds"]) / (points / kdl_s),
        "throughput_ratio": inv["median_chunk_points_per_second"] / kdl_median,
    }


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--points", type=int, default=100_000)
    ap.add_argument("--truepos", default=os.path.join(ROOT, "target", "release", "truepos"))
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--min-ratio", type=float, default=0.0)
    ap.add_argument("--machines", default=",".join(MACHINES))
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args()
    failed = []
    results = []
    with tempfile.TemporaryDirectory() as tmp:
        for m in args.machines.split(","):
            r = compare(m, args.points, args.truepos, tmp, args.repeats)
            results.append(r)
            if r["forward_max_tcp_difference_mm"] > 1e-9 or r["forward_max_direction_difference"] > 1e-12:
                failed.append(f"{m}: forward results differ from KDL")
            if r["truepos_inverse_converged"] != r["points"]:
                failed.append(f"{m}: {r['points'] - r['truepos_inverse_converged']} targets did not converge")
            if r["throughput_ratio"] < args.min_ratio:
                failed.append(f"{m}: throughput ratio {r['throughput_ratio']:.1f} < {args.min_ratio}")
    if args.json:
        print(json.dumps({"results": results, "failures": failed}, indent=1))
    else:
        print("throughputs are the median over chunks of 1000 targets, fastest of "
              f"{args.repeats} alternating repeats per side (total-time ratio in brackets)")
        print(f"{'machine':10s} {'fwd Δ mm':>9s} {'KDL IK/s':>10s} {'conv':>7s} "
              f"{'truepos inv/s':>13s} {'conv':>7s} {'ratio':>6s} {'(total)':>8s} {'fwd/s':>10s}")
        for r in results:
            print(f"{r['machine']:10s} {r['forward_max_tcp_difference_mm']:9.1e} "
                  f"{r['kdl_ik_median_chunk_points_per_second']:10.0f} {r['kdl_ik_converged']:7d} "
                  f"{r['truepos_inverse_median_chunk_points_per_second']:13.0f} "
                  f"{r['truepos_inverse_converged']:7d} "
                  f"{r['throughput_ratio']:6.1f} {r['throughput_ratio_total']:8.1f} "
                  f"{r['truepos_forward_points_per_second']:10.0f}")
        for f in failed:
            print("FAIL:", f)
    sys.exit(1 if failed else 0)


if __name__ == "__main__":
    main()
