#!/usr/bin/env bash
# The fleet benchmark (issue 31, docs/fleet.md): N simulated machines at 1 Hz, each its own MQTT
# connection sending what a truepos service sends (crates/fleet/examples/fleet_load.rs: the
# service's NBIRTH, then one NDATA a second with min/mean/max of the example machine's columns,
# stamped with the time of sending), into one Mosquitto and `truepos fleet ingest` into
# PostgreSQL 15 (fsync on, default settings), all on loopback on this machine. Prints: messages
# stored per second over the steady window and the backlog when the machines stop, latency
# p50/p99/max from publish to row (received_at - t), CPU of the broker, the ingester, PostgreSQL
# and the load generator (% of one core over the window), and PostgreSQL bytes per machine-day.
#
#   bash scripts/fleet_bench.sh [MACHINES=1000] [SECONDS=60]
#   FLEET_BENCH_INFLIGHT=N      Mosquitto's max_inflight_messages (default 20)
#   FLEET_BENCH_PG_OPTS="-c …"  PostgreSQL settings beyond the defaults
#   FLEET_BENCH_CHECK=1 bash scripts/fleet_bench.sh 50 10   # fails unless every message was
#                                                            # stored, kept up, p99 < 2 s
set -euo pipefail
cd "$(dirname "$0")/.."
machines=${1:-1000}
seconds=${2:-60}
MOSQUITTO=$(command -v mosquitto || echo /usr/sbin/mosquitto)
[ -x "$MOSQUITTO" ] || { echo "fleet_bench: mosquitto is missing: bash scripts/install_system_deps.sh" >&2; exit 1; }
PG=/usr/lib/postgresql/15/bin
[ -x "$PG/initdb" ] || { echo "fleet_bench: PostgreSQL 15 is missing: bash scripts/install_system_deps.sh" >&2; exit 1; }
# PostgreSQL refuses to run as root: as root, its commands run as the postgres user.
as_pg() { if [ "$(id -u)" = 0 ]; then runuser -u postgres -- "$@"; else "$@"; fi; }
if [ -z "${FLEET_BENCH_NO_BUILD:-}" ]; then
  cargo build --release -q -p truepos
  cargo build --release -q -p truepos-fleet --example fleet_load
fi
truepos=target/release/truepos
load=target/release/examples/fleet_load
# One descriptor per machine in the broker and in the generator.
ulimit -n "$(( machines * 2 + 1024 > 4096 ? machines * 2 + 1024 : 4096 ))" 2>/dev/null || true

dir=$(mktemp -d /tmp/truepos-fleet-bench.XXXXXX)
pids=()
cleanup() {
  for p in "${pids[@]}"; do kill "$p" 2>/dev/null || true; done
  as_pg "$PG/pg_ctl" -D "$dir/pg" -m immediate stop >/dev/null 2>&1 || true
  for p in "${pids[@]}"; do wait "$p" 2>/dev/null || true; done
  rm -rf "$dir"
}
trap cleanup EXIT
free_port() { python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])'; }

# The seconds the machines send: the example machine's replay, logged as the service logs it.
"$truepos" run --fast --source replay:examples/vmc3/run.csv --log "$dir/log.sqlite" \
  --duration-s 600 --json >/dev/null

port=$(free_port)
# Mosquitto queues at most 1000 messages per subscriber by default and drops the rest
# (docs/fleet.md): a fleet's ingester is one subscriber, so its queue is unbounded here.
# Mosquitto sends a subscriber at most max_inflight_messages unacknowledged messages (20 by
# default); the ingester stores what one read brings in one transaction, so this bounds its
# batches. FLEET_BENCH_INFLIGHT sets it (0: no bound).
inflight=${FLEET_BENCH_INFLIGHT:-20}
printf 'listener %s 127.0.0.1\nallow_anonymous true\nmax_queued_messages 0\nmax_inflight_messages %s\n' "$port" "$inflight" > "$dir/m.conf"
"$MOSQUITTO" -c "$dir/m.conf" >"$dir/mosquitto.log" 2>&1 &
broker=$!
pids+=("$broker")

