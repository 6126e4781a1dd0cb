#!/usr/bin/env python3
"""cso against an exact primal-dual active-set method with PARDISO (issue 15).

For each scene of the `two_blocks` family (`cso bench scene --hh H --max-cuts
SXxSY`, the scenes of `cso bench scaling`), this script

1. writes the scene's `.cso` text and exports its QP with `cso export` (PETSc
   binary: K, f, B_E, c_E, B_I, c_I, manifest.json),
2. solves it with `cso solve --threads N -o DIR` (wall time and report.json:
   Hessian applications, the solve's times, energy 1/2 u^T K u, compliance f^T u),
   optionally once more with `--local-f implicit`,
3. solves the same QP

       min 1/2 u^T K u - f^T u   s.t.   B_E u = c_E,   B_I u <= c_I

   by the primal-dual active-set method of Hintermueller, Ito and Kunisch (a
   semismooth Newton method on the KKT conditions): with the active set
   A = {i : lambda_i + c (B_I u - c_I)_i > 0}, each step solves

       [ K    B_E^T  B_I^T ] [u       ]   [f  ]
       [ B_E  0      0     ] [lambda_E] = [c_E]
       [ B_I  0      D     ] [lambda_I]   [c_I]

   where an active row keeps its row of B_I and D_ii = 0 (B_I,i u = c_I,i), an
   inactive one has its row (and column) of B_I zeroed and D_ii = -1/c
   (lambda_i = 0). The pattern is fixed, so PARDISO (MKL, through pypardiso,
   real symmetric indefinite, mtype -2, upper triangle) analyses it once
   (phase 11, METIS ordering) and every step is a numerical factorization
   (phase 22) and a solve (phase 33). The inertia of each factor must be
   (n positive, m_E + m_I negative): every inactive row adds -1/c, every active
   or equality row a negative Schur complement direction. It stops when the
   active set repeats and the relative KKT residuals are below --kkt-tol; then
   the active set is the exact solution's (up to round-off),
4. compares the energy with cso's (relative difference) and prints a Markdown
   table: primal, dual, cuts, cso Hessian applications, cso seconds, PDAS
   iterations, PDAS seconds, the ratio, the energy difference.

Times: "cso s" is the report's total (lowering, assembling and factorizing the
subdomains, the coarse problem, the dual solve, the reconstruction; not
parsing or writing files), "cso wall s" the whole `cso solve` process.
"PDAS s" is building the KKT matrix from the exported K and B, the analysis,
every factorization and solve and the residual checks; it does not count
assembling K (the export does it), so the ratio is, if anything, in PDAS's
favour. MKL and OpenMP get --threads threads (MKL_NUM_THREADS, OMP_NUM_THREADS).

    bench/pdas_reference.py --hh 32 --cuts 8x4 --cuts 20x10 --cuts 28x14 --cuts 32x16
    bench/pdas_reference.py --check    # a small scene; exit 1 if the energies differ

Exit codes: 0 success, 1 an energy differs by more than --energy-tol (or PDAS
failed), 2 usage or a failed cso command, 77 pypardiso (or numpy/scipy) missing.
"""
import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time


