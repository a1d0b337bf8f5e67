"""Golden noisy cylinder pressure for `physid cycles --pressure-lowpass`: gen_wiebe.py's Wiebe
trace (two identical cycles at 0.25 deg, 1500 rpm) with white noise of NOISE_PA rms added
(numpy's default_rng(SEED)), and what scipy's zero-phase Butterworth low-pass makes of its one
complete cycle — numpy and scipy only, no physid code.

Run: python3 gen_wiebe_noisy.py  (numpy, scipy; after gen_wiebe.py) -> wiebe_noisy.csv, wiebe_noisy.json

The cycle is -360 ... 360 - STEP deg ATDC (the compression from cycle 0's block, the expansion
from cycle 1's), as physid cuts it. Its mean speed from its times as written,
rpm = 120 / (span * n / (n - 1)), gives the sample rate fs = 6 * rpm / STEP; the filter is
scipy.signal.butter(ORDER, CUTOFF_HZ, fs=fs, output="sos") through sosfiltfilt (its default odd
padding). wiebe_noisy.json: cutoff_hz, order, noise_pa, and of the filtered cycle imep_pa
(numpy's trapezoid over the closed loop / V_d), p_max_pa (the largest sample).
"""
import json

import numpy as np
from scipy.signal import butter, sosfiltfilt

import gen_wiebe as w

NOISE_PA = 3.0e4
SEED = 43
CUTOFF_HZ = 3000.0
ORDER = 4


def main():
    rows = np.loadtxt("wiebe_cycles.csv", delimiter=",", skiprows=2)
    rng = np.random.default_rng(SEED)
    noisy = rows.copy()
    noisy[:, 3] = rows[:, 3] + rng.normal(0.0, NOISE_PA, len(rows))
    with open("wiebe_noisy.csv", "w") as f:
        f.write("t,cycle,crank_deg,p_cyl\ns,-,deg,Pa\n")
        for t, c, d, p in noisy:
            f.write(f"{t:.9e},{int(c)},{d:.2f},{p:.6f}\n")
    back = np.loadtxt("wiebe_noisy.csv", delimiter=",", skiprows=2)
    per = int(round(720 / w.STEP))
    # -360 ... 0 from block 0's second half, 0 ... 360 from block 1's first half.
    cyc = np.concatenate([back[per // 2: per], back[per: per + per // 2]])
    t, p = cyc[:, 0], cyc[:, 3]
    atdc = np.concatenate([cyc[: per // 2, 2] - 720, cyc[per // 2:, 2]])
    n = len(t)
    rpm = 120.0 / ((t[-1] - t[0]) * n / (n - 1))
    fs = 6.0 * rpm / w.STEP
    sos = butter(ORDER, CUTOFF_HZ, fs=fs, output="sos")
    pf = sosfiltfilt(sos, p)
    v = w.volume(atdc)
    vv, pp = np.append(v, v[0]), np.append(pf, pf[0])
    work = float(np.sum(0.5 * (pp[1:] + pp[:-1]) * np.diff(vv)))
    out = dict(cutoff_hz=CUTOFF_HZ, order=ORDER, noise_pa=NOISE_PA, seed=SEED, rpm=rpm,
               imep_pa=work / (w.AREA * w.STROKE), p_max_pa=float(pf.max()))
    with open("wiebe_noisy.json", "w") as f:
        json.dump(out, f, indent=1, sort_keys=True)
        f.write("\n")


if __name__ == "__main__":
    main()
