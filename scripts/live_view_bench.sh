#!/usr/bin/env bash
# The live view's cost (docs/benchmarks.md, "The live view"), in two parts.
#
# 1. `truepos run` (release) at 1 kHz on the example run with `--http`, with 0, 1 and 10 pages
#    streaming (curl on /events): the CPU of the live view's own threads (named truepos-live-*)
#    and of the cycle thread, read from /proc by thread, and the run's late cycles (`--json`).
# 2. First paint of 24 h of history at 1 Hz: two days made of the example run (4 h) played forth
#    and back, replayed at 5000× with a cycle and a logged record every second of service time
#    (86 400 records in 17 s; the service goes on logging 5000 records a second while it is
#    measured); then `/api/history` of the last 24 h timed with curl, and the
#    page opened on that window in headless Chromium driven over the DevTools protocol (node):
#    from navigation to the end of its first drawing with the history, on one clock (the
#    page's `performance.now()`, fetches included) and as the driver saw it. The page's size, and
#    its JavaScript's, gzipped.
#
# scripts/test.sh runs it short (D=15, STREAMS="0 1") and prints its figures; none is asserted,
# since each is a figure of the host as much as of truepos.
#
#   bash scripts/live_view_bench.sh            # 40 s per 1 kHz run
#   D=60 bash scripts/live_view_bench.sh
#   PARTS=paint bash scripts/live_view_bench.sh   # the first paint only (PARTS=cpu: the rest)
#   STREAMS="0 1" bash scripts/live_view_bench.sh # the numbers of streams of part 1
set -euo pipefail
cd "$(dirname "$0")/.."
D=${D:-40}
PARTS=${PARTS:-cpu,paint}
# BUILD=0: the release binary as it is (while the tree does not build).
[ "${BUILD:-1}" = 0 ] || cargo build --release -q -p truepos
target=$(cargo metadata --format-version 1 --no-deps | python3 -c 'import json,sys; print(json.load(sys.stdin)["target_directory"])')
bin="$target/release/truepos"
dir=$(mktemp -d)
trap 'kill $(jobs -p) 2>/dev/null || true; rm -rf "$dir"' EXIT

# Starts `truepos run ARGS…` in the background; sets $pid and $addr (http://IP:PORT).
start() {
  "$bin" run "$@" --log "$dir/log.sqlite" --http 127.0.0.1:0 --json >"$dir/out.json" 2>"$dir/err.txt" &
  pid=$!
  for _ in $(seq 300); do grep -q "live view on" "$dir/err.txt" 2>/dev/null && break; sleep 0.1; done
  addr=$(grep -o "http://[0-9.:]*" "$dir/err.txt" | head -1 || true)
  [ -n "$addr" ] || { echo "no live view within 30 s:"; cat "$dir/err.txt"; exit 1; }
}

if [[ $PARTS == *cpu* ]]; then
  for n in ${STREAMS:-0 1 10}; do
    rm -f "$dir"/log.sqlite*
    start --source replay:examples/vmc3/run.csv --period-ms 1 --duration-s "$D"
    for _ in $(seq "$n"); do curl -sN --max-time $((D + 5)) "$addr/events" >/dev/null & done
    sleep $((D - 3))
    python3 - "$pid" $((D - 3)) "$n" <<'PY'
import os, sys
pid, wall, n = sys.argv[1], float(sys.argv[2]), sys.argv[3]
ticks = {}
for t in os.listdir(f"/proc/{pid}/task"):
    try:
        comm = open(f"/proc/{pid}/task/{t}/comm").read().strip()
        f = open(f"/proc/{pid}/task/{t}/stat").read().rsplit(")", 1)[1].split()
    except OSError:
        continue
    key = "live view threads" if comm.startswith("truepos-live") else comm
    ticks[key] = ticks.get(key, 0) + int(f[11]) + int(f[12])
parts = ", ".join(f"{k} {v / 100 / wall * 100:.2f} %" for k, v in sorted(ticks.items()))
print(f"1 kHz, {n} stream(s): {parts} of one core")
PY
    wait "$pid" || true
    python3 -c "import json,sys; r=json.load(open(sys.argv[1])); print('  the run:', r['cycles'], 'cycles,', r['overruns'], 'late, cycle work p50/p99/max', r['cycle_us']['p50'], r['cycle_us']['p99'], r['cycle_us']['max'], 'us, process', round(r['cpu_percent_of_one_core'], 2), '% of one core')" "$dir/out.json"
  done
fi

if [[ $PARTS == *paint* ]]; then
  rm -f "$dir"/log.sqlite*
  # The example run (4 h, a row a minute) forth and back, twelve times: 48 h without a jump.
  python3 - examples/vmc3/run.csv "$dir/day.csv" <<'PY'
import sys
lines = open(sys.argv[1]).read().splitlines()
head, rows = lines[0], [l.split(",") for l in lines[1:]]
span = float(rows[-1][0])
out = [head]
for k in range(12):
    seq = rows if k % 2 == 0 else rows[::-1]
    for i, r in enumerate(seq):
        if k and i == 0:
            continue
        t = k * span + (float(r[0]) if k % 2 == 0 else span - float(r[0]))
        out.append(",".join([f"{t:g}"] + r[1:]))
