"""Golden file for physid-signal's Butterworth design and zero-phase filtering: scipy's
`butter` (ba and sos) and `filtfilt` (default padding: odd extension, padlen = 3*max(len(a),
len(b))) and `sosfiltfilt`, on a fixed test signal.

Run: python3 gen_scipy_filters.py  (scipy, numpy) -> scipy_filters.json
"""
import json

import numpy as np
import scipy
from scipy import signal

fs = 10_000.0
n = 3000
t = np.arange(n) / fs
rng = np.random.default_rng(4)
x = (np.sin(2 * np.pi * 37 * t) + 0.5 * np.sin(2 * np.pi * 810 * t + 0.3)
     + 0.2 * rng.normal(size=n) + 0.8 * t + 2.0)

cases = [
    {"order": 1, "wn": [300.0], "btype": "lowpass"},
    {"order": 2, "wn": [500.0], "btype": "lowpass"},
    {"order": 7, "wn": [900.0], "btype": "lowpass"},
    {"order": 4, "wn": [200.0], "btype": "lowpass"},
    {"order": 5, "wn": [1200.0], "btype": "lowpass"},
    {"order": 8, "wn": [2000.0], "btype": "lowpass"},
    {"order": 10, "wn": [3000.0], "btype": "lowpass"},
    {"order": 3, "wn": [100.0], "btype": "highpass"},
    {"order": 4, "wn": [50.0], "btype": "highpass"},
    {"order": 2, "wn": [20.0, 300.0], "btype": "bandpass"},
    {"order": 3, "wn": [600.0, 1000.0], "btype": "bandpass"},
]
out = {"scipy": scipy.__version__, "fs": fs, "x": x.tolist(), "cases": []}
for c in cases:
    wn = c["wn"] if len(c["wn"]) == 2 else c["wn"][0]
    b, a = signal.butter(c["order"], wn, btype=c["btype"], fs=fs)
    sos = signal.butter(c["order"], wn, btype=c["btype"], fs=fs, output="sos")
    y = signal.filtfilt(b, a, x)
    ys = signal.sosfiltfilt(sos, x)
    zi = signal.lfilter_zi(b, a)
    out["cases"].append(dict(c, b=b.tolist(), a=a.tolist(), zi=zi.tolist(),
                             filtfilt=y.tolist(), sosfiltfilt=ys.tolist()))
with open("scipy_filters.json", "w") as f:
    json.dump(out, f)
