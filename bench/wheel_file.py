#!/usr/bin/env python3
"""A time-basis recording whose engine angle is a raw sensor's signal, for bench/memory.sh
(ONLY=wheel): IN's channels CHANNELS (not theta_en, the counts or the marker) and either `enc`,
a Hall sensor over a 60-2 wheel made from IN's theta_en (high over the first half of each tooth
pitch, the teeth after the 58th of each revolution left out), or with --quadrature `qa`, `qb`,
`qz`, a 36-line quadrature encoder (B a quarter line behind A, the index high over the first
2 % of each revolution) — written a row group at a time (pyarrow, numpy), so a one-hour file
needs no more memory than a row group.

Usage: wheel_file.py IN.parquet OUT.parquet [--quadrature]
"""
import sys

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

CHANNELS = ["t", "omega_en", "alpha_en", "p_cyl", "p_int", "p_crank", "p_atm", "T_oil",
            "torque_engine", "torque_shaft"]
TEETH, MISSING = 60, 2
LINES = 36


def sensor(theta, quadrature):
    """The sensor's channels (name, values) at the angles `theta` [rad]."""
    if quadrature:
        line = np.mod(theta / (2 * np.pi / LINES), 1.0)
        return [("qa", line < 0.5), ("qb", np.mod(line - 0.25, 1.0) < 0.5),
                ("qz", np.mod(theta / (2 * np.pi), 1.0) < 0.02)]
    x = theta / (2 * np.pi / TEETH)
    tooth = np.floor(x)
    return [("enc", (np.mod(tooth, TEETH) < TEETH - MISSING) & (x - tooth < 0.5))]


def main(src, dst, *flags):
    f = pq.ParquetFile(src)
    meta = f.schema_arrow.metadata
    writer = None
    for g in range(f.num_row_groups):
        table = f.read_row_group(g, columns=CHANNELS + ["theta_en"])
        theta = table.column("theta_en").to_numpy()
        out = table.drop(["theta_en"])
        for name, v in sensor(theta, "--quadrature" in flags):
            out = out.append_column(pa.field(name, pa.float64(), metadata={b"unit": b"V"}),
                                    pa.array(v.astype(np.float64)))
        if writer is None:
            writer = pq.ParquetWriter(dst, out.schema.with_metadata(meta))
        writer.write_table(out.replace_schema_metadata(meta))
    writer.close()


if __name__ == "__main__":
    main(*sys.argv[1:])
