#!/usr/bin/env python3
"""cso against PERMON's TFETI on the same exported QP (issue 41, item 5).

For each scene (a `.cso` file, or a `cso bench scaling` scene given as
`--bench H:SXxSY`), this script

1. exports the scene's primal QP with `cso export --format petsc` (K block
   diagonal by subdomain, f, B_E, c_E, B_I, c_I, the kernel basis R),
2. solves the scene with `cso solve --threads 1` (report.json: Hessian
   applications, the solve's times, the energy 1/2 u^T K u),
3. solves the exported QP with a PERMON driver (`--driver`, a program the
   user builds against PERMON; this repository holds neither PERMON nor a way
   to build it). The driver must load the files of step 1, give them to a
   PERMON `QP` (operator K with null space R, rhs f, equalities B_E u = c_E,
   inequalities B_I u <= c_I), run `QPTFromOptions` and a `QPS` from options,
   and print `key=value` lines: `load_s`, `setup_s` (QPTFromOptions: the
   dualization with the factorization of K, then QPSSetUp), `solve_s`
   (QPSSolve), `reason`, `energy` (1/2 x^T K x of the primal solution). It is
   run with `-feti -qps_type smalxe -qps_max_it 100000 -log_view
   -qps_view_convergence` and `-rtol` the scene's tolerance (as cso's report
   states it): TFETI (dualize, project), SMALXE with MPGP inside, PERMON's
   defaults otherwise (but for SMALXE's 100 outer iterations, too few for
   some of these scenes), one process. From `-log_view` the script reads the
   KSPSolve counts (one solve with the factor of K per application of
   F = B K^+ B^T) of the stage named `dual solve`, which the driver must push
   around QPSSolve, and of the main stage (the dualization and QPSSetUp);
   from `-qps_view_convergence` MPGP's own count of Hessian multiplications,
4. prints a Markdown table: the sizes and tolerance, cso's Hessian
   applications and seconds, PERMON's MPGP multiplications, its solves with
   K^+ in the set-up and in the dual solve, its seconds, both peak resident
   sets, the ratios, why PERMON stopped, and the relative difference of the
   energies.

Both run one thread (`--threads 1`; PERMON one MPI process, OMP and BLAS
threads 1), `--reps` interleaved rounds, the least total time kept.

    bench/permon.py --driver /path/to/permon_driver --scene examples/hertz3d.cso --bench 16:4x2

Exit codes: 0 success, 1 an energy differs by more than --energy-tol or
PERMON did not converge, 2 usage or a failed command, 77 no driver.
"""
import argparse
import json
import os
import re
import subprocess
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from rounds import least  # noqa: E402


class Failed(Exception):
    pass


def parse_args(argv):
    p = argparse.ArgumentParser(description="cso against PERMON's TFETI (issue 41, item 5)")
    p.add_argument("--cso", default=None, help="the cso binary (default: target/release/cso)")
    p.add_argument("--driver", required=True, help="the PERMON driver program (see the doc)")
    p.add_argument("--scene", action="append", default=[], help="a .cso file, repeatable")
    p.add_argument("--bench", action="append", default=[],
                   help="a cso bench scaling scene H:SXxSY, repeatable")
    p.add_argument("--tolerance", type=float, default=None,
                   help="PERMON's rtol (default: the scene's tolerance, as cso reports it)")
    p.add_argument("--reps", type=int, default=3, help="interleaved rounds (least kept)")
    p.add_argument("--energy-tol", type=float, default=1e-5)
    p.add_argument("--work", default=None, help="working directory (default: a temporary one)")
    p.add_argument("--json", default=None, help="write the rows here too")
    p.add_argument("--plain", action="store_true",
                   help="also cso without a preconditioner or a predicted active set "
                        "(SMALBE + MPRGP alone, as PERMON 3.18's MPGP, which takes none)")
    return p.parse_args(argv)


def run(cmd, env=None):
    r = subprocess.run(cmd, capture_output=True, text=True, env=env)
    if r.returncode != 0:
        raise Failed(f"{' '.join(cmd)} exited with {r.returncode}:\n{r.stderr.strip()[-2000:]}")
    return r.stdout, r.stderr


