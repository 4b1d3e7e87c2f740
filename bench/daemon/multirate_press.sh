#!/usr/bin/env bash
# An object too fine for the 1 ms tick, touched at 1 kHz: rheod --device sim-spidar-g (the
# SPIDAR-G emulator on a pseudo-terminal behind the real driver), a sample sketch meshed to about
# 100k tetrahedra, added with the daemon's default (multi-rate: the 64 nodes nearest the press
# point every tick on the loop, the whole on a thread of its own), and pressed by the emulated
# hand over and over for S seconds. The same daemon is first measured idle for S seconds (the
# loop's floor on this machine). Prints both runs' loop timing and device counters, and the
# multi-rate object's counters (whole steps, their duration and the time each covered).
#   bench/daemon/multirate_press.sh [--build DIR] [--seconds S] [--resolution M] [--sketch FILE]
set -euo pipefail
cd "$(dirname "$0")/../.."
BUILD=build/dev
SECONDS_RUN=30
RESOLUTION=0.0024
SKETCH=samples/bean.json
while [ $# -gt 0 ]; do
  case "$1" in
    --build) BUILD=$2; shift 2 ;;
    --seconds) SECONDS_RUN=$2; shift 2 ;;
    --resolution) RESOLUTION=$2; shift 2 ;;
    --sketch) SKETCH=$2; shift 2 ;;
    *) echo "usage: $0 [--build DIR] [--seconds S] [--resolution M] [--sketch FILE]" >&2; exit 2 ;;
  esac
done
RHEOD="$BUILD/server/daemon/rheod"
RHEOCTL="$BUILD/clients/cli/rheoctl"
for f in "$RHEOD" "$RHEOCTL"; do
  [ -x "$f" ] || { echo "missing $f (build rheod and rheoctl in $BUILD)" >&2; exit 1; }
done

PIDS=()
DATA=$(mktemp -d /tmp/rheo-multirate-XXXXXX)
cleanup() {
  for p in "${PIDS[@]}"; do kill "$p" 2>/dev/null || true; done
  wait 2>/dev/null || true
  rm -rf "$DATA"
}
trap cleanup EXIT

# start: a daemon on $DATA; sets addr and ctl.
start() {
  LOG="$DATA/rheod-$1.log"
  "$RHEOD" --listen 127.0.0.1:0 --data-dir "$DATA" --device sim-spidar-g 2>"$LOG" &
  RHEOD_PID=$!
  PIDS=("$RHEOD_PID")
  addr=""
  for _ in $(seq 1 200); do
    addr=$(grep -o 'listening on [0-9.]*:[0-9]*' "$LOG" | awk '{print $3}') && [ -n "$addr" ] && break
    sleep 0.05
  done
  [ -n "$addr" ] || { echo "rheod did not start:" >&2; cat "$LOG" >&2; exit 1; }
  ctl=("$RHEOCTL" --server "$addr" --token-file "$DATA/admin.token")
}
stop() {
  for p in "${PIDS[@]:1}"; do kill "$p" 2>/dev/null || true; done
  kill -TERM "$RHEOD_PID" 2>/dev/null || true
  wait "$RHEOD_PID" 2>/dev/null || true
  PIDS=()
}

# The loop's timing over one window: the status before and after, into $DATA/$1-a.json and -b.json.
window() {
  "${ctl[@]}" status --json >"$DATA/$1-a.json"
  sleep "$SECONDS_RUN"
  "${ctl[@]}" status --json >"$DATA/$1-b.json"
}

# The loop's percentiles cover a daemon's whole life: the idle run is one daemon, the press
# another on the same data directory (the mesh made by the first, between its window and its end).
start idle
echo "# idle: ${SECONDS_RUN} s" >&2
window idle
"${ctl[@]}" device status --json >"$DATA/idle-dev.json"

