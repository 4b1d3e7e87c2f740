#!/usr/bin/env bash
# The full 1 kHz tick end to end, with real processes: rheod --device sim-spidar-g (emulator on a
# pseudo-terminal, real driver, pose solver, QP), one object of about 5k tetrahedra made from a
# sample sketch and pressed by the emulated hand over and over, for S seconds; then the same with
# 8 `rheoctl watch --positions` clients at 60 Hz and a mesh job running back to back. Prints the
# loop's own timing (rheoctl status) and the device counters of each run.
#   bench/daemon/full_tick.sh [--build DIR] [--seconds S] [--resolution M] [--sketch FILE]
set -euo pipefail
cd "$(dirname "$0")/../.."
BUILD=build/full
SECONDS_RUN=60
RESOLUTION=0.007
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
cleanup() {
  for p in "${PIDS[@]}"; do kill "$p" 2>/dev/null || true; done
  wait 2>/dev/null || true
}
trap cleanup EXIT

# run LABEL LOADED
run() {
  local label=$1 loaded=$2
  local data log addr
  data=$(mktemp -d /tmp/rheo-fulltick-XXXXXX)
  log="$data/rheod.log"
  "$RHEOD" --listen 127.0.0.1:0 --data-dir "$data" --device sim-spidar-g 2>"$log" &
  local rheod_pid=$!
  PIDS=("$rheod_pid")
  for _ in $(seq 1 200); do
    addr=$(grep -o 'listening on [0-9.]*:[0-9]*' "$log" | awk '{print $3}') && [ -n "$addr" ] && break
    sleep 0.05
  done
  [ -n "${addr:-}" ] || { echo "rheod did not start:" >&2; cat "$log" >&2; exit 1; }
  local ctl=("$RHEOCTL" --server "$addr" --token-file "$data/admin.token")
  "${ctl[@]}" object create "$SKETCH" --name bench --resolution "$RESOLUTION" >/dev/null 2>&1
  local id tets
  id=$("${ctl[@]}" object list | awk 'NR==1{print $1}')
  tets=$("${ctl[@]}" object get "$id" | grep -o '"tetrahedron_count": *[0-9]*' | grep -o '[0-9]*$' || echo "?")
  "${ctl[@]}" scene add "$id" --preset organ --integrator implicit >/dev/null
  sleep 1
  # The hand presses 2-8 mm into the object and lets go, over and over.
  ( while :; do
      for d in 0.002 0.005 0.008; do "${ctl[@]}" device push --depth $d --seconds 0.5 --report 0.6 >/dev/null 2>&1 || true; done
      "${ctl[@]}" device hand --release >/dev/null 2>&1 || true
    done ) &
  PIDS+=($!)
  if [ "$loaded" = 1 ]; then
    for _ in $(seq 1 8); do
      "${ctl[@]}" watch --rate 60 --positions >/dev/null 2>&1 &
      PIDS+=($!)
    done
    ( while :; do
        "${ctl[@]}" object create "$SKETCH" --name job --resolution 0.003 >/dev/null 2>&1 || true
        j=$("${ctl[@]}" object list | awk '$2=="job"{print $1; exit}')
        [ -n "$j" ] && "${ctl[@]}" object delete "$j" >/dev/null 2>&1 || true
      done ) &
    PIDS+=($!)
  fi
  sleep "$SECONDS_RUN"
  local st dev
  st=$("${ctl[@]}" status --json)
  dev=$("${ctl[@]}" device status --json)
  for p in "${PIDS[@]:1}"; do kill "$p" 2>/dev/null || true; done
  kill -TERM "$rheod_pid" 2>/dev/null || true
  wait "$rheod_pid" 2>/dev/null || true
  PIDS=()
  python3 - "$label" "$tets" "$st" "$dev" <<'EOF'
import json, sys
label, tets, st, dev = sys.argv[1], sys.argv[2], json.loads(sys.argv[3]), json.loads(sys.argv[4])
loop = st.get("loop", {})
def p(section, key):
    return float(loop.get(section, {}).get(key, 0.0))
c = dev.get("counters", {})
print(f"| {label:<8} | {tets:>5} | {int(loop.get('ticks', 0)):>6} | "
      f"{p('period','p50_us'):7.1f} {p('period','p99_us'):8.1f} {p('period','p999_us'):8.1f} {p('period','max_us'):9.1f} | "
      f"{p('work','p50_us'):7.1f} {p('work','p99_us'):8.1f} {p('work','p999_us'):8.1f} | "
      f"{int(loop.get('late_ticks', 0)):>5} {int(loop.get('overruns', 0)):>6} {int(loop.get('skipped_ticks', 0)):>7} | "
      f"{int(c.get('deadline_misses', 0)):>5} {int(c.get('watchdog_trips', 0)):>4} {int(c.get('device_errors', 0)):>4} | "
      f"{int(loop.get('restores', 0)):>4} | "
      f"{'yes' if loop.get('realtime_priority') else 'no':>3} |")
EOF
  rm -rf "$data"
}

echo "# full tick, ${SECONDS_RUN} s per run, sketch $(basename "$SKETCH") at ${RESOLUTION} m, preset organ, implicit"
echo "| run      |  tets |  ticks | period p50 / p99 / p99.9 / max [us]  | work p50 / p99 / p99.9 [us] |  late overrn skipped |  miss trip  err | rstr | rt  |"
run idle 0
run loaded 1
