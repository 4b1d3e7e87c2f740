#!/usr/bin/env bash
# rheod under a lab's load, with real processes: rheod --device sim-spidar-g with its browser
# gateway, one object (the bean at 6 mm, about 5k tetrahedra) pressed by the emulated hand, and
# for S seconds at once:
#   - W frame watchers (rheoctl watch, gRPC, 60 frames/s with positions, JSON);
#   - V studio viewers through the gateway's WebSocket (bench/web/web_watchers: the studio's own
#     request, 30 frames/s with 16-bit positions, JSON), as V browser tabs of /?view would be;
#   - a mesh job every 2 s (the heart at 12 mm, stored; --job-every J: every J s, 0 = none);
#   - a parameter change every 100 ms (k_v between two values; a rheoctl process each, so the
#     clients' own start-up shares the machine too);
#   - a recording of it all (60 frames/s).
# Before that, the same daemon runs S/4 seconds with the object and the hand only: the idle floor.
# Prints, for the floor and the load: the loop's ticks, late ticks, overruns and skipped periods
# (per 1000 ticks), its period percentiles (cumulative since start, as rheoctl status gives them),
# frames each watcher of either kind got and dropped, the recording's dropped ticks and events,
# rheod's RSS and open descriptors at the start and the end, and the jobs and changes done.
# --sample N (a soak: e.g. --seconds 600 --sample 10) also samples rheod's RSS and open
# descriptors every N seconds of the load and prints their least-squares slopes (MB/min, fds/min)
# with the first and last samples.
#   bench/reliability/load.sh [--build DIR] [--seconds S] [--watchers W] [--web-watchers V]
#                             [--sample N] [--resolution M] [--job-every J]
# RHEOD_WRAP="heaptrack -o FILE" (or any command and its arguments) runs rheod under it, to find
# where a soak's memory goes.
# (bench/web/viewers_bench measures the gateway's viewers alone.)
set -euo pipefail
cd "$(dirname "$0")/../.."
BUILD=build/dev
SECONDS_RUN=60
WATCHERS=16
WEB_WATCHERS=16
WEB_RATE=30
SAMPLE=0
RESOLUTION=0.006
JOB_EVERY=2
usage="usage: $0 [--build DIR] [--seconds S] [--watchers W] [--web-watchers V] [--sample N] [--resolution M] [--job-every J]"
int() {  # option value: a whole number >= $3
  [[ "$2" =~ ^[0-9]+$ ]] && [ "$2" -ge "$3" ] || { echo "$1: '$2' is not a whole number >= $3" >&2; exit 2; }
}
while [ $# -gt 0 ]; do
  [ $# -ge 2 ] || { echo "$1: needs a value; $usage" >&2; exit 2; }
  case "$1" in
    --build) BUILD=$2 ;;
    --seconds) int "$1" "$2" 4; SECONDS_RUN=$2 ;;
    --watchers) int "$1" "$2" 0; WATCHERS=$2 ;;
    --web-watchers) int "$1" "$2" 0; WEB_WATCHERS=$2 ;;
    --sample) int "$1" "$2" 1; SAMPLE=$2 ;;
    --resolution) RESOLUTION=$2 ;;
    --job-every) int "$1" "$2" 0; JOB_EVERY=$2 ;;
    *) echo "$usage" >&2; exit 2 ;;
  esac
  shift 2
done
RHEOD="$BUILD/server/daemon/rheod"
RHEOCTL="$BUILD/clients/cli/rheoctl"
WEB_WATCH="$BUILD/bench/web/web_watchers"
for f in "$RHEOD" "$RHEOCTL" "$WEB_WATCH"; do
  [ -x "$f" ] || { echo "missing $f (build rheod, rheoctl and web_watchers in $BUILD)" >&2; exit 1; }
done

PIDS=()
cleanup() {
  for p in "${PIDS[@]}"; do kill "$p" 2>/dev/null || true; done
  wait 2>/dev/null || true
}
trap cleanup EXIT

data=$(mktemp -d /tmp/rheo-load-XXXXXX)
log="$data/rheod.log"
read -r -a wrap <<<"${RHEOD_WRAP:-}"
"${wrap[@]}" "$RHEOD" --listen 127.0.0.1:0 --http 127.0.0.1:0 --data-dir "$data" --device sim-spidar-g \
  --watchdog-timeout 100 --limit-streams 0 --limit-calls 0 2>"$log" &
