#!/usr/bin/env python3
"""Contact families for issue 41 (BENCHMARKS.md, "Why the outer loop grows"):
writes roller{1,2,4,8,16}.cso, stack{1,2,4,8}.cso and ball{1,2,3,4}.cso into
OUT (and the 2D two at H/h = 64: roller64_{1,2,4}, stack64_{1,2}) and, with --run CSO, solves each with `--smalbe metric=off` and `on` and
prints subdomains, outer iterations, Hessian applications and solve seconds.

    python3 bench/families.py /tmp/fam --run target/release/cso
"""
import json, subprocess, sys, os
def roller(k, hh=16):  # 2D: roller on a floor, traction, symmetry; cut k x 2k, H/h = 16
    return f"""scene roller{k} {{ dim = 2, thickness = 1 m }}
let R = 50 mm
material steel {{ E = 210 GPa, nu = 0.3 }}
body roller {{ material = steel, x = 0 .. 10 mm, y = 0 .. 20 mm, bottom = R - sqrt(R^2 - x^2),
  mesh = {hh*k} x {2*hh*k}, subdomains = {k} x {2*k} }}
obstacle floor {{ point = (0, 0), normal = (0, 1) }}
symmetry roller.left
traction roller.top = (0, -100 MPa)
contact seat {{ primary = floor, secondary = roller.bottom }}
solver {{ tolerance = 1e-6 }}
"""
def stack(c, hh=16):  # 2D: semicoercive punch on a base, traction; base 3c x 2c, punch c x 2c, H/h = 16
    return f"""scene stack{c} {{ dim = 2 }}
material soft {{ E = 1000, nu = 0.3 }}
body base {{ material = soft, x = 1.5 .. 3, y = 0 .. 1, mesh = {3*hh*c} x {2*hh*c}, subdomains = {3*c} x {2*c} }}
body punch {{ material = soft, x = 1.5 .. 2, y = 1 .. 2, bottom = 1 + 0.02 * (2*x - 3)^2,
  mesh = {hh*c} x {2*hh*c}, subdomains = {c} x {2*c} }}
fix base.bottom
symmetry base.left
symmetry punch.left
traction punch.top = (0, -5)
contact seat {{ primary = base.top, secondary = punch.bottom }}
solver {{ tolerance = 1e-6 }}
"""
def ball(k):  # 3D: quarter column with a spherical end on a floor, pressure; cut k x k x 2k, H/h = 8
    return f"""scene ball{k} {{ dim = 3 }}
let R = 50 mm
material steel {{ E = 210 GPa, nu = 0.3 }}
body ball {{ material = steel, x = 0 .. 5 mm, y = 0 .. 5 mm, z = 0 .. 10 mm, bottom = R - sqrt(R^2 - x^2 - y^2),
  mesh = {8*k} x {8*k} x {16*k}, subdomains = {k} x {k} x {2*k} }}
obstacle floor {{ point = (0, 0, 0), normal = (0, 0, 1) }}
symmetry ball.left
symmetry ball.front
pressure ball.top = 100 MPa
contact seat {{ primary = floor, secondary = ball.bottom }}
solver {{ tolerance = 1e-6 }}
"""

def main():
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    out = sys.argv[1]
    os.makedirs(out, exist_ok=True)
    names = []
    for make, sizes, stem in ((roller, (1, 2, 4, 8, 16), "roller"), (stack, (1, 2, 4, 8), "stack"), (ball, (1, 2, 3, 4), "ball")):
        for k in sizes:
            path = os.path.join(out, f"{stem}{k}.cso")
            open(path, "w").write(make(k))
            names.append(path)
    # The 2D families at H/h = 64 (issue 41, item 2: where `auto` takes
    # Dirichlet): roller64_{1,2,4}.cso, stack64_{1,2}.cso.
    for make, sizes, stem in ((roller, (1, 2, 4), "roller64_"), (stack, (1, 2), "stack64_")):
        for k in sizes:
            path = os.path.join(out, f"{stem}{k}.cso")
            open(path, "w").write(make(k, 64))
    if "--run" not in sys.argv:
        return
    cso = sys.argv[sys.argv.index("--run") + 1]
    for path in names:
        cells = [os.path.basename(path)[:-4]]
        for metric in ("off", "on"):
            res = os.path.join(out, "out_" + metric)
            run = subprocess.run([cso, "solve", path, "--smalbe", "metric=" + metric, "-o", res, "--threads", "2"], capture_output=True, text=True)
            if run.returncode != 0:
                cells.append("fail: " + run.stderr.strip().splitlines()[-1])
                continue
            r = json.load(open(os.path.join(res, "report.json")))
            s = r["solver"]
            cells.append(f"{r['sizes'].get('subdomains', '?')} {s['outer_iterations']} {s['hessian_applications']} {r['times']['solve']:.2f}")
        print(" | ".join(cells), flush=True)


if __name__ == "__main__":
    main()