def timed(cmd, env=None):
    """Runs `cmd` under /usr/bin/time; returns stdout, stderr, peak RSS (MB), wall s."""
    t = time.perf_counter()
    out, err = run(["/usr/bin/time", "-f", "peak_kb=%M", *cmd], env=env)
    wall = time.perf_counter() - t
    peak = re.findall(r"peak_kb=(\d+)", err)
    return out, err, (int(peak[-1]) / 1024 if peak else float("nan")), wall


def cso_solve(cso, scene, out, extra=()):
    _, _, peak, wall = timed([cso, "--quiet", "solve", scene, "--threads", "1", "-o", out, *extra])
    with open(os.path.join(out, "report.json")) as fh:
        rep = json.load(fh)
    return {
        "total": rep["times"]["total"],
        "wall": wall,
        "peak_mb": peak,
        "hessian": rep["solver"]["hessian_applications"],
        "tolerance": rep["solver"]["tolerance"],
        "energy": rep["energy"],
    }


def stage_counts(log):
    """KSPSolve counts per -log_view stage name."""
    counts, stage = {}, None
    for line in log.splitlines():
        m = re.match(r"--- Event Stage \d+: (.*)", line)
        if m:
            stage = m.group(1).strip()
            continue
        m = re.match(r"KSPSolve\s+(\d+)", line)
        if m and stage is not None and stage not in counts:
            counts[stage] = int(m.group(1))
    return counts