RHEOD_PID=$!
PIDS=($RHEOD_PID)
addr="" web_port=""
for _ in $(seq 1 400); do
  addr=$(grep -o 'listening on [0-9.]*:[0-9]*' "$log" | awk '{print $3}' || true)
  web_port=$(grep -o 'studio at http://127.0.0.1:[0-9]*' "$log" | grep -o '[0-9]*$' || true)
  [ -n "$addr" ] && [ -n "$web_port" ] && break
  sleep 0.025
done
[ -n "$addr" ] && [ -n "$web_port" ] || { echo "rheod did not start:" >&2; cat "$log" >&2; exit 1; }
if [ ${#wrap[@]} -gt 0 ]; then  # RSS and descriptors are rheod's, not its wrapper's
  exe=$(realpath "$RHEOD")
  for p in $(pgrep -f -- "--data-dir $data"); do
    [ "$(readlink "/proc/$p/exe" 2>/dev/null)" = "$exe" ] && RHEOD_PID=$p
  done
  WRAP_PID=${PIDS[0]}
  PIDS=($RHEOD_PID "${PIDS[@]}")  # rheod ends first, so the wrapper sees it out
fi
ctl=("$RHEOCTL" --server "$addr" --token-file "$data/admin.token")
rss() { awk '/^VmRSS:/ {print $2}' "/proc/$RHEOD_PID/status"; }
fds() { ls "/proc/$RHEOD_PID/fd" | wc -l; }
# The RSS's anonymous and file-backed parts [kB] and the threads (where a slope comes from).
parts() { awk '/^(Threads|RssAnon|RssFile):/ {printf "%s ", $2}' "/proc/$RHEOD_PID/status"; }
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

echo "# bean at $RESOLUTION m: $tets tetrahedra; $(nproc) cores; $WATCHERS gRPC watchers at 60 Hz," \
  "$WEB_WATCHERS gateway watchers at $WEB_RATE Hz; $SECONDS_RUN s of load"
rss0=$(rss) fds0=$(fds)
c0=$(counters)
sleep $((SECONDS_RUN / 4))
c1=$(counters)
report floor "$c0" "$c1"
echo "  $(period) (cumulative, at the end of the floor)"

"${ctl[@]}" record start --name load >/dev/null 2>&1
for w in $(seq 1 "$WATCHERS"); do
  # Only each frame's start and its dropped_frames are kept (a frame's JSON is ~60 kB: a 10-minute
  # soak's would fill the disk). grep ends, flushing, when the watcher does: after S seconds,
  # like the gateway's watchers, so frames per second compare.
  timeout "$SECONDS_RUN" "${ctl[@]}" watch --rate 60 --json --positions 2>/dev/null \
    > >(grep -oE '^\{|"dropped_frames": *"?[0-9]+' >"$data/watch-$w.txt") &
  PIDS+=($!)
done
if [ "$WEB_WATCHERS" -gt 0 ]; then
  "$WEB_WATCH" --port "$web_port" --token-file "$data/admin.token" --viewers "$WEB_WATCHERS" \
    --rate "$WEB_RATE" --seconds "$SECONDS_RUN" >"$data/web.txt" 2>&1 &
  WEB_PID=$!
fi
if [ "$SAMPLE" -gt 0 ]; then
  ( while :; do
      echo "$(date +%s.%N) $(rss) $(fds) $(parts)" >>"$data/samples"
      sleep "$SAMPLE"
    done ) &
  PIDS+=($!)
fi
# --job-every 0: no jobs (a soak's control: does the RSS slope follow the stored designs?).
if [ "$JOB_EVERY" -gt 0 ]; then
  ( n=0; while :; do
      "${ctl[@]}" object create samples/heart.json --name "job $n" --resolution 0.012 >/dev/null 2>&1 &&
        echo ok >>"$data/jobs" || echo failed >>"$data/jobs"
      n=$((n + 1))
      sleep "$JOB_EVERY"
    done ) &
  PIDS+=($!)
fi
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
[ "$SAMPLE" -gt 0 ] && echo "$(date +%s.%N) $(rss) $(fds) $(parts)" >>"$data/samples"
c2=$(counters)
report load "$c1" "$c2"
echo "  $(period) (cumulative, at the end of the load)"
json=$("${ctl[@]}" record stop --json 2>/dev/null || true)
rss1=$(rss) fds1=$(fds)
for p in "${PIDS[@]:1}"; do [ "$p" = "${WRAP_PID:-}" ] || kill "$p" 2>/dev/null || true; done
[ -n "${WEB_PID:-}" ] && { wait "$WEB_PID" || true; }
sleep 1
summary() {  # label asked-Hz, then "frames dropped" lines on stdin
  sort -n | awk -v label="$1" -v hz="$2" -v s="$SECONDS_RUN" '{a[NR] = $1; d += $2} END {
    if (!NR) { printf "%s: none\n", label; exit }
    m = a[int((NR + 1) / 2)];
    printf "%s (%d, %d Hz asked): frames each min %d, median %d, max %d (%.1f/s at the median);", \
      label, NR, hz, a[1], m, a[NR], m / s;
    printf " %d frames skipped for them in all (slow client skips)\n", d }'
}
for w in $(seq 1 "$WATCHERS"); do
  f="$data/watch-$w.txt"
  echo "$(grep -c '^{' "$f" || true) $(grep -o '[0-9]*$' "$f" | awk '{s += $1} END {print s + 0}')"
done | summary "gRPC watchers" 60
if [ "$WEB_WATCHERS" -gt 0 ]; then
  sed -n 's/^viewer [0-9]*: \([0-9]*\) frames, \([0-9]*\) dropped.*/\1 \2/p' "$data/web.txt" |
    summary "gateway watchers" "$WEB_RATE"
  ended=$(grep -c 'ended:' "$data/web.txt" || true)
  [ "$ended" -eq 0 ] || { echo "  $ended gateway watcher(s) ended early:"; grep 'ended:' "$data/web.txt" | head -3; }
fi
num() { { grep -o "\"$1\": *\"*[0-9]*" || true; } | grep -o '[0-9]*$' | head -1 | awk '{print $1 + 0} END {if (!NR) print 0}'; }
echo "recording: $(echo "$json" | num dropped_ticks) ticks dropped, $(echo "$json" | num dropped_events)" \
  "events dropped, $(echo "$json" | num bytes) bytes"
count() { [ -f "$2" ] || { echo 0; return; }; grep -c "$1" "$2" || true; }
echo "jobs: $(count ok "$data/jobs") stored, $(count failed "$data/jobs") failed;" \
  "parameter changes: $(count ok "$data/params") taken, $(count failed "$data/params") refused"
echo "rheod RSS ${rss0} -> ${rss1} kB; open descriptors ${fds0} -> ${fds1}"
if [ "$SAMPLE" -gt 0 ]; then
  # Least squares over the samples: RSS [MB], descriptors, anonymous RSS [MB] and threads against
  # time [min]; the RSS also over the second half alone (past the start-up of the load:
  # connections, caches, store pages).
  awk -v every="$SAMPLE" '
    function slope(y, from, to,   i, m, st, stt, sy, sty, d) {
      for (i = from; i <= to; i++) { m++; st += T[i]; stt += T[i] * T[i]; sy += y[i]; sty += T[i] * y[i] }
      d = m * stt - st * st
      return d > 0 ? (m * sty - st * sy) / d : 0
    }
    NR == 1 {t0 = $1}
    { n++; T[n] = ($1 - t0) / 60; R[n] = $2 / 1024; F[n] = $3; A[n] = $4 / 1024; B[n] = $5 / 1024; H[n] = $6
      if (n == 1 || R[n] > rmax) rmax = R[n] }
    END {
      h = int(n / 2) + 1
      printf "soak: %d samples every %d s over %.1f min\n", n, every, T[n]
      printf "  RSS first %.1f MB, last %.1f MB, max %.1f MB; slope %+.3f MB/min\n", R[1], R[n], rmax,
        slope(R, 1, n)
      printf "  open descriptors first %d, last %d; slope %+.3f fds/min\n", F[1], F[n], slope(F, 1, n)
      printf "  of the RSS: anonymous %.1f -> %.1f MB (slope %+.3f MB/min), file-backed %.1f -> %.1f MB\n",
        A[1], A[n], slope(A, 1, n), B[1], B[n]
      printf "  threads first %d, last %d; slope %+.3f/min\n", H[1], H[n], slope(H, 1, n)
      printf "  RSS slope over the second half (%d samples): %+.3f MB/min\n", n - h + 1, slope(R, h, n)
    }' "$data/samples"
fi
rm -rf "$data"
