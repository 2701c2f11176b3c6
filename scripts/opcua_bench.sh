#!/usr/bin/env bash
# Write round trips of the OPC UA sink at 10 Hz on loopback: the simulated control
# (scripts/opcua_control.py, Python asyncua) and `truepos run --sink opcua:` with
# Basic256Sha256 SignAndEncrypt, user and password, 3 axes (K0 and tanβ of X, Y, Z in one Write
# request per period). Prints the sink's summary: writes, round trip p50/p99/max.
# Usage: bash scripts/opcua_bench.sh [SECONDS]   (default 60: 600 writes)
set -euo pipefail
cd "$(dirname "$0")/.."
SECONDS_RUN="${1:-60}"
bash scripts/setup_python.sh >/dev/null
cargo build -q -p truepos
BIN="${CARGO_TARGET_DIR:-target}/debug/truepos"
DIR="$(mktemp -d)"
trap 'kill "$SERVER" 2>/dev/null || true; rm -rf "$DIR"' EXIT
PORT=$(.venv/bin/python -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])')
temps=()
for t in x_slide_top=24 x_slide_bottom=27 y_slide_top=23 y_slide_bottom=25.5 z_slide_front=22.5 \
         z_slide_rear=24.5 spindle_front_bearing=35 spindle_rear_bearing=30 ambient=21; do
  temps+=(--temp "$t")
done
.venv/bin/python scripts/opcua_control.py --port "$PORT" --pki "$DIR/server" --record "$DIR/rec.csv" \
  --user truepos:bench "${temps[@]}" >"$DIR/server.log" 2>&1 &
SERVER=$!
for _ in $(seq 600); do grep -q listening "$DIR/server.log" && break; sleep 0.1; done
conn() {
  printf 'endpoint = "opc.tcp://127.0.0.1:%s/truepos-sim"\nsecurity_policy = "Basic256Sha256"\nsecurity_mode = "%s"\npki_dir = "%s"\nuser = "truepos"\npassword = "bench"\n' \
    "$PORT" "$1" "$DIR/client"
}
{ conn SignAndEncrypt; echo 'rate_hz = 10'
  for u in 1 2 3; do
    axis=$(echo X Y Z | cut -d' ' -f$u)
    printf '[[axis]]\naxis = "%s"\nk0 = "ns=2;s=/NC/_N_AX_SEA_ACX/$SA_TEMP_COMP_ABS_VALUE[u%s]"\ntan_beta = "ns=2;s=/NC/_N_AX_SEA_ACX/$SA_TEMP_COMP_SLOPE[u%s]"\np0 = "ns=2;s=/NC/_N_AX_SEA_ACX/$SA_TEMP_COMP_REF_POSITION[u%s]"\nmax_rate_um_per_s = 1000\n' "$axis" $u $u $u
  done; } >"$DIR/sink.toml"
{ conn Sign; echo 'sample_ms = 100'
  for u in 1 2 3; do
    axis=$(echo X Y Z | cut -d' ' -f$u)
    printf '[[channel]]\naxis = "%s"\nnode = "ns=2;s=/Channel/MachineAxis/actToolBasePos[u1,%s]"\n' "$axis" $u
  done
  for t in "${temps[@]}"; do
    [ "$t" = --temp ] && continue
    id="${t%%=*}"
    printf '[[channel]]\ntemperature = "%s"\nnode = "ns=2;s=/Plc/Temp/%s"\n' "$id" "$id"
  done; } >"$DIR/source.toml"
run() {
  "$BIN" run --machine examples/vmc3/machine.toml --models examples/vmc3/model.toml --blend-s 0 \
    --source "opcua:$DIR/source.toml" --sink "opcua:$DIR/sink.toml" --duration-s "$1" --json
}
# The first connection is refused (unknown server certificate); trust it as a person would.
run 1 >/dev/null 2>&1 || true
mkdir -p "$DIR/client/trusted"
mv "$DIR"/client/rejected/*.der "$DIR/client/trusted/"
run "$SECONDS_RUN" 2>"$DIR/run.err" >"$DIR/run.json" || { cat "$DIR/run.err"; exit 1; }
grep "round trip" "$DIR/run.err"
