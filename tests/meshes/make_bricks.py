"""Writes the 3D brick meshes of cso's tests (run: python3 make_bricks.py):
brick_hexes.msh, the box [0, 20] x [0, 20] x [0, 10] mm of 4 x 4 x 2
hexahedra, node for node the structured body `x = 0 .. 20 mm, y = 0 .. 20 mm,
z = 0 .. 10 mm, mesh = 4 x 4 x 2`; brick_tets.msh, the same grid with each
hexahedron cut into six tetrahedra. Coordinates in mm; faces `left`,
`right`, `front`, `back`, `bottom`, `top`."""
import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "examples", "meshes"))
from msh41 import write, grid_3d

for name, tets in [("brick_hexes.msh", False), ("brick_tets.msh", True)]:
    nodes, cells, sides = grid_3d((0.0, 0.0, 0.0), (20.0, 20.0, 10.0), (4, 4, 2), tets=tets)
    groups = [(s, 2, 2 if tets else 3, f) for s, f in sides.items()]
    write(name, 3, nodes, cells, groups, region="brick")
