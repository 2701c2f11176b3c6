#!/usr/bin/env bash
# Debian's Chromium, for the test that renders truepos's HTML reports in a real browser
# (crates/cli/tests/report_browser.rs). Idempotent.
set -euo pipefail
if command -v chromium >/dev/null; then
  echo "install_chromium: $(chromium --version 2>/dev/null | head -1)"
  exit 0
fi
SUDO=""
[ "$(id -u)" = 0 ] || SUDO="sudo"
$SUDO apt-get update -q
DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -q chromium
command -v chromium >/dev/null
echo "install_chromium: done ($(chromium --version 2>/dev/null | head -1))"
