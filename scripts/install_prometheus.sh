#!/usr/bin/env bash
# Debian's Prometheus, for `promtool check metrics` on the live view's /metrics
# (crates/cli/tests/live_view.rs). Idempotent.
set -euo pipefail
if command -v promtool >/dev/null; then
  echo "install_prometheus: $(promtool --version 2>&1 | head -1)"
  exit 0
fi
SUDO=""
[ "$(id -u)" = 0 ] || SUDO="sudo"
$SUDO apt-get update -q
DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -q --no-install-recommends prometheus
command -v promtool >/dev/null
echo "install_prometheus: done ($(promtool --version 2>&1 | head -1))"
