#!/usr/bin/env python3
"""Writes Rheo's sample sketches (see README.md). Python 3 standard library only, deterministic:
every run writes the same bytes.

    samples/generate.py            # (re)writes the files next to this script
    samples/generate.py --out DIR  # writes them into DIR
    samples/generate.py --check    # regenerates into a temporary folder and compares; exits 1
                                   # naming every file that differs from the committed one

Each case is an ideal outline (a parametric curve, or the zero set of a signed distance field
traced by marching squares), wobbled as a hand would draw it (the truth), then sampled as a
sketch pad sends it (strokes with pen jitter), inked on white (the clean picture) and
photographed (the photo: slight rotation and perspective, uneven light, greyish grainy paper,
slight blur).
"""
import argparse
import filecmp
import json
import math
import os
import random
import struct
import sys
import tempfile
import zlib

W = H = 512
TAU = 2 * math.pi


# ---------------------------------------------------------------------------------------------
# Geometry helpers


def resample(pts, spacing, closed=True):
    """Points every `spacing` px along the polyline (closed: back to the start)."""
    seq = list(pts) + ([pts[0]] if closed else [])
    out = [seq[0]]
    carry = 0.0
    for (x0, y0), (x1, y1) in zip(seq, seq[1:]):
        seg = math.hypot(x1 - x0, y1 - y0)
        t = spacing - carry
        while t <= seg:
            f = t / seg
            out.append((x0 + f * (x1 - x0), y0 + f * (y1 - y0)))
            t += spacing
        carry = seg - (t - spacing)
    if closed and math.dist(out[-1], out[0]) < 0.5 * spacing:
        out.pop()
    if not closed and math.dist(out[-1], seq[-1]) > 1e-9:
        out.append(seq[-1])
    return out


def normals(pts):
    n = len(pts)
    out = []
    for i in range(n):
        (xa, ya), (xb, yb) = pts[i - 1], pts[(i + 1) % n]
        dx, dy = xb - xa, yb - ya
        L = math.hypot(dx, dy) or 1.0
        out.append((-dy / L, dx / L))
    return out


def signed_area(p):
    return 0.5 * sum(p[i - 1][0] * p[i][1] - p[i][0] * p[i - 1][1] for i in range(len(p)))


def segments_cross(a, b, c, d):
    def orient(p, q, r):
        return (q[0] - p[0]) * (r[1] - p[1]) - (q[1] - p[1]) * (r[0] - p[0])
    return (orient(a, b, c) * orient(a, b, d) < 0) and (orient(c, d, a) * orient(c, d, b) < 0)


