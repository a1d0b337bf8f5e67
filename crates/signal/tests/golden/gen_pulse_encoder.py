"""Golden raw single-channel pulse encoder with an analog index, known truth, for the trigger-wheel
decoder's index mode (`--encoder-raw enc=360 --index-raw idx`) — numpy and pyarrow only, no
physid code.

Run: python3 gen_pulse_encoder.py  (numpy, pyarrow; gen_wheels.py beside it)
     -> pulse_encoder_360.parquet, pulse_encoder.json

The crank angle theta(t) [rad] as gen_wheels.py integrates it (RK4 at 1 us): a mean speed
ramping from 600 to 3000 rpm over 0.8 s with a 5 % cyclic fluctuation of the four-stroke
single cylinder. Sampled at 200 kHz.

* enc: a 360-pulse encoder's analog output, a rounded square wave high over the first half of
  each line (2.5 + 2.2*tanh(3*sin(360*theta))) V, with white noise of 20 mV rms; one line's pulse
  left out (a missing edge: the pulse of line 100 of revolution 12), and five glitches (a
  single sample at 5 V in the middle of a low half-line, at revolutions 3, 9, 15, 21, 27).
* idx: the index, once per revolution: a Gaussian pulse of 4 V (sigma a tenth of a line) on
  0.4 V centred a quarter line after the encoder's 0 on the wheel, white noise of 20 mV, and one
  glitch (a single sample at 4.4 V half a revolution after the index of revolution 6).

Channels: t [us] (int32), enc and idx (int16 ADC counts of 1 mV), theta_true [urad] (int64).
pulse_encoder.json: the pulses, the rate, the samples, the glitch count on enc, the sample of the
missing edge's finding (the first sample at or past the level crossing of the line after the
missing one), the revolutions, the rpm range.
"""
import json

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from gen_wheels import integrate, resample

PULSES = 360
FS = 200_000.0
DURATION = 0.8


def main():
    t_fine, th_fine = integrate(DURATION, 600.0, 3000.0, 0.05, 0.7)
    t, th, _ = resample(t_fine, th_fine, FS, DURATION)
    line = 2 * np.pi / PULSES
    rng = np.random.default_rng(360)
    v = 2.5 + 2.2 * np.tanh(3 * np.sin(PULSES * th))
    # The missing pulse: line 100 of revolution 12 held low.
    k = np.floor(th / line).astype(np.int64)
    drop = 12 * PULSES + 100
    v = np.where(k == drop, 2.5 - 2.2 * np.tanh(3.0), v)
    v += rng.normal(scale=0.02, size=v.size)
    glitches = 0
    for r in (3, 9, 15, 21, 27):
        centre = (r * PULSES + 50 + 0.75) * line  # the middle of a low half-line
        i = int(np.searchsorted(th, centre))
        if i < len(th):
            v[i] = 5.0
            glitches += 1
    # The edge after the missing one: line drop + 1's rising crossing of the mid level.
    missing_at = int(np.searchsorted(th, (drop + 1) * line))
    z = 0.4 + 4.0 * np.exp(-0.5 * ((np.mod(th - line / 4 + np.pi, 2 * np.pi) - np.pi) / (0.1 * line)) ** 2)
    z += rng.normal(scale=0.02, size=z.size)
    zg = int(np.searchsorted(th, 6 * 2 * np.pi + np.pi))
    z[zg] = 4.4
    table = pa.table(
        {
            "t": pa.array(np.round(t * 1e6).astype(np.int32)),
            "enc": pa.array(np.round(v / 0.001).astype(np.int16)),
            "idx": pa.array(np.round(z / 0.001).astype(np.int16)),
            "theta_true": pa.array(np.round(th * 1e6).astype(np.int64)),
        }
    )
    schema = pa.schema(
        [
            pa.field("t", pa.int32(), metadata={"unit": "us"}),
            pa.field("enc", pa.int16()),
            pa.field("idx", pa.int16()),
            pa.field("theta_true", pa.int64(), metadata={"unit": "urad"}),
        ]
    )
    pq.write_table(table.cast(schema), "pulse_encoder_360.parquet", compression="zstd",
                   use_dictionary=False,
                   column_encoding={"t": "DELTA_BINARY_PACKED", "theta_true": "DELTA_BINARY_PACKED"})
    info = {
        "pulses": PULSES,
        "rate_hz": FS,
        "samples": len(t),
        "glitches": glitches,
        "index_glitch_sample": zg,
        "missing_edge_sample": missing_at,
        "revolutions": int(np.floor(th[-1] / (2 * np.pi))),
        "rpm": [600.0, 3000.0],
    }
    with open("pulse_encoder.json", "w") as f:
        json.dump(info, f, indent=1)
        f.write("\n")
    print(json.dumps(info, indent=1))


if __name__ == "__main__":
    main()
