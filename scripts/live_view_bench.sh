#!/usr/bin/env bash
# The live view's cost (docs/benchmarks.md, "The live view"): `truepos run` (release) at 1 kHz on
# the example run with `--http`, and N pages streaming (curl on /events); the CPU of the live
# view's own threads (named truepos-live-*) and of the cycle thread, read from /proc by thread,
# for N = 1 and 10. Then the history of a long log: the example run replayed at 500× with a
# record every 0.1 s (over 86 400 rows after 18 s, 27 columns), `/api/history` of the whole run
# in 1500 buckets timed with curl, and the page's first paint of it in headless Chromium. Not
# part of scripts/test.sh (a figure of the host as much as of truepos).
#
#   bash scripts/live_view_bench.sh            # 40 s per run
#   D=60 bash scripts/live_view_bench.sh
set -euo pipefail
cd "$(dirname "$0")/.."
D=${D:-40}
cargo build --release -q -p truepos
target=$(cargo metadata --format-version 1 --no-deps | python3 -c 'import json,sys; print(json.load(sys.stdin)["target_directory"])')
bin="$target/release/truepos"
dir=$(mktemp -d)
trap 'kill $(jobs -p) 2>/dev/null || true; rm -rf "$dir"' EXIT

# Starts `truepos run ARGS…` in the background; sets $pid and $addr (http://IP:PORT).
start() {
  "$bin" run "$@" --log "$dir/log.sqlite" --http 127.0.0.1:0 --json >"$dir/out.json" 2>"$dir/err.txt" &
  pid=$!
  for _ in $(seq 100); do grep -q "live view on" "$dir/err.txt" 2>/dev/null && break; sleep 0.1; done
  addr=$(grep -o "http://[0-9.:]*" "$dir/err.txt" | head -1)
  [ -n "$addr" ] || { cat "$dir/err.txt"; exit 1; }
}

for n in 1 10; do
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
done

rm -f "$dir"/log.sqlite*
# 5000 records/s of real time: over 86 400 (24 h at 1 Hz) after 18 s; the replay lasts 28.8 s.
start --source replay:examples/vmc3/run.csv@500 --period-ms 10 --log-every-s 0.1
sleep 18
for _ in 1 2; do
  curl -s -o "$dir/h.json" -w "history of the whole run, 1500 buckets: %{time_total} s, %{size_download} bytes\n" "$addr/api/history?buckets=1500" || true
done
curl -s -H "Accept-Encoding: gzip" -o /dev/null -w "the same gzipped: %{time_total} s, %{size_download} bytes\n" "$addr/api/history?buckets=1500" || true
python3 -c "import json,sys; h=json.load(open(sys.argv[1])); print('rows', sum(b['rows'] for b in h['buckets']), 'buckets', len(h['buckets']), 'columns', len(h['columns']))" "$dir/h.json" || true
# The page in headless Chromium on the whole run: time from navigation to the first drawing
# with the history (the page's own `performance.now()`, which runs on Chromium's virtual clock:
# the fetches do not count, the history's answer time above adds to it), and its points.
timeout 60 chromium --headless --no-sandbox --disable-gpu --no-first-run --virtual-time-budget=3000 \
  --user-data-dir="$dir/chromium" --window-size=1280,1000 --dump-dom "$addr/?selftest=2&window=all" 2>/dev/null \
  | grep -o '<pre id="selftest">[^<]*</pre>' | tail -1 | sed 's/&quot;/"/g' \
  | python3 -c "import json,re,sys; v=json.loads(re.sub('<[^>]*>','',sys.stdin.read())); print('the page before its first paint of the whole run:', v['first_paint_ms'], 'ms of Chromium virtual clock (fetches excluded: add the history answer above),', v['points'], 'points, errors', v['errors'])" || true
wait "$pid" || true