def is_simple(p):
    """True when no two non-adjacent edges of the closed polygon cross (grid-bucketed)."""
    n = len(p)
    cell = 8.0
    buckets = {}
    for i in range(n):
        a, b = p[i], p[(i + 1) % n]
        for gx in range(int(min(a[0], b[0]) // cell), int(max(a[0], b[0]) // cell) + 1):
            for gy in range(int(min(a[1], b[1]) // cell), int(max(a[1], b[1]) // cell) + 1):
                buckets.setdefault((gx, gy), []).append(i)
    for edges in buckets.values():
        for x in range(len(edges)):
            for y in range(x + 1, len(edges)):
                i, j = edges[x], edges[y]
                if abs(i - j) <= 1 or abs(i - j) == n - 1:
                    continue
                if segments_cross(p[i], p[(i + 1) % n], p[j], p[(j + 1) % n]):
                    return False
    return True


def smooth_noise(rng, period, terms=4):
    """A smooth periodic function of arclength s in [0, period): sum of random sinusoids."""
    comps = []
    for k in range(terms):
        f = rng.randint(2 + 3 * k, 5 + 6 * k)
        comps.append((f, rng.uniform(0, TAU), rng.uniform(0.5, 1.0) / (1 + k)))
    norm = sum(a for _, _, a in comps)
    return lambda s: sum(a * math.sin(TAU * f * s / period + ph) for f, ph, a in comps) / norm


def hand(ideal, rng, amp):
    """The ideal outline as a hand draws it: resampled every px, offset along the normal by a
    smooth wobble of about `amp` px. Returns the drawn centreline (the truth)."""
    pts = resample(ideal, 1.0)
    per = float(len(pts))
    wob = smooth_noise(rng, per)
    nrm = normals(pts)
    return [(x + amp * wob(i) * nx, y + amp * wob(i) * ny)
            for i, ((x, y), (nx, ny)) in enumerate(zip(pts, nrm))]


# ---------------------------------------------------------------------------------------------
# Ideal outlines: parametric curves


def ellipse_curve(cx, cy, a, b, rot, n=900):
    c, s = math.cos(rot), math.sin(rot)
    out = []
    for i in range(n):
        t = TAU * i / n
        x, y = a * math.cos(t), b * math.sin(t)
        out.append((cx + c * x - s * y, cy + s * x + c * y))
    return out


def bean_curve(n=900):
    out = []
    for i in range(n):
        t = TAU * i / n
        x = 256 + 185 * math.cos(t)
        y = 262 + 118 * math.sin(t)
        d = t - 1.5 * math.pi
        y += 78 * math.exp(-(d / 0.62) ** 2)  # the dent on top (y down)
        x += 14 * math.sin(2 * t)
        out.append((x, y))
    return out


def star_curve(n=1500):
    out = []
    for i in range(n):
        t = TAU * i / n
        r = 78 + 132 * ((1 + math.cos(5 * (t + 0.3))) / 2) ** 3
        out.append((256 + r * math.cos(t), 262 + r * math.sin(t)))
    return out


def spiral_curve():
    """The closed outline of a band spiralling outwards: outer edge out, round cap, inner edge
    back, round cap."""
    r0, pitch, half, turns = 56.0, 58.0, 14.0, 1.85
    t1 = TAU * turns
    n = 1400

    def centre(t):
        r = r0 + pitch * t / TAU
        return r, (256 + r * math.cos(t), 256 + r * math.sin(t))

    outer, inner = [], []
    for i in range(n + 1):
        t = t1 * i / n
        r, _ = centre(t)
        outer.append((256 + (r + half) * math.cos(t), 256 + (r + half) * math.sin(t)))
        inner.append((256 + (r - half) * math.cos(t), 256 + (r - half) * math.sin(t)))

    def cap(t, forward):
        _, (cx, cy) = centre(t)
        ux, uy = math.cos(t), math.sin(t)  # radial
        tx, ty = (-uy, ux) if forward else (uy, -ux)  # bulge direction
        pts = []
        for k in range(1, 40):
            a = math.pi * k / 40
            pts.append((cx + half * (math.cos(a) * ux + math.sin(a) * tx),
                        cy + half * (math.cos(a) * uy + math.sin(a) * ty)))
        return pts

    end_cap = cap(t1, True)  # outer edge round the end to the inner edge
    start_cap = cap(0.0, False)[::-1]  # inner edge round the start to the outer edge
    return outer + end_cap + inner[::-1] + start_cap


def blob_curve(n=900):
    out = []
    for i in range(n):
        t = TAU * i / n
        r = 168 + 26 * math.sin(2 * t + 1.0) + 13 * math.cos(3 * t) + 6 * math.sin(5 * t + 2)
        out.append((256 + 1.05 * r * math.cos(t), 256 + 0.9 * r * math.sin(t)))
    return out


def cushion_curve(n=900):
    out = []
    for i in range(n):
        t = TAU * i / n
        c, s = math.cos(t), math.sin(t)
        x = 175 * math.copysign(abs(c) ** 0.6, c)
        y = 150 * math.copysign(abs(s) ** 0.6, s)
        a = 0.12
        out.append((256 + x * math.cos(a) - y * math.sin(a), 256 + x * math.sin(a) + y * math.cos(a)))
    return out


# ---------------------------------------------------------------------------------------------
# Ideal outlines: signed distance fields (negative inside), traced by marching squares


def sd_circle(px, py, cx, cy, r):
    return math.hypot(px - cx, py - cy) - r


def sd_ellipse(px, py, cx, cy, a, b, rot=0.0):
    c, s = math.cos(rot), math.sin(rot)
    x, y = c * (px - cx) + s * (py - cy), -s * (px - cx) + c * (py - cy)
    k = math.hypot(x / a, y / b)
    return (k - 1) * min(a, b) if k > 0 else -min(a, b)


def sd_round_box(px, py, cx, cy, hx, hy, r, rot=0.0):
    c, s = math.cos(rot), math.sin(rot)
    x, y = c * (px - cx) + s * (py - cy), -s * (px - cx) + c * (py - cy)
    qx, qy = abs(x) - hx + r, abs(y) - hy + r
    return math.hypot(max(qx, 0), max(qy, 0)) + min(max(qx, qy), 0) - r


def sd_capsule(px, py, ax, ay, bx, by, ra, rb):
    """Tapered capsule (round cone) from a (radius ra) to b (radius rb)."""
    hx, hy = bx - ax, by - ay
    h = math.hypot(hx, hy)
    ux, uy = hx / h, hy / h
    x, y = px - ax, py - ay
    along, across = x * ux + y * uy, abs(-x * uy + y * ux)
    b = (ra - rb) / h
    a = math.sqrt(1 - b * b)
    k = -b * across + a * along
    if k < 0:
        return math.hypot(across, along) - ra
    if k > a * h:
        return math.hypot(across, along - h) - rb
    return a * across + b * along - ra


def sd_polygon(px, py, poly):
    d = float("inf")
    inside = False
    n = len(poly)
    for i in range(n):
        (ax, ay), (bx, by) = poly[i], poly[(i + 1) % n]
        ex, ey = bx - ax, by - ay
        wx, wy = px - ax, py - ay
        t = max(0.0, min(1.0, (wx * ex + wy * ey) / (ex * ex + ey * ey)))
        d = min(d, math.hypot(wx - t * ex, wy - t * ey))
        if (ay > py) != (by > py) and px < ax + (py - ay) * ex / ey:
            inside = not inside
    return -d if inside else d


def smin(a, b, k):
    if k <= 0:
        return min(a, b)
    h = max(k - abs(a - b), 0.0) / k
    return min(a, b) - h * h * k * 0.25


def trace(sdf, step=2.0):
    """Zero set of sdf on a grid of `step` px: the one closed loop, as a polygon."""
    nx = int(W / step) + 1
    ny = int(H / step) + 1
    v = [[sdf(i * step, j * step) for i in range(nx)] for j in range(ny)]
    # Edge points keyed by edge id; segments link them.
    def edge_point(i0, j0, i1, j1):
        a, b = v[j0][i0], v[j1][i1]
        t = a / (a - b)
        return ((i0 + t * (i1 - i0)) * step, (j0 + t * (j1 - j0)) * step)
    nxt = {}
    pos = {}
    for j in range(ny - 1):
        for i in range(nx - 1):
            a, b, c, d = v[j][i], v[j][i + 1], v[j + 1][i + 1], v[j + 1][i]
            code = (a < 0) | ((b < 0) << 1) | ((c < 0) << 2) | ((d < 0) << 3)
            if code in (0, 15):
                continue
            # Edges: 0 top (a-b), 1 right (b-c), 2 bottom (d-c), 3 left (a-d).
            ids = {0: ("h", i, j), 1: ("v", i + 1, j), 2: ("h", i, j + 1), 3: ("v", i, j)}
            ends = {0: (i, j, i + 1, j), 1: (i + 1, j, i + 1, j + 1),
                    2: (i, j + 1, i + 1, j + 1), 3: (i, j, i, j + 1)}
            # Segments oriented with the inside on the left in y-down screen terms, consistent.
            table = {1: [(3, 0)], 2: [(0, 1)], 3: [(3, 1)], 4: [(1, 2)], 6: [(0, 2)],
                     7: [(3, 2)], 8: [(2, 3)], 9: [(2, 0)], 11: [(2, 1)], 12: [(1, 3)],
                     13: [(1, 0)], 14: [(0, 3)]}
            if code == 5 or code == 10:
                centre = (a + b + c + d) / 4
                if code == 5:
                    segs = [(3, 2), (1, 0)] if centre < 0 else [(3, 0), (1, 2)]
                else:
                    segs = [(0, 1), (2, 3)] if centre >= 0 else [(0, 3), (2, 1)]
            else:
                segs = table[code]
            for e0, e1 in segs:
                k0, k1 = ids[e0], ids[e1]
                nxt[k0] = k1
                for k, e in ((k0, e0), (k1, e1)):
                    if k not in pos:
                        pos[k] = edge_point(*ends[e])
    loops = []
    seen = set()
    for start in nxt:
        if start in seen:
            continue
        loop = []
        k = start
        while k not in seen:
            seen.add(k)
            loop.append(pos[k])
            k = nxt[k]
        loops.append(loop)
    if len(loops) != 1:
        raise SystemExit("outline is not one loop: %d loops" % len(loops))
    return loops[0]


def mitten_sdf(x, y):
    palm = sd_round_box(x, y, 270, 250, 100, 150, 92, 0.08)
    thumb = sd_capsule(x, y, 200, 310, 118, 205, 34, 27)
    return smin(palm, thumb, 12)


def fish_sdf(x, y):
    body = sd_ellipse(x, y, 218, 256, 140, 98, 0.0)
    tail = sd_polygon(x, y, [(334, 256), (446, 158), (418, 256), (446, 354)]) - 5  # round tips
    return smin(body, tail, 22)


def dumbbell_sdf(x, y):
    a = sd_circle(x, y, 128, 256, 100)
    b = sd_circle(x, y, 384, 250, 94)
    neck = sd_capsule(x, y, 128, 256, 384, 250, 9, 9)
    return smin(min(a, b), neck, 24)


OCTO_TENTACLES = []


def octopus_tentacles():
    if OCTO_TENTACLES:
        return OCTO_TENTACLES
    for k in range(5):
        ang = math.radians(-52 + 26 * k)  # fan out from straight down
        bx, by = 256 + 48 * (k - 2), 262 - 4 * abs(k - 2)
        chain = []
        n = 12
        length = 185 - 12 * abs(k - 2)
        for i in range(n + 1):
            s = i / n
            curl = 0.55 * math.sin(math.pi * s * 1.1 + k) * s
            a = ang + curl
            if i == 0:
                x, y = bx, by
            else:
                px, py = chain[-1][0], chain[-1][1]
                x, y = px + length / n * math.sin(a), py + length / n * math.cos(a)
            chain.append((x, y, 11.5 - 6.5 * s))
        OCTO_TENTACLES.append(chain)
    return OCTO_TENTACLES


def octopus_sdf(x, y):
    head = sd_ellipse(x, y, 256, 180, 112, 100, 0.0)
    tent = float("inf")
    for chain in octopus_tentacles():
        for (ax, ay, ra), (bx, by, rb) in zip(chain, chain[1:]):
            if abs(x - ax) > 60 or abs(y - ay) > 60:
                continue
            tent = min(tent, sd_capsule(x, y, ax, ay, bx, by, ra, rb))
    return smin(head, tent, 14)


def letter_c_sdf(x, y):
    rm, half, gap = 148.0, 44.0, math.radians(38)  # opening on the right, +-gap
    dx, dy = x - 256, y - 256
    phi = math.atan2(dy, dx)
    if abs(phi) >= gap:
        return abs(math.hypot(dx, dy) - rm) - half
    ex = rm * math.cos(gap)
    ey = rm * math.sin(gap) * (1 if dy >= 0 else -1)
    return math.hypot(dx - ex, dy - ey) - half


def heart_sdf(x, y):
    left = sd_circle(x, y, 186, 196, 100)
    right = sd_circle(x, y, 326, 196, 100)
    point = sd_polygon(x, y, [(98, 222), (414, 222), (256, 430)]) - 6  # a slightly round point
    return smin(min(left, right), point, 40)


def pear_sdf(x, y):
    bottom = sd_circle(x, y, 250, 338, 118)
    top = sd_circle(x, y, 268, 170, 64)
    return smin(bottom, top, 75)


# ---------------------------------------------------------------------------------------------
# Strokes as a sketch pad sends them


def pad_sample(path, rng, jitter=0.3):
    """Pad events along a drawn polyline: spacing varies with the speed of the hand, each event
    has a little sensor jitter."""
    out = []
    s_total = 0.0
    cum = [0.0]
    for p, q in zip(path, path[1:]):
        s_total += math.dist(p, q)
        cum.append(s_total)
    s = 0.0
    i = 0
    phase = rng.uniform(0, TAU)
    while True:
        while i + 1 < len(cum) - 1 and cum[i + 1] < s:
            i += 1
        seg = cum[i + 1] - cum[i] if i + 1 < len(cum) else 0
        f = (s - cum[i]) / seg if seg > 0 else 0
        f = max(0.0, min(1.0, f))
        (x0, y0), (x1, y1) = path[i], path[min(i + 1, len(path) - 1)]
        out.append((x0 + f * (x1 - x0) + rng.gauss(0, jitter),
                    y0 + f * (y1 - y0) + rng.gauss(0, jitter)))
        if s >= s_total:
            break
        speed = 1.55 + 0.75 * math.sin(phase + s / 37.0) + rng.uniform(-0.25, 0.25)
        s = min(s_total, s + max(0.5, speed))
    return out


def arc(truth, start, length, offset=(0.0, 0.0), wob=None):
    """`length` points of the closed truth from index `start` (negative length: backwards),
    shifted by offset and optionally wobbled along the normal."""
    n = len(truth)
    step = 1 if length >= 0 else -1
    idx = [(start + step * k) % n for k in range(abs(length))]
    nrm = normals(truth)
    out = []
    for m, i in enumerate(idx):
        w = wob(m) if wob else 0.0
        out.append((truth[i][0] + offset[0] + w * nrm[i][0], truth[i][1] + offset[1] + w * nrm[i][1]))
    return out


def stroke_plan(name, truth, rng):
    """The strokes of each case, drawn along the truth (indices are px of arclength)."""
    n = len(truth)
    st = rng.randrange(n)
    wob = lambda amp: (lambda m, f=rng.uniform(60, 120), ph=rng.uniform(0, TAU):
                       amp * math.sin(TAU * m / f + ph))
    if name in ("ellipse", "star5", "fish", "pear", "spiral"):
        # One stroke, a short overshoot past the start.
        return [arc(truth, st, n + rng.randint(8, 16))]
    if name in ("bean", "letter_c", "mitten", "dumbbell"):
        # Two strokes, the second overlapping both ends of the first a little.
        a = n // 2 + rng.randint(-40, 40)
        return [arc(truth, st, a + 12), arc(truth, st + a, n - a + 14, wob=wob(0.5))]
    if name == "octopus":
        cuts = sorted(rng.sample(range(n), 3))
        out = []
        for k in range(3):
            s0 = cuts[k]
            s1 = cuts[(k + 1) % 3] + (n if k == 2 else 0)
            out.append(arc(truth, s0 - 6, s1 - s0 + 14, wob=wob(0.4)))
        return out
    if name == "heart":
        # Both halves from the top cusp down to the point, as hearts are usually drawn.
        top = min(range(n), key=lambda i: (truth[i][1] - 120) ** 2 + (truth[i][0] - 256) ** 2)
        bottom = max(range(n), key=lambda i: truth[i][1])
        fwd = (bottom - top) % n
        return [arc(truth, top, fwd + 6), arc(truth, top, -((top - bottom) % n) - 6, wob=wob(0.5))]
    if name == "overdraw":
        # Sketchy: nine short strokes, half of them drawn backwards, each overlapping its
        # neighbours by a third and a little off the others; two go back over themselves.
        out = []
        k = 9
        seg = n // k
        for j in range(k):
            s0 = st + j * seg - rng.randint(25, 45)
            length = seg + rng.randint(50, 90)
            off = (rng.gauss(0, 1.0), rng.gauss(0, 1.0))
            s = arc(truth, s0, length, off, wob(0.9))
            if j in (2, 6):  # back and forth over its own end
                back = s[-1:-60:-1]
                again = [(x + 0.6, y - 0.5) for x, y in s[-60:]]
                s = s + back + again
            if j % 2:
                s = s[::-1]
            out.append(s)
        return out
    if name == "gaps":
        # Four strokes; each stops a few px short of where the next starts.
        out = []
        gaps = []
        q = n // 4
        pos = st
        for j in range(4):
            g = rng.randint(3, 7)
            gaps.append(g)
            out.append(arc(truth, pos, q - g + (n - 4 * q if j == 3 else 0), wob=wob(0.4)))
            pos += q
        return out, gaps
    raise KeyError(name)


# ---------------------------------------------------------------------------------------------
# Pictures


def ink(cov, stroke, width):
    """Max-coverage of a round pen of `width` px along an open polyline into cov (W x H)."""
    r = width / 2
    for (x0, y0), (x1, y1) in zip(stroke, stroke[1:]) if len(stroke) > 1 else []:
        ex, ey = x1 - x0, y1 - y0
        ll = ex * ex + ey * ey
        for py in range(max(0, int(min(y0, y1) - r - 2)), min(H, int(max(y0, y1) + r + 3))):
            cy = py + 0.5
            row = py * W
            for px in range(max(0, int(min(x0, x1) - r - 2)), min(W, int(max(x0, x1) + r + 3))):
                cx = px + 0.5
                wx, wy = cx - x0, cy - y0
                t = (wx * ex + wy * ey) / ll if ll > 0 else 0.0
                t = 0.0 if t < 0 else (1.0 if t > 1 else t)
                dx, dy = wx - t * ex, wy - t * ey
                c = r + 0.5 - math.sqrt(dx * dx + dy * dy)
                if c > 0:
                    c = 1.0 if c > 1 else c
                    if c > cov[row + px]:
                        cov[row + px] = c


def png_bytes(w, h, px):
    raw = bytearray()
    prev = bytes(w)
    for y in range(h):
        row = bytes(px[y * w:(y + 1) * w])
        raw.append(2)  # filter Up
        raw.extend((row[i] - prev[i]) & 0xFF for i in range(w))
        prev = row
    def chunk(tag, data):
        c = struct.pack(">I", len(data)) + tag + data
        return c + struct.pack(">I", zlib.crc32(tag + data) & 0xFFFFFFFF)
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 0, 0, 0, 0)) +
            chunk(b"IDAT", zlib.compress(bytes(raw), 9)) + chunk(b"IEND", b""))


def clean_picture(strokes, width, ink_level):
    cov = [0.0] * (W * H)
    for s in strokes:
        ink(cov, s, width)
    return [int(round(255 - c * (255 - ink_level))) for c in cov]


class Camera:
    """Slight rotation, scale and perspective about the picture centre."""

    def __init__(self, rng):
        self.rot = math.radians(rng.uniform(2.0, 5.0) * rng.choice((-1, 1)))
        self.scale = rng.uniform(0.9, 0.95)
        self.gx = rng.uniform(-1.6e-4, 1.6e-4)
        self.gy = rng.uniform(-1.6e-4, 1.6e-4)
        self.shift = (rng.uniform(-8, 8), rng.uniform(-8, 8))

    def __call__(self, p):
        x, y = p[0] - 256, p[1] - 256
        c, s = math.cos(self.rot), math.sin(self.rot)
        u, v = self.scale * (c * x - s * y), self.scale * (s * x + c * y)
        w = 1 + self.gx * x + self.gy * y
        return (256 + self.shift[0] + u / w, 256 + self.shift[1] + v / w)


def photo_picture(strokes, width, cam, rng):
    cov = [0.0] * (W * H)
    for s in strokes:
        ink(cov, [cam(p) for p in s], width * cam.scale)
    # Light: a lamp off to one side (a broad gradient) and the lens' vignetting.
    lx, ly = rng.uniform(0, W), rng.uniform(0, H)
    paper = rng.uniform(175, 205)
    ink_frac = rng.uniform(0.45, 0.6)  # ink reflects this much of the light the paper does
    vig = rng.uniform(0.35, 0.5)
    reach = rng.uniform(0.9, 1.3) * W
    # Paper grain: a coarse random field, bilinearly interpolated, plus per-pixel noise later.
    g = 16
    coarse = [[rng.gauss(0, 1) for _ in range(W // g + 2)] for _ in range(H // g + 2)]
    img = [0.0] * (W * H)
    for y in range(H):
        gy, fy = divmod(y / g, 1)
        gy = int(gy)
        r0, r1 = coarse[gy], coarse[gy + 1]
        for x in range(W):
            gx, fx = divmod(x / g, 1)
            gx = int(gx)
            grain = ((r0[gx] * (1 - fx) + r0[gx + 1] * fx) * (1 - fy) +
                     (r1[gx] * (1 - fx) + r1[gx + 1] * fx) * fy)
            d2 = ((x - lx) ** 2 + (y - ly) ** 2) / (reach * reach)
            light = (1 - vig * min(1.0, d2)) * (1 - 0.25 * (((x - 256) ** 2 + (y - 256) ** 2) / 131072))
            c = cov[y * W + x]
            img[y * W + x] = light * (paper + 4.0 * grain) * (1 - c * (1 - ink_frac))
    # Slight blur (out of focus): separable [1 2 1] / 4, twice.
    for _ in range(2):
        tmp = img[:]
        for y in range(H):
            row = y * W
            for x in range(1, W - 1):
                tmp[row + x] = 0.25 * (img[row + x - 1] + 2 * img[row + x] + img[row + x + 1])
        for y in range(1, H - 1):
            row = y * W
            for x in range(W):
                img[row + x] = 0.25 * (tmp[row - W + x] + 2 * tmp[row + x] + tmp[row + W + x])
    out = []
    for v in img:
        v += rng.gauss(0, 2.5)  # sensor noise
        out.append(0 if v < 0 else (255 if v > 255 else int(round(v))))
    return out


# ---------------------------------------------------------------------------------------------
# Cases


CASES = [
    # name, ideal outline, seed (README.md describes each case)
    ("ellipse", lambda: ellipse_curve(256, 256, 192, 128, 0.14), 11),
    ("bean", bean_curve, 12),
    ("star5", star_curve, 13),
    ("letter_c", lambda: trace(letter_c_sdf), 14),
    ("fish", lambda: trace(fish_sdf), 15),
    ("mitten", lambda: trace(mitten_sdf), 16),
    ("dumbbell", lambda: trace(dumbbell_sdf), 17),
    ("octopus", lambda: trace(octopus_sdf, 1.0), 18),
    ("spiral", spiral_curve, 19),
    ("overdraw", blob_curve, 20),
    ("gaps", cushion_curve, 21),
    ("pear", lambda: trace(pear_sdf), 22),
    ("heart", lambda: trace(heart_sdf), 23),
]

LINE_WIDTH = 4


def r2(p):
    return [round(p[0], 2), round(p[1], 2)]


def build(name, ideal_fn, seed, out_dir):
    rng = random.Random(seed)
    ideal = ideal_fn()
    truth = hand(ideal, rng, 0.9)
    if signed_area(truth) < 0:
        truth = truth[::-1]
    if not is_simple(truth):
        raise SystemExit(name + ": truth outline crosses itself")
    plan = stroke_plan(name, truth, rng)
    gap = 0
    if name == "gaps":
        plan, gaps = plan
        gap = max(gaps)
    strokes = [pad_sample(s, rng) for s in plan]
    truth_out = resample(truth, 2.0)
    files = {}
    files[name + ".json"] = json.dumps(
        {"width": W, "height": H, "strokes": [[r2(p) for p in s] for s in strokes]}).encode()
    files[name + ".truth.json"] = json.dumps(
        {"contour": [r2(p) for p in truth_out], "line_width": LINE_WIDTH,
         "closed_gap_px": gap}).encode()
    strokes_r = [[tuple(r2(p)) for p in s] for s in strokes]
    files[name + ".png"] = png_bytes(W, H, clean_picture(strokes_r, LINE_WIDTH, rng.randint(15, 40)))
    cam = Camera(rng)
    files[name + ".photo.png"] = png_bytes(W, H, photo_picture(strokes_r, LINE_WIDTH, cam, rng))
    files[name + ".photo.truth.json"] = json.dumps(
        {"contour": [r2(cam(p)) for p in truth_out],
         "line_width": round(LINE_WIDTH * cam.scale, 2), "closed_gap_px": round(gap * cam.scale, 1)}).encode()
    for fname, data in files.items():
        with open(os.path.join(out_dir, fname), "wb") as f:
            f.write(data)
    return list(files)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", default=os.path.dirname(os.path.abspath(__file__)))
    ap.add_argument("--check", action="store_true")
    ap.add_argument("--only", nargs="*", help="only these cases")
    args = ap.parse_args()
    cases = [c for c in CASES if not args.only or c[0] in args.only]
    if not args.check:
        for name, fn, seed in cases:
            build(name, fn, seed, args.out)
        return 0
    here = os.path.dirname(os.path.abspath(__file__))
    bad = []
    with tempfile.TemporaryDirectory() as tmp:
        for name, fn, seed in cases:
            for fname in build(name, fn, seed, tmp):
                committed = os.path.join(here, fname)
                if not os.path.exists(committed) or not filecmp.cmp(committed, os.path.join(tmp, fname), shallow=False):
                    bad.append(fname)
    for f in bad:
        print("differs from the generator's output: samples/" + f, file=sys.stderr)
    if bad:
        print("run samples/generate.py and commit the result", file=sys.stderr)
        return 1
    print("all %d cases match" % len(cases))
    return 0


if __name__ == "__main__":
    sys.exit(main())
