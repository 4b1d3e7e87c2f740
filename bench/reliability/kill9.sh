#!/usr/bin/env bash
# rheod killed with SIGKILL, over and over, in three situations: while idle, during a mesh job and
# during a recording (an object in the scene pressed by the emulated hand). After each kill rheod
# is started again on the same data directory, and the script checks what a lab would lose:
#   - the object store: SQLite's PRAGMA integrity_check says "ok";
#   - every design stored before the kill (each one rheoctl saw acknowledged) is listed and its
#     mesh exports (rheoctl object export, VTU);
#   - every recording is listed COMPLETE or TRUNCATED (none FAILED), and each one replays offline
#     (rheo replay) up to its last complete chunk.
# Prints one line per kill and a summary with the restart times.
#   bench/reliability/kill9.sh [--build DIR] [--rounds N]
set -euo pipefail
cd "$(dirname "$0")/../.."
BUILD=build/dev
ROUNDS=20
while [ $# -gt 0 ]; do
  case "$1" in
    --build) BUILD=$2; shift 2 ;;
    --rounds) ROUNDS=$2; shift 2 ;;
    *) echo "usage: $0 [--build DIR] [--rounds N]" >&2; exit 2 ;;
  esac
done
RHEOD="$BUILD/server/daemon/rheod"
RHEOCTL="$BUILD/clients/cli/rheoctl"
RHEO="$BUILD/server/tools/rheo/rheo"
for f in "$RHEOD" "$RHEOCTL" "$RHEO"; do
  [ -x "$f" ] || { echo "missing $f (build rheod, rheoctl and rheo in $BUILD)" >&2; exit 1; }
done
command -v sqlite3 >/dev/null || { echo "sqlite3 is needed (apt-get install sqlite3)" >&2; exit 1; }

data=$(mktemp -d /tmp/rheo-kill9-XXXXXX)
PID=""
cleanup() {
  [ -n "$PID" ] && kill -9 "$PID" 2>/dev/null || true
  wait 2>/dev/null || true
}
trap cleanup EXIT

addr=""
start_rheod() {  # starts rheod on $data; sets PID, addr and the start-up time
  local log="$data/rheod.log" t0
  : >"$log"
  t0=$(date +%s.%N)
  "$RHEOD" --listen 127.0.0.1:0 --http off --data-dir "$data" --device sim-spidar-g \
    --watchdog-timeout 100 2>"$log" &
  PID=$!
  addr=""
  for _ in $(seq 1 400); do
    addr=$(grep -o 'listening on [0-9.]*:[0-9]*' "$log" | awk '{print $3}') && [ -n "$addr" ] && break
    kill -0 "$PID" 2>/dev/null || break
    sleep 0.025
  done
  if [ -z "$addr" ]; then
    echo "rheod did not start:" >&2
    cat "$log" >&2
    exit 1
  fi
  START_S=$(awk -v a="$(date +%s.%N)" -v b="$t0" 'BEGIN { printf "%.3f", a - b }')
}
ctl() { "$RHEOCTL" --server "$addr" --token-file "$data/admin.token" "$@"; }

kill9() {
  kill -9 "$PID"
  wait "$PID" 2>/dev/null || true
  PID=""
}

