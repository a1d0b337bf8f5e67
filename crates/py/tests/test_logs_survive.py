"""No data lost, read by other people's readers (docs/live.md): a live log that `physid live`
was writing when it was stopped by SIGTERM or SIGINT, or killed by SIGKILL at a seeded random
moment, is read by pyarrow (Parquet, after `physid recover` for a kill) and asammdf (MDF4, as
it is); its samples are a stretch of `physid simulate`'s for the same scenario, bit for bit,
read by pyarrow too. The same checks with physid's own reader are in
crates/cli/tests/no_data_lost.rs."""
import json
import os
import random
import signal
import subprocess
import threading
import time

import numpy as np
import pyarrow.parquet as pq
import pytest

asammdf = pytest.importorskip("asammdf")

BIN = os.environ["PHYSID_BIN"]


def _read(path):
    """Every channel of a log as numpy arrays, by pyarrow or asammdf."""
    if path.endswith(".parquet"):
        t = pq.read_table(path)
        return {n: t.column(n).to_numpy() for n in t.column_names}
    mdf = asammdf.MDF(path)
    out = {}
    masters = {mdf.groups[0].channels[i].name for i in [mdf.masters_db.get(0, 0)]}
    for name in mdf.channels_db:
        if name in masters or name == "t":
            continue
        s = mdf.get(name)
        out[name] = np.asarray(s.samples, dtype=float)
        out["t"] = np.asarray(s.timestamps, dtype=float)
    return out


@pytest.mark.parametrize("sig,ext,seed", [
    (signal.SIGTERM, "parquet", 1),
    (signal.SIGINT, "mf4", 2),
    (signal.SIGKILL, "parquet", 3),
    (signal.SIGKILL, "mf4", 4),
])
def test_a_killed_log_reads_in_pyarrow_and_asammdf(tmp_path, sig, ext, seed):
    sim = tmp_path / "sim.parquet"
    subprocess.run([BIN, "simulate", "--scenario", "shaft-steady", "--duration", "12",
                    "--recording", str(sim)], check=True, capture_output=True)
    want = pq.read_table(sim)
    logs = tmp_path / "logs"
    live = subprocess.Popen(
        [BIN, "live", "--headless", "--json", "--scenario", "shaft-steady", "--duration", "12",
         "--pace", "4", "--controls", "-", "--log-dir", str(logs)],
        stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    name = f"run.{ext}"
    live.stdin.write(json.dumps({"cmd": "record", "file": name}) + "\n")
    live.stdin.flush()
    events = []

    def read():
        for line in live.stdout:
            events.append((time.monotonic(), json.loads(line)))

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    deadline = time.monotonic() + 30
    while not any(e["type"] == "log" for _, e in events):
        assert time.monotonic() < deadline, "no log event in 30 s"
        time.sleep(0.02)
    time.sleep(random.Random(seed).uniform(0.3, 2.0))
    killed = time.monotonic()
    live.send_signal(sig)
    code = live.wait(timeout=30)
    reader.join(timeout=10)
    live.stdin.close()
    path = str(logs / name)
    if sig == signal.SIGKILL:
        if ext == "parquet":
            subprocess.run([BIN, "recover", path], check=True, capture_output=True)
    else:
        assert code == 0
        assert any(e["type"] == "log" and e["state"] == "closed" for _, e in events)
    got = _read(path)
    n = len(got["t"])
    assert n > 0
    t_sim = want.column("t").to_numpy()
    k0 = int(np.flatnonzero(t_sim == got["t"][0])[0])
    assert set(got) == set(want.column_names)
    for name_ in want.column_names:
        np.testing.assert_array_equal(got[name_], want.column(name_).to_numpy()[k0:k0 + n],
                                      err_msg=name_)
    # At most the last second and a half before the kill is missing.
    processed = [e["t_s"] for at, e in events
                 if e["type"] == "estimate" and at + 1.5 <= killed]
    if processed:
        assert got["t"][-1] >= max(processed)
