#!/usr/bin/env bash
# The speed benchmarks of this tree and of an older revision, side by side in one run, so a
# refactor can show it cost no speed (issue 12): one evaluated control cycle
# (`evaluate`), the kinematics transforms (`kinematics`) and a simulated twin day (`day`).
# Each benchmark runs old, new, old, new (ROUNDS, default 2) so a change of the host's load
# falls on both sides alike. The benches are found by file name wherever they live in either
# tree (crates move between revisions).
#
#   bash scripts/bench_side_by_side.sh 8fc3f44          # the revision before issue 12
#   BENCHES="evaluate day" ROUNDS=1 bash scripts/bench_side_by_side.sh HEAD~5
#   BUILD_ONLY=1 bash scripts/bench_side_by_side.sh 8fc3f44  # build both sides now, run later
#
# Not part of scripts/test.sh or .ci/run: it builds two trees in release (about 10 minutes on
# two cores) and its figures are the host's as much as ours.
set -euo pipefail
cd "$(dirname "$0")/.."
old_rev=${1:?usage: bench_side_by_side.sh OLD_REVISION}
benches=${BENCHES:-evaluate kinematics day}
rounds=${ROUNDS:-2}
new_tree=$(pwd)
target=$(cargo metadata --format-version 1 --no-deps | python3 -c 'import json,sys; print(json.load(sys.stdin)["target_directory"])')
old_tree="$target/bench-old-tree"
old_target="$target/bench-old-target"

# The old tree stays (under target/, ignored) so a second run reuses its build; it is made
# again only for another revision.
git worktree prune
if [ "$(git -C "$old_tree" rev-parse HEAD 2>/dev/null)" != "$(git rev-parse "$old_rev^{commit}")" ]; then
  git worktree remove --force "$old_tree" >/dev/null 2>&1 || rm -rf "$old_tree"
  git worktree prune
  git worktree add --detach "$old_tree" "$old_rev" >/dev/null
fi

# The package whose benches/NAME.rs exists in TREE (empty when none does).
package_of() {
  local tree=$1 name=$2 file
  file=$(cd "$tree" && ls crates/*/benches/"$name".rs 2>/dev/null | head -1)
  [ -n "$file" ] || return 0
  sed -n 's/^name = "\(.*\)"/\1/p' "$tree/$(dirname "$(dirname "$file")")/Cargo.toml" | head -1
}

run_bench() {
  local side=$1 tree=$2 dir=$3 name=$4 package
  package=$(package_of "$tree" "$name")
  if [ -z "$package" ]; then
    echo "== $name ($side): no benches/$name.rs in this tree"
    return
  fi
  echo "== $name ($side, $package @ $(git -C "$tree" rev-parse --short HEAD))"
  (cd "$tree" && CARGO_TARGET_DIR=$dir cargo bench -q -p "$package" --bench "$name" 2>/dev/null)
}

for name in $benches; do
  for side in old new; do
    tree=$new_tree; dir=$target
    [ "$side" = old ] && { tree=$old_tree; dir=$old_target; }
    package=$(package_of "$tree" "$name")
    [ -n "$package" ] && (cd "$tree" && CARGO_TARGET_DIR=$dir cargo bench -q --no-run -p "$package" --bench "$name" >/dev/null 2>&1)
  done
done

[ -n "${BUILD_ONLY:-}" ] && exit 0

for name in $benches; do
  for round in $(seq "$rounds"); do
    run_bench old "$old_tree" "$old_target" "$name"
    run_bench new "$new_tree" "$target" "$name"
  done
done