def parse_args(argv):
    p = argparse.ArgumentParser(
        description="cso against a primal-dual active-set method with PARDISO (issue 15)"
    )
    p.add_argument("--cso", default=None, help="the cso binary (default: target/release/cso)")
    p.add_argument(
        "--hh", type=int, default=None, help="elements per subdomain side, H/h (default 32)"
    )
    p.add_argument(
        "--cuts",
        action="append",
        default=None,
        help="base cut SXxSY, repeatable (default 8x4 20x10 28x14 32x16)",
    )
    p.add_argument("--tolerance", type=float, default=1e-6, help="cso's dual tolerance")
    p.add_argument("--threads", type=int, default=2, help="threads of cso and of MKL")
    p.add_argument(
        "--implicit",
        action="store_true",
        help="also run cso with --local-f implicit (an extra column)",
    )
    p.add_argument(
        "--assembled",
        action="store_true",
        help="also run PDAS on the assembled problem (gluing rows eliminated: "
        "one dof per node, as a direct solver's user would set it up)",
    )
    p.add_argument("--energy-tol", type=float, default=1e-6, help="relative energy agreement")
    p.add_argument("--kkt-tol", type=float, default=1e-10, help="PDAS's relative KKT residual")
    p.add_argument("--max-iterations", type=int, default=100, help="PDAS steps at most")
    p.add_argument(
        "--check",
        action="store_true",
        help="one small scene (8x4 at H/h = 8, unless --cuts/--hh say otherwise); "
        "exit 1 when the energies differ by more than --energy-tol",
    )
    p.add_argument(
        "--iparm",
        action="append",
        default=[],
        metavar="I=V",
        help="override PARDISO's iparm[I] (0-based, as in MKL's C documentation), repeatable",
    )
    p.add_argument("--keep", default=None, help="keep the scenes, exports and reports here")
    p.add_argument("--json", default=None, help="also write the rows as JSON to this file")
    a = p.parse_args(argv)
    if a.hh is None:
        a.hh = 8 if a.check else 32
    if a.check and a.cuts is None:
        a.cuts = ["8x4"]
    if a.cuts is None:
        a.cuts = ["8x4", "20x10", "28x14", "32x16"]
    for c in a.cuts:
        parts = c.split("x")
        if len(parts) != 2 or not all(x.isdigit() and int(x) > 0 for x in parts):
            p.error(f"--cuts takes SXxSY, e.g. 32x16, not {c!r}")
    try:
        a.iparm = [tuple(int(x) for x in kv.split("=")) for kv in a.iparm]
    except ValueError:
        p.error("--iparm takes I=V, e.g. 23=1")
    if any(len(kv) != 2 or not 0 <= kv[0] < 64 for kv in a.iparm):
        p.error("--iparm takes I=V with 0 <= I < 64")
    if a.hh < 1 or a.threads < 1:
        p.error("--hh and --threads must be at least 1")
    return a


ARGS = parse_args(sys.argv[1:])
# Before numpy and MKL load: their thread pools are sized once.
for var in ("MKL_NUM_THREADS", "OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS"):
    os.environ[var] = str(ARGS.threads)

try:
    import numpy as np
    import scipy.sparse as sp
    import pypardiso

    pypardiso.PyPardisoSolver()  # finds MKL's mkl_rt, or raises ImportError
except (ImportError, OSError) as e:
    print(f"SKIPPED: {e} (pip install pypardiso)", file=sys.stderr)
    sys.exit(77)


class Failed(Exception):
    """A cso command failed or PDAS did not converge."""


# ---------------------------------------------------------------- the QP


def read_petsc_mat(path):
    """A PETSc binary AIJ matrix (big-endian, 32-bit indices) as scipy CSR."""
    with open(path, "rb") as fh:
        raw = fh.read()
    head = np.frombuffer(raw, dtype=">i4", count=4)
    if head[0] != 1211216:
        raise Failed(f"{path}: not a PETSc matrix (class id {head[0]})")
    m, n, nnz = (int(x) for x in head[1:])
    off = 16
    counts = np.frombuffer(raw, dtype=">i4", count=m, offset=off).astype(np.int64)
    off += 4 * m
    cols = np.frombuffer(raw, dtype=">i4", count=nnz, offset=off).astype(np.int32)
    off += 4 * nnz
    vals = np.frombuffer(raw, dtype=">f8", count=nnz, offset=off).astype(np.float64)
    ptr = np.zeros(m + 1, dtype=np.int64)
    np.cumsum(counts, out=ptr[1:])
    return sp.csr_matrix((vals, cols, ptr), shape=(m, n))


def read_petsc_vec(path):
    with open(path, "rb") as fh:
        raw = fh.read()
    head = np.frombuffer(raw, dtype=">i4", count=2)
    if head[0] != 1211214:
        raise Failed(f"{path}: not a PETSc vector (class id {head[0]})")
    return np.frombuffer(raw, dtype=">f8", count=int(head[1]), offset=8).astype(np.float64)


def read_qp(d):
    m = lambda n: read_petsc_mat(os.path.join(d, n + ".bin"))
    v = lambda n: read_petsc_vec(os.path.join(d, n + ".bin"))
    return m("K"), v("f"), m("BE"), v("cE"), m("BI"), v("cI")


