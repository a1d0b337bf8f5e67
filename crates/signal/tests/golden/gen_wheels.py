"""Golden raw trigger-wheel recordings with known truth, for physid-signal's wheel decoder
(`physid_signal::wheel`) — written with numpy and pyarrow only, no physid code.

Run: python3 gen_wheels.py  (numpy, pyarrow) -> wheel_vr_60m3.parquet, wheel_hall_36m1.parquet,
                                                quadrature_500.parquet, wheels.json

The crank angle theta(t) [rad] is integrated (RK4 at 1 µs) from a mean speed that ramps, with
a cyclic fluctuation of the four-stroke single cylinder (period 720° of crank angle):
    dtheta/dt = w_mean(t) * (1 + a * sin(theta / 2 + phi)).
Tooth i of an N-M wheel is centred at theta = (i + 0.5) * pitch on the wheel, i = 0 … N-M-1
(the M missing teeth follow the last one); the wheel's angle is the crank angle (the wheel on
the crankshaft).

* wheel_vr_60m3.parquet — an inductive (variable-reluctance) pickup over a 60-3 wheel at
  100 kHz, 1.2 s from 300 to 2400 rpm: per tooth the derivative of a Gaussian with unequal
  widths on either side (a tall narrow positive lobe, a wide shallow negative one) — an
  asymmetric wave whose amplitude grows with speed — on a 0.3 V offset, with white noise; in
  the first revolutions (below 1000 rpm) a narrow glitch pulse in the middle of each gap, tall
  enough to cross the hysteresis but a tenth of a tooth's width. A cylinder-pressure channel
  (V) peaks at the compression TDC, which lies `tdc_offset_deg` after the first tooth's edge
  on the wheel in one revolution out of two.
* wheel_hall_36m1.parquet — a digital Hall sensor (0/5 V, high while a tooth passes, a tooth
  half a pitch wide) over a 36-1 wheel at 50 kHz, 2 s from 800 to 1500 rpm; one tooth's pulse
  is dropped (a missing edge) and one spurious pulse, 40 % of a tooth wide, is added in the
  middle of a tooth space (an extra edge).
* quadrature_500.parquet — an A/B/Z quadrature encoder of 500 lines (digital, 200 kHz): the
  shaft turns back 40° first, then forward up to 1200 rpm; edges jittered by up to 3 % of a
  line; Z once per revolution (see `quadrature_file`).

Channels: t [us] (int32), enc (int16 ADC counts of 0.2 mV; the Hall file: 1 mV), p_cyl
(int16 counts of 1 mV; VR file only) — the raw channels without a unit, as a DAQ's text file, theta_true [urad] (int64: the true crank angle at the sample,
0 at the wheel's reference, tooth 0's centre at half a pitch). wheels.json: per file the wheel,
the true angle of tooth 0's rising-edge level crossing is *not* given (it depends on the
decoder's threshold level: compare angles up to a constant), the sample indices of the
injected faults, the TDC offset and the number of glitches.
"""
import json
import math

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq


def integrate(duration, rpm0, rpm1, a, phi, dt=1e-6):
    """theta(t) on a 1 µs grid by RK4; mean speed ramping linearly rpm0 -> rpm1."""
    n = int(round(duration / dt)) + 1
    t = np.arange(n) * dt
    th = np.empty(n)
    th[0] = 0.0

    def f(tt, x):
        w = (rpm0 + (rpm1 - rpm0) * tt / duration) * math.pi / 30.0
        return w * (1.0 + a * math.sin(x / 2.0 + phi))

    x = 0.0
    for k in range(n - 1):
        tk = t[k]
        k1 = f(tk, x)
        k2 = f(tk + dt / 2, x + dt / 2 * k1)
        k3 = f(tk + dt / 2, x + dt / 2 * k2)
        k4 = f(tk + dt, x + dt * k3)
        x += dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        th[k + 1] = x
    return t, th


def resample(t_fine, th_fine, fs, duration):
    n = int(round(duration * fs))
    idx = np.arange(n) * int(round(1.0 / fs / 1e-6))
    return t_fine[idx], th_fine[idx], idx


def tooth_phase(theta, n, m):
    """Angle from the nearest present tooth's centre [rad] and whether that tooth exists."""
    pitch = 2 * np.pi / n
    k = np.floor(theta / pitch)  # tooth slot index, unbounded
    x = theta - (k + 0.5) * pitch  # from the slot's centre, in [-pitch/2, pitch/2)
    present = np.mod(k, n) < n - m
    return x, present, k