pgport=$(free_port)
mkdir "$dir/pg"
[ "$(id -u)" = 0 ] && chown postgres:postgres "$dir/pg"
chmod 755 "$dir"
as_pg "$PG/initdb" -A trust -U postgres --no-sync -D "$dir/pg" >/dev/null
# FLEET_BENCH_PG_OPTS: more server settings, e.g. "-c default_toast_compression=lz4".
as_pg "$PG/pg_ctl" -D "$dir/pg" -o "-p $pgport -k $dir/pg -c listen_addresses=127.0.0.1 ${FLEET_BENCH_PG_OPTS:-}" -l "$dir/pg/log" -w start >/dev/null
postmaster=$(head -1 "$dir/pg/postmaster.pid")
sql() { psql -h 127.0.0.1 -p "$pgport" -U postgres -Atq -c "$1"; }

"$truepos" fleet ingest --mqtt "mqtt://127.0.0.1:$port" --db "postgres://postgres@127.0.0.1:$pgport/postgres" \
  --client-id fleet-bench-ingest --idle-exit-s 5 2>"$dir/ingest.err" &
ingest=$!
pids+=("$ingest")
until sql "select 1 from fleet_schema_migrations limit 1" 2>/dev/null | grep -q 1; do sleep 0.2; done
for _ in $(seq 50); do (echo >/dev/tcp/127.0.0.1/$port) 2>/dev/null && break; sleep 0.1; done
# The ingester subscribes right after its migrations.
sleep 1

# CPU time (utime + stime, clock ticks) of processes, and of PostgreSQL's processes all.
ticks() { local t=0 p; for p in "$@"; do [ -r "/proc/$p/stat" ] && t=$(( t + $(awk '{print $14 + $15}' "/proc/$p/stat") )); done; echo "$t"; }
pg_ticks() { ticks "$postmaster" $(pgrep -P "$postmaster" || true); }
stored() { sql "select count(*) from fleet_seconds"; }

ramp=$(python3 -c "print($machines / 500)")
launched=$(date +%s.%N)
"$load" --mqtt "mqtt://127.0.0.1:$port" --log "$dir/log.sqlite" --machines "$machines" \
  --duration-s "$seconds" --ramp-s "$ramp" >"$dir/load.json" 2>"$dir/load.err" &
