"""Golden fired cylinder-pressure trace from a known Wiebe burn, for `physid cycles`' heat
release and burn angles — numpy and scipy only, no physid code.

Run: python3 gen_wiebe.py  (numpy, scipy) -> wiebe_cycles.csv, wiebe_mixed.csv, wiebe_flags.csv, wiebe.json

Single zone, constant gamma, no wall heat, no crevices, valves closed from IVC = -150 deg ATDC to
EVO = +130 deg ATDC (Heywood 1988, Eq. 9.25 solved for the pressure):
    dp/da = (gamma - 1)/V * dQ/da - gamma * p/V * dV/da
    Q(a)  = Q_fuel * x(a),  x(a) = 1 - exp(-A ((a - a0)/D)^(M+1))  for a >= a0   (Wiebe)
    V(a)  = V_c + Ap*(r(1 - cos a) + L - sqrt(L^2 - r^2 sin^2 a)),  V_c = Ap*S/(eps - 1)
integrated by scipy's solve_ivp (DOP853, rtol 1e-12) from p(IVC) = p_ivc, evaluated every STEP
degrees. Outside the closed part the pressure is p_ivc (exhaust and intake at one pressure, so
the gas exchange does no work). Two identical cycles at 1500 rpm, as a crank-angle CSV with a
units row (t [s], cycle [-], crank_deg [deg from the firing TDC, 0..720), p_cyl [Pa]).

wiebe_mixed.csv: the same engine at 1 deg steps, 5 fired cycles then 3 motored (each cycle
from its firing TDC to the next: the compression at its end belongs to the next TDC's burn) (the same equation with no
burn: p*V^gamma constant while the valves are closed, so the motored trace peaks at TDC) — what
a placement of the TDC from the pressure must tell apart.

wiebe_flags.csv: the same engine at 1 deg steps, the heat FLAGS_HEAT[c] burned at firing TDC c:
full burns with a partial burn (250 J) and a misfire (0 J) among them.

wiebe.json: the geometry, gamma, the burn, and what an analysis must find:
* mfb_deg: the angles where the burn reaches 10, 50, 90 % of what it has released by the
  window's end WINDOW[1] (closed form: x(a) = k*x(WINDOW[1]));
* heat_j: the heat released in the window, Q_fuel*x(WINDOW[1]) (x is 0 before a0 > WINDOW[0]);
* imep_pa: the net work over the cycle by numpy (trapezoid over the samples) / V_d;
* p_max_deg: the pressure's peak on a 0.001 deg evaluation of the solution;
* dp_max_pa_per_deg, dp_max_deg: the largest dp/da (the right-hand side on the solution) in the
  window, on the same evaluation;
* rw_mfb_deg: the 10, 50, 90 % burn angles by Rassweiler & Withrow (Heywood Eq. 9.13-9.16) with
  n = rw_exponent (= gamma) over the window, from wiebe_cycles.csv's pressures as written: the
  combustion pressure rise dp_c = p[k] - p[k-1]*(V[k-1]/V[k])**n, the mass burned the cumulative
  sum of dp_c*V[k-1], normalised from its smallest before its largest to its largest, each angle
  where it first reaches k %, linearly between the samples.
"""
import json
import math

import numpy as np
from scipy.integrate import solve_ivp

BORE, STROKE, ROD, EPS = 0.086, 0.086, 0.145, 10.5
GAMMA = 1.35
P_IVC = 1.0e5
IVC, EVO = -150.0, 130.0
A0, D, A, M = -12.0, 45.0, 6.9, 2.0
Q_FUEL = 600.0
RPM = 1500.0
STEP = 0.25
WINDOW = (-90.0, 120.0)
# The fuel energy [J] burned at each firing TDC of wiebe_flags.csv (cycle c: TDC c).
FLAGS_HEAT = [600.0] * 6 + [250.0, 0.0] + [600.0] * 4
AREA = math.pi * BORE**2 / 4
R = STROKE / 2
VC = AREA * STROKE / (EPS - 1)


def volume(a_deg):
    a = np.radians(a_deg)
    return VC + AREA * (R * (1 - np.cos(a)) + ROD - np.sqrt(ROD**2 - (R * np.sin(a)) ** 2))


def dvolume(a_deg):
    """dV/da per degree."""
    a = np.radians(a_deg)
    s = np.sin(a)
    ds = R * s + R**2 * s * np.cos(a) / np.sqrt(ROD**2 - (R * s) ** 2)
    return AREA * ds * math.pi / 180


def burned(a_deg):
    z = np.clip((np.asarray(a_deg) - A0) / D, 0.0, None)
    return 1 - np.exp(-A * z ** (M + 1))


def dburned(a_deg):
    z = max((a_deg - A0) / D, 0.0)
    return A * (M + 1) / D * z**M * math.exp(-A * z ** (M + 1))


def rhs(a, y, q_fuel=Q_FUEL):
    p = y[0]
    v = volume(a)
    return [(GAMMA - 1) / v * q_fuel * dburned(a) - GAMMA * p / v * dvolume(a)]


def cycle_pressure(deg, q_fuel):
    """The pressure at the crank angles deg [0, 720) of one cycle, burning q_fuel."""
    sol = solve_ivp(lambda a, y: rhs(a, y, q_fuel), (IVC, EVO), [P_IVC], method="DOP853",
                    rtol=1e-12, atol=1e-6, dense_output=True, max_step=0.5)
    atdc = np.where(deg >= 360, deg - 720, deg)
    closed = (atdc >= IVC) & (atdc <= EVO)
    p = np.full(len(deg), P_IVC)
    p[closed] = sol.sol(atdc[closed])[0]
    return p


