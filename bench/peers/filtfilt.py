"""scipy peer of `physid-signal`'s zero-phase filtering benchmark: order-4 Butterworth
low-pass (500 Hz at fs = 10 kHz), `filtfilt` (ba) and `sosfiltfilt`, on the same 10^6-sample
signal as `crates/signal/benches/signal.rs`. Prints samples per second (best of 5).

Run: python3 bench/peers/filtfilt.py
"""
import json
import time

import numpy as np
import scipy
from scipy import signal

n = 1_000_000
i = np.arange(n, dtype=float)
x = np.sin(i * 0.013) + 0.1 * np.cos(i * 1.7)
b, a = signal.butter(4, 500.0, fs=10_000.0)
sos = signal.butter(4, 500.0, fs=10_000.0, output="sos")


def best(f):
    ts = []
    for _ in range(5):
        t = time.perf_counter()
        f()
        ts.append(time.perf_counter() - t)
    return min(ts)


out = {"scipy": scipy.__version__, "n": n,
       "filtfilt_samples_per_s": n / best(lambda: signal.filtfilt(b, a, x)),
       "sosfiltfilt_samples_per_s": n / best(lambda: signal.sosfiltfilt(sos, x))}
print(json.dumps(out))
