"""Golden wall heat by Woschni's correlation on the Wiebe trace (wiebe_cycles.csv), for the
gross heat release of `physid cycles --wall-heat` — numpy only, no physid code.

Run: python3 gen_woschni.py  (numpy; after gen_wiebe.py) -> woschni.json

Woschni 1967 (SAE 670931), Heywood 1988 Eq. 12.19, over each step of the heat release's window
(-90 ... 120 deg ATDC, 0.25 deg) at the step's mean pressure p, volume V and gas temperature
T = p V / (m R), m R = p_r V_r / T_r from the state at IVC (-150 deg ATDC, T_r given):
    Q_w = h A (T - T_w) dtheta / (6 N)       A = pi B^2 / 2 + 4 V / B
    h   = 3.26 B^-0.2 (p/1000)^0.8 T^-0.55 w^0.8
    w   = C1 * 2 S N / 60  [+ C2 * Vd T_r / (p_r V_r) * (p - p_m)],   p_m = p_r (V_r / V)^n
n by least squares of ln p on ln V over the samples in -100 ... -40 deg ATDC. Written per step:
`wall_c1` without the combustion term, `wall_full` with it (C2 = 3.24e-3); element 0 (the
window's first sample) is 0. Which steps take the combustion term (those after the start of
combustion) is the test's to decide.
"""
import json
import math
from pathlib import Path

import numpy as np

HERE = Path(__file__).parent
W = json.loads((HERE / "wiebe.json").read_text())
BORE, STROKE, ROD, EPS = W["bore"], W["stroke"], W["rod"], W["compression_ratio"]
RPM, STEP, IVC = W["rpm"], W["step_deg"], W["ivc_deg"]
LO, HI = W["window_deg"]
T_IVC, T_WALL = 330.0, 420.0
C1, C2 = 2.28, 3.24e-3

AREA = math.pi * BORE**2 / 4
VD = AREA * STROKE
VC = VD / (EPS - 1)
R = STROKE / 2


def volume(a_deg):
    a = np.radians(a_deg)
    return VC + AREA * (R * (1 - np.cos(a)) + ROD - np.sqrt(ROD**2 - (R * np.sin(a)) ** 2))


data = np.genfromtxt(HERE / "wiebe_cycles.csv", delimiter=",", skip_header=2)
deg, p_all = data[:, 2], data[:, 3]
first = data[:, 1] == 0
per = int(round(720 / STEP))
# One cycle, -360 ... 360 deg ATDC: every cycle of the trace is the same.
atdc = -360.0 + np.arange(per) * STEP
p = np.interp(np.where(atdc < 0, atdc + 720, atdc), deg[first], p_all[first])
v = volume(atdc)

comp = (atdc >= -100.0) & (atdc <= -40.0)
slope = np.polyfit(np.log(v[comp]), np.log(p[comp]), 1)[0]
n = -slope
p_r, v_r = np.interp(IVC, atdc, p), np.interp(IVC, atdc, v)
m_r = p_r * v_r / T_IVC

win = (atdc >= LO) & (atdc <= HI)
a, pw, vw = atdc[win], p[win], v[win]
pm, vm = 0.5 * (pw[1:] + pw[:-1]), 0.5 * (vw[1:] + vw[:-1])
t = pm * vm / m_r
s_per_deg = 1.0 / (6.0 * RPM)
area = math.pi * BORE**2 / 2 + 4 * vm / BORE


def wall(w):
    h = 3.26 * BORE**-0.2 * (pm * 1e-3) ** 0.8 * t**-0.55 * w**0.8
    return np.concatenate([[0.0], h * area * (t - T_WALL) * np.diff(a) * s_per_deg])


w_c1 = np.full_like(pm, C1 * 2 * STROKE * RPM / 60)
p_mot = p_r * (v_r / vm) ** n
w_full = w_c1 + C2 * VD * T_IVC / (p_r * v_r) * (pm - p_mot)
out = {
    "t_ivc_k": T_IVC,
    "t_wall_k": T_WALL,
    "c1": C1,
    "c2": C2,
    "n_compression": n,
    "window_samples": int(win.sum()),
    "wall_c1": wall(w_c1).tolist(),
    "wall_full": wall(w_full).tolist(),
}
(HERE / "woschni.json").write_text(json.dumps(out))
print(f"n = {n:.6f}; wall heat {sum(out['wall_c1']):.3f} J (C1 only), "
      f"{sum(out['wall_full']):.3f} J (C2 throughout)")
