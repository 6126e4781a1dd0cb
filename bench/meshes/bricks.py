"""Writes the brick meshes of BENCHMARKS.md's "Bodies from Gmsh files"
(run: python3 bricks.py N [N ...] in bench/meshes; examples/meshes/msh41.py
is the writer): brick_hexN.msh and brick_tetN.msh, the box [0, 20] x [0, 20]
x [0, 10] mm in N x N x N/2 hexahedra, and the same grid with each cut into
six tetrahedra (the same nodes, so the same unknowns). Faces: left, right,
front, back, bottom, top. The files are large and not kept in git."""
import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "..", "examples", "meshes"))
from msh41 import write, grid_3d  # noqa: E402

for n in map(int, sys.argv[1:]):
    for kind, tets in [("hex", False), ("tet", True)]:
        nodes, cells, sides = grid_3d((0.0, 0.0, 0.0), (20.0, 20.0, 10.0), (n, n, n // 2), tets=tets)
        groups = [(s, 2, 2 if tets else 3, f) for s, f in sides.items()]
        write("brick_%s%d.msh" % (kind, n), 3, nodes, cells, groups, region="brick")
