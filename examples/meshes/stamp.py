"""Writes the stamps of examples/stamp2d.cso and examples/stamp3d.cso (run:
python3 stamp.py in examples/meshes; pure Python, msh41.py beside it):

stamp2d.msh -- the 2D stamp [-20, 20] x [0, 16] mm in linear triangles: a
  grid of 24 x 10 cells graded towards the contact face (the rows at
  y = 16 (j / 10)^1.6), each cell cut along a diagonal mirrored about x = 0,
  so that the mesh is symmetric as the stamp is.
stamp3d.msh -- the 3D stamp [-10, 10] x [-10, 10] x [0, 10] mm in linear
  tetrahedra: 8 x 8 x 5 cells graded towards the contact face likewise, each
  cut into six tetrahedra (Kuhn's conforming cut).

Faces: bottom (the contact face), top, left, right (and front, back in 3D).
Coordinates in mm. In Gmsh: a Rectangle (a Box) with a transfinite mesh
progression towards the bottom, and Physical Curves (Surfaces) of these
names; the script is used here because Gmsh is not installed where cso is
tested."""
from msh41 import write, grid_2d, grid_3d

GRADE = 1.6


def graded(y, height):
    return height * (y / height) ** GRADE


# 2D: the grid, graded along y, diagonals mirrored about x = 0.
NX, NY, W, H = 24, 10, 20.0, 16.0
nodes, (kind, tris), sides = grid_2d(-W, W, 0.0, H, NX, NY, triangles=True)
nodes = [(x, graded(y, H), z) for x, y, z in nodes]
at = lambda i, j: j * (NX + 1) + i
tris = []
for j in range(NY):
    for i in range(NX):
        a, b, c, d = at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)
        if i < NX // 2:
            tris += [(a, b, d), (b, c, d)]
        else:
            tris += [(a, b, c), (a, c, d)]
groups = [(s, 1, 1, lines) for s, lines in sides.items()]
write("../stamp2d.msh", 2, nodes, (kind, tris), groups, region="stamp")

# 3D: the box, graded along z.
S, T = 10.0, 10.0
nodes, cells, sides = grid_3d(
    (-S, -S, 0.0), (S, S, T), (8, 8, 5), tets=True, warp=lambda x, y, z: (x, y, graded(z, T))
)
groups = [(s, 2, 2, tris) for s, tris in sides.items()]
write("../stamp3d.msh", 3, nodes, cells, groups, region="stamp")
