"""Golden motored cylinder-pressure recordings with known truth, for `physid compression fit`
and `--tdc-from` — written with numpy and pyarrow only, no physid code.

Run: python3 gen_motored.py  (numpy, pyarrow) -> motored_deg.parquet, motored_wheel.parquet,
                                                 motored.json

The motored pressure with the valves closed (true crank angle a after the firing TDC, rad):
    V(a) = V_c + A*(r*(1 - cos a) + L - sqrt(L^2 - r^2 sin^2 a)),  V_c = A*S/(eps - 1)
    p(a) = p_bdc * (V(-pi)/V(a))^n * exp(-k_loss*(a + pi))        for -pi <= a <= pi
and p_bdc * (1 + 0.02 sin(...)) during the gas exchange (|a| > pi, not fitted). The sensor
reads p + p_offset, with white noise.

* motored_deg.parquet — a crank-angle recording as physid writes one (schema metadata
  physid.basis = crank_angle; channels t [s], cycle [-], crank_deg [deg], p_cyl [Pa]): 12
  cycles at 1 deg steps, 1500 rpm, the recording's crank angle 0 `tdc_shift` degrees BEFORE the
  true TDC (the true TDC at crank_deg = tdc_shift), noise 300 Pa.
* motored_wheel.parquet — a raw time recording at 100 kHz, 1 s at 1500 rpm with a cyclic
  speed fluctuation: t [us] (int32), enc (int8: a digital Hall sensor, 0/5 V, over a 60-2
  wheel, high from a quarter to three quarters of each tooth's pitch), cam (int8: 0/5 V, high
  from 100 deg to 10 deg before each firing TDC), p_cyl (float32, V: the pressure over a gain
  of 1e6 Pa/V, noise 0.5 mV), theta_true (int64, urad: the true crank angle, 0 at the wheel's
  reference, tooth 0 centred at half a pitch). The firing TDC lies `tdc_offset_deg` after
  tooth 0's rising edge (at a quarter pitch), in the revolutions 0, 2, 4, … counted from
  the wheel's reference.

motored.json: the truth of both (eps, tdc_shift or tdc_offset_deg, p_offset, n, p_bdc, k_loss,
geometry, noise).
"""
import json
import math

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

STROKE, ROD = 0.09, 0.15


def ratio(a, eps):
    """V(-pi)/V(a) for the slider crank (bore cancels)."""
    r = STROKE / 2
    s = r * (1 - np.cos(a)) + ROD - np.sqrt(ROD**2 - (r * np.sin(a)) ** 2)
    vc = STROKE / (eps - 1)
    return (vc + STROKE) / (vc + s)


def pressure(a, t):
    """True pressure at the true angle a [rad ATDC, any real] for the truth dict t."""
    a = np.mod(a + 2 * math.pi, 4 * math.pi) - 2 * math.pi  # -2pi .. 2pi
    closed = np.abs(a) <= math.pi
    p = np.where(
        closed,
        t["p_bdc"] * ratio(a, t["eps"]) ** t["n"] * np.exp(-t["k_loss"] * (a + math.pi)),
        t["p_bdc"] * (1 + 0.02 * np.sin(3 * a)),
    )
    return p


def crank_angle_file(rng):
    truth = dict(eps=10.5, tdc_shift=0.6, p_offset=3.0e4, n=1.31, p_bdc=0.95e5, k_loss=0.05,
                 noise=300.0, rpm=1500.0, cycles=12, step_deg=1.0)
    per = 720
    k = np.arange(truth["cycles"] * per)
    deg = (k % per).astype(float)
    cycle = (k // per).astype(float)
    theta = k * 1.0  # continuous recording angle [deg] from the first TDC
    t = theta / (truth["rpm"] * 6.0)
    a = np.radians(theta - truth["tdc_shift"])
    p = pressure(a, truth) + truth["p_offset"] + rng.normal(0, truth["noise"], k.size)
    schema = pa.schema(
        [
            pa.field("t", pa.float64(), metadata={"unit": "s"}),
            pa.field("cycle", pa.float64(), metadata={"unit": "-"}),
            pa.field("crank_deg", pa.float64(), metadata={"unit": "deg"}),
            pa.field("p_cyl", pa.float64(), metadata={"unit": "Pa"}),
        ],
        metadata={"physid.basis": "crank_angle"},
    )
    table = pa.table([t, cycle, deg, p], schema=schema)
    pq.write_table(table, "motored_deg.parquet", compression="zstd")
    return truth


def wheel_file(rng):
    truth = dict(eps=17.0, tdc_offset_deg=73.5, p_offset=-2.0e4, n=1.34, p_bdc=1.0e5,
                 k_loss=0.03, noise_v=5e-4, gain_pa_per_v=1e6, rpm=1500.0, rate_hz=100e3,
                 duration_s=1.0, wheel="60-2", fluctuation_rad=0.01)
    n_teeth, pitch = 60, 2 * math.pi / 60
    fs = truth["rate_hz"]
    t = np.arange(int(truth["duration_s"] * fs)) / fs
    w = truth["rpm"] * math.pi / 30
    # Closed form: theta(t) = w t + A sin(w t / 2) (one fluctuation per cycle), from a start
    # 1.3 revolutions before the reference (so that the first gap passes early).
    start = -1.3 * 2 * math.pi
    theta = start + w * t + truth["fluctuation_rad"] * np.sin(w * t / 2)
    # Hall: high from (i + 1/4) to (i + 3/4) pitch of tooth i < 58.
    pos = np.mod(theta, 2 * math.pi) / pitch
    tooth = np.floor(pos)
    frac = pos - tooth
    enc = np.where((tooth < n_teeth - 2) & (frac >= 0.25) & (frac < 0.75), 5, 0).astype(np.int8)
    # The firing TDC: tdc_offset after tooth 0's rising edge, in even revolutions.
    tdc = 0.25 * pitch + math.radians(truth["tdc_offset_deg"])
    a = theta - tdc  # true angle after a firing TDC (mod 4 pi)
    am = np.mod(a + 2 * math.pi, 4 * math.pi) - 2 * math.pi
    cam = np.where((am >= math.radians(-100)) & (am < math.radians(-10)), 5, 0).astype(np.int8)
    p = pressure(a, truth) + truth["p_offset"]
    volts = p / truth["gain_pa_per_v"] + rng.normal(0, truth["noise_v"], t.size)
    schema = pa.schema(
        [
            pa.field("t", pa.int32(), metadata={"unit": "us"}),
            pa.field("enc", pa.int8()),
            pa.field("cam", pa.int8()),
            pa.field("p_cyl", pa.float32(), metadata={"unit": "V"}),
            pa.field("theta_true", pa.int64(), metadata={"unit": "urad"}),
        ]
    )
    table = pa.table(
        [
            np.round(t * 1e6).astype(np.int32),
            enc,
            cam,
            volts.astype(np.float32),
            np.round(theta * 1e6).astype(np.int64),
        ],
        schema=schema,
    )
    pq.write_table(table, "motored_wheel.parquet", compression="zstd")
    return truth


def main():
    rng = np.random.default_rng(20261126)
    out = {
        "geometry": {"stroke": STROKE, "rod": ROD},
        "deg": crank_angle_file(rng),
        "wheel": wheel_file(rng),
    }
    with open("motored.json", "w") as f:
        json.dump(out, f, indent=1)


if __name__ == "__main__":
    main()
