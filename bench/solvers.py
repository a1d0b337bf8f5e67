#!/usr/bin/env python3
"""The two test-cell solvers run to run: every built-in scenario simulated with the default
ROS2 (`solver.order = 2`) and with RK4 (`solver.order = 4`), one sample per crank degree, and
the largest difference of each channel over the whole recording, relative to the channel's
largest magnitude (docs/simulate.md, "Why ROS2 is the default"). Both runs draw the same sensor
noise, so the differences are the solvers'. Compared at the same crank angles: on a time basis
(`--basis time`, 10 kHz) the difference is mostly the engine's phase, which the speed control
does not hold (the largest |Δθ_en| in rad is printed), seen through the steep pressure near TDC.

    pip install numpy pyarrow
    cargo build --release
    python3 bench/solvers.py [--physid target/release/physid] [--scenarios fig314,...]
                             [--basis crank|time] [--dir DIR]
    python3 bench/solvers.py --demo      # `physid demo` with each solver: the estimates' moves

With `--demo`, `physid demo --solver-order 2` and `--solver-order 4` instead, and how far each
estimate of the three applications moved, in its standard errors (RK4's), with the alarms and
estimable sets of both.
"""
import argparse
import json
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


def demo(physid, d):
    summaries = {}
    for order in (2, 4):
        out = os.path.join(d, f"demo-order{order}")
        subprocess.run([physid, "demo", "--solver-order", str(order), "--out", out],
                       check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        with open(os.path.join(out, "summary.json")) as f:
            summaries[order] = json.load(f)
    a, b = summaries[4], summaries[2]
    for app in ("shaft", "torque_fit", "friction_fit"):
        est = a[app]["std_err"]
        moves = {k: abs(b[app]["final" if app == "shaft" else "params"][k]
                        - a[app]["final" if app == "shaft" else "params"][k]) / est[k]
                 for k in est if est[k]}
        worst = max(moves, key=moves.get)
        print(f"{app:<13} largest move {moves[worst]:.3f} σ ({worst})")
    for key, f in (("shaft alarms", lambda s: [x["param"] for x in s["shaft"]["alarms"]]),
                   ("friction estimable", lambda s: s["friction_fit"]["estimable"]),
                   ("torque estimable", lambda s: s["torque_fit"]["estimable"]),
                   ("torque identifiability",
                    lambda s: [t["estimable"] for t in s["torque_identifiability"]])):
        print(f"{key:<23} {'the same' if f(a) == f(b) else f'{f(b)} vs RK4 {f(a)}'}")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--physid", default="target/release/physid")
    ap.add_argument("--scenarios", default=",".join(SCENARIOS))
    ap.add_argument("--basis", default="crank", choices=["crank", "time"])
    ap.add_argument("--dir", default=None, help="keep the recordings here")
    ap.add_argument("--demo", action="store_true", help="compare the demo's results instead")
    a = ap.parse_args()
    d = a.dir or tempfile.mkdtemp()
    os.makedirs(d, exist_ok=True)
    if a.demo:
        demo(a.physid, d)
        return
    worst = {c: (0.0, "") for c in CHANNELS}
    for s in a.scenarios.split(","):
        tables = {}
        for order in (2, 4):
            f = os.path.join(d, f"{s}-{a.basis}-order{order}.parquet")
            subprocess.run([a.physid, "simulate", "--scenario", s, "--basis", a.basis,
                            "--set", f"solver.order={order}", "--out", f],
                           check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
            tables[order] = pq.read_table(f, columns=CHANNELS + ["theta_en"])
        n = min(tables[2].num_rows, tables[4].num_rows)
        dtheta = np.max(np.abs(tables[4]["theta_en"].to_numpy()[:n]
                               - tables[2]["theta_en"].to_numpy()[:n]))
        print(f"{s} ({n} samples, {a.basis} basis): max |ROS2 − RK4| / max |RK4|; "
              f"max |Δθ_en| {dtheta:.2e} rad")
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
