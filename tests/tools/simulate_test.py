#!/usr/bin/env python3
"""`rheo simulate` end to end: a sample meshed and dropped 2 cm; every frame reports the shape
change free of rigid motion, the run ends with the summary (peak compression, residual
deformation after unloading), and the VTU series is an index ParaView reads whose every file is
the object's mesh. Bad output paths are refused in words.

    simulate_test.py RHEO SKETCH
"""
import json
import os
import subprocess
import sys
import tempfile
import xml.etree.ElementTree as ET

rheo, sketch = sys.argv[1], sys.argv[2]
failures = []


def check(cond, what):
    if not cond:
        failures.append(what)
        print("FAIL:", what)


def run(*args):
    return subprocess.run([rheo, *args], capture_output=True, text=True, timeout=240)


with tempfile.TemporaryDirectory() as tmp:
    vtu = os.path.join(tmp, "bean.vtu")
    r = run("mesh", sketch, "--out", vtu, "--resolution", "0.012")
    check(r.returncode == 0, f"rheo mesh: {r.stderr}")
    points = int(ET.parse(vtu).getroot().find(".//Piece").get("NumberOfPoints"))
    series = os.path.join(tmp, "series")
    jsonl = os.path.join(tmp, "frames.jsonl")
    r = run("simulate", vtu, "--time", "0.4", "--drop-height", "0.02", "--frame", "0.1",
            "--relax", "0.3", "--jsonl", jsonl, "--vtu-series", series)
    check(r.returncode == 0, f"rheo simulate: {r.stderr}")
    print(r.stderr.strip())
    lines = [json.loads(l) for l in open(jsonl)]
    frames, summary = lines[:-1], lines[-1].get("summary")
    check(len(frames) == 5, f"5 frames (0, 0.1, ... 0.4 s), got {len(frames)}")
    check(all("compression" in f and "deformation_rms" in f for f in frames), "every frame has the shape change")
    # At rest before the fall: no deformation, although the object was lifted 2 cm.
    check(abs(frames[0]["compression"]) < 1e-9 and frames[0]["deformation_rms"] < 1e-9,
          f"frame 0 is undeformed: {frames[0]}")
    check(summary is not None, "the last line is the summary")
    if summary:
        check(0.01 < summary["peak_compression"] < 0.6, f"a drop squashes it: {summary}")
        check(summary["peak_compression"] >= max(f["compression"] for f in frames) - 1e-12,
              "the peak is at least every frame's")
        check(abs(summary["residual_compression"]) < summary["peak_compression"],
              f"it recovers after unloading: {summary}")
        check(summary["relax_s"] == 0.3, "relax as asked")
    check("peak compression" in r.stderr and "residual (plastic) deformation" in r.stderr,
          "the report says both in words")
    # The series: the index lists every frame's file at its time, each the whole mesh.
    root = ET.parse(os.path.join(series, "series.pvd")).getroot()
    check(root.get("type") == "Collection", "series.pvd is a VTK collection")
    sets = root.findall("./Collection/DataSet")
    check(len(sets) == len(frames), f"{len(frames)} datasets, got {len(sets)}")
    for d, f in zip(sets, frames):
        check(abs(float(d.get("timestep")) - f["time"]) < 1e-9, f"timestep {d.get('timestep')} = frame time {f['time']}")
        piece = ET.parse(os.path.join(series, d.get("file"))).getroot().find(".//Piece")
        check(piece is not None and int(piece.get("NumberOfPoints")) == points, f"{d.get('file')} has the mesh's {points} points")
    # A series that cannot be written is refused, saying where.
    r = run("simulate", vtu, "--time", "0.01", "--vtu-series", "/proc/rheo-cannot-write")
    check(r.returncode == 1 and "cannot write the VTU series in /proc/rheo-cannot-write" in r.stderr,
          f"an unwritable series: rc {r.returncode} {r.stderr.strip()}")

print("1 passed, 0 failed" if not failures else f"{len(failures)} checks failed")
sys.exit(1 if failures else 0)
