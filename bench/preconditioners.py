#!/usr/bin/env python3
"""Which dual preconditioner is fastest, scene by scene (issue 41, item 2).

Solves every SCENE.cso with `--preconditioner none`, `lumped` and `dirichlet`
(REPS interleaved rounds, the fastest of each kept) and prints one row per
scene and preconditioner: dimension, subdomains, dofs per subdomain, contact
rows per subdomain, Hessian applications, set-up and solve seconds, and which
one was fastest. With --auto it also runs `--preconditioner auto` and says
whether auto picked the fastest (or one within 10% of it).

    python3 bench/preconditioners.py target/release/cso REPS SCENE.cso... [--auto]
"""
import json, os, subprocess, sys, tempfile

from rounds import least

KINDS = ["none", "lumped", "dirichlet"]


def solve(cso, scene, kind):
    with tempfile.TemporaryDirectory() as out:
        p = subprocess.run([cso, "solve", scene, "-o", out, "-q", "--preconditioner", kind],
                           capture_output=True, text=True)
        if p.returncode != 0:
            return None
        r = json.load(open(os.path.join(out, "report.json")))
    s, t = r["sizes"], r["times"]
    return {
        "dim": r["scene"].get("dim", 0) if isinstance(r.get("scene"), dict) else 0,
        "subdomains": s["subdomains"],
        "primal": s["primal"],
        "contact": s["multipliers"]["contact"],
        "dual": s["dual"],
        "hessian": r["solver"]["hessian_applications"],
        "status": r["solver"]["status"]["status"],
        "solve": t["solve"],
        "total": t["total"],
        "chosen": r.get("solver", {}).get("preconditioner"),
    }


def main():
    args = [a for a in sys.argv[1:] if a != "--auto"]
    if len(args) < 3:
        sys.exit(__doc__)
    cso, reps, scenes = args[0], int(args[1]), args[2:]
    kinds = KINDS + (["auto"] if "--auto" in sys.argv else [])
    best = least(reps, scenes, kinds, lambda scene, kind: solve(cso, scene, kind))
    print("| scene | n_s | dofs/s | contact/s | none | lumped | dirichlet | fastest |" + (" auto |" if "auto" in kinds else ""))
    print("|---|---|---|---|---|---|---|---|" + ("---|" if "auto" in kinds else ""))
    for scene in scenes:
        rows = {k: best.get((scene, k)) for k in kinds}
        base = next((r for r in rows.values() if r), None)
        if base is None:
            continue
        ns = base["subdomains"]
        cells = []
        for k in KINDS:
            r = rows[k]
            cells.append("-" if r is None else f"{r['hessian']}, {r['total']:.3f} s" + ("" if r["status"] == "converged" else " (" + r["status"] + ")"))
        timed = {k: rows[k]["total"] for k in KINDS if rows[k] and rows[k]["status"] == "converged"}
        fastest = min(timed, key=timed.get) if timed else "-"
        line = f"| {os.path.basename(scene)} | {ns} | {base['primal'] // ns} | {base['contact'] / ns:.1f} | " + " | ".join(cells) + f" | {fastest} |"
        if "auto" in kinds and rows["auto"]:
            a = rows["auto"]
            near = [k for k in timed if timed[k] <= 1.1 * timed[fastest]]
            line += f" {a['hessian']}, {a['total']:.3f} s ({'ok' if a['hessian'] in [rows[k]['hessian'] for k in near] else 'slower'}) |"
        print(line, flush=True)


if __name__ == "__main__":
    main()
