"""A minimal Gmsh MSH 4.1 ASCII writer (pure Python, no dependencies), for
cso's test and example meshes where Gmsh itself is not installed.

write(path, dim, nodes, cells, groups):
  nodes  -- list of (x, y, z)
  cells  -- (gmsh_type, list of node-index tuples) of the body's dimension
            (2: 3-node triangle, 3: 4-node quadrangle, 4: tetrahedron,
             5: hexahedron), node indices 0-based into `nodes`
  groups -- list of (name, dim, gmsh_type, list of node-index tuples): physical
            groups; a group of dimension `dim` names the body's region, one of
            dimension dim - 1 a face (1: 2-node line, 2: triangle, 3: quadrangle)

Each physical group is one entity; the body's cells are one entity of their
own (physical group `body` unless a group of dimension `dim` is given with
cells=None, meaning "all the body's cells"). Node tags are 1-based, element
tags run on across blocks, as Gmsh writes them."""


def write(path, dim, nodes, cells, groups, region="body"):
    out = []
    w = out.append
    w("$MeshFormat\n4.1 0 8\n$EndMeshFormat\n")
    phys = [(dim, 1, region)] + [(g[1], i + 2, g[0]) for i, g in enumerate(groups)]
    w("$PhysicalNames\n%d\n" % len(phys))
    for d, tag, name in phys:
        w('%d %d "%s"\n' % (d, tag, name))
    w("$EndPhysicalNames\n")
    # Entities: one per physical group; tag = physical tag.
    by_dim = {0: [], 1: [], 2: [], 3: []}
    by_dim[dim].append(1)
    for i, g in enumerate(groups):
        by_dim[g[1]].append(i + 2)
    lo = [min(p[a] for p in nodes) for a in range(3)]
    hi = [max(p[a] for p in nodes) for a in range(3)]
    box = " ".join("%.17g" % v for v in lo + hi)
    w("$Entities\n%d %d %d %d\n" % tuple(len(by_dim[d]) for d in range(4)))
    for d in range(1, 4):
        for tag in by_dim[d]:
            w("%d %s 1 %d 0\n" % (tag, box, tag))
    w("$EndEntities\n")
    n = len(nodes)
    w("$Nodes\n1 %d 1 %d\n%d 1 0 %d\n" % (n, n, dim, n))
    for k in range(n):
        w("%d\n" % (k + 1))
    for p in nodes:
        w("%.17g %.17g %.17g\n" % tuple(p))
    w("$EndNodes\n")
    blocks = [(dim, 1, cells[0], cells[1])] + [
        (g[1], i + 2, g[2], g[3]) for i, g in enumerate(groups)
    ]
    total = sum(len(b[3]) for b in blocks)
    w("$Elements\n%d %d 1 %d\n" % (len(blocks), total, total))
    tag = 1
    for d, etag, typ, elems in blocks:
        w("%d %d %d %d\n" % (d, etag, typ, len(elems)))
        for e in elems:
            w("%d %s\n" % (tag, " ".join(str(v + 1) for v in e)))
            tag += 1
    w("$EndElements\n")
    with open(path, "w") as f:
        f.write("".join(out))


def grid_2d(x0, x1, y0, y1, nx, ny, triangles=False):
    """A structured 2D grid (node (i, j) at j * (nx + 1) + i, as cso numbers
    its structured bodies), its cells (quadrangles counter-clockwise, or each
    cut into two triangles along the diagonal) and its four sides as lines
    (bottom, right, top, left), oriented counter-clockwise around the body."""
    nodes = [
        (x0 + (x1 - x0) * i / nx, y0 + (y1 - y0) * j / ny, 0.0)
        for j in range(ny + 1)
        for i in range(nx + 1)
    ]
    at = lambda i, j: j * (nx + 1) + i
    quads = [
        (at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1))
        for j in range(ny)
        for i in range(nx)
    ]
    if triangles:
        cells = (2, [t for a, b, c, d in quads for t in ((a, b, c), (a, c, d))])
    else:
        cells = (3, quads)
    sides = {
        "bottom": [(at(i, 0), at(i + 1, 0)) for i in range(nx)],
        "right": [(at(nx, j), at(nx, j + 1)) for j in range(ny)],
        "top": [(at(i + 1, ny), at(i, ny)) for i in range(nx)],
        "left": [(at(0, j + 1), at(0, j)) for j in range(ny)],
    }
    return nodes, cells, sides