def vr_file():
    n, m = 60, 3
    fs = 100_000.0
    duration = 1.2
    t_fine, th_fine = integrate(duration, 300.0, 2400.0, 0.06, 0.4)
    t, th, _ = resample(t_fine, th_fine, fs, duration)
    pitch = 2 * np.pi / n
    w = np.interp(t, t_fine[1:], np.diff(th_fine) / 1e-6)
    v = np.full_like(th, 0.3)
    s_pos, s_neg = 0.10 * pitch, 0.22 * pitch
    # Sum of the neighbouring slots' pulses (a pulse is negligible beyond ±1.5 pitches).
    for shift in (-1, 0, 1):
        x, present, _ = tooth_phase(th + shift * pitch, n, m)
        x = x - shift * pitch
        sig = np.where(x < 0, s_pos, s_neg)
        # Positive lobe before the centre, negative after; amplitude ∝ speed.
        g = -x / sig * np.exp(0.5 - 0.5 * (x / sig) ** 2)
        g = np.where(x < 0, 4.1 * g, 1.1 * g)
        v += np.where(present, g * (w / (2000 * np.pi / 30)), 0.0)
    rng = np.random.default_rng(20)
    v += rng.normal(scale=0.004, size=v.size)
    # Glitches: in the middle of the gap, while the speed is below 1000 rpm.
    gap_mid = (n - m + m / 2.0) * pitch  # the gap's middle on the wheel
    rev = np.floor(th / (2 * np.pi))
    glitches = 0
    for r in range(int(rev[-1]) + 1):
        centre = r * 2 * np.pi + gap_mid
        i = np.searchsorted(th, centre)
        if i >= len(th) or w[i] * 30 / np.pi > 1000:
            continue
        width = 0.1 * s_pos  # a tenth of a tooth's positive lobe
        x = th - centre
        v += 0.8 * (w / (2000 * np.pi / 30)) * 4.1 * np.exp(-0.5 * (x / width) ** 2)
        glitches += 1
    # Cylinder pressure: a motored compression pulse around the compression TDC, which lies
    # tdc_offset_deg after tooth 0's centre in even revolutions (the odd ones' TDC is the
    # gas-exchange one, without a peak).
    tdc_offset_deg = 117.0
    tdc0 = 0.5 * pitch + np.deg2rad(tdc_offset_deg)
    cyc = np.mod(th - tdc0 + 2 * np.pi, 4 * np.pi) - 2 * np.pi  # from the nearest compression TDC
    p = 0.5 + 2.0 * np.exp(-0.5 * (cyc / np.deg2rad(35.0)) ** 2)
    p += rng.normal(scale=0.002, size=p.size)
    enc = np.round(v / 0.0002).astype(np.int16)
    pc = np.round(p / 0.001).astype(np.int16)
    table = pa.table(
        {
            "t": pa.array(np.round(t * 1e6).astype(np.int32)),
            "enc": pa.array(enc),
            "p_cyl": pa.array(pc),
            "theta_true": pa.array(np.round(th * 1e6).astype(np.int64)),
        }
    )
    schema = pa.schema(
        [
            pa.field("t", pa.int32(), metadata={"unit": "us"}),
            pa.field("enc", pa.int16()),
            pa.field("p_cyl", pa.int16()),
            pa.field("theta_true", pa.int64(), metadata={"unit": "urad"}),
        ]
    )
    table = table.cast(schema)
    return table, {
        "wheel": "60-3",
        "rate_hz": fs,
        "samples": len(t),
        "enc_volts_per_count": 0.0002,
        "p_cyl_volts_per_count": 0.001,
        "rpm": [300.0, 2400.0],
        "glitches": glitches,
        "tdc_offset_from_tooth0_centre_deg": tdc_offset_deg,
        "revolutions": int(rev[-1]),
    }


def hall_file():
    n, m = 36, 1
    fs = 50_000.0
    duration = 2.0
    t_fine, th_fine = integrate(duration, 800.0, 1500.0, 0.04, 1.1)
    t, th, _ = resample(t_fine, th_fine, fs, duration)
    pitch = 2 * np.pi / n
    x, present, slot = tooth_phase(th, n, m)
    high = present & (np.abs(x) < pitch / 4)  # a tooth half a pitch wide
    # The tooth to drop: slot 20 of revolution 10; the spurious pulse: the space after slot 5
    # of revolution 30, 40 % of a tooth wide.
    drop_slot = 10 * n + 20
    high &= ~(slot == drop_slot)
    extra_centre = (30 * n + 5 + 1.0) * pitch  # the middle of the space between slots 5 and 6
    high |= np.abs(th - extra_centre) < 0.4 * pitch / 4
    v = np.where(high, 5.0, 0.0)
    # The sample of each fault's edge: the first sample at or after the rising crossing.
    # Missing: the next tooth's rising edge (slot 21's leading edge) ends the long period.
    missing_at = int(np.searchsorted(th, (drop_slot + 1 + 0.5) * pitch - pitch / 4))
    extra_at = int(np.searchsorted(th, extra_centre - 0.4 * pitch / 4))
    table = pa.table(
        {
            "t": pa.array(np.round(t * 1e6).astype(np.int32)),
            "enc": pa.array(np.round(v / 0.001).astype(np.int16)),
            "theta_true": pa.array(np.round(th * 1e6).astype(np.int64)),
        }
    )
    schema = pa.schema(
        [
            pa.field("t", pa.int32(), metadata={"unit": "us"}),
            pa.field("enc", pa.int16()),
            pa.field("theta_true", pa.int64(), metadata={"unit": "urad"}),
        ]
    )
    return table.cast(schema), {
        "wheel": "36-1",
        "rate_hz": fs,
        "samples": len(t),
        "rpm": [800.0, 1500.0],
        "missing_edge_sample": missing_at,
        "extra_edge_sample": extra_at,
        "revolutions": int(np.floor(th[-1] / (2 * np.pi))),
    }


