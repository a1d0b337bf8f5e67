"""Golden stream for the cyclic-torque stage (thesis Eq. 8.2, app. B.4; SPEC §9).

Independent of physid: the torque is written out symbolically as the thesis's closed forms (as
in crates/models/tests/golden/gen_cyclic_torque_gradient.py: TDC angle phi = asin(delta/(r+L)),
a = theta - phi, the root of (1-psi)/psi with the sign of q) and evaluated with 30 significant
digits (mpmath) at every crank degree of a motored stream: 4 cycles of 720 samples, one per
degree from a firing TDC (theta_k = k*pi/180), at 1500, 2500, 3500 and 2000 rpm (alpha = 0),
a compression peak of 20 bar at each firing TDC, p_crank 1 bar, oil at 80 degC, the parameters
of the gradient golden file (delta = 2.1 mm).

Run: python3 gen_torque_stream.py  (sympy 1.14, mpmath 1.3) -> torque_stream.json
"""
import json
import math

import mpmath
import sympy as sp

mpmath.mp.dps = 30

M, b, L, r, d = sp.symbols("M_rec b L r delta", real=True)
c = sp.symbols("c1:11", real=True)
th, w, al, pc, pk, T = sp.symbols("theta omega alpha p_cyl p_crank T_oil", real=True)
phi = sp.asin(d / (r + L))
a = th - phi
q = d + r * sp.sin(a)
psi = 1 - (q / L) ** 2
root = q / (L * sp.sqrt(psi))
G = sp.sin(th) + root * sp.cos(th)
G1 = r * (sp.cos(a) * (r * sp.cos(a) / (L * psi ** sp.Rational(3, 2)) + 1) - root * sp.sin(a))
G2 = r * (root * sp.cos(a) + sp.sin(a))
N = w * 30 / sp.pi
fmep = (c[0] + c[1] * N - c[2] * T + c[3] * N**2 - c[4] * N * T + c[5] * T**2
        - c[6] * N**3 + c[7] * N**2 * T + c[8] * N * T**2 - c[9] * T**3)
Ap = sp.pi * b**2 / 4
tau = (pc - pk) * Ap * r * G - M * r * G * (G1 * w**2 + G2 * al) - fmep * 1000 * Ap * r / (2 * sp.pi)
f_tau = sp.lambdify([M, b, L, r, d, *c, th, w, al, pc, pk, T], tau, "mpmath")

p0 = [0.80, 0.054, 0.088, 0.0257, 0.0021,
      60.0, 0.02, 0.4, 1e-6, 1e-4, 2e-3, 1e-10, 1e-8, 1e-6, 1e-5]
rpm = [1500.0, 2500.0, 3500.0, 2000.0]
t_oil_c, p_crank = 80.0, 1.0e5

p_cyl, torque = [], []
for k in range(720 * len(rpm)):
    theta = k * math.pi / 180.0
    omega = rpm[k // 720] * math.pi / 30.0
    # Crank angle from the nearest firing TDC, in (-2pi, 2pi].
    x = math.remainder(theta, 4 * math.pi)
    p = 1.0e5 + 1.9e6 * math.exp(-x * x / 0.2)
    p_cyl.append(p)
    torque.append(float(f_tau(*[mpmath.mpf(v) for v in p0 + [theta, omega, 0.0, p, p_crank, t_oil_c]])))

with open("torque_stream.json", "w") as f:
    json.dump({"params": p0, "rpm_per_cycle": rpm, "t_oil_c": t_oil_c, "p_crank_pa": p_crank,
               "p_cyl_pa": p_cyl, "torque_nm": torque}, f)
    f.write("\n")