open(sys.argv[2], "w").write("\n".join(out) + "\n")
PY
  # 5000 cycles and records a second of real time; measured from the 19th second on (over 24 h
  # logged), the run going on beyond so that the server still serves it.
  start --source "replay:$dir/day.csv@5000" --period-ms 1000 --log-every-s 1 --duration-s 400000
  sleep 19
  curl -s "$addr/api/state" | python3 -c "import json,sys; s=json.load(sys.stdin); print('service time', round(s['time_s']), 's,', s['cycles'], 'cycles')"
  for _ in 1 2 3; do
    curl -s -o "$dir/h.json" -w "history of the last 24 h, 1500 buckets: %{time_total} s, %{size_download} bytes\n" "$addr/api/history?window_s=86400&buckets=1500"
  done
  curl -s -H "Accept-Encoding: gzip" -o /dev/null -w "the same gzipped: %{time_total} s, %{size_download} bytes\n" "$addr/api/history?window_s=86400&buckets=1500"
  curl -s -H "Accept-Encoding: gzip" -o /dev/null -w "in 540 buckets (the page at 1280 px), gzipped: %{time_total} s, %{size_download} bytes\n" "$addr/api/history?window_s=86400&buckets=540"
  python3 -c "import json,sys; h=json.load(open(sys.argv[1])); print('  records', sum(b['rows'] for b in h['buckets']), 'in', len(h['buckets']), 'buckets,', len(h['columns']), 'columns')" "$dir/h.json"
  curl -s -o "$dir/page.html" "$addr/"
  python3 - "$dir/page.html" <<'PY'
import gzip, sys
page = open(sys.argv[1], "rb").read()
js = page[page.index(b"<script>") + 8:page.index(b"</script>")]
print(f"the page: {len(page)} bytes, {len(gzip.compress(page, 9))} gzipped; its JavaScript: {len(js)} bytes, {len(gzip.compress(js, 9))} gzipped")
PY
  # The page over the DevTools protocol: navigation, then its first drawing polled every 5 ms.
  cat >"$dir/paint.js" <<'JS'
const [wsUrl, page] = process.argv.slice(2);
const ws = new WebSocket(wsUrl);
let id = 0;
const pending = new Map();
const send = (method, params = {}, sessionId) => new Promise((res, rej) => {
  const i = ++id; pending.set(i, { res, rej });
  ws.send(JSON.stringify({ id: i, method, params, sessionId }));
});
ws.onmessage = (m) => {
  const d = JSON.parse(m.data);
  const p = d.id && pending.get(d.id);
  if (p) { pending.delete(d.id); d.error ? p.rej(new Error(JSON.stringify(d.error))) : p.res(d.result); }
};
const probe = "typeof firstPaintMs === 'number' ? JSON.stringify({ first_paint_ms: firstPaintMs, " +
  "points: Object.values(series).reduce((n, x) => n + x.t.length, 0), buckets: historyBuckets, marks, errors }) : ''";
ws.onopen = async () => {
  const { targetId } = await send("Target.createTarget", { url: "about:blank" });
  const { sessionId } = await send("Target.attachToTarget", { targetId, flatten: true });
  await send("Page.enable", {}, sessionId);
  const t0 = Date.now();
  await send("Page.navigate", { url: page }, sessionId);
  let out = { error: "no first paint within 30 s" };
  while (Date.now() - t0 < 30000) {
    try {
      const r = await send("Runtime.evaluate", { expression: probe, returnByValue: true }, sessionId);
      if (r.result && r.result.value) { out = JSON.parse(r.result.value); out.driver_ms = Date.now() - t0; break; }
    } catch (e) { /* the page is still loading */ }
    await new Promise((r) => setTimeout(r, 5));
  }
  console.log(JSON.stringify(out));
  process.exit(0);
};
JS
  for k in 1 2 3; do
    rm -rf "$dir/chromium"
    chromium --headless --no-sandbox --disable-gpu --no-first-run --remote-debugging-port=0 \
      --user-data-dir="$dir/chromium" --window-size=1280,1000 about:blank 2>"$dir/chromium.txt" &
    cpid=$!
    for _ in $(seq 100); do grep -q "DevTools listening on" "$dir/chromium.txt" && break; sleep 0.1; done
    ws=$(grep -o "ws://[^ ]*" "$dir/chromium.txt" | head -1)
    node --experimental-websocket --no-warnings "$dir/paint.js" "$ws" "$addr/?window=86400" \
      | python3 -c "import json,sys; v=json.load(sys.stdin); print('first paint of the last 24 h:', v.get('first_paint_ms') and round(v['first_paint_ms']), 'ms from navigation (the page clock, fetches included),', v.get('driver_ms'), 'ms as the driver saw it,', v.get('points'), 'points,', v.get('buckets'), 'buckets; read', {k: round(x) for k, x in v.get('marks', {}).items()}, 'ms; errors', v.get('errors', v))"
    kill "$cpid" 2>/dev/null || true
    wait "$cpid" 2>/dev/null || true
  done
  kill "$pid" 2>/dev/null || true
  wait "$pid" 2>/dev/null || true
fi