echo "# meshing $(basename "$SKETCH") at ${RESOLUTION} m" >&2
t0=$(date +%s)
"${ctl[@]}" object create "$SKETCH" --name fine --resolution "$RESOLUTION" >/dev/null
mesh_s=$(( $(date +%s) - t0 ))
id=$("${ctl[@]}" object list | awk 'NR==1{print $1}')
tets=$("${ctl[@]}" object get "$id" | grep -o '"tetrahedron_count": *[0-9]*' | grep -o '[0-9]*$' || echo "?")
stop
start press
echo "# $tets tets in ${mesh_s} s; adding (multi-rate by default)" >&2
ADD=$("${ctl[@]}" scene add "$id" --preset organ --integrator implicit)
echo "$ADD" >&2
sleep 2
# The hand presses 2-8 mm into the object and lets go, over and over.
( while :; do
    for d in 0.002 0.005 0.008; do "${ctl[@]}" device push --depth $d --seconds 0.5 --report 0.6 >/dev/null 2>&1 || true; done
    "${ctl[@]}" device hand --release >/dev/null 2>&1 || true
  done ) &
PIDS+=($!)
echo "# pressing: ${SECONDS_RUN} s" >&2
"${ctl[@]}" device status --json >"$DATA/press-dev0.json"
window press
"${ctl[@]}" device status --json >"$DATA/press-dev.json"
"${ctl[@]}" scene show >"$DATA/scene.json"
stop

python3 - "$tets" "$mesh_s" "$RESOLUTION" "$SECONDS_RUN" "$DATA" <<'EOF'
import json, sys, os
tets, mesh_s, res, secs, data = sys.argv[1:6]
def load(name):
    with open(os.path.join(data, name)) as f:
        return json.load(f)
idle = (load("idle-a.json"), load("idle-b.json"))
press = (load("press-a.json"), load("press-b.json"))
idle_dev, press_dev0, press_dev = load("idle-dev.json"), load("press-dev0.json"), load("press-dev.json")
scene = load("scene.json")
def diff(pair, key):
    return int(pair[1].get("loop", {}).get(key, 0)) - int(pair[0].get("loop", {}).get(key, 0))
def pct(pair, section, key):
    return float(pair[1].get("loop", {}).get(section, {}).get(key, 0.0))
print(f"# multi-rate press: {tets} tets ({res} m, meshed in {mesh_s} s), organ, implicit; {secs} s idle, then {secs} s pressed")
print("# counts are over each window; percentiles over each daemon's life (idle: start + window; press: start, add, window)")
print("| run   |  ticks | late | skipped | overruns | period p50 / p99 / p99.9 / max [us] | work p50 / p99 / p99.9 [us] | dev misses |")
for label, pair, d0, d1 in (("idle", idle, None, idle_dev), ("press", press, press_dev0, press_dev)):
    c1 = d1.get("counters", {})
    c0 = d0.get("counters", {}) if d0 else {}
    miss = int(c1.get("deadline_misses", 0)) - int(c0.get("deadline_misses", 0))
    print(f"| {label:<5} | {diff(pair,'ticks'):>6} | {diff(pair,'late_ticks'):>4} | {diff(pair,'skipped_ticks'):>7} | {diff(pair,'overruns'):>8} | "
          f"{pct(pair,'period','p50_us'):7.1f} {pct(pair,'period','p99_us'):7.1f} {pct(pair,'period','p999_us'):8.1f} {pct(pair,'period','max_us'):8.1f} | "
          f"{pct(pair,'work','p50_us'):6.1f} {pct(pair,'work','p99_us'):7.1f} {pct(pair,'work','p999_us'):7.1f} | {miss:>10} |")
for o in scene.get("objects", []):
    m = o.get("multi_rate")
    if not m:
        print(f"# instance {o.get('instance_id')}: not multi-rate"); continue
    print(f"# multi-rate: patch {m.get('patch_inner_nodes')} nodes / {m.get('patch_tets')} tets at {float(o.get('predicted_tick_us', 0)):.0f} us predicted; "
          f"whole every {m.get('period_ticks')} ticks, predicted {float(m.get('predicted_whole_step_ms', 0)):.1f} ms a step, "
          f"last {float(m.get('whole_step_ms', 0)):.1f} ms (max {float(m.get('whole_step_max_ms', 0)):.1f}), its load averaged over {float(m.get('whole_window_ms', 0)):.1f} ms; "
          f"{m.get('syncs', 0)} syncs, {m.get('late_ticks', 0)} ticks with the whole late, {m.get('patch_rebuilds', 0)} patches, "
          f"{m.get('whole_restores', 0)} whole restores ({m.get('whole_substeps', 0)} substeps a step now); the whole {float(m.get('whole_lag_ms', 0)):.0f} ms behind real time")
EOF
