"""A long MDF4 file of three channel groups, for the memory benchmark of reading several groups
(BENCHMARKS.md, "MDF4 in several groups, and written compressed, as it comes"):

  python3 bench/mdf_groups.py SECONDS OUT.mf4

Two groups of four channels each on one 10 kHz time base, a third of one channel at 10 Hz —
how a lab's logger often writes (asammdf 8.8, pip install asammdf). Written a group at a time.
"""
import sys

import numpy as np
from asammdf import MDF, Signal

seconds, out = float(sys.argv[1]), sys.argv[2]
n = int(seconds * 10_000)
t = np.arange(n) / 10_000.0
m = MDF(version="4.10")
for g, names in enumerate([[("omega_en", "rad/s"), ("omega_dy", "rad/s"),
                            ("torque_shaft", "N*m"), ("p_int", "Pa")],
                           [("T_oil", "K"), ("T_water", "K"), ("p_oil", "Pa"),
                            ("lambda", "-")]]):
    sigs = [Signal(300.0 + np.sin(t * (k + 1 + 4 * g)) * 100.0, t, name=name, unit=unit)
            for k, (name, unit) in enumerate(names)]
    m.append(sigs, comment=f"fast {g}")
    del sigs
slow_t = np.arange(int(seconds * 10)) / 10.0
m.append([Signal(300.0 + slow_t, slow_t, name="T_air", unit="K")], comment="slow")
m.save(out, overwrite=True)