expected="$data/expected-ids"  # designs acknowledged before a kill
: >"$expected"
failures=0
killed_inside=0  # "during a job" kills that came before the job reported done
starts=()
check() {  # after a restart: the store, every acknowledged design, every recording
  local what=$1 bad="" n=0 rec_ok=0 rec_n=0 rec_empty=0
  local integrity
  integrity=$(sqlite3 "$data/objects.db" 'PRAGMA integrity_check;' 2>&1)
  [ "$integrity" = "ok" ] || bad+=" integrity_check: $integrity;"
  local listed
  listed=$(ctl object list 2>&1 | awk '{print $1}')
  while read -r id; do
    [ -z "$id" ] && continue
    n=$((n + 1))
    grep -qx "$id" <<<"$listed" || { bad+=" $id is not listed;"; continue; }
    ctl object export "$id" --format vtu --out "$data/export.vtu" >/dev/null 2>&1 &&
      [ -s "$data/export.vtu" ] || bad+=" $id does not export;"
  done <"$expected"
  while read -r rid state _; do
    [ -z "$rid" ] && continue
    rec_n=$((rec_n + 1))
    case "$state" in
      complete | truncated)
        # Each file is replayed once, the first time it is listed (a file never changes after
        # its recording ends); later checks see its listing only.
        if grep -qx "$rid" "$data/replayed" 2>/dev/null; then
          rec_ok=$((rec_ok + 1))
        elif "$RHEO" replay "$data/recordings/$rid.mcap" >"$data/replay.txt" 2>&1; then
          echo "$rid" >>"$data/replayed"
          rec_ok=$((rec_ok + 1))
        elif [ "$state" = truncated ] && grep -q "holds no /tool sample" "$data/replay.txt"; then
          rec_empty=$((rec_empty + 1))  # killed before its first chunk was complete
        else
          bad+=" $rid ($state) does not replay: $(tail -1 "$data/replay.txt");"
        fi ;;
      *) bad+=" $rid is $state;" ;;
    esac
  done < <(ctl record list 2>/dev/null | awk 'NR>1 && $1 ~ /^rec-/ {print $1, $2}')
  if [ -n "$bad" ]; then
    failures=$((failures + 1))
    printf '%-10s FAILED:%s\n' "$what" "$bad"
  else
    printf '%-10s ok: restart %.2f s, %d designs intact and exported, %d of %d recordings replay (%d empty: killed before a chunk)\n' \
      "$what" "$START_S" "$n" "$rec_ok" "$rec_n" "$rec_empty"
  fi
  starts+=("$START_S")
}

start_rheod
ctl object create samples/heart.json --name heart --resolution 0.012 >/dev/null 2>&1
ctl object list | awk '{print $1}' >>"$expected"
for round in $(seq 1 "$ROUNDS"); do
  # Idle: nothing running.
  sleep 0.2
  kill9
  start_rheod
  check "idle $round"

  # During a mesh job (a fine bean): killed as soon as the job reports a stage past the queue,
  # so that the kill lands inside the job rather than after it (rheoctl prints each stage).
  ctl object create samples/bean.json --name "bean $round" --resolution 0.003 >"$data/job.txt" 2>&1 &
  job=$!
  for _ in $(seq 1 1000); do
    grep -v " queued " "$data/job.txt" 2>/dev/null | grep -q "%" && break
    sleep 0.005
  done
  inside=$(grep -c " done " "$data/job.txt" 2>/dev/null || true)
  [ "${inside:-0}" -eq 0 ] && killed_inside=$((killed_inside + 1))
  kill9
  wait "$job" 2>/dev/null || true
  start_rheod
  check "job $round"
  # A design stored in this round (the job may have finished before the kill) must stay.
  ctl object list | awk '{print $1}' | sort -u >"$data/now"
  sort -u "$expected" "$data/now" >"$data/merged" && mv "$data/merged" "$expected"

  # During a recording: the heart in the scene, the hand pressing it, 3-4 s recorded (a chunk
  # is 1 MiB: about 3 s of this session at 60 frames/s).
  heart=$(head -1 "$expected")
  ctl record start --name "round $round" >/dev/null 2>&1
  ctl scene add "$heart" --preset hard-jelly --integrator implicit --set friction=5 >/dev/null
  ctl device push --depth 0.005 --seconds 3 >/dev/null 2>&1 &
  push=$!
  sleep "3.$((RANDOM % 10))"
  kill9
  wait "$push" 2>/dev/null || true
  start_rheod
  check "record $round"
done
kill9

sorted=$(printf '%s\n' "${starts[@]}" | sort -n)
count=${#starts[@]}
median=$(sed -n "$(((count + 1) / 2))p" <<<"$sorted")
max=$(tail -1 <<<"$sorted")
echo "kills: $count (idle, during a job, during a recording: $ROUNDS each); failures: $failures"
echo "kills during a job that came before it was done: $killed_inside of $ROUNDS"
echo "restart to listening: median $median s, max $max s"
echo "designs at the end: $(wc -l <"$expected"); recordings: $(ls "$data/recordings"/*.mcap 2>/dev/null | wc -l)"
rm -rf "$data"
[ "$failures" -eq 0 ]
