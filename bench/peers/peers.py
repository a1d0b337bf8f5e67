"""Peer benchmark: the same recursive least-squares work in the Python tools engineers use.

    pip install statsmodels==0.15.0 padasip==1.2.2 numpy
    python3 bench/peers/peers.py            # prints JSON

Data: the SplitMix64 stream of physid's standard workload (physid_estim::workload): regressors
uniform on [-1, 1), y = sum((i+1)*phi_i) + 0.01*uniform — identical values to `physid bench`.
Timed: statsmodels RecursiveLS(...).filter() (RLS, lambda = 1, a Cython Kalman filter) and padasip
FilterRLS(mu=0.98).run() (RLS with forgetting lambda = 0.98, P0 = 1000 I), per sample update
rates, best of 3.
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
    out = {
        "machine": f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores",
        "versions": {"statsmodels": statsmodels.__version__, "padasip": version("padasip"),
                     "numpy": np.__version__, "python": platform.python_version()},
        "results": results,
    }
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
