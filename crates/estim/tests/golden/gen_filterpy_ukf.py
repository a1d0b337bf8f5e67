"""Golden file for physid-estim: the UKF (thesis Alg. 5.7) against filterpy's UnscentedKalmanFilter.

Regenerate:  pip install filterpy==2.0.0 numpy && python3 gen_filterpy_ukf.py

Parameter estimation with n = 10 random-walk parameters: fx = identity, Q = R1, R = R2,
hx(theta, phi) the non-linear model below, MerweScaledSigmaPoints(n, alpha=1, beta=2,
kappa=3-n) — the thesis's defaults, for which W0 < 0. Alg. 5.7 draws the sigma points of the
update from the prior P + R1; filterpy's update() reuses the points drawn before Q was added, so
after predict() this script redraws them from the predicted (x, P): the same algorithm as the
thesis. physid keeps P0 as the prior of the first sample (Eq. 5.19's convention), so filterpy
starts from P0 - Q, making its first prior P0.
Writes filterpy_ukf.json: data, settings, the state after every update and the final P.
"""
import json

import filterpy
import numpy as np
from filterpy.kalman import MerweScaledSigmaPoints, UnscentedKalmanFilter

N = 10
STEPS = 600


def hx(theta, phi):
    # y = sum(theta_j phi_j) + 0.3 theta_0 theta_1 phi_0 + 0.2 sin(theta_2) phi_1 + 0.05 theta_3^2
    return np.array([theta @ phi + 0.3 * theta[0] * theta[1] * phi[0]
                     + 0.2 * np.sin(theta[2]) * phi[1] + 0.05 * theta[3] ** 2])


rng = np.random.default_rng(57)
truth = np.linspace(-1.0, 1.5, N)
phis = rng.uniform(-1.0, 1.0, size=(STEPS, N))
ys = np.array([hx(truth, p)[0] for p in phis]) + 0.05 * rng.normal(size=STEPS)
r1 = 1e-6 * np.eye(N) + 2e-7 * (np.eye(N, k=1) + np.eye(N, k=-1))
r2 = 0.0025

points = MerweScaledSigmaPoints(N, alpha=1.0, beta=2.0, kappa=3.0 - N)
ukf = UnscentedKalmanFilter(dim_x=N, dim_z=1, dt=1.0, hx=hx, fx=lambda x, dt: x, points=points)
ukf.x = np.zeros(N)
ukf.P = 1.0 * np.eye(N) - r1  # first prior = P0 (see above)
ukf.Q = r1
ukf.R = np.array([[r2]])
states = []
for k in range(STEPS):
    ukf.predict()
    ukf.sigmas_f = points.sigma_points(ukf.x, ukf.P)  # Alg. 5.7: points from P + R1
    ukf.update(np.array([ys[k]]), phi=phis[k])
    states.append(ukf.x.tolist())

out = {
    "generator": f"filterpy {filterpy.__version__} UnscentedKalmanFilter + MerweScaledSigmaPoints, numpy {np.__version__}",
    "alpha": 1.0, "beta": 2.0, "kappa": 3.0 - N, "p0_scale": 1.0,
    "r1": r1.tolist(), "r2": r2,
    "phi": phis.tolist(), "y": ys.tolist(), "truth": truth.tolist(),
    "states": states, "final_p": ukf.P.tolist(),
    "weights": {"wm0": float(points.Wm[0]), "wc0": float(points.Wc[0]), "wi": float(points.Wm[1])},
}
with open("filterpy_ukf.json", "w") as f:
    json.dump(out, f)
print("wrote filterpy_ukf.json", out["generator"], out["weights"])
