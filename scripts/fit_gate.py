#!/usr/bin/env python3
"""The development gate: a change to the fit's defaults against a base, paired run by run.

A change becomes a default only when this gate says better with a confidence interval
(docs/fitting.md, "The development gate"). It draws a twin population afresh — seeds offset by
a draw the change was not developed on (the development population is draw 0) — simulates each
case once, fits it with both binaries (each at its defaults, or the base with --base-args),
and pairs the held-out runs: per run, the candidate's test RMSE minus the base's. The mean
difference gets a 95 % confidence interval by a bootstrap over cases (a case's runs share a
machine, so cases, not runs, are the independent units). FL_THERMAL's channels are fitted by
both and reported beside it.

Prints a Markdown table per run, the FL_THERMAL channels and one JSON summary line. With
--assert it exits 1 when the interval says the candidate is worse than the base (its lower
bound above zero): the test command runs it so against the simple baseline
(`--base-args='--family baseline'`), so the defaults may never be shown worse than the plain
reference.

    fit_gate.py --candidate BIN --base BIN --work DIR [--size ci|full] [--draw N]
                [--base-args ARGS] [--cases N] [--fl CSV] [--assert]
"""

import argparse
import json
import os
import random
import shlex
import statistics
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import fit_population as fp  # noqa: E402

BOOTSTRAP = 2000


def simulate(c, binary, work):
    """The case's runs as CSV files (simulated once, fitted by both binaries)."""
    d = os.path.join(work, c["name"])
    os.makedirs(d, exist_ok=True)
    twin = os.path.join(d, "twin.toml")
    with open(twin, "w") as f:
        f.write(c["machine"])
    csvs = []
    for i, (text, seed) in enumerate(c["runs"]):
        sc = os.path.join(d, f"run{i + 1}.toml")
        with open(sc, "w") as f:
            f.write(text)
        out = os.path.join(d, f"run{i + 1}.csv")
        fp.call([binary, "sim", "--twin", twin, "--scenario", sc, "--seed", str(seed), "-o", out])
        csvs.append(out)
    return csvs


def per_run(binary, c, csvs, extra):
    """{run name: (test RMSE, uncompensated RMSE)} of the case's first target."""
    cmd = [binary, "fit"]
    for p in csvs:
        cmd += ["--run", p]
    cmd += ["--target", c["target"], "--inputs", ",".join(c["inputs"]), "--time", "time_s",
            "--split", c["split"], "--json"] + list(extra)
    v = json.loads(fp.call(cmd))["validation"]
    out = {}
    for r in v["per_run"]:
        t = r["targets"][0]
        out[os.path.basename(r["run"])] = (t["rmse_um"], t["uncompensated_rmse_um"])
    return out


def bootstrap(groups, stat, rng):
    """95 % percentile interval of stat over case-level resamples of `groups`."""
    values = []
    for _ in range(BOOTSTRAP):
        sample = [x for _ in groups for x in rng.choice(groups)]
        values.append(stat(sample))
    values.sort()
    return values[int(0.025 * BOOTSTRAP)], values[int(0.975 * BOOTSTRAP) - 1]


