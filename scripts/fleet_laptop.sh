#!/usr/bin/env bash
# A fleet on a laptop (issue 31, docs/fleet.md), the first of two commands: Mosquitto and a
# PostgreSQL 15 cluster of its own on loopback ports, `truepos fleet ingest` between them, and
# three machines — `truepos run --mqtt` replaying the example VMC's 4 h run at 10×, 20× and 30×
# real time under the node ids vmc-1, vmc-2 and vmc-3, each with its own log. It prints the
# second command, `truepos fleet status --db URL`, and runs until Ctrl-C; everything it started
# is stopped and its directory removed then.
#
#   bash scripts/fleet_laptop.sh                       # until Ctrl-C
#   DURATION=20 CHECK=1 bash scripts/fleet_laptop.sh   # stops after 20 s; fails unless the
#                                                      # status shows three machines online,
#                                                      # also on its page in headless Chromium
set -euo pipefail
cd "$(dirname "$0")/.."
MOSQUITTO=$(command -v mosquitto || echo /usr/sbin/mosquitto)
[ -x "$MOSQUITTO" ] || { echo "fleet_laptop: mosquitto is missing: bash scripts/install_system_deps.sh" >&2; exit 1; }
PG=/usr/lib/postgresql/15/bin
[ -x "$PG/initdb" ] || { echo "fleet_laptop: PostgreSQL 15 is missing: bash scripts/install_system_deps.sh" >&2; exit 1; }
# PostgreSQL refuses to run as root: as root, its commands run as the postgres user.
as_pg() { if [ "$(id -u)" = 0 ]; then runuser -u postgres -- "$@"; else "$@"; fi; }
cargo build --release -q -p truepos
truepos=$PWD/target/release/truepos

dir=$(mktemp -d /tmp/truepos-fleet-laptop.XXXXXX)
pids=()
cleanup() {
  for p in "${pids[@]}"; do kill "$p" 2>/dev/null || true; done
  as_pg "$PG/pg_ctl" -D "$dir/pg" -m fast stop >/dev/null 2>&1 || true
  for p in "${pids[@]}"; do wait "$p" 2>/dev/null || true; done
  rm -rf "$dir"
}
trap cleanup EXIT
trap 'exit 0' INT TERM
free_port() { python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])'; }

port=$(free_port)
printf 'listener %s 127.0.0.1\nallow_anonymous true\nmax_queued_messages 0\n' "$port" > "$dir/m.conf"
"$MOSQUITTO" -c "$dir/m.conf" >"$dir/mosquitto.log" 2>&1 &
pids+=("$!")

pgport=$(free_port)
mkdir "$dir/pg"
[ "$(id -u)" = 0 ] && chown postgres:postgres "$dir/pg"
chmod 755 "$dir"
as_pg "$PG/initdb" -A trust -U postgres --no-sync -D "$dir/pg" >/dev/null
as_pg "$PG/pg_ctl" -D "$dir/pg" -o "-p $pgport -k $dir/pg -c listen_addresses=127.0.0.1" -l "$dir/pg/log" -w start >/dev/null
db="postgres://postgres@127.0.0.1:$pgport/postgres"
mqtt="mqtt://127.0.0.1:$port"

"$truepos" fleet ingest --mqtt "$mqtt" --db "$db" 2>"$dir/ingest.err" &
pids+=("$!")
until psql -h 127.0.0.1 -p "$pgport" -U postgres -Atqc "select 1 from fleet_schema_migrations limit 1" 2>/dev/null | grep -q 1; do sleep 0.2; done
sleep 1 # the ingester subscribes right after its migrations

for i in 1 2 3; do
  "$truepos" run --source "replay:examples/vmc3/run.csv@$((i * 10))" --log "$dir/vmc-$i.sqlite" \
    --mqtt "$mqtt" --mqtt-node "vmc-$i" >/dev/null 2>"$dir/vmc-$i.err" &
  pids+=("$!")
done

cat <<EOF
A fleet of three machines (vmc-1, vmc-2, vmc-3) publishing to Mosquitto at $mqtt,
stored by truepos fleet ingest in PostgreSQL at $db.
The second command, in another terminal:

  $truepos fleet status --db $db

Ctrl-C stops it all.
EOF
if [ -n "${DURATION:-}" ]; then
  sleep "$DURATION"
  status=$("$truepos" fleet status --db "$db" --json)
  echo "$status"
  if [ -n "${CHECK:-}" ]; then
    STATUS="$status" python3 - <<'PY'
import json, os, sys
rows = json.loads(os.environ["STATUS"])
rows = rows.get("machines", rows) if isinstance(rows, dict) else rows
online = sorted(r["machine"] for r in rows if r.get("online"))
if online != ["vmc-1", "vmc-2", "vmc-3"]:
    sys.exit(f"fleet_laptop: expected vmc-1, vmc-2, vmc-3 online, got {online}")
print("fleet_laptop: three machines online")
PY
    # The same status as a page, in a real browser: three rows drawn from /api/fleet.
    webport=$(free_port)
    "$truepos" fleet status --db "$db" --http "127.0.0.1:$webport" --duration-s 120 2>"$dir/view.err" &
    pids+=("$!")
    for _ in $(seq 100); do (echo >/dev/tcp/127.0.0.1/$webport) 2>/dev/null && break; sleep 0.1; done
    chrome=(timeout 60 /usr/bin/chromium --headless --no-sandbox --disable-gpu --no-first-run
      --hide-scrollbars --virtual-time-budget=3000 --user-data-dir="$dir/chromium")
    rows=$("${chrome[@]}" --dump-dom "http://127.0.0.1:$webport/" 2>/dev/null | grep -o 'data-machine="vmc-[0-9]"' | sort -u | wc -l)
    [ "$rows" = 3 ] || { echo "fleet_laptop: the fleet page drew $rows machines, not 3" >&2; exit 1; }
    mkdir -p target
    "${chrome[@]}" --window-size=1100,400 --screenshot="$PWD/target/fleet_view.png" "http://127.0.0.1:$webport/" >/dev/null 2>&1
    echo "fleet_laptop: the fleet page in Chromium shows the three machines (target/fleet_view.png)"
  fi
else
  wait
fi