gen=$!
pids+=("$gen")
# The machines send from launch + ramp + 1 s for SECONDS; the steady window leaves out the
# first and last quarter (at most 5 s each).
read -r w0 w1 < <(python3 -c "
s = $launched + $ramp + 1; d = $seconds; m = min(5.0, d / 4)
print(s + m, s + d - m)")
sleep "$(python3 -c "import time; print(max(0, $w0 - time.time()))")"
a_time=$(date +%s.%N); a_rows=$(stored)
a_broker=$(ticks "$broker"); a_ingest=$(ticks "$ingest"); a_pg=$(pg_ticks); a_gen=$(ticks "$gen")
sleep "$(python3 -c "import time; print(max(0, $w1 - time.time()))")"
b_time=$(date +%s.%N); b_rows=$(stored)
b_broker=$(ticks "$broker"); b_ingest=$(ticks "$ingest"); b_pg=$(pg_ticks); b_gen=$(ticks "$gen")
wait "$gen" || { echo "fleet_bench: the load generator failed:" >&2; cat "$dir/load.err" >&2; exit 1; }
stopped=$(date +%s.%N)
at_stop=$(stored)
sent=$(python3 -c "import json; print(json.load(open('$dir/load.json'))['ndata_sent'])")
# The backlog drains: wait until every message is stored or nothing moves for 10 s.
drained=""
last=-1; still=0
while :; do
  n=$(stored)
  if [ "$n" -ge "$sent" ]; then drained=$(date +%s.%N); break; fi
  if [ "$n" = "$last" ]; then still=$((still + 1)); else still=0; fi
  [ "$still" -ge 20 ] && break
  last=$n; sleep 0.5
done
final=$(stored)
lat=$(sql "select percentile_cont(0.5) within group (order by x), percentile_cont(0.99) within group (order by x), max(x), count(*)
  from (select extract(epoch from received_at - t) as x from fleet_seconds
        where t >= to_timestamp($w0) and t < to_timestamp($w1)) s")
size=$(sql "select coalesce(sum(pg_total_relation_size(inhrelid)), 0) from pg_inherits
  where inhparent in ('fleet_seconds'::regclass, 'fleet_events'::regclass)")
wait "$ingest" 2>/dev/null || true
python3 - "$machines" "$seconds" "$dir/load.json" "$lat" "$size" "$final" "$dir/ingest.err" <<PY
import json, sys
machines, seconds = int(sys.argv[1]), float(sys.argv[2])
load = json.load(open(sys.argv[3]))
p50, p99, mx, nlat = sys.argv[4].split("|")
size, final = int(sys.argv[5]), int(sys.argv[6])
ingest_line = open(sys.argv[7]).read().strip().splitlines()
window = $b_time - $a_time
hz = 100.0  # clock ticks a second (CLK_TCK)
cpu = lambda a, b: 100.0 * (b - a) / hz / window
rate = ($b_rows - $a_rows) / window
sent = load["ndata_sent"]
backlog = sent - $at_stop
drain = ("$drained" and float("$drained" or 0) - $stopped)
# Kept up: stored as fast as sent over the window, everything stored, p99 under 2 s.
kept_up = rate >= 0.98 * sent / seconds and final >= sent and float(p99) < 2.0
print(f"fleet_bench: {machines} machines at 1 Hz for {seconds:.0f} s ({load['columns']} columns, "
      f"{load['payload_bytes_per_ndata']} B a message), one Mosquitto (max_inflight_messages $inflight), one ingester, PostgreSQL 15, loopback, 2 cores")
print(f"  machines connected {load['connected']} of {machines}, failed {load['failed']}; generator late sends {load['late_sends']}, worst lag {load['max_lag_ms']} ms")
for e in load["errors"]:
    print(f"  machine failed: {e}")
print(f"  sent {sent} NDATA; stored {final}; broker acknowledged {load['acknowledged']} (NDATA, births, deaths)")
print(f"  messages/s sustained: {rate:.0f} stored/s over the steady window of {window:.1f} s (offered {machines}/s)")
print(f"  backlog when the machines stopped: {backlog} messages; " + (f"drained {drain:.1f} s later" if drain != "" and drain is not False else "NOT drained"))
print(f"  latency publish -> row (received_at - t, {nlat} rows of the window): p50 {float(p50)*1000:.0f} ms, p99 {float(p99)*1000:.0f} ms, max {float(mx)*1000:.0f} ms")
print(f"  CPU over the window (% of one core): broker {cpu($a_broker, $b_broker):.1f}, ingester {cpu($a_ingest, $b_ingest):.1f}, "
      f"PostgreSQL {cpu($a_pg, $b_pg):.1f}, load generator {cpu($a_gen, $b_gen):.1f}")
store_cpu = cpu($a_broker, $b_broker) + cpu($a_ingest, $b_ingest) + cpu($a_pg, $b_pg)
print(f"  machines' worth per core (broker + ingester + PostgreSQL, {store_cpu:.1f} % of one core): {rate / max(store_cpu, 0.1) * 100:.0f}")
print(f"  PostgreSQL: {size} bytes for {final} machine-seconds -> {size / max(final, 1) * 86400 / 1e6:.1f} MB per machine-day")
if ingest_line:
    print(f"  {ingest_line[-1]}")
print(f"  kept up: {'yes' if kept_up else 'NO'}")
if "${FLEET_BENCH_CHECK:-}":
    ok = final == sent and sent > 0 and load["failed"] == 0 and float(p99) < 2.0 and kept_up
    if not ok:
        print("fleet_bench: FAILED (every message stored, none failed, p99 < 2 s, kept up)", file=sys.stderr)
        sys.exit(1)
PY
