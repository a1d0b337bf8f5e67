"""Golden file for the friction design-parameter ranking (thesis §7.2, app. B.2, Table 7.1).

Independent of physid: the friction torque is written out symbolically from SPEC §2.5 (thesis
preset, as the thesis's own MATLAB code did with the symbolic toolbox) and differentiated by
sympy; the normalised sensitivities z_j = (p_j / tau) * dtau/dp_j are evaluated at the 3^3
full-factorial grid, speed varying fastest, p_atm = 101 kPa.

Also records, for the note, the ranking when the constant +4.12 kPa is dropped from rfmep as
in app. B.2's printed code (SPEC §2.5 keeps it).

Run: python3 gen_friction_rank.py  (sympy 1.14) -> friction_rank.json
"""
import json
import sympy as sp

B, S, rc, Di, De, Lv, Db, Lb, r = sp.symbols("B S rc Di De Lv Db Lb r", positive=True)
N, Pi, Toil = sp.symbols("N Pi Toil", positive=True)
names = ["B", "S", "kappa", "Di", "De", "Lv", "Db", "Lb", "r"]
syms = [B, S, rc, Di, De, Lv, Db, Lb, r]

# 0W40, SOHC_III, Ft/Fto = 1, Cr = 1, nc = 1, nv = 2, nb = 2 (thesis code, app. B.2)
k, th1, th2, u_uo = 0.01341, 1986.4, 189.7, 0.67
Cff, Crf, Coh, Com = 200, 0.0076, 0.5, 10.7
Ft_Fto, Cr, nc, nv, nb, Pa, Tref, K = 1, 1, 1, 2, 2, 101, 90, sp.Rational(238, 10000)
design = {B: 54, S: 51.5, rc: 12, Di: 27, De: 23, Lv: 9, Db: 52, Lb: 13, r: 25.7}


def torque(with_constant):
    Sp = 2 * (S / 1000) * (N / 60)
    ri, re = Di / B, De / B
    uo = k * sp.exp(th1 / (th2 + Tref))
    u = k * sp.exp(th1 / (th2 + Toil)) * u_uo
    uscl = sp.sqrt(u / uo)
    cfmep = 1.22e5 * (Db / (B**2 * S * nc)) + 3.03e-4 * uscl * (N * Db**3 * Lb * nb) / (B**2 * S * nc) \
        + 1.35e-10 * (Db**2 * N**2 * nb) / nc
    rfmep = 2.94e2 * uscl * (Sp / B) + 4.06e4 * (Ft_Fto * Cr) * (1 + 500 / N) / B**2 \
        + 3.03e-4 * u_uo * (N * Db**3 * Lb * nb) / (B**2 * S * nc) \
        + 6.89 * (Pi / Pa) * (0.088 * uscl * rc + 0.182 * Ft_Fto * rc ** (1.33 - 2 * K * Sp))
    if with_constant:
        rfmep = rfmep + 4.12
    vfmep = 244 * u_uo * (N * nb) / (B**2 * S * nc) + Cff * (1 + 500 / N) * nv / (S * nc) \
        + Crf * N * nv / (S * nc) + Coh * u_uo * (Lv**1.5 * sp.sqrt(N) * nv) / (B * S * nc) \
        + Com * (1 + 500 / N) * Lv * nv / (S * nc)
    afmep = 8.32 + 1.86e-3 * N + 7.45e-7 * N**2
    pmep = (Pa - Pi) + 4.12e-3 * (Pi / Pa) ** 2 * Sp**2 / (nv**2 * ri**4) \
        + 0.178 * ((Pi / Pa) * Sp) ** 2 + 4.12e-3 * (Pi / Pa) ** 2 * Sp**2 / (nv**2 * re**4)
    fmep = cfmep + rfmep + vfmep + afmep + pmep
    return fmep * 1e3 / (2 * sp.pi) * (sp.pi * (B / 1000) ** 2 / 4) * (r / 1000)


def table(with_constant):
    tau = torque(with_constant)
    grads = [sp.diff(tau, s) for s in syms]
    tests = []
    for t in [20, 55, 90]:
        for p in [10, 55, 100]:
            for n in [1000, 3000, 5000]:
                at = dict(design)
                at.update({N: n, Pi: p, Toil: t})
                tv = float(tau.subs(at).evalf(30))
                z = [float((g.subs(at) * at[s] / tv).evalf(30)) for g, s in zip(grads, syms)]
                order = sorted(range(9), key=lambda j: (-z[j] ** 2, j))
                tests.append({"n_rpm": n, "p_int_kpa": p, "t_oil_c": t, "tau_nm": tv,
                              "sensitivity": z, "ranking": [names[j] for j in order]})
    return tests


out = {"parameters": names, "p_atm_kpa": Pa, "tests": table(True),
       "without_rfmep_constant": [t["ranking"] for t in table(False)]}
with open("friction_rank.json", "w") as f:
    json.dump(out, f, indent=1)
