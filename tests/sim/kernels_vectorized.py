#!/usr/bin/env python3
"""Every `#pragma omp simd` loop of the simulation kernels must vectorise.

The kernels are written as block passes whose inner loop is meant to run in SIMD lanes; if the
compiler cannot vectorise one (a branch it cannot if-convert, a load it cannot prove safe), the
code still works, only several times slower, and no other test notices. The tet kernel ran
scalar that way for several rounds: `std::max(GF[k], 1e-30f)` returns a reference, which GCC
turned into a masked gather, and 58 us became 112 us per call at 5k tets.

Usage: kernels_vectorized.py BUILD_DIR SOURCE...
Recompiles each source with the flags compile_commands.json gives it, for one target ISA at a
time (x86-64-v3 and x86-64-v4, the clones the library runs on current CPUs), with GCC's
vectorisation report, and fails naming each `omp simd` loop that was not vectorised.
"""
import json
import os
import re
import shlex
import subprocess
import sys

ISAS = ["x86-64-v3", "x86-64-v4"]


def pragma_loops(path):
    """Each `#pragma omp simd` loop as (line of its `for`, line of its closing brace), 1-based.

    GCC names a vectorised loop by a location inside it that depends on the flags: an -O3
    build reports the `for`, the CI's RelWithDebInfo build the first statement with code in
    the body (line and column of an inner loop the vectoriser had already unrolled). So a
    loop counts as vectorised when a report falls anywhere in its lines. The kernels' inner
    loops have constant trip counts of 3 or 9 and are unrolled before vectorisation, so a
    report inside the body is the outer loop's."""
    lines = open(path, encoding="utf-8").read().splitlines()
    out = []
    for i, line in enumerate(lines):
        if not line.strip().startswith("#pragma omp simd"):
            continue
        start = i + 1  # 0-based index of the `for`
        if lines[start].split("//", 1)[0].rstrip().endswith(";"):
            out.append((start + 1, start + 1))  # a one-line loop: no braces to match
            continue
        depth, end, opened = 0, start, False
        for n in range(start, len(lines)):
            code = lines[n].split("//", 1)[0]
            depth += code.count("{") - code.count("}")
            opened = opened or "{" in code
            if opened and depth <= 0:
                end = n
                break
        out.append((start + 1, end + 1))
    return out


def main():
    if len(sys.argv) < 3:
        print(__doc__)
        return 2
    build, sources = sys.argv[1], sys.argv[2:]
    with open(os.path.join(build, "compile_commands.json"), encoding="utf-8") as f:
        commands = {os.path.realpath(e["file"]): e for e in json.load(f)}
    failures = 0
    for src in sources:
        src = os.path.realpath(src)
        entry = commands.get(src)
        if entry is None:
            print(f"FAIL {src}: not in {build}/compile_commands.json")
            failures += 1
            continue
        args = shlex.split(entry["command"]) if "command" in entry else list(entry["arguments"])
        # Drop the output file; keep the compiler, flags and the source.
        cleaned, skip = [], False
        for a in args:
            if skip:
                skip = False
                continue
            if a == "-o":
                skip = True
                continue
            cleaned.append(a)
        loops = pragma_loops(src)
        name = os.path.basename(src)
        for isa in ISAS:
            cmd = cleaned + ["-o", os.devnull, "-DRHEO_SIM_NO_CLONES", f"-march={isa}",
                             "-fopt-info-vec-optimized"]
            run = subprocess.run(cmd, cwd=entry["directory"], capture_output=True, text=True)
            if run.returncode != 0:
                print(f"FAIL {name} ({isa}): the compile failed:\n{run.stderr[-2000:]}")
                failures += 1
                continue
            done = set()
            for m in re.finditer(re.escape(name) + r":(\d+):\d+: optimized: loop vectorized",
                                 run.stderr):
                done.add(int(m.group(1)))
            for line, last in loops:
                if any(line <= d <= last for d in done):
                    print(f"ok   {name}:{line} ({isa})")
                else:
                    print(f"FAIL {name}:{line} ({isa}): the `omp simd` loop was not vectorised "
                          f"(rebuild with -fopt-info-vec-missed to see why)")
                    failures += 1
    print(f"{failures} loop(s) not vectorised" if failures else "every omp simd loop vectorised")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
