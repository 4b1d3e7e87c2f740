#!/usr/bin/env bash
# The deployment, as far as this machine can test it: `cmake --install` into a temporary prefix,
# then the installed rheod runs from there (its frame files and studio found next to it), the
# installed rheoctl talks to it with the admin token, the installed systemd unit passes
# `systemd-analyze verify`, the udev rule parses, and `cpack -G DEB` makes a package holding them.
# Usage: install_test.sh BUILD_DIR
set -euo pipefail
BUILD=$(cd "$1" && pwd)
TMP=$(mktemp -d)
PID=""
cleanup() {
  [ -n "$PID" ] && kill "$PID" 2>/dev/null && wait "$PID" 2>/dev/null
  rm -rf "$TMP"
}
trap cleanup EXIT
fail() { echo "FAIL: $*"; [ -f "$TMP/rheod.log" ] && tail -20 "$TMP/rheod.log"; exit 1; }

PREFIX=$TMP/prefix
cmake --install "$BUILD" --prefix "$PREFIX" > "$TMP/install.log" || fail "cmake --install: $(tail -5 "$TMP/install.log")"
for f in bin/rheod bin/rheoctl bin/spidar-g-sim share/rheo/devices/spidar_g_x5.json \
         share/rheo/web/index.html share/rheo/web/js/main.js \
         share/rheo/web/node_modules/three/build/three.module.js \
         lib/systemd/system/rheod.service lib/udev/rules.d/60-rheo-spidar-g.rules \
         share/rheo/deploy/rheod.toml share/rheo/deploy/Containerfile; do
  [ -e "$PREFIX/$f" ] || fail "the install has no $f"
done
echo "installed $(find "$PREFIX" -type f | wc -l) files into a temporary prefix"

# The unit names the installed rheod and passes systemd's own check.
grep -q "^ExecStart=$PREFIX/bin/rheod " "$PREFIX/lib/systemd/system/rheod.service" \
  || fail "the installed unit's ExecStart does not name $PREFIX/bin/rheod"
if command -v systemd-analyze > /dev/null; then
  out=$(systemd-analyze verify "$PREFIX/lib/systemd/system/rheod.service" 2>&1) || fail "systemd-analyze verify: $out"
  # Only a missing user may be reported (the package's postinst-free install does not make it).
  if [ -n "$out" ] && echo "$out" | grep -v -q "rheo"; then fail "systemd-analyze verify: $out"; fi
  echo "systemd-analyze verify: clean${out:+ ($out)}"
else
  echo "systemd-analyze not installed: unit check skipped"
fi

# The udev rule: every line a comment or KEY[{attr}] OP "value" pairs that udev knows.
python3 - "$PREFIX/lib/udev/rules.d/60-rheo-spidar-g.rules" <<'PY' || fail "the udev rule does not parse"
import re, sys
keys = {"SUBSYSTEM", "ENV", "ATTR", "ATTRS", "GROUP", "MODE", "SYMLINK", "TAG", "KERNEL", "OWNER"}
pair = re.compile(r'\s*([A-Z]+)(\{[A-Za-z_]+\})?\s*(==|!=|\+=|:=|=)\s*"([^"]*)"\s*(,|$)')
n = 0
for no, line in enumerate(open(sys.argv[1]), 1):
    line = line.strip()
    if not line or line.startswith("#"):
        continue
    pos, ops = 0, []
    while pos < len(line):
        m = pair.match(line, pos)
        if not m or m.group(1) not in keys:
            sys.exit(f"line {no}: cannot parse at: {line[pos:]}")
        ops.append(m.group(3))
        pos = m.end()
    if not any(o == "==" for o in ops) or not any(o in ("=", "+=") for o in ops):
        sys.exit(f"line {no}: a rule needs a match (==) and an assignment (=)")
    n += 1
print(f"udev rule: {n} rules parse")
PY

# The installed daemon runs from the prefix: the emulator with the installed frame file, the
# studio from share/rheo/web.
DATA=$TMP/data
"$PREFIX/bin/rheod" --listen 127.0.0.1:0 --http 127.0.0.1:0 --data-dir "$DATA" --device sim-spidar-g \
  --no-realtime --sim-budget 0 > "$TMP/rheod.log" 2>&1 &
PID=$!
for _ in $(seq 1 300); do
  grep -q "studio at http://" "$TMP/rheod.log" && break
  kill -0 "$PID" 2>/dev/null || fail "the installed rheod exited"
  sleep 0.1
done
grep -q "frame file $PREFIX/share/rheo/devices/spidar_g_x5.json" "$TMP/rheod.log" \
  || fail "the installed rheod did not use the installed frame file"
GRPC=$(sed -n 's/.*listening on \(127.0.0.1:[0-9]*\).*/\1/p' "$TMP/rheod.log" | head -1)
HTTP=$(sed -n 's/.*studio at http:\/\/\(127.0.0.1:[0-9]*\)\/.*/\1/p' "$TMP/rheod.log" | head -1)
[ -n "$GRPC" ] && [ -n "$HTTP" ] || fail "no addresses in the log"
python3 - "$HTTP" <<'PY' || fail "the installed studio is not served"
import sys, urllib.request
base = "http://" + sys.argv[1]
page = urllib.request.urlopen(base + "/").read().decode()
assert "Rheo" in page, "index.html"
three = urllib.request.urlopen(base + "/vendor/three/build/three.module.js").read()
assert len(three) > 100000, "three.module.js"
print(f"studio served from the install: / {len(page)} bytes, three.module.js {len(three)} bytes")
PY
"$PREFIX/bin/rheoctl" --server "$GRPC" --data-dir "$DATA" whoami | grep -q "^admin (admin)$" \
  || fail "the installed rheoctl did not authenticate with the admin token"
"$PREFIX/bin/rheoctl" --server "$GRPC" --data-dir "$DATA" device status | grep -q "SPIDAR-G" \
  || fail "rheoctl device status"
echo "installed rheod and rheoctl work: $GRPC"
kill "$PID"; wait "$PID" || true; PID=""

# The package: cpack -G DEB over the same install (skipped without dpkg-deb).
if command -v dpkg-deb > /dev/null && [ "${RHEO_SKIP_DEB:-0}" != "1" ]; then
  (cd "$TMP" && cpack -G DEB --config "$BUILD/CPackConfig.cmake" -B "$TMP/deb" > "$TMP/cpack.log" 2>&1) \
    || fail "cpack: $(tail -5 "$TMP/cpack.log")"
  DEB=$(ls "$TMP"/deb/rheo_*.deb | head -1)
  dpkg-deb -c "$DEB" > "$TMP/deb.list"
  for f in ./usr/bin/rheod ./usr/bin/rheoctl ./usr/lib/systemd/system/rheod.service \
           ./usr/share/rheo/web/index.html; do
    grep -q " $f$" "$TMP/deb.list" || fail "the .deb has no $f"
  done
  echo "package: $(basename "$DEB"), $(du -k "$DEB" | cut -f1) KB, depends: $(dpkg-deb -f "$DEB" Depends | cut -c1-120)"
fi
echo "install_test: passed"
