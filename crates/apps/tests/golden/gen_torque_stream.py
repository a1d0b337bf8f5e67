"""Golden stream for the cyclic-torque stage (thesis Eq. 8.2, app. B.4; SPEC §9).

Independent of physid: the torque written out symbolically as the thesis's closed forms by
crates/models/tests/golden/gen_cyclic_torque_gradient.py (imported from there: TDC angle
phi = asin(delta/(r+L)), a = theta - phi, the root of (1-psi)/psi with the sign of q) and
evaluated with 30 significant digits (mpmath) at every crank degree of a motored stream: 4
cycles of 720 samples, one per degree from a firing TDC (theta_k = k*pi/180), at 1500, 2500, 3500 and 2000 rpm (alpha = 0),
a compression peak of 20 bar at each firing TDC, p_crank 1 bar, oil at 80 degC, the parameters
of the gradient golden file (delta = 2.1 mm).

Run: python3 gen_torque_stream.py  (sympy 1.14, mpmath 1.3) -> torque_stream.json
"""
import json
import math
import pathlib
import sys

import mpmath

# The model as the gradient golden file writes it out: Eq. 8.2's closed forms, f_tau over
# (M_rec, b, L, r, delta, c1 ... c10, theta, omega, alpha, p_cyl, p_crank, T_oil), and its p0.
sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[3] / "models/tests/golden"))
from gen_cyclic_torque_gradient import f_tau, p0  # noqa: E402

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
