#!/usr/bin/env python3
"""Read a `cso export` back with real readers and solve the QP independently.

Usage: export_roundtrip.py DIR, where DIR holds `mm/` (MatrixMarket export),
optionally `petsc/` (PETSc binary export) and `reference.json` (cso's u and
lambda). MatrixMarket is read by scipy.io.mmread, PETSc binary by petsc4py
when it is installed. The QP

    min 1/2 u^T K u - f^T u  s.t.  B_E u = c_E,  B_I u <= c_I

is solved by a primal-dual active-set method on the sparse KKT system
(SuperLU), and the largest difference to cso's u, relative to max |u|, is
printed as JSON per format. Exit code 77 when scipy is missing (skipped).
"""
import json
import os
import sys

try:
    import numpy as np
    import scipy.io
    import scipy.sparse as sp
    import scipy.sparse.linalg as spla
except ImportError:
    print("scipy is not installed", file=sys.stderr)
    sys.exit(77)


def read_mm(d):
    m = lambda n: sp.csr_matrix(scipy.io.mmread(os.path.join(d, n + ".mtx")))
    v = lambda n: np.asarray(scipy.io.mmread(os.path.join(d, n + ".mtx"))).ravel()
    return m("K"), v("f"), m("BE"), v("cE"), m("BI"), v("cI")


def petsc4py_importable():
    """petsc4py, also from Debian's packages without the petsc-dev symlink."""
    import glob

    def loads():
        try:
            from petsc4py import PETSc  # noqa: F401

            return True
        except Exception:  # not installed, or built for another numpy
            return False

    if loads():
        return True
    for path in sorted(glob.glob("/usr/lib/petscdir/*/*-real/lib/python3/dist-packages")):
        sys.path.append(path)
        if loads():
            return True
        sys.path.remove(path)
        for name in [m for m in sys.modules if m.startswith("petsc4py")]:
            del sys.modules[name]
    return False


def read_petsc(d):
    from petsc4py import PETSc

    def mat(n):
        viewer = PETSc.Viewer().createBinary(os.path.join(d, n + ".bin"), "r")
        a = PETSc.Mat().load(viewer)
        ip, ix, vals = a.getValuesCSR()
        return sp.csr_matrix((vals, ix, ip), shape=a.getSize())

    def vec(n):
        viewer = PETSc.Viewer().createBinary(os.path.join(d, n + ".bin"), "r")
        return PETSc.Vec().load(viewer).getArray().copy()

    return mat("K"), vec("f"), mat("BE"), vec("cE"), mat("BI"), vec("cI")


def solve(K, f, BE, cE, BI, cI):
    n = K.shape[0]
    c = K.diagonal().mean()
    active = np.zeros(BI.shape[0], dtype=bool)
    for _ in range(100):
        B = sp.vstack([BE, BI[active]]).tocsr()
        rhs_c = np.concatenate([cE, cI[active]])
        m = B.shape[0]
        A = sp.bmat([[K, B.T], [B, None]]).tocsc()
        x = spla.spsolve(A, np.concatenate([f, rhs_c]))
        u, lam = x[:n], x[n:]
        lI = np.zeros(BI.shape[0])
        lI[active] = lam[len(cE):]
        new = lI + c * (BI @ u - cI) > 0
        if np.array_equal(new, active):
            return u
        active = new
    raise RuntimeError("the active set did not settle")


def main():
    d = sys.argv[1]
    ref = json.load(open(os.path.join(d, "reference.json")))
    u_ref = np.array(ref["u"])
    scale = np.abs(u_ref).max()
    out = {}
    out["mm"] = float(np.abs(solve(*read_mm(os.path.join(d, "mm"))) - u_ref).max() / scale)
    if petsc4py_importable():
        out["petsc"] = float(
            np.abs(solve(*read_petsc(os.path.join(d, "petsc"))) - u_ref).max() / scale
        )
    else:
        out["petsc"] = None
    print(json.dumps(out))


if __name__ == "__main__":
    main()
