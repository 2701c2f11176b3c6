#!/usr/bin/env bash
# Installs LinuxCNC 2.9 (userspace realtime, simulator) from Debian bookworm, for the HAL
# component of truepos and its end-to-end test. Idempotent: does nothing when everything is
# already installed. Called by .ci/run (as root on a fresh Debian machine).
set -euo pipefail

PACKAGES=(linuxcnc-uspace linuxcnc-uspace-dev python3 util-linux bsdutils procps)

missing=()
for p in "${PACKAGES[@]}"; do
    if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
        missing+=("$p")
    fi
done
if [ ${#missing[@]} -eq 0 ]; then
    echo "install_linuxcnc: all packages present"
    exit 0
fi

SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
export DEBIAN_FRONTEND=noninteractive
echo "install_linuxcnc: installing ${missing[*]}"
$SUDO apt-get update -q
$SUDO apt-get install -y -q --no-install-recommends "${missing[@]}"
# halcmd, linuxcnc and the python module must now be there; fail loudly otherwise.
command -v halcmd >/dev/null
command -v linuxcnc >/dev/null
# The Debian python modules live in the system interpreter (not a pyenv one on PATH).
/usr/bin/python3 -c 'import linuxcnc, hal'
echo "install_linuxcnc: done ($(dpkg-query -W -f='${Version}' linuxcnc-uspace))"
