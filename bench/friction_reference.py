"""Cattaneo's and Mindlin's solutions against a solved cattaneo2d or
mindlin3d: `cso solve examples/cattaneo2d.cso -o out && python3
bench/friction_reference.py out 2` (or `... out 3` for mindlin3d).

Equal elastic bodies (E = 210 GPa, nu = 0.3, R = 50 mm as in the examples),
normal force P and tangential Q < mu P from the solve itself (the report's
contact force and tangential resultant; mindlin3d is a half model, so both
are doubled). Prints the stick zone's c/a measured (2D: tributary lengths of
sticking over pressed nodes; 3D: the square root of their areas' ratio)
against sqrt(1 - Q/(mu P)) (2D) or (1 - Q/(mu P))^(1/3) (3D), and in 2D the
shear traction against Cattaneo's
q(x) = mu p0 (sqrt(1 - x^2/a^2) - (c/a) sqrt(1 - x^2/c^2)) (|x| < c),
mu p(x) beyond, relative to mu p0, with Hertz's a and p0 for the model's P.
K. L. Johnson, Contact Mechanics, 1985, 7.1 and 7.2."""
import json
import math
import sys

out, dim = sys.argv[1], int(sys.argv[2])
r = json.load(open(out + "/report.json"))
c = r["contacts"][0]
mu = c["friction"]["coefficient"]
copies = 1 if dim == 2 else 2
P = c["total_force"] * copies
Q = abs(c["friction"]["tangential_resultant"][0]) * copies
E_star = 210e9 / (2 * (1 - 0.3**2))
R = 0.05
pressed = stick = 0.0
for n in c["nodes"]:
    if n["pressure"] > 0 and n["state"] != "open":
        extent = n["multiplier"] / n["pressure"]
        pressed += extent
        if n["state"] == "stick":
            stick += extent
ratio = stick / pressed if dim == 2 else math.sqrt(stick / pressed)
expected = (1 - Q / (mu * P)) ** (0.5 if dim == 2 else 1 / 3)
print(f"P = {P:.6g} N{'/m' if dim == 2 else ''}, Q = {Q:.6g}, Q/(mu P) = {Q / (mu * P):.4f}")
print(f"c/a = {ratio:.4f} against {expected:.4f} ({ratio / expected - 1:+.2%})")
if dim == 2:
    a = math.sqrt(4 * P * R / (math.pi * E_star))
    p0 = 2 * P / (math.pi * a)
    cc = expected * a
    total = sum(n["multiplier"] for n in c["nodes"])
    x0 = sum(n["multiplier"] * n["x"] for n in c["nodes"]) / total
    errors = []
    for n in c["nodes"]:
        x = n["x"] - x0
        if abs(x) >= a:
            continue
        q = mu * p0 * math.sqrt(1 - (x / a) ** 2)
        if abs(x) < cc:
            q -= mu * p0 * expected * math.sqrt(1 - (x / cc) ** 2)
        errors.append(abs(math.hypot(*n["shear"])) - q)
    rms = math.sqrt(sum(e * e for e in errors) / len(errors))
    print(
        f"shear traction against Cattaneo's over {len(errors)} nodes: rms {rms / (mu * p0):.2%}, "
        f"largest {max(map(abs, errors)) / (mu * p0):.2%} of mu p0 = {mu * p0:.4g} Pa"
    )
