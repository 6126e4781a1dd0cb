"""The exported QP of a scene with friction, read back with scipy, against
cso's own solution: equilibrium K u - f + B^T lambda = 0 over all rows
(B = [B_E; B_I; B_T]), each node's tangential force within its bound (gT, or
muT times its normal force from nT), and no slip where a node is inside it.
Prints the residuals as JSON; exits 77 without scipy."""
import json
import os
import sys

try:
    import numpy as np
    import scipy.io
    import scipy.sparse as sp
except ImportError:
    sys.exit(77)

d = sys.argv[1]
m = lambda n: sp.csr_matrix(scipy.io.mmread(os.path.join(d, n + ".mtx")))
v = lambda n: np.asarray(scipy.io.mmread(os.path.join(d, n + ".mtx"))).ravel()
man = json.load(open(os.path.join(d, "manifest.json")))
ref = json.load(open(os.path.join(d, "reference.json")))
K, f = m("K"), v("f")
BE, BI, BT = m("BE"), m("BI"), m("BT")
nT, gT, muT = v("nT").astype(int), v("gT"), v("muT")
u, lam = np.array(ref["u"]), np.array(ref["lambda"])
ne, ni, nt = BE.shape[0], BI.shape[0], BT.shape[0]
assert man["friction"] == nt and len(lam) == ne + ni + nt
B = sp.vstack([BE, BI, BT])
r = K @ u - f + B.T @ lam
equilibrium = np.linalg.norm(r) / max(np.linalg.norm(f), np.linalg.norm(B.T @ lam))
scale = np.array([row["scale"] for row in man["rows"]])
lt, sc_t = lam[ne + ni:], scale[ne + ni:]
normal = lam[ne + nT] / scale[ne + nT]
bound = gT + muT * np.maximum(normal, 0)
# A node's rows follow each other and share nT.
excess, stick_slip = 0.0, 0.0
slip = BT @ u
i = 0
while i < nt:
    j = i + 1
    while j < nt and nT[j] == nT[i]:
        j += 1
    force = np.linalg.norm(lt[i:j] / sc_t[i:j])
    excess = max(excess, (force - bound[i]) / max(bound.max(), 1e-300))
    if force < bound[i] * (1 - 1e-6):
        stick_slip = max(stick_slip, np.linalg.norm(slip[i:j]) / max(np.abs(u).max(), 1e-300))
    i = j
print(json.dumps({"equilibrium": equilibrium, "excess": excess, "stick_slip": stick_slip}))