def grid_3d(lo, hi, n, tets=False, warp=None):
    """A structured 3D grid of the box `lo .. hi` with `n` cells per axis
    (node (i, j, k) at (k (ny + 1) + j) (nx + 1) + i, as cso numbers its
    structured bodies), optionally moved by `warp(x, y, z) -> (x, y, z)`; its
    cells (hexahedra, or each cut into the six tetrahedra about its diagonal
    from the lowest to the highest corner, Kuhn's conforming cut) and its six
    sides (left, right, front, back, bottom, top) as quadrangles or the
    triangles the tetrahedra induce on them."""
    nx, ny, nz = n
    at = lambda i, j, k: (k * (ny + 1) + j) * (nx + 1) + i
    nodes = []
    for k in range(nz + 1):
        for j in range(ny + 1):
            for i in range(nx + 1):
                p = [lo[a] + (hi[a] - lo[a]) * (i, j, k)[a] / n[a] for a in range(3)]
                nodes.append(tuple(warp(*p)) if warp else tuple(p))
    cells = []
    for k in range(nz):
        for j in range(ny):
            for i in range(nx):
                c = lambda a, b, d: at(i + a, j + b, k + d)
                if not tets:
                    cells.append((c(0, 0, 0), c(1, 0, 0), c(1, 1, 0), c(0, 1, 0),
                                  c(0, 0, 1), c(1, 0, 1), c(1, 1, 1), c(0, 1, 1)))
                    continue
                for perm in ((0, 1, 2), (0, 2, 1), (1, 0, 2), (1, 2, 0), (2, 0, 1), (2, 1, 0)):
                    step = [0, 0, 0]
                    path = [c(0, 0, 0)]
                    for a in perm:
                        step[a] = 1
                        path.append(c(*step))
                    cells.append(positive(nodes, path))
    def side(axis, far):
        t = [a for a in range(3) if a != axis]
        out = []
        for b in range(n[t[1]]):
            for a in range(n[t[0]]):
                def corner(da, db):
                    ijk = [0, 0, 0]
                    ijk[axis] = n[axis] if far else 0
                    ijk[t[0]] = a + da
                    ijk[t[1]] = b + db
                    return at(*ijk)
                q = (corner(0, 0), corner(1, 0), corner(1, 1), corner(0, 1))
                if tets:
                    out += [(q[0], q[1], q[2]), (q[0], q[2], q[3])]
                else:
                    out.append(q)
        return out
    names = [("left", 0, 0), ("right", 0, 1), ("front", 1, 0), ("back", 1, 1),
             ("bottom", 2, 0), ("top", 2, 1)]
    sides = {name: side(axis, far) for name, axis, far in names}
    return nodes, (4 if tets else 5, cells), sides


def positive(nodes, tet):
    """The tetrahedron's nodes in an order of positive volume."""
    p = [nodes[v] for v in tet]
    u = [[p[m][a] - p[0][a] for a in range(3)] for m in (1, 2, 3)]
    det = (u[0][0] * (u[1][1] * u[2][2] - u[1][2] * u[2][1])
           - u[0][1] * (u[1][0] * u[2][2] - u[1][2] * u[2][0])
           + u[0][2] * (u[1][0] * u[2][1] - u[1][1] * u[2][0]))
    return tuple(tet) if det > 0 else (tet[0], tet[2], tet[1], tet[3])
