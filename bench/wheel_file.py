#!/usr/bin/env python3
"""A time-basis recording whose engine angle is a trigger wheel's raw signal, for
bench/memory.sh (ONLY=wheel): IN's channels CHANNELS (not theta_en, the counts or the marker)
and `enc`, a Hall sensor over a 60-2 wheel made from IN's theta_en (high over the first half of
each tooth pitch, the teeth after the 58th of each revolution left out) — written a row group
at a time (pyarrow, numpy), so a one-hour file needs no more memory than a row group.

Usage: wheel_file.py IN.parquet OUT.parquet
"""
import sys

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

CHANNELS = ["t", "omega_en", "alpha_en", "p_cyl", "p_int", "p_crank", "p_atm", "T_oil",
            "torque_engine", "torque_shaft"]
TEETH, MISSING = 60, 2


def main(src, dst):
    f = pq.ParquetFile(src)
    meta = f.schema_arrow.metadata
    writer = None
    for g in range(f.num_row_groups):
        table = f.read_row_group(g, columns=CHANNELS + ["theta_en"])
        theta = table.column("theta_en").to_numpy()
        x = theta / (2 * np.pi / TEETH)
        tooth = np.floor(x)
        enc = ((np.mod(tooth, TEETH) < TEETH - MISSING) & (x - tooth < 0.5)).astype(np.float64)
        out = table.drop(["theta_en"]).append_column(
            pa.field("enc", pa.float64(), metadata={b"unit": b"V"}), pa.array(enc))
        if writer is None:
            writer = pq.ParquetWriter(dst, out.schema.with_metadata(meta))
        writer.write_table(out.replace_schema_metadata(meta))
    writer.close()


if __name__ == "__main__":
    main(*sys.argv[1:])
