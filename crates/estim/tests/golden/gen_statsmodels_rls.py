"""Golden file for physid-estim: RLS against statsmodels RecursiveLS.

Regenerate:  pip install statsmodels==0.15.0 numpy && python3 gen_statsmodels_rls.py
Writes statsmodels_rls.json: the data (X, y), the initial state, statsmodels' recursive
coefficients after every sample (`recursive_coefficients.filtered`) and its CUSUM statistic
(`cusum`, with `d` residuals burnt).
"""
import json

import numpy as np
import statsmodels
import statsmodels.api as sm

rng = np.random.default_rng(20261122)
n, k = 400, 4
t = np.arange(n) * 0.01
X = np.column_stack([
    np.ones(n),
    np.sin(2 * np.pi * 1.7 * t) + 0.3 * rng.normal(size=n),
    rng.normal(size=n),
    np.cos(2 * np.pi * 0.4 * t) * rng.uniform(0.5, 1.5, size=n),
])
beta = np.array([1.5, -2.0, 0.7, 3.0])
y = X @ beta + 0.2 * rng.normal(size=n)
# a level shift in the last quarter, so the CUSUM has something to see
y[3 * n // 4:] += 0.5
theta0 = np.array([0.5, -0.2, 0.1, 0.0])
p0 = 1000.0 * np.eye(k)

res = sm.RecursiveLS(y, X, initialization="known", initial_state=theta0,
                     initial_state_cov=p0).filter()
d = int(max(res.nobs_diffuse, res.loglikelihood_burn))
out = {
    "generator": f"statsmodels {statsmodels.__version__} RecursiveLS, numpy {np.__version__}",
    "X": X.tolist(),
    "y": y.tolist(),
    "theta0": theta0.tolist(),
    "p0_scale": 1000.0,
    "filtered": res.recursive_coefficients.filtered.T.tolist(),  # n rows of k
    "cusum_burn": d,
    "cusum": res.cusum.tolist(),
    # statsmodels' 5 % significance lines at the start and end of the CUSUM record
    "cusum_bounds_5pct_upper": res._cusum_significance_bounds(0.05)[1].tolist(),
}
with open("statsmodels_rls.json", "w") as f:
    json.dump(out, f)
print("wrote statsmodels_rls.json", out["generator"])