def permon_solve(driver, qp_dir, tolerance):
    env = dict(os.environ, OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1")
    out, _, peak, wall = timed([driver, "-dir", qp_dir, "-feti", "-qps_type", "smalxe",
                                "-rtol", repr(tolerance), "-qps_max_it", "100000", "-log_view",
                                "-qps_view_convergence"], env=env)
    kv = dict(re.findall(r"^(\w+)=(\S+)$", out, flags=re.M))
    for key in ("setup_s", "solve_s", "energy", "reason"):
        if key not in kv:
            raise Failed(f"the PERMON driver printed no {key}=")
    mults = re.findall(r"number of Hessian multiplications (\d+)", out)
    counts = stage_counts(out)
    return {
        "total": float(kv["setup_s"]) + float(kv["solve_s"]),
        "setup_s": float(kv["setup_s"]),
        "solve_s": float(kv["solve_s"]),
        "wall": wall,
        "peak_mb": peak,
        "reason": kv["reason"],
        "energy": float(kv["energy"]),
        "mpgp_mults": int(mults[-1]) if mults else None,
        "kplus_setup": counts.get("Main Stage"),
        "kplus_solve": counts.get("dual solve"),
    }


def scenes(args, cso, work):
    out = []
    for path in args.scene:
        out.append((os.path.splitext(os.path.basename(path))[0], os.path.abspath(path)))
    for spec in args.bench:
        hh, cuts = spec.split(":")
        text, _ = run([cso, "bench", "scene", "--hh", hh, "--max-cuts", cuts])
        path = os.path.join(work, f"bench_h{hh}_{cuts}.cso")
        with open(path, "w") as fh:
            fh.write(text)
        out.append((f"bench H/h {hh} {cuts}", path))
    return out


def sizes(qp_dir):
    with open(os.path.join(qp_dir, "manifest.json")) as fh:
        m = json.load(fh)
    return {
        "primal": m["primal"],
        "dual": m["equalities"] + m["inequalities"],
        "subdomains": len(m["blocks"]),
        "dim": m["dim"],
    }


def kplus_solves(p):
    """PERMON's solves with the factor of K, set-up and dual solve: its
    applications of F."""
    return (p["kplus_setup"] or 0) + (p["kplus_solve"] or 0)


def table(rows):
    head = ("| scene | dim | primal | dual | subdomains | tolerance | cso Hessian | PERMON MPGP mults "
            "| PERMON K+ solves set-up / dual solve | ratio K+ solves | cso s | PERMON set-up s "
            "| PERMON solve s | ratio time | cso peak MB | PERMON peak MB | PERMON stops | energy diff |")
    lines = [head, "|" + "---|" * (head.count("|") - 1)]
    for r in rows:
        c, p = r["cso"], r["permon"]
        solves = kplus_solves(p)
        lines.append(
            f"| {r['name']} | {r['dim']} | {r['primal']} | {r['dual']} | {r['subdomains']} "
            f"| {c['tolerance']:.0e} "
            f"| {c['hessian']} | {p['mpgp_mults']} | {p['kplus_setup']} / {p['kplus_solve']} "
            f"| {solves / max(c['hessian'], 1):.1f} | {c['total']:.3f} | {p['setup_s']:.3f} "
            f"| {p['solve_s']:.3f} | {p['total'] / max(c['total'], 1e-9):.1f} "
            f"| {c['peak_mb']:.0f} | {p['peak_mb']:.0f} | {p['reason']} | {r['energy_diff']:.1e} |"
        )
    return "\n".join(lines)


PLAIN = ["--preconditioner", "none", "--smalbe", "predict=off"]


def plain_table(rows):
    """cso with SMALBE + MPRGP alone (no preconditioner, no prediction)
    against PERMON's SMALXE + MPGP: the same algorithm's counts."""
    lines = ["| scene | cso plain Hessian | PERMON K+ solves | ratio | cso plain s | PERMON s | ratio |",
             "|---|---|---|---|---|---|---|"]
    for r in rows:
        q, p = r["plain"], r["permon"]
        solves = kplus_solves(p)
        lines.append(
            f"| {r['name']} | {q['hessian']} | {solves} | {solves / max(q['hessian'], 1):.1f} "
            f"| {q['total']:.3f} | {p['total']:.3f} | {p['total'] / max(q['total'], 1e-9):.1f} |"
        )
    return "\n".join(lines)


def main():
    args = parse_args(sys.argv[1:])
    if not (os.path.isfile(args.driver) and os.access(args.driver, os.X_OK)):
        print(f"no PERMON driver at {args.driver}", file=sys.stderr)
        return 77
    here = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    cso = args.cso or os.path.join(here, "target", "release", "cso")
    work = args.work or tempfile.mkdtemp(prefix="cso-permon-")
    os.makedirs(work, exist_ok=True)
    try:
        todo = scenes(args, cso, work)
        if not todo:
            print("give at least one --scene or --bench", file=sys.stderr)
            return 2
        info = {}
        for name, path in todo:
            qp_dir = os.path.join(work, re.sub(r"\W+", "_", name) + "_qp")
            run([cso, "--quiet", "export", path, "--format", "petsc", "-o", qp_dir, "--force"])
            # The scene's tolerance, given to PERMON as its rtol.
            tolerance = args.tolerance or cso_solve(cso, path, qp_dir + "_solve")["tolerance"]
            info[name] = (path, qp_dir, tolerance)

        def one(name, variant):
            path, qp_dir, tolerance = info[name]
            if variant == "cso":
                return cso_solve(cso, path, qp_dir + "_solve")
            if variant == "plain":
                return cso_solve(cso, path, qp_dir + "_plain", PLAIN)
            return permon_solve(args.driver, qp_dir, tolerance)

        variants = ["cso", "permon"] + (["plain"] if args.plain else [])
        best = least(args.reps, list(info), variants, one)
    except Failed as e:
        print(e, file=sys.stderr)
        return 2
    rows, bad = [], False
    for name, (path, qp_dir, _) in info.items():
        c, p = best[(name, "cso")], best[(name, "permon")]
        diff = abs(c["energy"] - p["energy"]) / max(abs(p["energy"]), 1e-300)
        bad |= diff > args.energy_tol or not p["reason"].startswith("CONVERGED")
        rows.append({"name": name, "scene": path, **sizes(qp_dir), "cso": c, "permon": p,
                     "energy_diff": diff, "plain": best.get((name, "plain"))})
    print(table(rows))
    if args.plain:
        print()
        print(plain_table(rows))
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(rows, fh, indent=1)
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
