#!/usr/bin/env bash
# Issue 14's development benchmark: a population of twin machines and scenarios, generated from
# seeds (scripts/fit_population.py), each simulated with `truepos sim` and fitted with `truepos
# fit` at its defaults (only --run/--target/--inputs/--time/--split). Prints a Markdown table
# (per case: test RMSE, uncompensated, reduction, inner-CV estimate / test, runs made worse)
# and one JSON summary line. docs/fitting.md ("Development benchmark: the twin population").
#
#   bash scripts/fit_population.sh [--size ci|full] [--assert] [--static] [--only NAME] [--fit-args='ARGS']
#
# --size ci (default): 25 cases, shorter days (the test command runs it);
# full: 47 cases (docs/fitting.md's table). --static adds the static regression's test RMSE per
# case as a reference (a second fit each, not at the defaults). --assert exits 1 unless the issue's
# bars hold (median reduction ≥ 85 %, no run made worse, median inner/test within 1.5): the test
# command runs the ci size with it; the full size meets them too (docs/fitting.md).
# FIT_POPULATION_ASSERT=1 in the environment is the same as --assert. The generated runs go to
# target/fit-population/<size>/ (never committed).
set -euo pipefail
cd "$(dirname "$0")/.."
size=ci
args=()
while [ $# -gt 0 ]; do
  case "$1" in
    --size) size="${2:-}"; shift; [ $# -gt 0 ] && shift ;;
    --size=*) size="${1#--size=}"; shift ;;
    *) args+=("$1"); shift ;;
  esac
done
if [ "${FIT_POPULATION_ASSERT:-0}" = 1 ]; then args+=(--assert); fi
case "$size" in ci|full) ;; *) echo "fit_population: --size ci|full, got '$size'" >&2; exit 2 ;; esac
cargo build --quiet --release -p truepos >&2
target="${CARGO_TARGET_DIR:-target}"
work="$target/fit-population/$size"
rm -rf "$work"
mkdir -p "$work"
python3 scripts/fit_population.py --size "$size" --binary "$target/release/truepos" \
  --work "$work" ${args[@]+"${args[@]}"}