def assemble(K, f, BE, cE, gluing):
    """The same QP with the subdomains' copies of a node merged: P maps every
    copy to its node's dof (the connected components of the dofs that gluing
    rows tie), K_g = P^T K P, f_g = P^T f, and the gluing rows, which vanish on
    range(P), dropped. Returns P and the assembled K, f, B_E, c_E."""
    from scipy.sparse.csgraph import connected_components

    n = K.shape[0]
    g = abs(BE[gluing]).tocsc()
    tie = (g.T @ g).tocsr()
    count, label = connected_components(tie, directed=False)
    P = sp.csr_matrix((np.ones(n), (np.arange(n), label)), shape=(n, count))
    if abs(BE[gluing] @ P).max() > 1e-12:
        raise Failed("a gluing row does not vanish on the merged copies")
    keep = ~gluing
    Kg = (P.T @ K @ P).tocsr()
    return P, Kg, P.T @ f, (BE[keep] @ P).tocsr(), cE[keep]


# ---------------------------------------------------------------- PDAS


class Kkt:
    """The KKT matrix's upper triangle with a fixed pattern; the active set
    only changes values (the B_I columns and the D diagonal)."""

    def __init__(self, K, BE, BI, c):
        n, me, mi = K.shape[0], BE.shape[0], BI.shape[0]
        self.n, self.me, self.mi = n, me, mi
        ku = sp.triu(K, format="coo")
        be, bi = BE.tocoo(), BI.tocoo()
        # Entries in a fixed order (their "source" ids): K upper, B_E^T, B_I^T,
        # the zero diagonal of the equality rows, the D diagonal.
        rows = np.concatenate(
            [ku.row, be.col, bi.col, n + np.arange(me), n + me + np.arange(mi)]
        )
        cols = np.concatenate(
            [ku.col, n + be.row, n + me + bi.row, n + np.arange(me), n + me + np.arange(mi)]
        )
        nk, nbe, nbi = ku.nnz, be.nnz, bi.nnz
        self.values = np.concatenate([ku.data, be.data, bi.data, np.zeros(me), np.zeros(mi)])
        self.bi_slice = slice(nk + nbe, nk + nbe + nbi)
        self.bi_values = bi.data.copy()
        self.bi_row = bi.row.copy()
        self.d_slice = slice(nk + nbe + nbi + me, nk + nbe + nbi + me + mi)
        self.c = c
        size = n + me + mi
        ids = np.arange(len(rows), dtype=np.float64)  # exact below 2^53
        a = sp.coo_matrix((ids, (rows, cols)), shape=(size, size)).tocsr()
        a.sort_indices()
        if a.nnz != len(rows):
            raise Failed("the KKT pattern has duplicate entries")
        self.order = a.data.astype(np.int64)  # CSR slot -> source id
        self.a = a

    def set_active(self, active):
        """Active rows: B_I row kept, D_ii = 0; inactive: row zeroed, D_ii = -1/c."""
        self.values[self.bi_slice] = np.where(active[self.bi_row], self.bi_values, 0.0)
        self.values[self.d_slice] = np.where(active, 0.0, -1.0 / self.c)
        self.a.data = self.values[self.order]

    def full(self):
        """The whole symmetric matrix (for residuals)."""
        u = self.a
        return u + sp.triu(u, k=1, format="csr").T


def pardiso_solver(overrides, mtype=-2):
    s = pypardiso.PyPardisoSolver(mtype=mtype)
    s.iparm[:] = 0
    s.iparm[0] = 1  # set the parameters below, not the defaults
    s.iparm[1] = 2  # METIS nested dissection
    s.iparm[7] = 0  # iterative refinement: two steps only when pivots were perturbed
    s.iparm[9] = 8  # pivot perturbation 1e-8
    s.iparm[10] = 1  # symmetric scaling ...
    s.iparm[12] = 1  # ... and weighted matching (saddle-point systems)
    s.iparm[17] = -1  # report nnz of the factor
    s.iparm[20] = 1  # Bunch-Kaufman pivoting
    s.iparm[34] = 0  # one-based indices (pypardiso adds 1)
    for i, v in overrides:
        s.iparm[i] = v
    return s


def call(solver, a, phase, b):
    """One PARDISO phase on the matrix `a` (pypardiso's own solve() would run the
    analysis again, phase 13, whenever the values change)."""
    solver.set_phase(phase)
    return solver._call_pardiso(a, b)


