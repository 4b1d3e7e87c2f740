#!/usr/bin/env bash
# What a session recording costs, with real processes: rheod --device sim-spidar-g, one object
# made from a sample sketch (the heart, ~900 tetrahedra by default) pressed by the emulated hand
# over and over, recorded for S seconds at each /frames rate (0, 60, 1000 Hz). Prints, from the
# Recording rheod reports at stop: the recorded bytes per second, the /tool samples against the
# ticks they span, the ticks the ring dropped and its peak, the recorder thread's CPU share, and
# the loop's timing over the run (rheoctl status) beside a run without a recording.
#   bench/daemon/record_bench.sh [--build DIR] [--seconds S] [--resolution M] [--sketch FILE]
set -euo pipefail
cd "$(dirname "$0")/../.."
BUILD=build/dev
SECONDS_RUN=30
RESOLUTION=0.012
SKETCH=samples/heart.json
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
cleanup() {
  for p in "${PIDS[@]}"; do kill "$p" 2>/dev/null || true; done
  wait 2>/dev/null || true
}
trap cleanup EXIT

data=$(mktemp -d /tmp/rheo-recordbench-XXXXXX)
log="$data/rheod.log"
"$RHEOD" --listen 127.0.0.1:0 --http off --data-dir "$data" --device sim-spidar-g \
  --watchdog-timeout 100 2>"$log" &
PIDS=($!)
addr=""
for _ in $(seq 1 200); do
  addr=$(grep -o 'listening on [0-9.]*:[0-9]*' "$log" | awk '{print $3}') && [ -n "$addr" ] && break
  sleep 0.05
done
[ -n "$addr" ] || { echo "rheod did not start:" >&2; cat "$log" >&2; exit 1; }
ctl=("$RHEOCTL" --server "$addr" --token-file "$data/admin.token")
"${ctl[@]}" object create "$SKETCH" --name bench --resolution "$RESOLUTION" >/dev/null 2>&1
id=$("${ctl[@]}" object list | awk 'NR==1{print $1}')
tets=$("${ctl[@]}" object get "$id" | grep -o '"tetrahedron_count": *[0-9]*' | grep -o '[0-9]*$')
"${ctl[@]}" scene add "$id" --preset hard-jelly --integrator implicit --set friction=5 >/dev/null
sleep 1
# The hand presses 2-8 mm into the object and lets go, over and over.
( while :; do
    for d in 0.002 0.005 0.008; do
      "${ctl[@]}" device push --depth $d --seconds 0.5 --report 0.6 >/dev/null 2>&1 || true
    done
    "${ctl[@]}" device hand --release >/dev/null 2>&1 || true
  done ) &
PIDS+=($!)
sleep 2

loop_line() { "${ctl[@]}" status | grep -E '^loop:|tick period' | tr -s ' ' | paste -sd ';'; }
field() { grep -o "\"$1\": *\"*[0-9.e+-]*" | head -n 1 | grep -o '[0-9.e+-]*$'; }

echo "# $SKETCH at $RESOLUTION m: $tets tetrahedra; $SECONDS_RUN s per run; $(nproc) cores"
echo "no recording: $(loop_line)"
sleep "$SECONDS_RUN"
echo "no recording, after $SECONDS_RUN s: $(loop_line)"
for hz in 0 60 1000; do
  "${ctl[@]}" record start --name "bench-$hz" --frames-hz "$hz" >/dev/null
  before=$(loop_line)
  sleep "$SECONDS_RUN"
  after=$(loop_line)
  json=$("${ctl[@]}" record stop --json)
  seconds=$(echo "$json" | field duration_s)
  bytes=$(echo "$json" | field bytes)
  tool=$(echo "$json" | grep -o '"/tool": *"[0-9]*' | grep -o '[0-9]*$')
  frames=$(echo "$json" | grep -o '"/frames": *"[0-9]*' | grep -o '[0-9]*$' || echo 0)
  first=$(echo "$json" | field first_tick)
  last=$(echo "$json" | field last_tick)
  dropped=$(echo "$json" | field dropped_ticks || echo 0)
  peak=$(echo "$json" | field ring_peak || echo 0)
  cpu=$(echo "$json" | field recorder_cpu_s)
  awk -v hz="$hz" -v s="$seconds" -v b="$bytes" -v t="$tool" -v f="${frames:-0}" -v a="$first" \
      -v z="$last" -v d="${dropped:-0}" -v p="${peak:-0}" -v c="$cpu" 'BEGIN {
    printf "frames %4d Hz: %.1f s, %.0f kB/s (%.1f MB), /tool %d of %d ticks, %d dropped, ring peak %d of 8192, %d frames (%.1f/s), recorder CPU %.2f %% of a core\n",
      hz, s, b / s / 1e3, b / 1e6, t, z - a + 1, d, p, f, f / s, 100 * c / s }'
  echo "  loop before: $before"
  echo "  loop after:  $after"
done
