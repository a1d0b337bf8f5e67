"""Golden file for physid-ident's quantitative results: statsmodels OLS on a quadratic
y = b0 + b1*x + b2*x^2 + noise (n = 40, fixed seed): estimates, standard errors, t-values,
95 % confidence intervals (Student t), covariance, and the noise variance.

Run: python3 gen_statsmodels_ols.py  (statsmodels 0.15, numpy) -> statsmodels_ols.json
"""
import json

import numpy as np
import statsmodels
import statsmodels.api as sm

rng = np.random.default_rng(404)
n = 40
x = np.linspace(-2.0, 3.0, n)
y = 1.5 - 0.7 * x + 0.25 * x**2 + 0.3 * rng.normal(size=n)
X = np.column_stack([np.ones(n), x, x**2])
r = sm.OLS(y, X).fit()
out = {
    "statsmodels": statsmodels.__version__,
    "x": x.tolist(), "y": y.tolist(),
    "params": r.params.tolist(), "bse": r.bse.tolist(), "tvalues": r.tvalues.tolist(),
    "conf_int": r.conf_int(0.05).tolist(), "cov": r.cov_params().tolist(),
    "scale": float(r.scale), "ssr": float(r.ssr),
}
with open("statsmodels_ols.json", "w") as f:
    json.dump(out, f, indent=1)
