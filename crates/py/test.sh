#!/usr/bin/env bash
# The Python package's own tests (issue 21): build the wheel with maturin, install it into a
# fresh venv with the users' tools (numpy, pandas, pyarrow, statsmodels, filterpy, asammdf,
# nats-py for the outside DAQ client of the fleet, FMPy for the cell exported as an FMU),
# run pytest. PHYSID_BIN (physid's binary, for the parity test with `physid estimate`) defaults
# to the debug build `cargo test` leaves.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
root="$(cd "$here/../.." && pwd)"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
python3 -m venv "$work/venv"
py="$work/venv/bin/python"
"$py" -m pip install -q --disable-pip-version-check maturin pytest numpy pandas pyarrow statsmodels filterpy asammdf nats-py fmpy
(cd "$here" && "$work/venv/bin/maturin" build -q --out "$work/wheels")
"$py" -m pip install -q --disable-pip-version-check "$work"/wheels/physid-*.whl
PHYSID_BIN="${PHYSID_BIN:-$root/target/debug/physid}"
[ -x "$PHYSID_BIN" ] || (cd "$root" && cargo build -q -p physid)
export PHYSID_BIN="$(realpath "$PHYSID_BIN")"
cd "$here"
"$py" -m pytest -q -p no:cacheprovider tests