def quadrature_file():
    """A/B/Z quadrature encoder, 500 lines, digital 0/5 V at 200 kHz, 0.6 s: the shaft turns
    back by 40° (a rocking start), then forward, speeding up to 1200 rpm with cyclic
    fluctuation; every edge displaced by a random jitter of up to 3 % of a line."""
    ppr = 500
    fs = 200_000.0
    duration = 0.6
    dt = 1e-6
    n = int(round(duration / dt)) + 1
    tf = np.arange(n) * dt
    # theta(t): back 40° over the first 0.1 s (a half-cosine), then forward from rest:
    # 1200 rpm reached by a smooth ramp, with a 3 % fluctuation at the firing frequency.
    back = np.deg2rad(40.0)
    th = np.where(tf < 0.1, -back * 0.5 * (1 - np.cos(np.pi * tf / 0.1)), -back)
    u = np.clip((tf - 0.1) / 0.5, 0.0, None)
    w_mean = 1200 * np.pi / 30 * np.where(u < 1, u * u * (3 - 2 * u), 1.0)
    fwd = np.cumsum(w_mean) * dt
    th = th + fwd + 0.03 * np.sin(fwd / 2) * (fwd > 0)
    rng = np.random.default_rng(7)
    q = 2 * np.pi / ppr  # a line
    # Each line's rising and falling edge displaced by its own jitter of up to 3 % of a line:
    # high on [k + r_k, k + 1/2 + f_k) in lines.
    jr = rng.uniform(-0.03, 0.03, size=100_000)
    jf = rng.uniform(-0.03, 0.03, size=100_000)
    def channel(shift):
        x = th / q + shift
        k = np.floor(x).astype(np.int64)
        r0, f0 = jr[k % jr.size], jf[k % jf.size]
        r1 = jr[(k + 1) % jr.size]
        high = ((x >= k + r0) & (x < k + 0.5 + f0)) | (x >= k + 1 + r1)
        return np.where(high, 5.0, 0.0)
    a = channel(0.0)
    b = channel(-0.25)  # B lags A by a quarter line when turning forward
    # Z: high for a quarter line once per revolution, at the wheel's 0.
    zx = np.mod(th, 2 * np.pi)
    z = np.where(zx < q / 4, 5.0, 0.0)
    idx = np.arange(int(round(duration * fs))) * int(round(1.0 / fs / dt))
    table = pa.table(
        {
            "t": pa.array(np.round(tf[idx] * 1e6).astype(np.int32)),
            "enc_a": pa.array(np.round(a[idx] / 0.001).astype(np.int16)),
            "enc_b": pa.array(np.round(b[idx] / 0.001).astype(np.int16)),
            "enc_z": pa.array(np.round(z[idx] / 0.001).astype(np.int16)),
            "theta_true": pa.array(np.round(th[idx] * 1e6).astype(np.int64)),
        }
    )
    schema = pa.schema(
        [
            pa.field("t", pa.int32(), metadata={"unit": "us"}),
            pa.field("enc_a", pa.int16()),
            pa.field("enc_b", pa.int16()),
            pa.field("enc_z", pa.int16()),
            pa.field("theta_true", pa.int64(), metadata={"unit": "urad"}),
        ]
    )
    first_z = int(np.argmax(z[idx] > 0))
    return table.cast(schema), {
        "ppr": ppr,
        "rate_hz": fs,
        "samples": len(idx),
        "back_deg": 40.0,
        "first_index_sample": first_z,
        "revolutions": int(np.floor(th[-1] / (2 * np.pi))),
    }


if __name__ == "__main__":
    out = {}
    for name, make in [
        ("wheel_vr_60m3", vr_file),
        ("wheel_hall_36m1", hall_file),
        ("quadrature_500", quadrature_file),
    ]:
        table, info = make()
        pq.write_table(
            table,
            f"{name}.parquet",
            compression="zstd",
            use_dictionary=False,
            column_encoding={"t": "DELTA_BINARY_PACKED", "theta_true": "DELTA_BINARY_PACKED"},
        )
        out[name] = info
    with open("wheels.json", "w") as f:
        json.dump(out, f, indent=1)
    print(json.dumps(out, indent=1))