def pdas(K, f, BE, cE, BI, cI, kkt_tol, max_iterations, iparm=()):
    """Primal-dual active set; the active set starts empty."""
    t_all = time.perf_counter()
    times = {"build": 0.0, "analysis": 0.0, "factorize": 0.0, "solve": 0.0, "check": 0.0}
    t = time.perf_counter()
    n, me, mi = K.shape[0], BE.shape[0], BI.shape[0]
    c = float(K.diagonal().mean())
    kkt = Kkt(K, BE, BI, c)
    rhs = np.concatenate([f, cE, cI])
    kkt.set_active(np.ones(mi, dtype=bool))  # representative values for the matching
    times["build"] += time.perf_counter() - t
    solver = pardiso_solver(iparm)
    t = time.perf_counter()
    call(solver, kkt.a, 11, np.zeros(0))
    times["analysis"] = time.perf_counter() - t
    nnz_factor = int(solver.iparm[17])
    active = np.zeros(mi, dtype=bool)
    history = []
    for it in range(1, max_iterations + 1):
        t = time.perf_counter()
        kkt.set_active(active)
        times["build"] += time.perf_counter() - t
        t = time.perf_counter()
        call(solver, kkt.a, 22, np.zeros(0))
        times["factorize"] += time.perf_counter() - t
        inertia = (int(solver.iparm[21]), int(solver.iparm[22]))
        perturbed = int(solver.iparm[13])
        t = time.perf_counter()
        x = call(solver, kkt.a, 33, rhs)
        times["solve"] += time.perf_counter() - t
        t = time.perf_counter()
        u, le, li = x[:n], x[n : n + me], x[n + me :]
        li = np.where(active, li, 0.0)
        gap = BI @ u - cI
        new = li + c * gap > 0
        res = kkt_residuals(K, f, BE, cE, BI, cI, u, le, li)
        times["check"] += time.perf_counter() - t
        history.append(
            {
                "active": int(active.sum()),
                "changed": int((new != active).sum()),
                "inertia": inertia,
                "perturbed_pivots": perturbed,
                "refinement_steps": int(solver.iparm[6]),
                "kkt": max(res.values()),
            }
        )
        if np.array_equal(new, active):
            if max(res.values()) > kkt_tol:
                raise Failed(f"PDAS: the active set settled but the KKT residual is {res}")
            if inertia != (n, me + mi):
                raise Failed(f"PDAS: inertia {inertia}, expected ({n}, {me + mi})")
            return {
                "iterations": it,
                "u": u,
                "lambda_E": le,
                "lambda_I": li,
                "active": int(active.sum()),
                "residuals": res,
                "history": history,
                "times": times,
                "total": time.perf_counter() - t_all,
                "nnz_kkt": int(kkt.a.nnz),
                "nnz_factor": nnz_factor,
                "c": c,
            }
        active = new
    raise Failed(f"PDAS: the active set did not settle in {max_iterations} steps: {history}")


def kkt_residuals(K, f, BE, cE, BI, cI, u, le, li):
    """Relative KKT residuals of the QP (max norms)."""
    ku = K @ u
    bt = BE.T @ le + BI.T @ li
    scale_force = max(np.abs(f).max(initial=0), np.abs(ku).max(), np.abs(bt).max(), 1e-300)
    scale_u = max(np.abs(u).max(), 1e-300)
    gap = BI @ u - cI
    return {
        "stationarity": float(np.abs(ku - f + bt).max() / scale_force),
        "equality": float(np.abs(BE @ u - cE).max(initial=0) / scale_u),
        "feasibility": float(max(gap.max(initial=0), 0.0) / scale_u),
        "sign": float(max(-li.min(initial=0), 0.0) / scale_force),
        "complementarity": float(
            np.abs(li * gap).max(initial=0) / (scale_force * scale_u)
        ),
    }


# ---------------------------------------------------------------- cso


def run(cmd, **kw):
    r = subprocess.run(cmd, capture_output=True, text=True, **kw)
    if r.returncode != 0:
        raise Failed(f"{' '.join(cmd)} exited with {r.returncode}:\n{r.stderr.strip()}")
    return r.stdout


