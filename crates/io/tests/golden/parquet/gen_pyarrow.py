"""Parquet files written by pyarrow for physid-io's reader tests, and the check that pyarrow
reads the file physid-io writes.

  python3 gen_pyarrow.py           -> pyarrow_written.parquet and expected.json
  python3 gen_pyarrow.py --checksummed -> pyarrow_checksummed.parquet: the same table, every
                                      page with its CRC-32 (write_page_checksum=True)
  python3 gen_pyarrow.py --check   -> reads physid_written.parquet (committed, written by
                                      physid-io's writer test) and compares with
                                      expected_physid.json: values, units (field metadata
                                      "unit"), the basis (schema metadata "physid.basis")

pyarrow (pip install pyarrow).
"""
import json
import sys

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq


def table():
    n = 5000
    t = np.arange(n) / 1000.0
    omega = 100.0 + 5.0 * np.sin(7.0 * t)
    count = np.floor(np.cumsum(omega) / 1000.0 / (2 * np.pi / 360)).astype(np.int64)
    tq = (3.0 * np.cos(40.0 * t)).astype(np.float32)
    schema = pa.schema([
        pa.field("t", pa.float64(), metadata={"unit": "s"}),
        pa.field("omega_en", pa.float64(), metadata={"unit": "rad/s"}),
        pa.field("count_en", pa.int64(), metadata={"unit": "-"}),
        pa.field("torque_shaft", pa.float32(), metadata={"unit": "N*m"}),
    ])
    return t, omega, count, tq, pa.table([t, omega, count, tq], schema=schema)


def generate():
    t, omega, count, tq, tab = table()
    # Several row groups, as large loggers write them.
    pq.write_table(tab, "pyarrow_written.parquet", row_group_size=1500)
    json.dump({"pyarrow": pa.__version__, "t": t.tolist(), "omega_en": omega.tolist(),
               "count_en": count.astype(float).tolist(),
               "torque_shaft": tq.astype(float).tolist(),
               "units": {"t": "s", "omega_en": "rad/s", "count_en": "-", "torque_shaft": "N*m"}},
              open("expected.json", "w"))


def checksummed():
    # Small pages, so a chunk holds several, each with its checksum.
    pq.write_table(table()[-1], "pyarrow_checksummed.parquet", row_group_size=1500,
                   write_page_checksum=True, data_page_size=4096)


def check():
    exp = json.load(open("expected_physid.json"))
    table = pq.read_table("physid_written.parquet")
    assert table.schema.metadata[b"physid.basis"].decode() == exp["basis"]
    for name, values in exp["channels"].items():
        col = table.column(name).to_numpy()
        assert np.array_equal(col, np.array(values)), name
        unit = table.schema.field(name).metadata[b"unit"].decode()
        assert unit == exp["units"][name], (name, unit)
    print("pyarrow", pa.__version__, "reads physid_written.parquet:", len(exp["channels"]),
          "channels, units and basis equal")


if __name__ == "__main__":
    if "--check" in sys.argv:
        check()
    elif "--checksummed" in sys.argv:
        checksummed()
    else:
        generate()