def fl_thermal(path, candidate, base, base_extra):
    """Per channel (candidate, base) test RMSE on FL_THERMAL, chrono 60/40."""
    cmd = ["fit", "--run", path, "--target", "ch*_um", "--inputs", "t*_c,spindle_rpm",
           "--time", "time_s", "--split", "chrono:0.6", "--json"]
    a = json.loads(fp.call([candidate] + cmd))["validation"]["metrics"]
    b = json.loads(fp.call([base] + cmd + list(base_extra)))["validation"]["metrics"]
    return {m["target"]: (m["rmse_um"], n["rmse_um"]) for m, n in zip(a, b)}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--candidate", required=True, help="the binary with the change")
    ap.add_argument("--base", required=True, help="the binary to compare with (main's)")
    ap.add_argument("--base-args", default="", help="options for the base's fits")
    ap.add_argument("--work", required=True)
    ap.add_argument("--size", choices=["ci", "full"], default="ci")
    ap.add_argument("--draw", type=int, help="population draw ≥ 1 (default: a fresh one)")
    ap.add_argument("--cases", type=int, help="use only the first N cases of each kind cycle")
    ap.add_argument("--fl", help="FL_THERMAL CSV, fitted by both")
    ap.add_argument("--assert", dest="check", action="store_true",
                    help="exit 1 when the interval says the candidate is worse")
    a = ap.parse_args()
    draw = a.draw if a.draw is not None else random.SystemRandom().randrange(1, 10_000)
    if draw < 1:
        sys.exit("fit_gate: --draw must be at least 1 (draw 0 is the development population)")
    base_extra = shlex.split(a.base_args)
    cases = fp.population(a.size, draw * fp.SEED_STRIDE, gate=True)
    if a.cases:
        cases = [cases[i] for i in range(0, len(cases), max(1, len(cases) // a.cases))][:a.cases]
    t0 = time.monotonic()
    groups, lines = [], []
    for c in cases:
        print(f"{c['name']} (draw {draw}): simulating, fitting twice", file=sys.stderr)
        csvs = simulate(c, a.candidate, a.work)
        new = per_run(a.candidate, c, csvs, [])
        old = per_run(a.base, c, csvs, base_extra)
        pairs = []
        for run, (rmse, unc) in new.items():
            if run in old:
                pairs.append((rmse - old[run][0], (rmse - old[run][0]) / max(unc, 1e-9),
                              c["kind"], rmse > unc, old[run][0] > unc))
                lines.append(f"| {c['name']} | {run} | {unc:.2f} | {old[run][0]:.2f} "
                             f"| {rmse:.2f} | {rmse - old[run][0]:+.2f} |")
        groups.append(pairs)
    groups = [g for g in groups if g]
    rng = random.Random(draw)
    flat = [p for g in groups for p in g]
    mean_um = statistics.fmean(p[0] for p in flat)
    mean_rel = statistics.fmean(p[1] for p in flat)
    ci_um = bootstrap(groups, lambda s: statistics.fmean(p[0] for p in s), rng)
    ci_rel = bootstrap(groups, lambda s: statistics.fmean(p[1] for p in s), rng)
    verdict = "better" if ci_um[1] < 0 else "worse" if ci_um[0] > 0 else "no clear difference"
    summary = {
        "benchmark": "development gate: candidate − base, per held-out run, fresh twin draw",
        "draw": draw, "size": a.size, "cases": len(groups), "runs": len(flat),
        "base_args": a.base_args,
        "mean_difference_um": round(mean_um, 3),
        "ci95_um": [round(x, 3) for x in ci_um],
        "mean_difference_of_uncompensated": round(mean_rel, 4),
        "ci95_of_uncompensated": [round(x, 4) for x in ci_rel],
        "candidate_better_runs": sum(p[0] < 0 for p in flat),
        "base_better_runs": sum(p[0] > 0 for p in flat),
        "candidate_runs_made_worse": sum(p[3] for p in flat),
        "base_runs_made_worse": sum(p[4] for p in flat),
        "mean_difference_um_per_kind": {
            k: round(statistics.fmean(p[0] for p in flat if p[2] == k), 3)
            for k in dict.fromkeys(p[2] for p in flat)},
        "verdict": verdict,
        "seconds": round(time.monotonic() - t0, 1),
    }
    print("| case | run | uncompensated µm | base µm | candidate µm | difference µm |")
    print("|---|---|---|---|---|---|")
    print("\n".join(lines))
    if a.fl:
        fl = fl_thermal(a.fl, a.candidate, a.base, base_extra)
        summary["fl_thermal_um"] = {k: {"candidate": round(x, 3), "base": round(y, 3)}
                                    for k, (x, y) in fl.items()}
        print("\nFL_THERMAL (chrono 60/40): " + ", ".join(
            f"{k} {x:.2f} (base {y:.2f})" for k, (x, y) in fl.items()))
    print(f"\nmean difference {mean_um:+.3f} µm, 95 % CI [{ci_um[0]:+.3f}, {ci_um[1]:+.3f}] µm "
          f"({mean_rel:+.2%} of uncompensated, CI [{ci_rel[0]:+.2%}, {ci_rel[1]:+.2%}]) over "
          f"{len(flat)} runs of {len(groups)} cases, draw {draw}: {verdict}; runs made worse: "
          f"candidate {summary['candidate_runs_made_worse']}, base {summary['base_runs_made_worse']}")
    print("per kind (mean difference µm): " + ", ".join(
        f"{k} {v:+.2f}" for k, v in summary["mean_difference_um_per_kind"].items()))
    print(json.dumps(summary, ensure_ascii=False))
    if a.check and verdict == "worse":
        sys.exit("fit_gate: the candidate is worse than the base (the interval is above zero)")


if __name__ == "__main__":
    main()
