"""Writes the 2D block meshes of cso's tests (run: python3 make_blocks.py):
block_quads.msh, the block [0, 40] x [0, 20] mm of 8 x 4 quadrangles, node
for node the structured body `x = 0 .. 40 mm, y = 0 .. 20 mm, mesh = 8 x 4`;
block_tris.msh, the same grid with each quadrangle cut into two triangles.
Coordinates in mm; faces `bottom`, `right`, `top`, `left`."""
import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "examples", "meshes"))
from msh41 import write, grid_2d

for name, tri in [("block_quads.msh", False), ("block_tris.msh", True)]:
    nodes, cells, sides = grid_2d(0.0, 40.0, 0.0, 20.0, 8, 4, triangles=tri)
    groups = [(s, 1, 1, lines) for s, lines in sides.items()]
    write(name, 2, nodes, cells, groups, region="block")

# The triangles with two nodes that no element uses (cso ignores them and
# says so in the summary).
nodes, cells, sides = grid_2d(0.0, 40.0, 0.0, 20.0, 8, 4, triangles=True)
nodes += [(100.0, 100.0, 0.0), (-50.0, 7.0, 0.0)]
write("block_tris_stray.msh", 2, nodes, cells, [(s, 1, 1, l) for s, l in sides.items()], region="block")

# Two blocks of triangles side by side, 10 mm apart, in one file and one
# region: a mesh in two pieces (`pieces = separate` takes it).
nodes, (kind, tris), sides = grid_2d(0.0, 40.0, 0.0, 20.0, 8, 4, triangles=True)
k = len(nodes)
nodes2 = nodes + [(x + 50.0, y, z) for x, y, z in nodes]
tris2 = tris + [tuple(v + k for v in t) for t in tris]
groups = [(s, 1, 1, l + [tuple(v + k for v in e) for e in l]) for s, l in sides.items()]
write("two_pieces.msh", 2, nodes2, (kind, tris2), groups, region="pieces")

# A face group named `boundary`, the name cso gives the whole boundary.
nodes, cells, sides = grid_2d(0.0, 40.0, 0.0, 20.0, 8, 4, triangles=True)
write("named_boundary.msh", 2, nodes, cells, [("boundary", 1, 1, sides["bottom"])], region="block")
