#!/usr/bin/env bash
# Debian packages the build and the tests need (idempotent). Called by .ci/run.
# mosquitto and postgresql: the MQTT broker and the fleet store crates/cli/tests/fleet_mqtt.rs
# starts on loopback, and PostgreSQL for crates/cli/tests/fleet_models.rs (docs/fleet.md).
set -euo pipefail
pkgs=(libsqlite3-dev pkg-config mosquitto postgresql)
missing=()
for p in "${pkgs[@]}"; do
  dpkg -s "$p" >/dev/null 2>&1 || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  export DEBIAN_FRONTEND=noninteractive
  apt-get update -qq
  apt-get install -y -qq "${missing[@]}"
fi
echo "system packages present: ${pkgs[*]}"
