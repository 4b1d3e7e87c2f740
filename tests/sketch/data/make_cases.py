#!/usr/bin/env python3
"""Writes the stroke cases of this folder (deterministic). Same format as the shared samples:
NAME.json (strokes) and NAME.truth.json (what the hand drew, closed). Run from this folder."""
import json
import math
import random


def curve(kind, n):
    pts = []
    for i in range(n):
        a = 2 * math.pi * i / n
        if kind == "blob":
            r = 150 + 40 * math.sin(3 * a) + 15 * math.cos(5 * a)
            pts.append((256 + r * math.cos(a), 256 + 0.8 * r * math.sin(a)))
        elif kind == "peanut":
            r = 120 + 60 * math.cos(2 * a)
            pts.append((256 + 1.3 * r * math.cos(a), 256 + r * math.sin(a)))
        elif kind == "drop":
            pts.append((256 + 160 * math.sin(a) * math.sin(a / 2) ** 2,
                        256 - 190 * math.cos(a)))
    return pts


def jitter(pts, sigma, rng):
    return [(x + rng.gauss(0, sigma), y + rng.gauss(0, sigma)) for x, y in pts]


def write(name, strokes, truth, line_width, gap):
    r2 = lambda p: [round(p[0], 2), round(p[1], 2)]
    with open(name + ".json", "w") as f:
        json.dump({"width": 512, "height": 512, "strokes": [[r2(p) for p in s] for s in strokes]}, f)
    with open(name + ".truth.json", "w") as f:
        json.dump({"contour": [r2(p) for p in truth], "line_width": line_width,
                   "closed_gap_px": gap}, f)


rng = random.Random(3)
# Noisy hand, five strokes overlapping by 15 points, two of them drawn backwards.
drawn = jitter(curve("blob", 900), 0.9, rng)
strokes = []
for k in range(5):
    s = [drawn[i % 900] for i in range(k * 180, (k + 1) * 180 + 15)]
    strokes.append(s[::-1] if k in (1, 3) else s)
write("noisy_five_strokes", strokes, drawn, 2, 0)

# One stroke stopping short: a gap of about 2 % of the perimeter, closed by default.
drawn = jitter(curve("peanut", 800), 0.5, rng)
gap = math.dist(drawn[783], drawn[0])
write("small_gap", [drawn[:784]], drawn, 2, round(gap, 1))

# A drop (sharp tip) drawn with an overshoot past the start and a retraced stretch.
drawn = jitter(curve("drop", 800), 0.4, rng)
over = [drawn[i % 800] for i in range(0, 840)]
retrace = [(x + 1.0, y + 0.5) for x, y in drawn[200:320]]
write("drop_overshoot_retrace", [over, retrace], drawn, 2, 0)
