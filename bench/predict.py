#!/usr/bin/env python3
"""A predicted active set against SMALBE alone (BENCHMARKS.md, "A predicted
active set"): solves each scene with `--smalbe predict=off` and with the
default, ROUNDS times interleaved, and prints per scene the Hessian
applications, the solve and total seconds of each one's fastest run, how the active set
was found, and the energies' relative difference.

    python3 bench/predict.py target/release/cso 3 examples/hertz3d.cso /tmp/fam/ball*.cso
"""
import json, os, subprocess, sys, tempfile

from rounds import least


def run(cso, scene, smalbe):
    with tempfile.TemporaryDirectory() as out:
        r = subprocess.run([cso, "--quiet", "solve", scene, "-o", out, "--smalbe", smalbe],
                           capture_output=True, text=True)
        if r.returncode != 0:
            return None
        rep = json.load(open(os.path.join(out, "report.json")))
    s = rep["solver"]
    t = rep.get("times", {})
    return {
        "h": s["hessian_applications"],
        "solve": t.get("solve"),
        "total": t.get("total"),
        "energy": rep.get("energy"),
        "active_set": s.get("active_set"),
        "subdomains": rep.get("sizes", {}).get("subdomains"),
    }


def main():
    if len(sys.argv) < 4:
        sys.exit(__doc__)
    cso, rounds, scenes = sys.argv[1], int(sys.argv[2]), sys.argv[3:]
    print("| scene | subdomains | SMALBE: Hessian, solve s, total s | predicted: Hessian, solve s, total s | how | total ratio | energy rel. diff. |")
    print("|---|---|---|---|---|---|---|")
    best = least(rounds, scenes, ("predict=off", "default"), lambda scene, k: run(cso, scene, k))
    for scene in scenes:
        off, on = best.get((scene, "predict=off")), best.get((scene, "default"))
        if off is None or on is None:
            print(f"| {os.path.basename(scene)} | failed |")
            continue
        a = on["active_set"]
        how = "SMALBE alone" if a is None else (
            f"SMALBE {a['smalbe_applications']} + {a['equality_solves']} equality solve(s)"
            + ("" if a["kept"] else ", refused: SMALBE finished"))
        d = abs(on["energy"] - off["energy"]) / abs(off["energy"]) if off["energy"] else float("nan")
        print(f"| {os.path.basename(scene)} | {off['subdomains']} | {off['h']}, {off['solve']:.3f}, {off['total']:.3f} | "
              f"{on['h']}, {on['solve']:.3f}, {on['total']:.3f} | {how} | {on['total'] / off['total']:.2f} | {d:.1e} |",
              flush=True)


if __name__ == "__main__":
    main()
