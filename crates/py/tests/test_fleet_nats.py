"""An outside client on the fleet's wire format: a DAQ written in Python with nats-py and
pyarrow — no physid code on the publishing side — registers its cell and publishes a recording
as Arrow IPC frames; a `physid worker` processes them. Its events equal those of
`physid live --headless --json --replay` on the same file (the same stages in one process: each
kind of event equal, in order), and
its end event counts every sample published. Starts its own nats-server on a loopback port."""
import asyncio
import json
import os
import shutil
import socket
import subprocess
import tempfile
import time

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

import physid

nats = pytest.importorskip("nats")


def _nats_server():
    for p in ("/usr/sbin/nats-server", "/usr/bin/nats-server", shutil.which("nats-server")):
        if p and os.path.exists(p):
            return p
    return None


def _free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def frame(batch: pa.RecordBatch, cell: str, run: int, seq: int, first: int, rate: float,
          end: bool = False) -> bytes:
    """One frame of the physid wire format, version 1 (docs/fleet.md), with pyarrow alone."""
    meta = {
        "physid.wire": "1", "physid.cell": cell, "physid.run": str(run), "physid.seq": str(seq),
        "physid.first_sample": str(first), "physid.rate_hz": repr(rate), "physid.basis": "time",
        "physid.end": "true" if end else "false",
    }
    schema = batch.schema.with_metadata(meta)
    sink = pa.BufferOutputStream()
    with pa.ipc.new_stream(sink, schema) as w:
        w.write_batch(batch.replace_schema_metadata(meta))
    return sink.getvalue().to_pybytes()


@pytest.mark.skipif(not os.environ.get("PHYSID_BIN"), reason="PHYSID_BIN (physid's binary) not given")
def test_a_python_daq_publishes_and_physid_processes():
    server = _nats_server()
    if server is None:
        assert not os.environ.get("CI"), "CI needs nats-server (apt-get install nats-server)"
        pytest.skip("nats-server not installed")
    binary = os.environ["PHYSID_BIN"]
    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "daq.parquet")
        physid.simulate("shaft-steady", duration=3.0, faults=["shaft.k=1100@1.5"]).write(path)
        table = pq.read_table(path)  # every channel the DAQ records
        rate = 10_000.0
        # Where the cycles start: theta_en at a firing TDC (docs/fleet.md) — the TDC marker's
        # first rising edge, or the one a revolution on: the revolution around a firing TDC has
        # the higher mean cylinder pressure (compression and expansion against the gas exchange).
        tdc = table["tdc"].to_numpy()
        theta, p = table["theta_en"].to_numpy(), table["p_cyl"].to_numpy()
        k = int(np.flatnonzero((tdc != 0) & (np.r_[0.0, tdc[:-1]] == 0))[0])

        def level(first):
            around = [(theta >= c - np.pi) & (theta < c + np.pi)
                      for c in first + 4 * np.pi * np.arange(1, 4)]
            return np.mean([p[m].mean() for m in around])

        marker = float(theta[k])
        theta_tdc = marker if level(marker) > level(marker + 2 * np.pi) else marker + 2 * np.pi
        reference = [json.loads(line) for line in subprocess.run(
            [binary, "live", "--headless", "--json", "--pace", "max", "--replay", path],
            check=True, capture_output=True, text=True).stdout.splitlines()]

        port = _free_port()
        nats_proc = subprocess.Popen(
            [server, "-js", "-a", "127.0.0.1", "-p", str(port), "-sd", os.path.join(tmp, "store")],
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        url = f"nats://127.0.0.1:{port}"
        deadline = time.monotonic() + 20
        while True:
            try:
                socket.create_connection(("127.0.0.1", port), timeout=1).close()
                break
            except OSError:
                assert time.monotonic() < deadline, "nats-server did not start"
                time.sleep(0.05)
        worker = subprocess.Popen([binary, "worker", "--nats", url, "--name", "py-test"],
                                  stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        try:
            events = asyncio.run(_publish_and_collect(url, table, rate, theta_tdc))
        finally:
            worker.terminate()
            _, err = worker.communicate(timeout=30)
            nats_proc.terminate()
            nats_proc.wait(timeout=30)
        assert worker.returncode == 0, err
    end = [e for e in events if e["type"] == "end"][0]
    assert end["samples"] == table.num_rows and end["dropped"] == 0
    alarms = [e for e in events if e["type"] == "alarm"]
    assert alarms and alarms[0]["param"] == "K"
    # The same stages over NATS and in one process: each kind of event the same, in the same
    # order (how kinds interleave follows the chunking: 250-row frames here, 100-row chunks in
    # the replay).
    def by_type(es):
        out = {}
        for e in es:
            out.setdefault(e["type"], []).append(e)
        return out
    got, want = by_type(events), by_type(reference)
    assert sorted(got) == sorted(want)
    for kind in want:
        assert got[kind] == want[kind], kind


async def _publish_and_collect(url: str, table: pa.Table, rate: float, theta_tdc: float) -> list:
    nc = await nats.connect(url, connect_timeout=2)
    deadline = time.monotonic() + 20
    js = nc.jetstream()
    # The worker makes the fleet's streams and buckets; wait for the registry.
    while True:
        try:
            kv = await js.key_value("physid_cells")
            break
        except Exception:
            if time.monotonic() > deadline:
                raise
            await asyncio.sleep(0.2)
    cell, run = "py-daq", int(time.time() * 1000)
    info = {"cell": cell, "run": run, "rate_hz": rate, "source": "a Python DAQ (nats-py)",
            "theta_tdc": theta_tdc}
    await kv.put(cell, json.dumps(info).encode())
    subject = f"physid.cell.{cell}.samples"
    seq, first = 0, 0
    for batch in table.to_batches(max_chunksize=250):
        seq += 1
        await js.publish(subject, frame(batch, cell, run, seq, first, rate),
                         headers={"Nats-Msg-Id": f"{cell}/{run}/{seq}"})
        first += batch.num_rows
    seq += 1
    empty = pa.RecordBatch.from_pylist([], schema=table.schema)
    await js.publish(subject, frame(empty, cell, run, seq, first, rate, end=True),
                     headers={"Nats-Msg-Id": f"{cell}/{run}/{seq}"})
    # Every event of the cell, from the stream's start, until its end.
    sub = await js.subscribe(f"physid.cell.{cell}.events", ordered_consumer=True,
                             deliver_policy=nats.js.api.DeliverPolicy.ALL)
    events = []
    while not any(e["type"] == "end" for e in events):
        msg = await sub.next_msg(timeout=30)
        events.append(json.loads(msg.data))
    await nc.close()
    return events