def rassweiler_withrow(path, n):
    """Burn angles by Rassweiler & Withrow from a crank-angle CSV's first cycle (see above)."""
    rows = np.loadtxt(path, delimiter=",", skiprows=2)
    first = rows[rows[:, 1] == 0]
    deg, p = first[:, 2], first[:, 3]
    atdc = np.where(deg >= 360, deg - 720, deg)
    order = np.argsort(atdc)
    atdc, p = atdc[order], p[order]
    keep = (atdc >= WINDOW[0]) & (atdc <= WINDOW[1])
    a, p = atdc[keep], p[keep]
    v = volume(a)
    dp_c = p[1:] - p[:-1] * (v[:-1] / v[1:]) ** n
    m = np.concatenate([[0.0], np.cumsum(dp_c * v[:-1])])
    k_max = int(np.argmax(m))
    k_min = int(np.argmin(m[: k_max + 1]))
    out = {}
    for pct in (10, 50, 90):
        target = m[k_min] + pct / 100 * (m[k_max] - m[k_min])
        k = k_min + 1 + int(np.argmax(m[k_min + 1: k_max + 1] >= target))
        out[str(pct)] = float(a[k - 1] + (target - m[k - 1]) / (m[k] - m[k - 1]) * (a[k] - a[k - 1]))
    return out


def main():
    sol = solve_ivp(rhs, (IVC, EVO), [P_IVC], method="DOP853", rtol=1e-12, atol=1e-6,
                    dense_output=True, max_step=0.5)
    per = int(round(720 / STEP))
    deg = np.arange(per) * STEP
    atdc = np.where(deg >= 360, deg - 720, deg)
    closed = (atdc >= IVC) & (atdc <= EVO)
    p = np.full(per, P_IVC)
    p[closed] = sol.sol(atdc[closed])[0]
    # The cycle's net work, in crank-angle order from -360 deg round to +360 deg (closed loop).
    order = np.argsort(atdc)
    vv, pp = volume(atdc[order]), p[order]
    vv, pp = np.append(vv, vv[0]), np.append(pp, pp[0])
    work = float(np.sum(0.5 * (pp[1:] + pp[:-1]) * np.diff(vv)))
    fine = np.arange(-10.0, 40.0, 0.001)
    p_fine = sol.sol(fine)[0]
    dp_fine = np.array([rhs(a, [pf])[0] for a, pf in zip(fine, p_fine)])
    x_end = float(burned(WINDOW[1]))
    mfb = {}
    for k in (10, 50, 90):
        x = k / 100 * x_end
        mfb[str(k)] = A0 + D * (-math.log(1 - x) / A) ** (1 / (M + 1))
    truth = dict(
        bore=BORE, stroke=STROKE, rod=ROD, compression_ratio=EPS, gamma=GAMMA, p_ivc=P_IVC,
        ivc_deg=IVC, evo_deg=EVO, wiebe=dict(start_deg=A0, duration_deg=D, a=A, m=M),
        q_fuel_j=Q_FUEL, rpm=RPM, step_deg=STEP, window_deg=list(WINDOW), cycles=2,
        mfb_deg=mfb, heat_j=Q_FUEL * x_end, imep_pa=work / (AREA * STROKE),
        p_max_deg=float(fine[np.argmax(p_fine)]), p_max_pa=float(p_fine.max()),
        dp_max_deg=float(fine[np.argmax(dp_fine)]), dp_max_pa_per_deg=float(dp_fine.max()),
    )
    w = RPM * 6.0  # deg/s
    with open("wiebe_cycles.csv", "w") as f:
        f.write("t,cycle,crank_deg,p_cyl\ns,-,deg,Pa\n")
        for c in range(2):
            for k in range(per):
                f.write(f"{(c * per + k) * STEP / w:.9e},{c},{deg[k]:.2f},{p[k]:.6f}\n")
    deg1 = np.arange(720) * 1.0
    fired, motored = cycle_pressure(deg1, Q_FUEL), cycle_pressure(deg1, 0.0)
    with open("wiebe_mixed.csv", "w") as f:
        f.write("t,cycle,crank_deg,p_cyl\ns,-,deg,Pa\n")
        # Cycle c runs from its firing TDC to the next: its first half is the expansion after
        # its own TDC, its second half the compression before the next cycle's.
        for c in range(8):
            now = fired if c < 5 else motored
            after = fired if c + 1 < 5 else motored
            for k in range(720):
                p_k = now[k] if deg1[k] < 360 else after[k]
                f.write(f"{(c * 720 + k) / w:.9e},{c},{deg1[k]:.0f},{p_k:.6f}\n")
    # wiebe_flags.csv: the heat each firing TDC burns — a partial burn and a misfire among
    # full burns, at 1 deg.
    traces = {q: cycle_pressure(deg1, q) for q in set(FLAGS_HEAT)}
    with open("wiebe_flags.csv", "w") as f:
        f.write("t,cycle,crank_deg,p_cyl\ns,-,deg,Pa\n")
        for c in range(len(FLAGS_HEAT) - 1):
            now, after = traces[FLAGS_HEAT[c]], traces[FLAGS_HEAT[c + 1]]
            for k in range(720):
                p_k = now[k] if deg1[k] < 360 else after[k]
                f.write(f"{(c * 720 + k) / w:.9e},{c},{deg1[k]:.0f},{p_k:.6f}\n")
    truth["flags_heat_j"] = FLAGS_HEAT[: len(FLAGS_HEAT) - 1]
    truth["rw_exponent"] = GAMMA
    truth["rw_mfb_deg"] = rassweiler_withrow("wiebe_cycles.csv", GAMMA)
    with open("wiebe.json", "w") as f:
        json.dump(truth, f, indent=1, sort_keys=True)
        f.write("\n")


if __name__ == "__main__":
    main()
