#!/bin/sh
# ctest driver for the Node reader check: write_sample writes a recording (and a report of what it
# wrote), then read_mcap.mjs reads it with @mcap/core and compares the counts with the report.
#   node_check.sh WRITE_SAMPLE NODE READ_MCAP WEB_ROOT WORK_DIR NAME [write_sample args...]
# A --truncate among the write_sample arguments makes the reader expect a file without footer.
set -eu
write_sample=$1 node=$2 read_mcap=$3 web_root=$4 work=$5 name=$6
shift 6
mkdir -p "$work"
file="$work/$name.mcap"
report="$work/$name.json"
"$write_sample" --out "$file" --report "$report" "$@"
flags=""
for a in "$@"; do
  [ "$a" = "--truncate" ] && flags="--expect-truncated"
done
# shellcheck disable=SC2086  # flags is empty or one word
exec "$node" "$read_mcap" "$file" --expect "$report" --web-root "$web_root" $flags