def cso_solve(cso, scene, out, threads, extra=()):
    cmd = [cso, "--quiet", "solve", scene, "--threads", str(threads), "-o", out, *extra]
    t = time.perf_counter()
    run(cmd)
    wall = time.perf_counter() - t
    with open(os.path.join(out, "report.json")) as fh:
        rep = json.load(fh)
    return {
        "wall": wall,
        "total": rep["times"]["total"],
        "times": rep["times"],
        "hessian": rep["solver"]["hessian_applications"],
        "outer": rep["solver"]["outer_iterations"],
        "inner": rep["solver"]["inner_iterations"],
        "energy": rep["energy"],
        "compliance": rep["compliance"],
        "sizes": rep["sizes"],
    }


def one_scene(cso, work, hh, cuts, args):
    tag = f"h{hh}_{cuts}"
    scene = os.path.join(work, f"{tag}.cso")
    text = run([cso, "bench", "scene", "--hh", str(hh), "--max-cuts", cuts,
                "--tolerance", repr(args.tolerance)])
    with open(scene, "w") as fh:
        fh.write(text)
    qp_dir = os.path.join(work, f"{tag}_qp")
    t = time.perf_counter()
    run([cso, "--quiet", "export", scene, "--format", "petsc", "-o", qp_dir, "--force"])
    export_s = time.perf_counter() - t
    K, f, BE, cE, BI, cI = read_qp(qp_dir)
    # Back to back: cso (default, then implicit local F), then PDAS.
    ours = cso_solve(cso, scene, os.path.join(work, f"{tag}_solve"), args.threads)
    implicit = None
    if args.implicit:
        implicit = cso_solve(cso, scene, os.path.join(work, f"{tag}_solve_implicit"),
                             args.threads, ["--local-f", "implicit"])
    ref = pdas(K, f, BE, cE, BI, cI, args.kkt_tol, args.max_iterations, args.iparm)
    assembled = None
    if args.assembled:
        with open(os.path.join(qp_dir, "manifest.json")) as fh:
            kinds = [r["kind"] for r in json.load(fh)["rows"][: BE.shape[0]]]
        t = time.perf_counter()
        P, Kg, fg, BEg, cEg = assemble(K, f, BE, cE, np.array([k == "gluing" for k in kinds]))
        t_assemble = time.perf_counter() - t
        BIg = (BI @ P).tocsr()
        assembled = pdas(Kg, fg, BEg, cEg, BIg, cI, args.kkt_tol, args.max_iterations, args.iparm)
        ua = P @ assembled["u"]
        assembled["energy"] = 0.5 * float(ua @ (K @ ua))
        assembled["merge_s"] = t_assemble
        assembled["primal"] = Kg.shape[0]
        assembled["dual"] = BEg.shape[0] + BI.shape[0]
        for k in ("u", "lambda_E", "lambda_I"):
            del assembled[k]
    u = ref["u"]
    energy = 0.5 * float(u @ (K @ u))
    compliance = float(f @ u)
    denergy = abs(ours["energy"] - energy) / max(abs(energy), 1e-300)
    dobjective = abs((ours["energy"] - ours["compliance"]) - (energy - compliance)) / max(
        abs(energy - compliance), 1e-300
    )
    row = {
        "hh": hh,
        "cuts": cuts,
        "primal": K.shape[0],
        "dual": BE.shape[0] + BI.shape[0],
        "equalities": BE.shape[0],
        "inequalities": BI.shape[0],
        "export_s": export_s,
        "cso": ours,
        "cso_implicit": implicit,
        "pdas": {k: v for k, v in ref.items() if k not in ("u", "lambda_E", "lambda_I")},
        "pdas_assembled": assembled,
        "energy_pdas": energy,
        "compliance_pdas": compliance,
        "energy_diff": denergy,
        "objective_diff": dobjective,
    }
    if assembled is not None:
        row["energy_diff_assembled"] = abs(assembled["energy"] - energy) / max(abs(energy), 1e-300)
    if implicit is not None:
        row["energy_diff_implicit"] = abs(implicit["energy"] - energy) / max(abs(energy), 1e-300)
    return row


