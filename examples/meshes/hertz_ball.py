"""Writes the meshes of examples/hertz_ball.cso (run: python3 hertz_ball.py
in examples/meshes; pure Python, msh41.py beside it):

ball.msh  -- a quarter of the lower half of a ball of radius 50 mm, centre
             (0, 0, 50) mm: x, y >= 0, 0 <= z <= 50 mm, in linear tetrahedra.
             The unit cube, graded towards the corner that becomes the ball's
             lowest point, is mapped onto the octant of the ball by the radial
             map p = R c max(c) / |c| (cube faces x = 0, y = 0 stay the
             symmetry planes, the far faces become the sphere); each of its
             hexahedra is cut into six tetrahedra. Faces: `sym_x`, `sym_y`,
             `top` (the flat cut z = 50 mm), `surface` (the sphere).
block.msh -- a quarter of a block, 0 .. 60 mm in x and y, -60 .. 0 mm in z,
             in hexahedra graded towards the contact point (0, 0, 0) (0.4 mm steps
             there, as on the ball). Faces:
             `sym_x`, `sym_y`, `bottom`, `top`, `sides` (x or y = 60 mm).

Coordinates in mm. The same geometry in Gmsh would be a Sphere and a Box cut
by BooleanIntersection with Physical Surfaces of these names; the script is
used here because Gmsh is not installed where cso is tested."""
import math
import sys
from msh41 import write, grid_3d

# python3 hertz_ball.py [N BALL BLOCK]: N cells per cube axis (16), and
# where to write (../ball.msh, ../block.msh); the tests take a coarse one.
R = 50.0
N = int(sys.argv[1]) if len(sys.argv) > 1 else 16
BALL = sys.argv[2] if len(sys.argv) > 2 else "../ball.msh"
BLOCK = sys.argv[3] if len(sys.argv) > 3 else "../block.msh"


def grade(t, first):
    """A map of [0, 1] onto itself whose first of N steps is `first` long
    (a fraction of the whole) and whose steps grow smoothly after it:
    fine and nearly even where the bodies touch, coarse far away."""
    a = first * N
    return a * t + (1.0 - a) * t ** 3


def ball_point(u, v, w):
    # Cube (u, v, w) in [0, 1]^3, graded towards (0, 0, 1): the pole.
    f = 6.4 / N / R  # 0.4 mm steps at the pole for N = 16
    c = [grade(u, f), grade(v, f), 1.0 - grade(1.0 - w, f)]
    m, r = max(c), math.sqrt(sum(x * x for x in c))
    s = R * m / r if r > 0 else 0.0
    # z of the cube runs towards the pole, which is the ball's lowest point.
    return (c[0] * s, c[1] * s, R - c[2] * s)


nodes, (kind, cells), sides = grid_3d((0, 0, 0), (1, 1, 1), (N, N, N), tets=True,
                                       warp=ball_point)
groups = [
    ("sym_x", 2, 2, sides["left"]),
    ("sym_y", 2, 2, sides["front"]),
    ("top", 2, 2, sides["bottom"]),
    ("surface", 2, 2, sides["right"] + sides["back"] + sides["top"]),
]
write(BALL, 3, nodes, (kind, cells), groups, region="ball")

L = 60.0


def block_point(x, y, z):
    # Unit cube graded towards (0, 0, 1), the contact point at the top.
    f = 6.4 / N / L
    return (L * grade(x, f), L * grade(y, f), -L * grade(1.0 - z, f))


nodes, (kind, cells), sides = grid_3d((0, 0, 0), (1, 1, 1), (N, N, N), warp=block_point)
groups = [
    ("sym_x", 2, 3, sides["left"]),
    ("sym_y", 2, 3, sides["front"]),
    ("bottom", 2, 3, sides["bottom"]),
    ("top", 2, 3, sides["top"]),
    ("sides", 2, 3, sides["right"] + sides["back"]),
]
write(BLOCK, 3, nodes, (kind, cells), groups, region="block")
