#!/usr/bin/python3
"""Writes study-plate.obj: the study's setup (PAPER.md) — a flat acrylic plate with one
cylindrical bump (4 mm diameter, 1 mm high) on its skin side. The camera looks at the plate's
top (+z); the finger presses the bump from below and, indented by the bump's height, touches
the plate's underside around it. Groups: `outer` (top, camera side), `side` (plate rim),
`contact` (underside, bump wall and bump face: one topological disk, so it can be charted).
Run: /usr/bin/python3 make_mesh.py  (numpy only; the .obj is committed).
Other bumps (scripts/simulate-cohort.py): make_mesh.py --radius R --height H --out FILE."""
import argparse
import math

HALF = 6.0         # plate half width, mm (12 x 12 mm)
THICK = 3.0        # plate thickness, mm; top at z = THICK, underside at z = 0
_args = argparse.ArgumentParser(description="the study's plate with one cylindrical bump")
_args.add_argument("--radius", type=float, default=2.0, help="bump radius, mm")
_args.add_argument("--height", type=float, default=1.0, help="bump height, mm")
_args.add_argument("--out", default="study-plate.obj", help="output .obj")
ARGS = _args.parse_args()
R = ARGS.radius    # bump radius, mm
H = ARGS.height    # bump height, mm: its face at z = -H
N = 96             # segments around
RINGS_FACE, RINGS_WALL, RINGS_PLATE = 8, 4, 10

verts, faces = [], {"outer": [], "side": [], "contact": []}


def v(x, y, z):
    verts.append((x, y, z))
    return len(verts)


def square_point(a):
    """Point on the plate's square rim in direction a."""
    c, s = math.cos(a), math.sin(a)
    t = HALF / max(abs(c), abs(s))
    return c * t, s * t


angles = [2 * math.pi * k / N for k in range(N)]
# Contact surface from the centre outwards: bump face (z=-H), wall (r=R), underside (z=0) to the rim.
centre = v(0, 0, -H)
rings = []
for i in range(1, RINGS_FACE + 1):
    r = R * i / RINGS_FACE
    rings.append([v(r * math.cos(a), r * math.sin(a), -H) for a in angles])
for i in range(1, RINGS_WALL + 1):
    z = -H + H * i / RINGS_WALL
    rings.append([v(R * math.cos(a), R * math.sin(a), z) for a in angles])
for i in range(1, RINGS_PLATE + 1):
    t = i / RINGS_PLATE
    pts = []
    for a in angles:
        sx, sy = square_point(a)
        pts.append(v((1 - t) * R * math.cos(a) + t * sx, (1 - t) * R * math.sin(a) + t * sy, 0.0))
    rings.append(pts)
# Faces seen from outside the part (from below, -z): counter-clockwise from below = clockwise from above.
for k in range(N):
    faces["contact"].append((centre, rings[0][(k + 1) % N], rings[0][k]))
for a_ring, b_ring in zip(rings, rings[1:]):
    for k in range(N):
        k1 = (k + 1) % N
        faces["contact"].append((a_ring[k], a_ring[k1], b_ring[k1]))
        faces["contact"].append((a_ring[k], b_ring[k1], b_ring[k]))
# Plate rim (side) from the underside's outer ring up to the top's outer ring, then the top.
bottom = rings[-1]
top_rim = [v(x, y, THICK) for (x, y, _) in (verts[i - 1] for i in bottom)]
for k in range(N):
    k1 = (k + 1) % N
    faces["side"].append((bottom[k], bottom[k1], top_rim[k1]))
    faces["side"].append((bottom[k], top_rim[k1], top_rim[k]))
# Top: rings towards the centre (seen from above: counter-clockwise).
top_rings = [top_rim]
for i in range(RINGS_PLATE - 1, 0, -1):
    t = i / RINGS_PLATE
    pts = []
    for a in angles:
        sx, sy = square_point(a)
        pts.append(v((1 - t) * R * math.cos(a) + t * sx, (1 - t) * R * math.sin(a) + t * sy, THICK))
    top_rings.append(pts)
for i in range(RINGS_FACE, 0, -1):
    r = R * i / RINGS_FACE
    top_rings.append([v(r * math.cos(a), r * math.sin(a), THICK) for a in angles])
top_centre = v(0, 0, THICK)
for a_ring, b_ring in zip(top_rings, top_rings[1:]):
    for k in range(N):
        k1 = (k + 1) % N
        faces["outer"].append((a_ring[k], a_ring[k1], b_ring[k1]))
        faces["outer"].append((a_ring[k], b_ring[k1], b_ring[k]))
for k in range(N):
    faces["outer"].append((top_centre, top_rings[-1][k], top_rings[-1][(k + 1) % N]))

with open(ARGS.out, "w") as f:
    f.write(f"# clearfit sample: the study's acrylic plate with a {2 * R:g} mm x {H:g} mm cylindrical bump (make_mesh.py)\n")
    for x, y, z in verts:
        f.write(f"v {x:.6f} {y:.6f} {z:.6f}\n")
    for group in ("outer", "side", "contact"):
        f.write(f"g {group}\n")
        for a, b, c in faces[group]:
            f.write(f"f {a} {b} {c}\n")
