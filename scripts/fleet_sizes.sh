#!/usr/bin/env bash
# The fleet telemetry's sizes, measured (docs/fleet.md): the example machine's 4 h run replayed
# through `truepos run --fast` into a log, then forwarded by `truepos fleet publish` to a
# Mosquitto on a free loopback port (started here, stopped at the end). Prints the log's bytes,
# the messages and their payload bytes, per service hour and per machine-day.
set -euo pipefail
cd "$(dirname "$0")/.."
MOSQUITTO=$(command -v mosquitto || echo /usr/sbin/mosquitto)
[ -x "$MOSQUITTO" ] || { echo "fleet_sizes: mosquitto is missing: bash scripts/install_system_deps.sh" >&2; exit 1; }
cargo build --release -q -p truepos
dir=$(mktemp -d /tmp/truepos-fleet-sizes.XXXXXX)
port=$(python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])')
printf 'listener %s 127.0.0.1\nallow_anonymous true\n' "$port" > "$dir/m.conf"
"$MOSQUITTO" -c "$dir/m.conf" >"$dir/mosquitto.log" 2>&1 &
broker=$!
trap 'kill $broker 2>/dev/null || true; rm -rf "$dir"' EXIT
hours=4
target/release/truepos run --fast --source replay:examples/vmc3/run.csv --log "$dir/log.sqlite" \
  --duration-s $((hours * 3600)) --json >/dev/null
for _ in $(seq 50); do (echo >/dev/tcp/127.0.0.1/$port) 2>/dev/null && break; sleep 0.1; done
start=$(date +%s.%N)
target/release/truepos fleet publish --log "$dir/log.sqlite" --mqtt "mqtt://127.0.0.1:$port" \
  --replay-per-s 100000 --timeout-s 600 2>"$dir/publish.err"
end=$(date +%s.%N)
line=$(cat "$dir/publish.err")
echo "$line"
python3 - "$dir/log.sqlite" "$hours" "$start" "$end" "$line" <<'PY'
import os, re, sqlite3, sys
db, hours, start, end, line = sys.argv[1], int(sys.argv[2]), float(sys.argv[3]), float(sys.argv[4]), sys.argv[5]
c = sqlite3.connect(db)
rows = c.execute("select count(*) from cycles").fetchone()[0]
size = os.path.getsize(db) + (os.path.getsize(db + "-wal") if os.path.exists(db + "-wal") else 0)
sent = int(re.search(r"of (\d+) sent", line).group(1))
payload = int(re.search(r"(\d+) payload bytes", line).group(1))
day = 24 / hours
print(f"log: {rows} cycle records, {size} bytes for {hours} h of service time -> {size * day / 1e6:.1f} MB per machine-day")
print(f"mqtt: {sent} NDATA, {payload / sent:.0f} bytes each on average -> {payload * day / 1e6:.1f} MB of payload per machine-day")
print(f"forwarding {sent} messages took {end - start:.1f} s ({sent / (end - start):.0f} messages/s, QoS 1, window 32, loopback)")
PY
