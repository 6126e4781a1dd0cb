#!/usr/bin/env python3
"""Every scene before and after a change, side by side in one run.

Solves each SCENE.cso with the binaries BEFORE and AFTER at their defaults
(plus any `--` arguments after the scenes), REPS interleaved rounds, and
prints per scene: Hessian applications, the fastest total seconds of each,
their ratio (after / before) and, where the report says, the preconditioner
each took.

    python3 bench/before_after.py BEFORE AFTER REPS SCENE.cso... [-- ARGS...]
"""
import json, os, subprocess, sys, tempfile

from rounds import least


def solve(cso, scene, extra):
    with tempfile.TemporaryDirectory() as out:
        p = subprocess.run([cso, "solve", scene, "-o", out, "-q"] + extra, capture_output=True, text=True)
        if p.returncode != 0:
            return None
        r = json.load(open(os.path.join(out, "report.json")))
    v = r["solver"]
    kind = v.get("preconditioner", {}).get("kind") if isinstance(v.get("preconditioner"), dict) else None
    return {
        "hessian": v["hessian_applications"],
        "status": v["status"]["status"],
        "total": r["times"]["total"],
        "precond": kind or "none",
    }


def main():
    args = sys.argv[1:]
    extra = []
    if "--" in args:
        at = args.index("--")
        args, extra = args[:at], args[at + 1:]
    if len(args) < 4:
        sys.exit(__doc__)
    before, after, reps, scenes = args[0], args[1], int(args[2]), args[3:]
    binaries = {"before": before, "after": after}
    best = least(reps, scenes, binaries, lambda scene, tag: solve(binaries[tag], scene, extra))
    print("| scene | before: Hessian, s | after: Hessian, s, preconditioner | time after / before |")
    print("|---|---|---|---|")
    for scene in scenes:
        b, a = best.get((scene, "before")), best.get((scene, "after"))
        if not b or not a:
            print(f"| {os.path.basename(scene)} | {'-' if not b else b['hessian']} | {'-' if not a else a['hessian']} | failed |")
            continue
        print(f"| {os.path.basename(scene)} | {b['hessian']}, {b['total']:.3f} | {a['hessian']}, {a['total']:.3f}, {a['precond']} | {a['total'] / b['total']:.2f} |", flush=True)


if __name__ == "__main__":
    main()
