#!/usr/bin/env bash
# The fleet telemetry's sizes, measured (docs/fleet.md): the example machine's 4 h run replayed
# through `truepos run --fast` into a log, then forwarded by `truepos fleet publish` to a
# Mosquitto on a free loopback port and taken by `truepos fleet ingest` into a PostgreSQL 15
# cluster of its own (both started here, stopped at the end). Prints the log's bytes, the
# messages and their payload bytes, and the store's bytes, per machine-day.
set -euo pipefail
cd "$(dirname "$0")/.."
MOSQUITTO=$(command -v mosquitto || echo /usr/sbin/mosquitto)
[ -x "$MOSQUITTO" ] || { echo "fleet_sizes: mosquitto is missing: bash scripts/install_system_deps.sh" >&2; exit 1; }
PG=/usr/lib/postgresql/15/bin
[ -x "$PG/initdb" ] || { echo "fleet_sizes: PostgreSQL 15 is missing: bash scripts/install_system_deps.sh" >&2; exit 1; }
# PostgreSQL refuses to run as root: as root, its commands run as the postgres user.
as_pg() { if [ "$(id -u)" = 0 ]; then runuser -u postgres -- "$@"; else "$@"; fi; }
cargo build --release -q -p truepos
dir=$(mktemp -d /tmp/truepos-fleet-sizes.XXXXXX)
port=$(python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])')
# Mosquitto queues at most 1000 messages for a subscriber by default and drops the rest: the
# ingester is slower than a replay, so the queue here is unbounded.
printf 'listener %s 127.0.0.1\nallow_anonymous true\nmax_queued_messages 0\n' "$port" > "$dir/m.conf"
"$MOSQUITTO" -c "$dir/m.conf" >"$dir/mosquitto.log" 2>&1 &
broker=$!
pgport=$(python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])')
mkdir "$dir/pg"
[ "$(id -u)" = 0 ] && chown postgres:postgres "$dir/pg"
chmod 755 "$dir"
as_pg "$PG/initdb" -A trust -U postgres --no-sync -D "$dir/pg" >/dev/null
as_pg "$PG/pg_ctl" -D "$dir/pg" -o "-p $pgport -k $dir/pg -c listen_addresses=127.0.0.1" -l "$dir/pg/log" -w start >/dev/null
trap 'kill $broker 2>/dev/null || true; as_pg "$PG/pg_ctl" -D "$dir/pg" -m immediate stop >/dev/null 2>&1 || true; rm -rf "$dir"' EXIT
hours=4
target/release/truepos run --fast --source replay:examples/vmc3/run.csv --log "$dir/log.sqlite" \
  --duration-s $((hours * 3600)) --json >/dev/null
db="postgres://postgres@127.0.0.1:$pgport/postgres"
target/release/truepos fleet ingest --mqtt "mqtt://127.0.0.1:$port" --db "$db" --idle-exit-s 5 2>"$dir/ingest.err" &
ingest=$!
until psql -h 127.0.0.1 -p "$pgport" -U postgres -Atc "select 1 from fleet_schema_migrations" 2>/dev/null | grep -q 1; do sleep 0.2; done
sleep 0.5
for _ in $(seq 50); do (echo >/dev/tcp/127.0.0.1/$port) 2>/dev/null && break; sleep 0.1; done
start=$(date +%s.%N)
target/release/truepos fleet publish --log "$dir/log.sqlite" --mqtt "mqtt://127.0.0.1:$port" \
  --replay-per-s 100000 --timeout-s 600 2>"$dir/publish.err"
end=$(date +%s.%N)
wait $ingest
# The ingester stops 5 s after its last message.
ingested=$(python3 -c "import time; print(time.time() - 5)")
line=$(cat "$dir/publish.err")
echo "$line"
cat "$dir/ingest.err"
store=$(psql -h 127.0.0.1 -p "$pgport" -U postgres -Atc \
  "select coalesce(sum(pg_total_relation_size(inhrelid)), 0) from pg_inherits where inhparent in ('fleet_seconds'::regclass, 'fleet_events'::regclass)")
python3 - "$dir/log.sqlite" "$hours" "$start" "$end" "$line" "$store" "$ingested" "$(cat "$dir/ingest.err")" <<'PY'
import os, re, sqlite3, sys
db, hours, start, end, line, store = sys.argv[1], int(sys.argv[2]), float(sys.argv[3]), float(sys.argv[4]), sys.argv[5], int(sys.argv[6])
ingested, ingest_line = float(sys.argv[7]), sys.argv[8]
c = sqlite3.connect(db)
rows = c.execute("select count(*) from cycles").fetchone()[0]
size = os.path.getsize(db) + (os.path.getsize(db + "-wal") if os.path.exists(db + "-wal") else 0)
sent = int(re.search(r"of (\d+) sent", line).group(1))
payload = int(re.search(r"(\d+) payload bytes", line).group(1))
day = 24 / hours
print(f"log: {rows} cycle records, {size} bytes for {hours} h of service time -> {size * day / 1e6:.1f} MB per machine-day")
print(f"mqtt: {sent} NDATA, {payload / sent:.0f} bytes each on average -> {payload * day / 1e6:.1f} MB of payload per machine-day")
print(f"PostgreSQL: {store} bytes (tables and indexes) -> {store * day / 1e6:.1f} MB per machine-day")
print(f"fleet publish: {sent} messages into the broker in {end - start:.1f} s ({sent / (end - start):.0f} messages/s, QoS 1, window 32, loopback)")
got = int(re.search(r"ingest: (\d+) messages", ingest_line).group(1))
print(f"fleet ingest: {got} messages into PostgreSQL by {ingested - start:.1f} s ({got / (ingested - start):.0f} messages/s, one commit per delivery the broker makes, at most 20 in flight)")
PY
