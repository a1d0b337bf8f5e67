"""Recordings: read, channels as float64 arrays with units; written by physid, read by
pandas, pyarrow and asammdf (the users' own tools) and back."""
import numpy as np
import pandas as pd
import pyarrow.parquet as pq
import pytest

import physid

MOTORED = "crates/apps/tests/golden/motored_deg.parquet"


def test_read_gives_float64_channels_units_and_basis(golden):
    rec = physid.read(golden(MOTORED))
    assert rec.channels == ["t", "cycle", "crank_deg", "p_cyl"]
    assert rec.basis == "crank_angle"
    assert rec.units["p_cyl"] == "Pa" and rec.units["crank_deg"] == "deg"
    p = rec["p_cyl"]
    assert p.dtype == np.float64 and p.shape == (len(rec),) and len(rec) == 8640
    # The same numbers pyarrow reads.
    np.testing.assert_array_equal(p, pq.read_table(golden(MOTORED))["p_cyl"].to_numpy())
    np.testing.assert_array_equal(rec.t, rec["t"])
    assert "p_cyl" in rec and "nope" not in rec


def test_a_selection_a_map_and_a_calibration(golden, tmp_path):
    f = tmp_path / "lab.csv"
    f.write_text("time,P\ns,V\n0,1.5\n0.001,2.0\n")
    rec = physid.read(f, map={"t": "time", "p_cyl": "P:V"}, scale={"p_cyl": (1e5, 0.0)})
    assert rec.channels == ["t", "p_cyl"]
    np.testing.assert_allclose(rec["p_cyl"], [1.5e5, 2.0e5])
    assert rec.units["p_cyl"] == "Pa"
    only = physid.read(golden(MOTORED), channels=["t", "p_cyl"])
    assert only.channels == ["t", "p_cyl"]


def test_written_by_physid_read_by_pandas_pyarrow_and_asammdf(golden, tmp_path):
    from asammdf import MDF

    rec = physid.read(golden(MOTORED), channels=["t", "p_cyl"])
    p = rec["p_cyl"]
    csv, parquet, mf4 = tmp_path / "r.csv", tmp_path / "r.parquet", tmp_path / "r.mf4"
    for f in (csv, parquet, mf4):
        rec.write(f)
    np.testing.assert_allclose(pd.read_csv(csv, skiprows=[1])["p_cyl"].to_numpy(), p, rtol=1e-12)
    np.testing.assert_array_equal(pq.read_table(parquet)["p_cyl"].to_numpy(), p)
    with MDF(mf4) as m:
        np.testing.assert_array_equal(m.get("p_cyl").samples, p)
        assert m.get("p_cyl").unit == "Pa"
    # And back.
    for f in (csv, parquet, mf4):
        np.testing.assert_allclose(physid.read(f)["p_cyl"], p, rtol=1e-12)


def test_to_pandas_and_from_pandas(golden):
    rec = physid.read(golden(MOTORED))
    df = rec.to_pandas()
    assert df.index.name == "t" and list(df.columns) == rec.channels[1:]
    assert df.attrs["units"]["p_cyl"] == "Pa"
    back = physid.Recording.from_pandas(df)
    assert back.channels == rec.channels
    assert back.basis == "crank_angle"
    np.testing.assert_array_equal(back["p_cyl"], rec["p_cyl"])


def test_a_recording_from_arrays():
    rec = physid.Recording([("t", np.arange(3) * 0.1), ("x", [1.0, 2.0, 3.0])], units={"t": "s"})
    assert rec.units == {"t": "s", "x": ""} and len(rec) == 3
    with pytest.raises(physid.Error, match="basis"):
        physid.Recording([("t", [0.0])], basis="sideways")
    with pytest.raises(physid.Error):
        physid.Recording([("t", [0.0, 1.0]), ("x", [1.0])])


def test_bad_input_names_what_is_wrong(tmp_path):
    with pytest.raises(physid.Error, match="nope.csv"):
        physid.read(tmp_path / "nope.csv")
    bad = tmp_path / "bad.csv"
    bad.write_text("t,x\n0,1\n0.1,abc\n")
    with pytest.raises(physid.Error, match="line 3"):
        physid.read(bad)
    rec = physid.Recording([("t", [0.0, 1.0])])
    with pytest.raises(KeyError, match="the channels are: t"):
        rec["x"]
    assert isinstance(physid.Error("x"), ValueError)


