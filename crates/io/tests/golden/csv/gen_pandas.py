"""What pandas reads from a CSV file physid wrote (physid_written.csv, made by
`PHYSID_BLESS=1 cargo test -p physid-io --test csv`), with the one documented option
`skiprows=[1]` (the units row) — and, with `header=[0, 1]`, the units as a second column level.

Run: python3 crates/io/tests/golden/csv/gen_pandas.py   (pandas ≥ 2)
Writes pandas_read.json beside this script; the Rust test `csv::pandas_reads_physids_csv`
compares physid's own reading of the same file with it.
"""
import json
import pathlib

import pandas as pd

here = pathlib.Path(__file__).parent
src = here / "physid_written.csv"
df = pd.read_csv(src, skiprows=[1])
units = pd.read_csv(src, header=[0, 1], nrows=0).columns
out = {
    "pandas": pd.__version__,
    "columns": list(df.columns),
    "dtypes": [str(t) for t in df.dtypes],
    "units": {name: unit for name, unit in units},
    # repr() of a float64 is the shortest string that reads back to the same value.
    "values": {c: [repr(float(v)) for v in df[c]] for c in df.columns},
}
(here / "pandas_read.json").write_text(json.dumps(out, indent=1) + "\n")
print(f"{len(df)} rows × {len(df.columns)} columns")
