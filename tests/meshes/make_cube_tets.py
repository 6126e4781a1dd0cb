"""Writes cube_tets_{ascii,binary}.msh (in tests/meshes/) with meshio (an MSH 4.1
writer independent of cso's reader and of its tests' hand-made bytes): the
cube [0, 10 mm]^3 cut into 6 tetrahedra about its diagonal, the physical
volume `cube` and the physical surface `bottom` (z = 0, 2 triangles), node
tags 1..8 in two entity blocks. Run: python3 make_cube_tets.py (meshio 5+)."""
import meshio
import numpy as np

p = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0],
              [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]], float) * 10.0
tets = [[0, a, b, 6] for a, b in [(1, 2), (2, 3), (3, 7), (7, 4), (4, 5), (5, 1)]]
tris = [[0, 1, 2], [0, 2, 3]]
mesh = meshio.Mesh(
    p,
    [("triangle", np.array(tris)), ("tetra", np.array(tets))],
    point_data={"gmsh:dim_tags": np.array([[2, 1]] * 4 + [[3, 1]] * 4)},
    cell_data={
        "gmsh:physical": [np.array([1, 1]), np.array([2] * 6)],
        "gmsh:geometrical": [np.array([1, 1]), np.array([1] * 6)],
    },
    field_data={"bottom": np.array([1, 2]), "cube": np.array([2, 3])},
)
meshio.write("cube_tets_ascii.msh", mesh, file_format="gmsh", binary=False)
meshio.write("cube_tets_binary.msh", mesh, file_format="gmsh", binary=True)
