#!/bin/sh
# ctest driver: a recording made by a real rheod, read by Foxglove's @mcap/core and protobufjs.
# rheod starts (the emulated SPIDAR-G, a temporary data dir), rheoctl records about a second
# while the bean of samples/ is stored and added to the scene and a parameter is set, stops the
# recording (its Recording as JSON is the expectation), exports it, and read_mcap.mjs --rheod
# decodes every message with the schemas embedded in the file and checks the counts, the tick
# times and the scene's mesh against it.
#   rheod_node_check.sh RHEOD RHEOCTL NODE READ_MCAP WEB_ROOT SAMPLES WORK_DIR
set -eu
rheod=$1 rheoctl=$2 node=$3 read_mcap=$4 web_root=$5 samples=$6 work=$7
rm -rf "$work"
mkdir -p "$work/data"
log="$work/rheod.log"
"$rheod" --listen 127.0.0.1:0 --http off --data-dir "$work/data" --no-realtime \
  --device sim-spidar-g --log-level info 2>"$log" &
pid=$!
cleanup() {
  kill -9 "$pid" 2>/dev/null || true
}
trap cleanup EXIT
fail() {
  echo "rheod_node_check: $*" >&2
  echo "--- rheod log ---" >&2
  cat "$log" >&2
  exit 1
}
# The address from the daemon's "listening on" line (port 0: any free one), within 30 s.
addr=""
i=0
while [ -z "$addr" ]; do
  addr=$(sed -n 's/.* listening on \([0-9.]*:[0-9]*\) .*/\1/p' "$log" | head -n 1)
  [ -n "$addr" ] && break
  kill -0 "$pid" 2>/dev/null || fail "rheod exited before listening"
  i=$((i + 1))
  [ "$i" -gt 300 ] && fail "rheod did not listen within 30 s"
  sleep 0.1
done
ctl() {
  "$rheoctl" --server "$addr" --data-dir "$work/data" "$@"
}
id=$(ctl record start --name node-check --frames-hz 100) || fail "record start failed"
ctl object create "$samples/bean.json" --resolution 0.012 --add >"$work/object.txt" ||
  fail "object create failed"
# A parameter change within the tick budget: k_v=300 keeps the bean at its substeps (a stiff
# k_v adds substeps, and the admission may then refuse it on a machine whose cost model reads high).
ctl param set 0 k_v=300 >/dev/null || fail "param set failed"
sleep 1  # recording a second of the scene, not synchronising
ctl record stop --json >"$work/recording.json" || fail "record stop failed"
ctl record export "$id" --out "$work/recording.mcap" || fail "record export failed"
kill -TERM "$pid"
wait "$pid" || fail "rheod did not exit 0 on SIGTERM"
trap - EXIT
exec "$node" "$read_mcap" "$work/recording.mcap" --rheod "$work/recording.json" \
  --web-root "$web_root"
