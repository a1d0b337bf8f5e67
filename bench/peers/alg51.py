"""Algorithm 5.1 (orthogonal estimability ranking, Yao et al. 2003) written straightforwardly in
numpy, as the thesis's MATLAB code does it: regress every column on the selected ones
(least squares), pick the largest residual sum of squares, repeat.

Two uses:
  python3 alg51.py golden OUT.json   -> a golden file for physid-ident's tests
  python3 alg51.py bench [N] [P]     -> seconds for the full ranking of an N x P matrix
                                        (the numpy peer of `physid bench`'s ident_batch)
numpy only; the golden matrix is generated from a fixed seed and stored in the file.
"""
import json
import sys
import time

import numpy as np


def alg51(Z):
    n, p = Z.shape
    selected, residuals = [], []
    remaining = list(range(p))
    ss = (Z ** 2).sum(axis=0)
    j = int(np.argmax(ss))
    selected.append(j)
    residuals.append(float(ss[j]))
    remaining.remove(j)
    while remaining:
        X = Z[:, selected]
        coef, *_ = np.linalg.lstsq(X, Z[:, remaining], rcond=None)
        R = Z[:, remaining] - X @ coef
        rss = (R ** 2).sum(axis=0)
        k = int(np.argmax(rss))
        selected.append(remaining[k])
        residuals.append(float(rss[k]))
        remaining.pop(k)
    return selected, residuals


def golden(path):
    rng = np.random.default_rng(20261122)
    n, p = 500, 8
    Z = rng.normal(size=(n, p)) * np.array([1.0, 3.0, 0.5, 2.0, 1.5, 0.8, 1.2, 2.5])
    # make column 5 nearly a combination of 0 and 3, and column 6 correlated with 1
    Z[:, 5] = 0.7 * Z[:, 0] - 0.2 * Z[:, 3] + 1e-3 * rng.normal(size=n)
    Z[:, 6] = 0.9 * Z[:, 1] + 0.5 * rng.normal(size=n)
    order, res = alg51(Z)
    with open(path, "w") as f:
        json.dump({"n": n, "p": p, "Z": Z.tolist(), "order": order, "residual_ss": res,
                   "numpy": np.__version__}, f)


def bench(n, p):
    rng = np.random.default_rng(1)
    Z = rng.normal(size=(n, p))
    t = time.perf_counter()
    alg51(Z)
    return time.perf_counter() - t


if __name__ == "__main__":
    if sys.argv[1] == "golden":
        golden(sys.argv[2])
    else:
        n = int(sys.argv[2]) if len(sys.argv) > 2 else 1_000_000
        p = int(sys.argv[3]) if len(sys.argv) > 3 else 15
        best = min(bench(n, p) for _ in range(3))
        print(json.dumps({"peer": "numpy Alg. 5.1 (lstsq per step)", "n": n, "p": p,
                          "seconds": best, "rows_per_s": n / best, "numpy": np.__version__}))
