"""MDF4 files written by asammdf, for physid-io's reader tests, and their expected contents.

  python3 gen_asammdf.py           -> time_plain.mf4, time_deflate.mf4, time_transposed.mf4,
                                      angle.mf4 and expected.json
  python3 gen_asammdf.py --groups  -> groups.mf4 and expected_groups.json: three channel
                                      groups, two on the same 1 kHz time base, one at 10 Hz
  python3 gen_asammdf.py --check   -> opens physid_written*.mf4 (committed, written by
                                      physid-io's writer test: plain, deflate, transposed
                                      deflate) and physid_streamed*.mf4 (its streaming writer,
                                      compressed in 13 blocks) with asammdf and compares them
                                      with expected_physid.json

asammdf 8.8 (pip install asammdf).
"""
import json
import sys

import numpy as np
import asammdf
from asammdf import MDF, Signal


def time_signals():
    t = np.arange(1000) / 1000.0
    omega = 104.7 + 3.0 * np.sin(2 * np.pi * 5 * t)
    torque = (12.0 * np.cos(2 * np.pi * 30 * t)).astype(np.float32)
    count = np.floor(np.cumsum(omega) / 1000.0 / (2 * np.pi / 360)).astype(np.uint32)
    raw_temp = (np.arange(1000) % 200 + 600).astype(np.int16)  # 0.1 K per bit + 273.15 K
    sigs = [
        Signal(omega, t, name="omega_en", unit="rad/s"),
        Signal(torque, t, name="torque_shaft", unit="N*m"),
        Signal(count, t, name="count_en", unit="-"),
        Signal(raw_temp, t, name="T_oil", unit="K",
               conversion={"a": 0.1, "b": 273.15}),
    ]
    expected = {
        "t": t.tolist(),
        "omega_en": omega.tolist(),
        "torque_shaft": torque.astype(float).tolist(),
        "count_en": count.astype(float).tolist(),
        "T_oil": (raw_temp * 0.1 + 273.15).tolist(),
        "units": {"omega_en": "rad/s", "torque_shaft": "N*m", "count_en": "-", "T_oil": "K"},
    }
    return sigs, expected


def angle_signals():
    theta = np.arange(3 * 720) * np.pi / 180.0  # rad, one sample per degree, 3 cycles
    cycle = (np.arange(3 * 720) // 720).astype(np.uint16)
    p = 1e5 + 2e6 * np.exp(-((np.mod(theta, 4 * np.pi) - 2 * np.pi) ** 2) * 4.0)
    sigs = [
        Signal(p, theta, name="p_cyl", unit="Pa", master_metadata=("crank_angle", 2)),
        Signal(cycle, theta, name="cycle", unit="-", master_metadata=("crank_angle", 2)),
    ]
    return sigs, {"theta": theta.tolist(), "p_cyl": p.tolist(),
                  "cycle": cycle.astype(float).tolist()}


def generate():
    sigs, exp_t = time_signals()
    for name, comp in [("time_plain", 0), ("time_deflate", 1), ("time_transposed", 2)]:
        m = MDF(version="4.10")
        m.append(sigs, comment="physid test")
        m.save(f"{name}.mf4", overwrite=True, compression=comp)
    asigs, exp_a = angle_signals()
    m = MDF(version="4.10")
    m.append(asigs, comment="crank angle")
    m.save("angle.mf4", overwrite=True, compression=2)
    with open("expected.json", "w") as f:
        json.dump({"asammdf": asammdf.__version__, "time": exp_t, "angle": exp_a}, f)


def groups():
    t = np.arange(1000) / 1000.0
    slow_t = np.arange(10) / 10.0
    omega = 104.7 + 3.0 * np.sin(2 * np.pi * 5 * t)
    torque = 12.0 * np.cos(2 * np.pi * 30 * t)
    temp = 350.0 + slow_t
    m = MDF(version="4.10")
    m.append([Signal(omega, t, name="omega_en", unit="rad/s")], comment="fast")
    m.append([Signal(torque, t, name="torque_shaft", unit="N*m")], comment="fast too")
    m.append([Signal(temp, slow_t, name="T_oil", unit="K")], comment="slow")
    m.save("groups.mf4", overwrite=True)
    with open("expected_groups.json", "w") as f:
        json.dump({"asammdf": asammdf.__version__, "t": t.tolist(), "omega_en": omega.tolist(),
                   "torque_shaft": torque.tolist(), "slow_t": slow_t.tolist(),
                   "T_oil": temp.tolist()}, f)


def check():
    exp = json.load(open("expected_physid.json"))
    for f in ["physid_written.mf4", "physid_written_deflate.mf4",
              "physid_written_transposed.mf4", "physid_streamed_deflate.mf4",
              "physid_streamed_transposed.mf4"]:
        m = MDF(f)
        for name, values in exp["channels"].items():
            s = m.get(name)
            assert np.array_equal(s.samples.astype(float), np.array(values)), name
            assert s.unit == exp["units"][name], (name, s.unit)
            assert np.array_equal(s.timestamps, np.array(exp["t"])), name
        print("asammdf", asammdf.__version__, "reads", f, ": all",
              len(exp["channels"]), "channels, units and times equal")


if __name__ == "__main__":
    if "--check" in sys.argv:
        check()
    elif "--groups" in sys.argv:
        groups()
    else:
        generate()
