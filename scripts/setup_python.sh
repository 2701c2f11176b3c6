#!/usr/bin/env bash
# Python virtual environment for the network tests: pymodbus's Modbus TCP server, which
# crates/protocols/tests/modbus_*.rs start on loopback (scripts/modbus_server.py), and asyncua's
# OPC UA server, the simulated control crates/cli/tests/opcua.rs starts (scripts/opcua_control.py),
# and pysparkplug (with paho-mqtt), the Sparkplug B host crates/cli/tests/fleet_mqtt.rs decodes
# the fleet telemetry with (scripts/sparkplug_listen.py).
# Idempotent: does nothing when .venv already holds the pinned version. .ci/run calls it.
set -euo pipefail
cd "$(dirname "$0")/.."
PYMODBUS_VERSION="3.16.1"
ASYNCUA_VERSION="2.1.0"
PYSPARKPLUG_VERSION="0.6.1"
VENV=".venv"

if [ -x "$VENV/bin/python" ] &&
    "$VENV/bin/python" -c "import pymodbus, sys; from importlib.metadata import version; sys.exit(pymodbus.__version__ != '$PYMODBUS_VERSION' or version('asyncua') != '$ASYNCUA_VERSION' or version('pysparkplug') != '$PYSPARKPLUG_VERSION')" 2>/dev/null; then
    echo "setup_python: $VENV has pymodbus $PYMODBUS_VERSION, asyncua $ASYNCUA_VERSION and pysparkplug $PYSPARKPLUG_VERSION"
    exit 0
fi

# A fresh Debian machine may lack python3 or its venv module: install them when we may (root).
if ! command -v python3 >/dev/null || ! python3 -c "import ensurepip, venv" 2>/dev/null; then
    if [ "$(id -u)" = "0" ] && command -v apt-get >/dev/null; then
        apt-get update
        DEBIAN_FRONTEND=noninteractive apt-get install -y --no-install-recommends python3 python3-venv
    else
        echo "setup_python: python3 with the venv module is needed (Debian: apt-get install python3-venv)" >&2
        exit 1
    fi
fi

rm -rf "$VENV"
python3 -m venv "$VENV"
"$VENV/bin/python" -m pip install --quiet --disable-pip-version-check "pymodbus==$PYMODBUS_VERSION" "asyncua==$ASYNCUA_VERSION" "pysparkplug==$PYSPARKPLUG_VERSION"
"$VENV/bin/python" -c "import pymodbus, asyncua; from importlib.metadata import version; print('setup_python: pymodbus', pymodbus.__version__, 'asyncua', version('asyncua'), 'and pysparkplug', version('pysparkplug'), 'in $VENV')"
