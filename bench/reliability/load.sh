#!/usr/bin/env bash
# rheod under a lab's load, with real processes: rheod --device sim-spidar-g, one object (the bean
# at 6 mm, about 5k tetrahedra) pressed by the emulated hand, and for S seconds at once:
#   - W frame watchers (rheoctl watch, gRPC, 60 frames/s with positions);
#   - a mesh job every 2 s (the heart at 12 mm, stored);
#   - a parameter change every 100 ms (k_v between two values; a rheoctl process each, so the
#     clients' own start-up shares the machine too);
#   - a recording of it all (60 frames/s).
# Before that, the same daemon runs S/4 seconds with the object and the hand only: the idle floor.
# Prints, for the floor and the load: the loop's ticks, late ticks, overruns and skipped periods
# (per 1000 ticks), its period percentiles (cumulative since start, as rheoctl status gives them),
# frames each watcher got and dropped, the recording's dropped ticks and events, rheod's RSS and
# open descriptors at the start and the end, and the jobs and changes done.
#   bench/reliability/load.sh [--build DIR] [--seconds S] [--watchers W] [--resolution M]
# (The browser gateway's viewers are measured by bench/web/viewers_bench.)
set -euo pipefail
cd "$(dirname "$0")/../.."
BUILD=build/dev
SECONDS_RUN=60
WATCHERS=32
RESOLUTION=0.006
while [ $# -gt 0 ]; do
  case "$1" in
    --build) BUILD=$2; shift 2 ;;
    --seconds) SECONDS_RUN=$2; shift 2 ;;
    --watchers) WATCHERS=$2; shift 2 ;;
    --resolution) RESOLUTION=$2; shift 2 ;;
    *) echo "usage: $0 [--build DIR] [--seconds S] [--watchers W] [--resolution M]" >&2; exit 2 ;;
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

data=$(mktemp -d /tmp/rheo-load-XXXXXX)
log="$data/rheod.log"
"$RHEOD" --listen 127.0.0.1:0 --http off --data-dir "$data" --device sim-spidar-g \
  --watchdog-timeout 100 --limit-streams 0 --limit-calls 0 2>"$log" &
RHEOD_PID=$!
PIDS=($RHEOD_PID)
addr=""
for _ in $(seq 1 400); do
  addr=$(grep -o 'listening on [0-9.]*:[0-9]*' "$log" | awk '{print $3}') && [ -n "$addr" ] && break
  sleep 0.025
done
[ -n "$addr" ] || { echo "rheod did not start:" >&2; cat "$log" >&2; exit 1; }
ctl=("$RHEOCTL" --server "$addr" --token-file "$data/admin.token")
rss() { awk '/^VmRSS:/ {print $2}' "/proc/$RHEOD_PID/status"; }
fds() { ls "/proc/$RHEOD_PID/fd" | wc -l; }
counters() {  # ticks late overruns skipped
  "${ctl[@]}" status | grep -o 'Hz, [0-9]* ticks, [0-9]* late, [0-9]* overruns, [0-9]* skipped' |
    grep -o '[0-9]*' | paste -sd ' '
}
period() { "${ctl[@]}" status | grep -E '^ *period' | tr -s ' '; }
report() {  # label "before counters" "after counters"
  awk -v label="$1" -v a="$2" -v b="$3" 'BEGIN {
    split(a, x, " "); split(b, y, " ");
    t = y[1] - x[1]; if (t < 1) t = 1;
    printf "%-6s %7d ticks; per 1000 ticks: %.1f late, %.1f overruns, %.1f skipped\n",
      label, t, 1000 * (y[2] - x[2]) / t, 1000 * (y[3] - x[3]) / t, 1000 * (y[4] - x[4]) / t }'
}