def table(rows, implicit, assembled):
    """The Markdown table; the last column is the energy difference (the test reads it)."""
    cols = ["H/h", "cuts", "primal", "dual", "active", "cso Hessian", "cso s", "cso wall s"]
    if implicit:
        cols += ["cso implicit Hessian", "cso implicit s"]
    cols += ["PDAS iterations", "PDAS analysis s", "PDAS factorize s", "PDAS solve s",
             "PDAS s", "ratio cso/PDAS"]
    if implicit:
        cols += ["ratio implicit/PDAS"]
    if assembled:
        cols += ["assembled primal", "assembled PDAS s", "ratio cso/assembled"]
    cols += ["energy (J)", "energy diff"]
    out = ["| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
    for r in rows:
        p, c = r["pdas"], r["cso"]
        cells = [r["hh"], r["cuts"], r["primal"], r["dual"], p["active"], c["hessian"],
                 f"{c['total']:.2f}", f"{c['wall']:.2f}"]
        if implicit:
            ci = r["cso_implicit"]
            cells += [ci["hessian"], f"{ci['total']:.2f}"]
        cells += [p["iterations"], f"{p['times']['analysis']:.2f}",
                  f"{p['times']['factorize']:.2f}", f"{p['times']['solve']:.2f}",
                  f"{p['total']:.2f}", f"{c['total'] / p['total']:.2f}"]
        if implicit:
            cells += [f"{r['cso_implicit']['total'] / p['total']:.2f}"]
        if assembled:
            a = r["pdas_assembled"]
            cells += [a["primal"], f"{a['total']:.2f}", f"{c['total'] / a['total']:.2f}"]
        diff = max(r.get(k, 0.0) for k in ("energy_diff", "energy_diff_implicit",
                                              "energy_diff_assembled"))
        cells += [f"{r['energy_pdas']:.9e}", f"{diff:.1e}"]
        out.append("| " + " | ".join(str(x) for x in cells) + " |")
    return "\n".join(out)


def main():
    args = ARGS
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    cso = args.cso or os.path.join(root, "target", "release", "cso")
    if not (os.path.isfile(cso) and os.access(cso, os.X_OK)):
        print(f"no cso binary at {cso} (cargo build --release, or --cso PATH)", file=sys.stderr)
        return 2
    work = args.keep or tempfile.mkdtemp(prefix="cso-pdas-")
    os.makedirs(work, exist_ok=True)
    rows, bad = [], []
    try:
        for cuts in args.cuts:
            try:
                row = one_scene(cso, work, args.hh, cuts, args)
            except Failed as e:
                print(f"error at {cuts}: {e}", file=sys.stderr)
                bad.append(cuts)
                continue
            rows.append(row)
            p = row["pdas"]
            print(
                f"{args.hh} {cuts}: PDAS {p['iterations']} steps "
                f"(active {[h['active'] for h in p['history']]}), "
                f"KKT {max(p['residuals'].values()):.1e}, nnz(L) {p['nnz_factor']}, "
                f"perturbed pivots {max(h['perturbed_pivots'] for h in p['history'])}, "
                f"refinement steps {[h['refinement_steps'] for h in p['history']]}; "
                f"energy diff {row['energy_diff']:.1e}, objective diff {row['objective_diff']:.1e}",
                file=sys.stderr,
            )
            a = row["pdas_assembled"]
            if a is not None:
                print(
                    f"{args.hh} {cuts} assembled: {a['primal']} dofs, merged in "
                    f"{a['merge_s']:.2f} s, PDAS {a['iterations']} steps, {a['total']:.2f} s "
                    f"(analysis {a['times']['analysis']:.2f}, factorize "
                    f"{a['times']['factorize']:.2f}, solve {a['times']['solve']:.2f}), "
                    f"nnz(L) {a['nnz_factor']}, energy diff {row['energy_diff_assembled']:.1e}",
                    file=sys.stderr,
                )
            worst = max(row.get(k, 0.0) for k in ("energy_diff", "energy_diff_implicit",
                                                   "energy_diff_assembled"))
            if worst > args.energy_tol:
                bad.append(cuts)
    finally:
        if args.keep is None:
            shutil.rmtree(work, ignore_errors=True)
    print(f"threads {args.threads}, cso tolerance {args.tolerance:g}, "
          f"energy agreement {args.energy_tol:g}")
    print(table(rows, args.implicit, args.assembled))
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(rows, fh, indent=1)
    if bad:
        print(f"energies differ or failed at: {', '.join(bad)}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
