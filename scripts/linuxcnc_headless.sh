# Sourced by every script that runs LinuxCNC headless (linuxcnc_e2e.sh, linuxcnc_comp.sh,
# linuxcnc_probe_loop.sh): the one way to start it, end what it leaves behind and judge its
# result file.
#
#   run_linuxcnc_headless INI TIMEOUT_S RESULT_FILE LOG_PATTERN
#
# runs `linuxcnc INI` (its folder holds linuxcnc.log afterwards), prints the log lines matching
# LOG_PATTERN, and exits the calling script with 1 (the log's tail printed) unless LinuxCNC ended
# in time and RESULT_FILE, written by the configuration's display program, says PASS.

run_linuxcnc_headless() {
    local ini="$1" limit="$2" result="$3" pattern="$4"
    local out
    out="$(dirname "$ini")"
    # rtapi_app refuses to run realtime as root unless RTAPI_UID names another user, and puts its
    # socket in $HOME, which that user must be able to write.
    if [ "$(id -u)" -eq 0 ]; then
        if ! id truepos-ci >/dev/null 2>&1; then
            useradd --system --no-create-home --shell /usr/sbin/nologin truepos-ci
        fi
        export RTAPI_UID="$(id -u truepos-ci)"
        export HOME="$out/home"
        mkdir -p "$HOME" && chown truepos-ci "$HOME"
    fi
    echo "== run LinuxCNC headless ($out)"
    local status=0
    # No terminal in CI: `script` gives the launcher one, so its output lands in linuxcnc.log.
    timeout "$limit" script -qec "linuxcnc $ini" /dev/null > "$out/linuxcnc.log" 2>&1 || status=$?
    # Should the run hang, end what it left behind: only processes of this very configuration.
    for pid in $(pgrep -f "$ini" || true); do kill "$pid" 2>/dev/null || true; done
    halrun -U >/dev/null 2>&1 || true
    grep -E "$pattern" "$out/linuxcnc.log" || true
    if [ "$status" -ne 0 ] || [ "$(cat "$result" 2>/dev/null)" != "PASS" ]; then
        echo "FAIL: LinuxCNC run (exit $status, result '$(cat "$result" 2>/dev/null)')"
        tail -40 "$out/linuxcnc.log"
        exit 1
    fi
}
