#!/usr/bin/env bash
# Issue 5's peer check: truepos's kinematics side by side with Orocos KDL.
# Installs python3-pykdl (Debian) if missing, builds truepos in release, and runs
# scripts/kdl_compare.py: forward results must agree with KDL within 1e-9 mm, every target of
# truepos's compensated inverse must converge, and the throughput ratio against KDL's
# ChainIkSolverPos_NR is printed (and checked against KDL_MIN_RATIO, default 3: a regression
# floor that a loaded CI machine still meets; the README quotes the figures measured quietly).
set -euo pipefail
cd "$(dirname "$0")/.."
if ! /usr/bin/python3 -c "import PyKDL" 2>/dev/null; then
  if [ "$(id -u)" = 0 ]; then
    export DEBIAN_FRONTEND=noninteractive
    apt-get update -qq
    apt-get install -y -qq python3-pykdl
  else
    echo "python3-pykdl is missing: apt-get install python3-pykdl (as root)" >&2
    exit 1
  fi
fi
cargo build --release -p truepos
/usr/bin/python3 scripts/kdl_compare.py --points "${KDL_POINTS:-100000}" \
  --min-ratio "${KDL_MIN_RATIO:-3}"