"${ctl[@]}" object create samples/bean.json --name load --resolution "$RESOLUTION" >/dev/null 2>&1
id=$("${ctl[@]}" object list | awk 'NR==1{print $1}')
tets=$("${ctl[@]}" object get "$id" | grep -o '"tetrahedron_count": *[0-9]*' | grep -o '[0-9]*$')
"${ctl[@]}" scene add "$id" --preset hard-jelly --integrator implicit --set friction=5 >/dev/null
instance=1  # the first object of a fresh daemon's scene
sleep 1
# The hand presses 2-8 mm into the object and lets go, over and over (floor and load alike).
( while :; do
    for d in 0.002 0.005 0.008; do
      "${ctl[@]}" device push --depth $d --seconds 0.5 --report 0.6 >/dev/null 2>&1 || true
    done
    "${ctl[@]}" device hand --release >/dev/null 2>&1 || true
  done ) &
PIDS+=($!)
sleep 2

echo "# bean at $RESOLUTION m: $tets tetrahedra; $(nproc) cores; $WATCHERS watchers; $SECONDS_RUN s of load"
rss0=$(rss) fds0=$(fds)
c0=$(counters)
sleep $((SECONDS_RUN / 4))
c1=$(counters)
report floor "$c0" "$c1"
echo "  $(period) (cumulative, at the end of the floor)"

"${ctl[@]}" record start --name load >/dev/null 2>&1
for w in $(seq 1 "$WATCHERS"); do
  timeout "$((SECONDS_RUN + 5))" "${ctl[@]}" watch --rate 60 --json --positions \
    >"$data/watch-$w.jsonl" 2>/dev/null &
  PIDS+=($!)
done
( n=0; while :; do
    "${ctl[@]}" object create samples/heart.json --name "job $n" --resolution 0.012 >/dev/null 2>&1 &&
      echo ok >>"$data/jobs" || echo failed >>"$data/jobs"
    n=$((n + 1))
    sleep 2
  done ) &
PIDS+=($!)
( v=0; while :; do
    k=$((400 + 100 * (v % 2)))
    # Not waited for: each change is its own rheoctl process, started every 100 ms.
    { "${ctl[@]}" param set "$instance" "k_v=$k" >/dev/null 2>&1 && echo ok >>"$data/params" ||
      echo failed >>"$data/params"; } &
    v=$((v + 1))
    sleep 0.1
  done ) &
PIDS+=($!)
sleep "$SECONDS_RUN"
c2=$(counters)
report load "$c1" "$c2"
echo "  $(period) (cumulative, at the end of the load)"
json=$("${ctl[@]}" record stop --json 2>/dev/null || true)
rss1=$(rss) fds1=$(fds)
for p in "${PIDS[@]:1}"; do kill "$p" 2>/dev/null || true; done
sleep 1
frames=() drops=()
for w in $(seq 1 "$WATCHERS"); do
  frames+=($(wc -l <"$data/watch-$w.jsonl"))
  drops+=($( (grep -o '"dropped_frames": *"*[0-9]*' "$data/watch-$w.jsonl" || true) |
    grep -o '[0-9]*$' | awk '{s += $1} END {print s + 0}'))
done
printf '%s\n' "${frames[@]}" | sort -n | awk -v s="$SECONDS_RUN" '{a[NR] = $1} END {
  printf "watchers: frames each min %d, median %d, max %d (%.1f/s at the median)\n",
    a[1], a[int((NR + 1) / 2)], a[NR], a[int((NR + 1) / 2)] / s }'
printf '%s\n' "${drops[@]}" | awk '{s += $1} END {printf "dropped frames (slow client skips): %d in all\n", s}'
num() { { grep -o "\"$1\": *\"*[0-9]*" || true; } | grep -o '[0-9]*$' | head -1 | awk '{print $1 + 0} END {if (!NR) print 0}'; }
echo "recording: $(echo "$json" | num dropped_ticks) ticks dropped, $(echo "$json" | num dropped_events)" \
  "events dropped, $(echo "$json" | num bytes) bytes"
count() { grep -c "$1" "$2" 2>/dev/null || true; }
echo "jobs: $(count ok "$data/jobs") stored, $(count failed "$data/jobs") failed;" \
  "parameter changes: $(count ok "$data/params") taken, $(count failed "$data/params") refused"
echo "rheod RSS ${rss0} -> ${rss1} kB; open descriptors ${fds0} -> ${fds1}"
rm -rf "$data"
