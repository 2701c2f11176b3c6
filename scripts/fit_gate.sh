#!/usr/bin/env bash
# The development gate (scripts/fit_gate.py; docs/fitting.md, "The development gate"): the fit's
# defaults in this tree against a base, paired run by run on a twin population drawn afresh,
# with a bootstrap confidence interval, and FL_THERMAL per channel beside it.
#
#   bash scripts/fit_gate.sh [--base-rev REV] [--size ci|full] [--draw N] [--cases N] [--assert]
#                            [--base-args='ARGS']
#
# --base-rev REV: the base is the binary built from that revision (e.g. main before the change);
# without it the base is this tree's own binary at --base-args, by default the simple baseline
# (`--family baseline`), which is what the test command asserts the defaults never lose to.
set -euo pipefail
cd "$(dirname "$0")/.."
rev=""
args=()
while [ $# -gt 0 ]; do
  case "$1" in
    --base-rev) rev="${2:-}"; shift; [ $# -gt 0 ] && shift ;;
    --base-rev=*) rev="${1#--base-rev=}"; shift ;;
    *) args+=("$1"); shift ;;
  esac
done
target="${CARGO_TARGET_DIR:-target}"
gate="$target/fit-gate"
mkdir -p "$gate"
cargo build --quiet --release -p truepos >&2
cp "$target/release/truepos" "$gate/candidate"
base="$gate/candidate"
base_args=(--base-args="--family baseline")
if [ -n "$rev" ]; then
  src="$gate/base-src"
  git worktree remove --force "$src" 2>/dev/null || rm -rf "$src"
  git worktree add --detach "$src" "$rev" >&2
  # Same target folder: the dependencies are built once; the base's own crates sit beside.
  CARGO_TARGET_DIR="$PWD/$target" cargo build --quiet --release -p truepos \
    --manifest-path "$src/Cargo.toml" >&2
  cp "$target/release/truepos" "$gate/base"
  cp "$gate/candidate" "$target/release/truepos"
  git worktree remove --force "$src"
  base="$gate/base"
  base_args=()
fi
FL="${FL_THERMAL:-../shared/data/fl_thermal/fl_thermal.csv}"
work="$gate/work"
rm -rf "$work"
mkdir -p "$work"
python3 scripts/fit_gate.py --candidate "$gate/candidate" --base "$base" --work "$work" \
  --fl "$FL" ${base_args[@]+"${base_args[@]}"} ${args[@]+"${args[@]}"}
