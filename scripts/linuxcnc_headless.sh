# Sourced by every script that runs LinuxCNC headless (linuxcnc_e2e.sh, linuxcnc_comp.sh,
# linuxcnc_probe_loop.sh): the one way to start it, end what it leaves behind and judge its
# result file.
#
#   run_linuxcnc_headless INI TIMEOUT_S RESULT_FILE LOG_PATTERN
#
# runs `linuxcnc INI` (its folder holds linuxcnc.log afterwards), prints the log lines matching
# LOG_PATTERN, and exits the calling script with 1 (the log's tail printed) unless LinuxCNC ended
# in time and RESULT_FILE, written by the configuration's display program, says PASS.
#
# LinuxCNC's shared memory has fixed keys, so two runs on one machine (two test commands at once)
# break each other, and a run killed mid-way leaves segments whose size the next run's HAL
# components cannot match (shmget: Invalid argument). Runs therefore take a machine-wide lock, and
# under it remove LinuxCNC segments that no process is attached to.

LINUXCNC_LOCK=/tmp/truepos-linuxcnc.lock

# Removes LinuxCNC's shared-memory segments that nothing is attached to: HAL, RTAPI and UUID keys
# (the ones LinuxCNC's own unload removes) and the sampler/streamer channels (0x4853....), which
# a killed rtapi_app leaves behind. Only called with none of LINUXCNC_PROGRAMS running.
remove_orphan_linuxcnc_memory() {
    local key id nattch
    while read -r key id nattch; do
        echo "removing shared memory $key left by an earlier LinuxCNC (id $id)"
        ipcrm -m "$id" || true
    done < <(ipcs -m | awk '$1 ~ /^0x/ && $6 == 0 &&
        ($1 == "0x48414c32" || $1 == "0x90280a48" || $1 == "0x48484c34" || $1 ~ /^0x4853/) \
        { print $1, $2, $6 }')
}

# The programs that hold LinuxCNC's shared memory: while one runs, its segments stay attached.
LINUXCNC_PROGRAMS="rtapi_app linuxcncsvr milltask halsampler halstreamer truepos-hal"

# Waits up to $1 s for every program of LINUXCNC_PROGRAMS to end; 1 (naming them) if one is left.
linuxcnc_ended_within() {
    local n=0 left p
    while :; do
        left=""
        for p in $LINUXCNC_PROGRAMS; do
            pgrep -x "$p" >/dev/null && left="$left $p"
        done
        [ -z "$left" ] && return 0
        if [ "$n" -ge "$(($1 * 10))" ]; then
            echo "still running:$left"
            return 1
        fi
        sleep 0.1
        n=$((n + 1))
    done
}

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
    local lock_fd
    # Created writable by all, then opened read-only (enough for flock): a lock file another user
    # created stays usable where the kernel protects files in sticky /tmp from other writers.
    [ -e "$LINUXCNC_LOCK" ] || (umask 0 && : >>"$LINUXCNC_LOCK")
    exec {lock_fd}<"$LINUXCNC_LOCK"
    if ! flock -w 900 "$lock_fd"; then
        echo "FAIL: another LinuxCNC test run held $LINUXCNC_LOCK for 900 s"
        exit 1
    fi
    if ! linuxcnc_ended_within 30; then
        echo "FAIL: LinuxCNC programs are still running 30 s after this run wanted to start (an" \
            "earlier run's leftovers or a LinuxCNC of yours); stop them first: their shared" \
            "memory would collide with this run's"
        exit 1
    fi
    remove_orphan_linuxcnc_memory
    local status=0
    # No terminal in CI: `script` gives the launcher one, so its output lands in linuxcnc.log.
    # The lock's descriptor is closed for LinuxCNC, so a process it leaves behind cannot hold it.
    timeout "$limit" script -qec "linuxcnc $ini" /dev/null > "$out/linuxcnc.log" 2>&1 {lock_fd}>&- \
        || status=$?
    # Should the run hang, end what it left behind: only processes of this very configuration.
    for pid in $(pgrep -f "$ini" || true); do kill "$pid" 2>/dev/null || true; done
    halrun -U >/dev/null 2>&1 {lock_fd}>&- || true
    # The lock is released only once this run's processes are gone, so the next run starts clean.
    linuxcnc_ended_within 30 || echo "warning: LinuxCNC programs left 30 s after the run; the next run waits for them"
    exec {lock_fd}>&-
    grep -E "$pattern" "$out/linuxcnc.log" || true
    if [ "$status" -ne 0 ] || [ "$(cat "$result" 2>/dev/null)" != "PASS" ]; then
        echo "FAIL: LinuxCNC run (exit $status, result '$(cat "$result" 2>/dev/null)')"
        tail -40 "$out/linuxcnc.log"
        exit 1
    fi
}
