"""Golden knock figures for `physid cycles --knock`, with scipy only (no physid code).

Run: python3 gen_knock.py  (numpy, scipy) -> knock.json

The knocking cycle of tests/knock.rs, written again here: a motored cycle (p*V^N constant from
BDC to BDC, P0 outside, the textbook slider crank) at STEP-degree samples from -360 to 360 deg
ATDC at RPM, plus A*exp(-t/tau)*sin(2*pi*F*t) from ONSET deg ATDC. scipy's butter(4, [5000,
20000], 'bandpass', fs=6*RPM/STEP, output='sos') and sosfiltfilt over the cycle; MAPO is the
largest |filtered| from 0 to 60 deg ATDC, IMPO the trapezoid of |filtered| over the same samples
[Pa*deg]; `peak` the oscillation's own largest |value| there. One entry per decay tau [s].
"""
import json
import math

import numpy as np
from scipy.signal import butter, sosfiltfilt

BORE, STROKE, ROD, CR, N, P0 = 0.084, 0.09, 0.15, 10.0, 1.3, 1e5
RPM, STEP = 1500.0, 0.1
F, A, ONSET = 7e3, 3e5, 8.0
WINDOW = (0.0, 60.0)


def volume(atdc):
    r = STROKE / 2
    a = np.radians(atdc)
    s = r * (1 - np.cos(a)) + ROD - np.sqrt(ROD**2 - (r * np.sin(a)) ** 2)
    area = math.pi * BORE**2 / 4
    return area * STROKE / (CR - 1) + area * s


def oscillation(atdc, tau):
    t = np.clip(atdc - ONSET, 0, None) / (6 * RPM)
    return np.where(atdc >= ONSET, A * np.exp(-t / tau) * np.sin(2 * math.pi * F * t), 0.0)


def main():
    per = int(round(720 / STEP))
    d = np.arange(per) * STEP
    atdc = np.concatenate([d[d >= 360] - 720, d[d < 360]])
    motored = np.where(np.abs(atdc) <= 180, P0 * (volume(180.0) / volume(atdc)) ** N, P0)
    sos = butter(4, [5000.0, 20000.0], "bandpass", fs=6 * RPM / STEP, output="sos")
    inside = (atdc >= WINDOW[0]) & (atdc <= WINDOW[1])
    out = {}
    for tau in (0.8e-3, 3e-3):
        osc = oscillation(atdc, tau)
        y = np.abs(sosfiltfilt(sos, motored + osc))[inside]
        a = atdc[inside]
        out[f"{tau:g}"] = dict(
            mapo_pa=float(y.max()),
            mapo_deg=float(a[np.argmax(y)]),
            impo_pa_deg=float(np.sum(0.5 * (y[1:] + y[:-1]) * np.diff(a))),
            peak_pa=float(np.abs(osc[inside]).max()),
        )
    with open("knock.json", "w") as f:
        json.dump(out, f, indent=1, sort_keys=True)
        f.write("\n")


if __name__ == "__main__":
    main()
