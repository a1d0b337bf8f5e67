"""The Student-t 97.5 % quantiles that physid_ident::fisher::t_quantile_975 is checked against
(its unit test holds them): scipy's, for few and for very many degrees of freedom.
Run: python gen_t_quantile.py (scipy 1.x)."""
from scipy import stats

for dof in [30, 10000, 20000, 50000, 1_000_000, 36_000_000]:
    print(dof, repr(float(stats.t.ppf(0.975, dof))))
