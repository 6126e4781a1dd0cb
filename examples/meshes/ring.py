"""Writes examples/ring.msh for examples/ring.cso (run: python3 ring.py in
examples/meshes; pure Python, msh41.py beside it): the right half (x >= 0)
of a ring of outer radius 20 mm and inner radius 14 mm, centred at the
origin, in linear triangles: a polar grid of 8 x 256 cells, each cut into two
triangles (the diagonals mirrored about y = 0). Faces: `sym` (the two cuts
on x = 0), `outer`, `inner`.
Coordinates in mm. In Gmsh: a Disk minus a Disk, cut by a Rectangle, with
Physical Curves of these names; the script is used here because Gmsh is not
installed where cso is tested."""
import math
from msh41 import write

RO, RI, NR, NT = 20.0, 14.0, 8, 256
at = lambda i, j: j * (NR + 1) + i  # i radial (inner to outer), j angular
nodes = []
for j in range(NT + 1):
    t = -math.pi / 2 + math.pi * j / NT
    for i in range(NR + 1):
        r = RI + (RO - RI) * i / NR
        # Exact zeros on the axes (cos(pi / 2) is 6e-17, not 0).
        x, y = (round(v, 12) + 0.0 for v in (r * math.cos(t), r * math.sin(t)))
        nodes.append((x, y, 0.0))
tris = []
for j in range(NT):
    for i in range(NR):
        a, b, c, d = at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)
        # (radial, angular) is counter-clockwise in (x, y). The diagonals of
        # the upper half mirror those of the lower half: the mesh is
        # symmetric about y = 0, as the ring is.
        if j < NT // 2:
            tris += [(a, b, c), (a, c, d)]
        else:
            tris += [(a, b, d), (b, c, d)]
groups = [
    ("sym", 1, 1, [(at(i + 1, 0), at(i, 0)) for i in range(NR)]
     + [(at(i, NT), at(i + 1, NT)) for i in range(NR)]),
    ("outer", 1, 1, [(at(NR, j), at(NR, j + 1)) for j in range(NT)]),
    ("inner", 1, 1, [(at(0, j + 1), at(0, j)) for j in range(NT)]),
]
write("../ring.msh", 2, nodes, (2, tris), groups, region="ring")
