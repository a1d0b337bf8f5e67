"""Peer benchmark: the same recursive least-squares work in the Python tools engineers use.

    pip install statsmodels==0.15.0 padasip==1.2.2 filterpy==2.0.0 numpy
    python3 bench/peers/peers.py            # prints JSON

Data: the SplitMix64 stream of physid's standard workload (physid_estim::workload): regressors
uniform on [-1, 1), y = sum((i+1)*phi_i) + 0.01*uniform — identical values to `physid bench`.
Timed: statsmodels RecursiveLS(...).filter() (RLS, lambda = 1, a Cython Kalman filter) and padasip
FilterRLS(mu=0.98).run() (RLS with forgetting lambda = 0.98, P0 = 1000 I), per sample update
rates, best of 3; and filterpy's UnscentedKalmanFilter (MerweScaledSigmaPoints, thesis defaults)
on physid's 10-parameter benchmark model Bench10 with the same inputs and truth (`physid bench`'s
`ukf` entry).
"""
import json
from importlib.metadata import version
import os
import platform
import time

import numpy as np
import padasip as pa
import statsmodels
import statsmodels.api as sm

MASK = (1 << 64) - 1


def splitmix_data(p, n, seed=0x5EED):
    s = seed
    rows = np.empty((n, p))
    y = np.empty(n)

    def nxt():
        nonlocal s
        s = (s + 0x9E3779B97F4A7C15) & MASK
        z = s
        z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & MASK
        z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & MASK
        z ^= z >> 31
        return ((z >> 11) / float(1 << 53)) * 2.0 - 1.0

    for k in range(n):
        acc = 0.0
        for i in range(p):
            v = nxt()
            rows[k, i] = v
            acc += (i + 1) * v
        y[k] = acc + 0.01 * nxt()
    return rows, y


def best_rate(fn, n, rounds=3):
    best = 0.0
    for _ in range(rounds):
        t0 = time.perf_counter()
        fn()
        best = max(best, n / (time.perf_counter() - t0))
    return best


# The 10-parameter benchmark model of physid_estim::workload::Bench10 (the cyclic-torque
# model's cost profile), with the same deterministic inputs and the same truth (nominal · 1.02).
NOMINAL10 = np.array([0.8, 0.054, 0.088, 0.0257, 1.2, -0.3, 0.05, 0.02, -0.01, 0.004])


def bench10_inputs(k):
    q = (k * 0.0174533) % (2 * np.pi)
    return np.array([q, 104.7 + 10.0 * np.sin(k * 1e-3), 5.0 * np.cos(k * 7e-3),
                     3e5 * (1.0 + np.cos(q)), 0.3 + 0.1 * np.sin(k * 1e-4)])


def bench10(k, u):
    q, w, a, f, s = u
    m, b, l, r = k[0], k[1], k[2], k[3]
    rs = r * np.sin(q) / l
    psi = 1.0 - rs * rs
    g = abs(rs) / np.sqrt(psi) * np.cos(q) + np.sin(q)
    g1 = r * ((r / l) * np.cos(q) / (psi * np.sqrt(psi)) + 1.0) * np.cos(q)
    ind = b * b * (np.pi / 4.0) * r * g * f
    rec = m * r * g * (g1 * w * w + r * g * a)
    fric = k[4] + k[5] * w + k[6] * s + k[7] * w * w + k[8] * w * s + k[9] * s * s
    return np.array([ind - rec - fric])


def filterpy_ukf_rate(steps=720):
    from filterpy.kalman import MerweScaledSigmaPoints, UnscentedKalmanFilter
    truth = NOMINAL10 * 1.02
    us = [bench10_inputs(k) for k in range(steps)]
    ys = [bench10(truth, u)[0] for u in us]
    points = MerweScaledSigmaPoints(10, alpha=1.0, beta=2.0, kappa=-7.0)
    ukf = UnscentedKalmanFilter(dim_x=10, dim_z=1, dt=1.0, hx=bench10, fx=lambda x, dt: x,
                                points=points)
    ukf.x = NOMINAL10.copy()
    ukf.P = np.diag((0.01 * NOMINAL10) ** 2)  # physid: scaled coordinates, P0 = 1e-4·I
    ukf.Q = np.zeros((10, 10))
    ukf.R = np.array([[1.0]])

    def run():
        for k in range(steps):
            ukf.predict()
            ukf.update(np.array([ys[k]]), u=us[k])
    return best_rate(run, steps)


def main():
    results = []
    for p in (2, 6, 20):
        n = 20000
        X, y = splitmix_data(p, n)
        model = sm.RecursiveLS(y, X)
        results.append({"name": "statsmodels_recursive_ls", "p": p,
                        "updates_per_s": best_rate(lambda: model.filter(), n)})
        nn = 5000
        def run_padasip():
            f = pa.filters.FilterRLS(n=p, mu=0.98, eps=0.001, w="zeros")
            f.run(y[:nn], X[:nn])
        results.append({"name": "padasip_filter_rls", "p": p,
                        "updates_per_s": best_rate(run_padasip, nn)})
    results.append({"name": "filterpy_ukf", "p": 10, "updates_per_s": filterpy_ukf_rate()})
    out = {
        "machine": f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores",
        "versions": {"statsmodels": statsmodels.__version__, "padasip": version("padasip"), "filterpy": version("filterpy"),
                     "numpy": np.__version__, "python": platform.python_version()},
        "results": results,
    }
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
