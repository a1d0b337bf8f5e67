"""Golden file for the cyclic-torque model's exact gradient (thesis Eq. 8.2, app. B.4; SPEC §9).

Independent of physid: the torque is written out symbolically as the thesis's closed forms
(TDC angle phi = asin(delta/(r+L)) taken literally, a = theta - phi, the root of (1-psi)/psi
with the sign of q as SPEC §2.3 requires), differentiated by sympy with respect to all 15
parameters, and evaluated with 30 significant digits (mpmath) at points spread over two revolutions,
with a pin offset delta != 0.

Run: python3 gen_cyclic_torque_gradient.py  (sympy 1.14, mpmath 1.3) -> cyclic_torque_gradient.json
(crates/apps/tests/golden/gen_torque_stream.py imports the model, tau and p0, from here.)
"""
import json
import random

import mpmath
import sympy as sp

mpmath.mp.dps = 30

names = ["M_rec", "b", "L", "r", "delta"] + [f"c{i}" for i in range(1, 11)]
M, b, L, r, d = sp.symbols("M_rec b L r delta", real=True)
c = sp.symbols("c1:11", real=True)
th, w, al, pc, pk, T = sp.symbols("theta omega alpha p_cyl p_crank T_oil", real=True)

phi = sp.asin(d / (r + L))
a = th - phi
q = d + r * sp.sin(a)
psi = 1 - (q / L) ** 2
root = q / (L * sp.sqrt(psi))  # sqrt((1-psi)/psi) with the sign of q
G = sp.sin(th) + root * sp.cos(th)
G1 = r * (sp.cos(a) * (r * sp.cos(a) / (L * psi ** sp.Rational(3, 2)) + 1) - root * sp.sin(a))
G2 = r * (root * sp.cos(a) + sp.sin(a))
N = w * 30 / sp.pi
fmep = (c[0] + c[1] * N - c[2] * T + c[3] * N**2 - c[4] * N * T + c[5] * T**2
        - c[6] * N**3 + c[7] * N**2 * T + c[8] * N * T**2 - c[9] * T**3)
Ap = sp.pi * b**2 / 4
tau = (pc - pk) * Ap * r * G - M * r * G * (G1 * w**2 + G2 * al) - fmep * 1000 * Ap * r / (2 * sp.pi)

params = [M, b, L, r, d, *c]
p0 = [0.80, 0.054, 0.088, 0.0257, 0.0021,
      60.0, 0.02, 0.4, 1e-6, 1e-4, 2e-3, 1e-10, 1e-8, 1e-6, 1e-5]
args = [*params, th, w, al, pc, pk, T]
f_tau = sp.lambdify(args, tau, "mpmath")


def main():
    grads = [sp.diff(tau, s) for s in params]
    f_grads = [sp.lambdify(args, g, "mpmath") for g in grads]
    random.seed(5)
    points = []
    for k in range(12):
        u = [random.uniform(0.0, 4 * 3.141592653589793), random.uniform(50.0, 600.0),
             random.uniform(-500.0, 500.0), random.uniform(2e4, 3e6), 1.0e5,
             random.uniform(20.0, 90.0)]
        x = [mpmath.mpf(v) for v in p0 + u]
        points.append({
            "inputs": u,
            "value": float(f_tau(*x)),
            "gradient": [float(g(*x)) for g in f_grads],
        })
    with open("cyclic_torque_gradient.json", "w") as f:
        json.dump({"params": names, "theta": p0, "points": points}, f, indent=1)
        f.write("\n")


if __name__ == "__main__":
    main()
