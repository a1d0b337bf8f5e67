"""Golden file for physid-estim: constant-λ RLS against filterpy's KalmanFilter.

Regenerate:  pip install filterpy==2.0.0 numpy && python3 gen_filterpy_rlsf.py
RLS with forgetting λ is a Kalman filter with F = I, Q = 0, R = 1 and fading memory
alpha = 1/sqrt(λ) (filterpy's predict step multiplies P by alpha²). One predict + update per
sample with H = φᵀ. Also the Kalman filter for random-walk parameters (Eq. 5.19) with a full R1, against filterpy
with Q = R1, R = R2 (update, then predict). Writes filterpy_rlsf.json: data, λ, and the state x
after every update for both runs.
"""
import json

import filterpy
import numpy as np
from filterpy.kalman import KalmanFilter

rng = np.random.default_rng(5)
n, k = 500, 3
lam = 0.95
t = np.arange(n) * 0.01
X = np.column_stack([np.sin(2 * np.pi * 2.3 * t), rng.normal(size=n), 1.0 + 0.5 * np.cos(t)])
theta = np.column_stack([np.where(t < 2.5, 2.0, -1.0), 0.5 + 0.1 * t, np.full(n, 4.0)])
y = np.sum(X * theta, axis=1) + 0.05 * rng.normal(size=n)

kf = KalmanFilter(dim_x=k, dim_z=1)
kf.x = np.zeros((k, 1))
kf.P = 1000.0 * np.eye(k)
kf.F = np.eye(k)
kf.Q = np.zeros((k, k))
kf.R = np.array([[1.0]])
kf.alpha = 1.0 / np.sqrt(lam)
states = []
for i in range(n):
    kf.predict()
    kf.update(np.array([[y[i]]]), H=X[i].reshape(1, k))
    states.append(kf.x.ravel().tolist())

# Kalman filter for random-walk parameters (Eq. 5.19): K = Pφ/(R2 + φᵀPφ), P = P − KφᵀP + R1.
# The thesis's P is the prior of the next step, so filterpy runs update, then predict (Q = R1).
r1 = np.array([[1e-3, 2e-4, 0.0], [2e-4, 5e-4, 0.0], [0.0, 0.0, 1e-6]])
r2 = 0.04
kf2 = KalmanFilter(dim_x=k, dim_z=1)
kf2.x = np.zeros((k, 1))
kf2.P = 10.0 * np.eye(k)
kf2.F = np.eye(k)
kf2.Q = r1
kf2.R = np.array([[r2]])
kalman_states = []
for i in range(n):
    kf2.update(np.array([[y[i]]]), H=X[i].reshape(1, k))
    kalman_states.append(kf2.x.ravel().tolist())
    kf2.predict()

out = {
    "generator": f"filterpy {filterpy.__version__} KalmanFilter (F=I, Q=0, R=1, alpha=1/sqrt(lambda)), numpy {np.__version__}",
    "lambda": lam,
    "p0_scale": 1000.0,
    "X": X.tolist(),
    "y": y.tolist(),
    "states": states,
    "kalman": {"r1": r1.tolist(), "r2": r2, "p0_scale": 10.0, "states": kalman_states,
               "final_p": kf2.P.tolist()},
}
with open("filterpy_rlsf.json", "w") as f:
    json.dump(out, f)
print("wrote filterpy_rlsf.json", out["generator"])
