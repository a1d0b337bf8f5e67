#!/usr/bin/env python3
"""The two test-cell solvers run to run: every built-in scenario simulated with the default
ROS2 (`solver.order = 2`) and with RK4 (`solver.order = 4`), one sample per crank degree, and
the largest difference of each channel over the whole recording, relative to the channel's
largest magnitude (docs/simulate.md, "Why ROS2 is the default"). Both runs draw the same sensor
noise, so the differences are the solvers'. Compared at the same crank angles: on a time basis
the difference would be mostly the engine's phase, which the speed control does not hold (a
few mrad after ten minutes), seen through the steep pressure near TDC.

    pip install numpy pyarrow
    cargo build --release
    python3 bench/solvers.py [--physid target/release/physid] [--scenarios fig314,...] [--dir DIR]
"""
import argparse
import os
import subprocess
import tempfile

import numpy as np
import pyarrow.parquet as pq

SCENARIOS = ["fig314", "shaft-steady", "shaft-ramp", "friction-sweep", "torque-steady",
             "torque-ramp", "torque-validation", "transient-10min"]
CHANNELS = ["p_cyl", "p_int", "p_exh", "omega_en", "omega_dy", "torque_shaft", "torque_engine",
            "true_torque_indicated", "true_torque_reciprocating", "true_torque_friction",
            "true_T_cyl", "T_int"]


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--physid", default="target/release/physid")
    ap.add_argument("--scenarios", default=",".join(SCENARIOS))
    ap.add_argument("--dir", default=None, help="keep the recordings here")
    a = ap.parse_args()
    d = a.dir or tempfile.mkdtemp()
    os.makedirs(d, exist_ok=True)
    worst = {c: (0.0, "") for c in CHANNELS}
    for s in a.scenarios.split(","):
        tables = {}
        for order in (2, 4):
            f = os.path.join(d, f"{s}-order{order}.parquet")
            subprocess.run([a.physid, "simulate", "--scenario", s, "--basis", "crank",
                            "--set", f"solver.order={order}", "--out", f],
                           check=True, stderr=subprocess.DEVNULL)
            tables[order] = pq.read_table(f, columns=CHANNELS)
        n = min(tables[2].num_rows, tables[4].num_rows)
        print(f"{s} ({n} degrees): max |ROS2 − RK4| / max |RK4|")
        for c in CHANNELS:
            x = tables[4][c].to_numpy()[:n]
            y = tables[2][c].to_numpy()[:n]
            r = np.max(np.abs(x - y)) / np.max(np.abs(x))
            print(f"  {c:<27} {r:.2e}")
            if r > worst[c][0]:
                worst[c] = (r, s)
    print("largest over the scenarios:")
    for c, (r, s) in worst.items():
        print(f"  {c:<27} {r:.2e} ({s})")


if __name__ == "__main__":
    main()