WHEEL = "crates/signal/tests/golden/wheel_vr_60m3.parquet"
QUADRATURE = "crates/signal/tests/golden/quadrature_500.parquet"
PULSES = "crates/signal/tests/golden/pulse_encoder_360.parquet"


def _cycle_starts(rec, period_deg):
    """The true angle [deg, modulo `period_deg`] of every sample at crank_deg 0 — the golden
    files' `theta_true` [µrad], made by numpy (crates/signal/tests/golden/gen_wheels.py), not
    by physid."""
    at = rec["crank_deg"] == 0.0
    return np.mod(np.degrees(rec["theta_true"][at] * 1e-6), period_deg)


def test_a_raw_trigger_wheel_is_read_on_a_crank_angle_basis(golden):
    """A 60−3 inductive pickup's raw signal decoded in Python as `convert --crank-angle
    --wheel` decodes it: every cycle starts at the same true angle (within 0.05°), 117–120°
    after the reference tooth's centre, in the revolution of the compression (from p_cyl)."""
    rec = physid.read(golden(WHEEL), wheel="enc=60-3", tdc_offset=117, phase_from="p_cyl")
    assert rec.basis == "crank_angle"
    assert {"cycle", "crank_deg", "t", "p_cyl"} <= set(rec.channels)
    assert "wheel 60-3 decoded" in rec.meta["angle"], rec.meta
    starts = _cycle_starts(rec, 720.0)
    assert len(starts) >= 12
    assert starts.max() - starts.min() < 0.05, starts
    assert 117.0 < starts.min() and starts.max() <= 120.0, starts
    # A finer step: the same cycles, ten samples per degree.
    fine = physid.read(golden(WHEEL), wheel="enc=60-3", tdc_offset=117, phase_from="p_cyl",
                       step_deg=0.1, channels=["p_cyl", "theta_true"])
    assert np.allclose(np.diff(fine["crank_deg"][:50]), 0.1)
    assert len(_cycle_starts(fine, 720.0)) == len(starts)


def test_a_raw_quadrature_encoder_is_read_on_a_crank_angle_basis(golden):
    """A 500-line quadrature encoder's A/B/Z: every cycle starts 90° after the index (the true
    angle within 0.1°), as `convert --crank-angle --quadrature` gives."""
    rec = physid.read(golden(QUADRATURE), quadrature="enc_a,enc_b,enc_z=500", tdc_offset=90)
    assert "quadrature encoder of 500 lines decoded" in rec.meta["angle"], rec.meta
    starts = _cycle_starts(rec, 360.0)
    assert len(starts) > 0
    assert np.all(np.abs(starts - 90.0) < 0.1), starts


def test_a_raw_pulse_encoder_with_its_index_is_read_on_a_crank_angle_basis(golden):
    """A 360-pulse analog encoder with an analog index: every revolution starts 30° after the
    first edge after the index (1° on the wheel), the true angle within 0.05°, as `convert
    --crank-angle --encoder-raw enc=360 --index-raw idx` gives."""
    rec = physid.read(golden(PULSES), encoder_raw="enc=360", index_raw="idx", tdc_offset=30)
    assert "encoder of 360 pulses with the index 'idx' decoded" in rec.meta["angle"], rec.meta
    starts = _cycle_starts(rec, 360.0)
    assert len(starts) > 5
    assert np.all(np.abs(starts - 31.0) < 0.05), starts
    with pytest.raises(physid.Error, match="go together"):
        physid.read(golden(PULSES), encoder_raw="enc=360")


def test_a_bad_angle_sensor_is_named(golden):
    for kwargs, says in [
        ({"wheel": "enc=60"}, "wheel '60': expected N-M"),
        ({"wheel": "enc"}, "wheel 'enc': expected CHANNEL=N-M"),
        ({"quadrature": "enc_a=500"}, "quadrature 'enc_a=500': expected A,B,Z=LINES"),
        ({"wheel": "enc=60-3", "tdc_offset": 400}, r"tdc_offset 400: expected an angle in \[0, 360\)"),
        ({"wheel": "enc=60-3", "edge": "up"}, "edge 'up': expected rising or falling"),
        ({"wheel": "enc=60-3", "tdc_from": "p_cyl"}, "tdc_from 'p_cyl' needs the crank's lengths"),
        ({"wheel": "enc=60-3", "step_deg": 0}, "step_deg 0"),
        ({"encoders": ["count_en"]}, "encoder 'count_en': expected CHANNEL=PPR"),
    ]:
        with pytest.raises(physid.Error, match=says):
            physid.read(golden(WHEEL), **kwargs)
