"""The package as a Python user expects it (issue 40, item 6): the documented constructors,
copies and pickles that are independent and continue exactly, pandas in (nullable columns)
and out (indexed by time), errors that name what is wrong, one thread per estimator, the
innovation of each update, reset, and a wheel that runs on any x86-64-v2 machine."""
import copy
import pickle
import shutil
import subprocess
import threading
import time

import numpy as np
import pandas as pd
import pytest

import physid


def data(n=300, seed=4):
    rng = np.random.default_rng(seed)
    X = np.column_stack([rng.normal(size=n), rng.uniform(-2, 2, n)])
    y = X @ np.array([1.5, -0.7]) + rng.normal(0, 0.1, n)
    return X, y


def test_a_recording_from_a_dict_as_documented():
    rec = physid.Recording({"t": np.arange(3.0), "x": [1, 2, 3]}, units={"t": "s"})
    assert rec.channels == ["t", "x"] and rec.units == {"t": "s", "x": ""}
    np.testing.assert_array_equal(rec["x"], [1.0, 2.0, 3.0])
    with pytest.raises(physid.Error, match="channel 'x'"):
        physid.Recording({"t": [0.0, 1.0], "x": ["a", "b"]})
    with pytest.raises(physid.Error, match=r"channel 'x'.*shape \(2, 2\)"):
        physid.Recording({"x": np.ones((2, 2))})


def test_strided_arrays_and_pandas_nullable_columns_are_taken():
    base = np.arange(10.0)
    rec = physid.Recording({"t": base[::2], "x": base[1::2]})
    np.testing.assert_array_equal(rec["x"], [1.0, 3.0, 5.0, 7.0, 9.0])
    s = pd.Series([1.0, None, 3.0], dtype="Float64")
    rec = physid.Recording({"t": pd.Series([0, 1, 2], dtype="Int64"), "x": s})
    assert np.isnan(rec["x"][1]) and rec["x"][2] == 3.0 and rec["t"].dtype == np.float64
    # The estimators take the same columns.
    X, y = data(50)
    df = pd.DataFrame({"a": X[:, 0], "b": X[:, 1], "y": y}).astype("Float64")
    r = physid.RLS(["a", "b"]).run(df[["a", "b"]], df["y"])
    np.testing.assert_array_equal(r.theta, physid.RLS(["a", "b"]).run(X, y).theta)


def test_to_pandas_is_indexed_by_time_and_comes_back():
    rec = physid.simulate("shaft-steady", duration=0.01)
    df = rec.to_pandas()
    assert df.index.name == "t" and "t" not in df.columns
    np.testing.assert_array_equal(df.index.to_numpy(), rec.t)
    back = physid.Recording.from_pandas(df)
    assert back.channels == rec.channels
    for c in rec.channels:
        np.testing.assert_array_equal(back[c], rec[c])
    X, y = data(len(rec))
    run = physid.RLS(["K", "B"]).run(X, y)
    rd = run.to_pandas(t=rec.t)
    assert list(rd.columns) == ["K", "B", "K_std_err", "B_std_err", "error"]
    assert rd.index.name == "t" and rd["K"].iloc[-1] == run.estimate[0]
    assert run.to_pandas().index[-1] == len(rec) - 1
    with pytest.raises(physid.Error, match="t has 3 values"):
        run.to_pandas(t=[0.0, 1.0, 2.0])


@pytest.mark.parametrize("make", [
    lambda: physid.RLSF(["K", "B"], lam=0.99),
    lambda: physid.DSFC(2),
    lambda: physid.KalmanRW(2, r1=1e-6, r2=0.01),
    lambda: physid.UKF("K*x + B*y", {"K": 1.0, "B": 0.0}, r2=0.01),
    lambda: physid.EKF("K*x + B*y", {"K": 1.0, "B": 0.0}, r2=0.01),
    lambda: physid.SRUKF("K*x + B*y", {"K": 1.0, "B": 0.0}, r2=0.01),
])
def test_copies_and_pickles_are_independent_and_continue_exactly(make):
    X, y = data()
    est = make()
    for i in range(100):
        est.update(X[i], y[i])
    shallow, deep = copy.copy(est), copy.deepcopy(est)
    pickled = pickle.loads(pickle.dumps(est))
    assert type(pickled) is type(est) and pickled.names == est.names
    assert pickled.method == est.method
    rest = est.run(X[100:], y[100:])
    for other in (shallow, deep, pickled):
        assert other.samples == 100  # untouched by the original's run
        r = other.run(X[100:], y[100:])
        np.testing.assert_array_equal(r.theta, rest.theta)
        np.testing.assert_array_equal(r.std_err, rest.std_err)
        np.testing.assert_array_equal(other.covariance, est.covariance)


def test_a_recording_copies_and_pickles():
    rec = physid.simulate("shaft-steady", duration=0.005)
    for other in (copy.copy(rec), copy.deepcopy(rec), pickle.loads(pickle.dumps(rec))):
        assert other.channels == rec.channels and other.units == rec.units
        assert other.basis == rec.basis and other.meta == rec.meta
        np.testing.assert_array_equal(other["omega_en"], rec["omega_en"])


def test_a_pickle_that_is_not_an_estimator_is_refused():
    with pytest.raises(physid.Error, match="not a pickled physid estimator"):
        physid._physid._estimator(b"\x93\x01\x02")


def test_update_gives_the_innovation_and_reset_starts_again():
    X, y = data()
    est = physid.RLS(2)
    first = est.update(X[0], y[0])
    # The first update of RLS from ϑ = 0, P = 1000·I: e = y, Var(e) = 1 + φᵀPφ (units of σ²).
    assert float(first) == first.error == y[0]
    assert first.variance == pytest.approx(1 + 1000 * X[0] @ X[0], rel=1e-12)
    assert first.standardized == pytest.approx(y[0] / np.sqrt(first.variance), rel=1e-12)
    assert -first == -y[0]  # still a number
    for i in range(1, 50):
        est.update(X[i], y[i])
    est.reset()
    assert est.samples == 0 and list(est.estimate) == [0.0, 0.0]
    again = est.update(X[0], y[0])
    assert again == first and again.variance == first.variance
    # The filters' innovation variance is absolute: R2 + JPJᵀ at the first sample (EKF).
    ekf = physid.EKF("K*x", {"K": 2.0}, p0=10.0, r2=0.5)
    inn = ekf.update([3.0], 1.0)
    assert inn == pytest.approx(1.0 - 6.0) and inn.variance == pytest.approx(0.5 + 9 * 10.0)


def test_errors_name_what_is_wrong():
    X, y = data()
    with pytest.raises(physid.Error, match="p=2.0: expected the number of parameters"):
        physid.RLS(2.0)
    with pytest.raises(physid.Error, match="a text is not split into names"):
        physid.RLS("KB")
    with pytest.raises(physid.Error, match="names='KB'"):
        physid.RLS(2, names="KB")
    data_ = {"x": X[:, 0], "z": X[:, 1], "out": y}
    with pytest.raises(physid.Error, match="y: the channel 'nope' is not in the data; the data "
                                           "have: x, z, out"):
        physid.identify("K*x", {"K": 1.0}, data_, y="nope")
    with pytest.raises(physid.Error, match="input 'w' is not in the data; the data have: x, z"):
        physid.identify("K*x + B*w", {"K": 1.0, "B": 1.0}, data_)
    # y as an array (the crash of `k != y` on an array).
    x = X[:, 0]
    r = physid.identify("K*x", {"K": 1.0}, {"x": x}, y=1.5 * x + 0.1 * X[:, 1])
    k_ls = np.linalg.lstsq(x[:, None], 1.5 * x + 0.1 * X[:, 1], rcond=None)[0][0]
    assert r.estimable == ["K"] and r.values["K"] == pytest.approx(k_ls, rel=1e-9)


def test_arguments_out_of_reason_are_refused_not_a_crash():
    """Found by driving every function with extreme and mistyped arguments: each was a panic,
    an abort of the interpreter, a hang, a MemoryError after seconds, an AttributeError or a
    message of 300 digits."""
    # A formula with no parameter: nalgebra's decomposition of the empty covariance panicked.
    for cls in (physid.EKF, physid.UKF, physid.SRUKF):
        with pytest.raises(physid.Error, match="no free parameter: nothing to estimate"):
            cls("sin(x)", {})
    # 2⁶³ parameters: a list of 2⁶³ names until the memory ran out.
    with pytest.raises(physid.Error, match="at most 100000 parameters"):
        physid.RLS(2**63)
    # 10⁵ named parameters: an 80 GB covariance aborted the interpreter.
    with pytest.raises(physid.Error, match="would take about 320.000 GB"):
        physid.RLS([f"k{i}" for i in range(100_000)])
    # A list where a mapping goes.
    for call in (lambda: physid.simulate("shaft-steady", duration=0.1, set=[1, 2]),
                 lambda: physid.identify("A*x", [1, 2], {"x": np.ones(3)}),
                 lambda: physid.identify("A*x", {"A": 1.0}, [1, 2]),
                 lambda: physid.EKF("A*x", [1, 2])):
        with pytest.raises(TypeError, match="expected a mapping such as"):
            call()
    # A complex channel lost its imaginary part, with a warning only.
    with pytest.raises(physid.Error, match="complex numbers: their imaginary parts would be"):
        physid.Recording({"t": np.arange(3.0), "a": np.array([1 + 1j, 2, 3])})
    # λ = 10³⁰⁰ is said as 1e300.
    with pytest.raises(physid.Error, match=r"λ = 1e300 is outside \(0, 1\]"):
        physid.RLSF(2, lam=1e300)
    # A duration of 10⁻³⁰⁰ s: its hundredths never moved the run's time, which looped for ever.
    r = physid.simulate("shaft-steady", duration=1e-300)
    assert len(r) <= 2 and r.t[0] == 0.0


def test_whole_numbers_and_crank_angle_options_are_checked(tmp_path):
    """A count beyond its native type was PyO3's OverflowError naming no argument; a float was
    cut (``cylinders=4.7`` taken as 4). A crank-angle option given to a time-basis reading was
    ignored, and ``phase_from`` with ``theta_en`` (as ``physid convert --phase-from``) was
    refused as needing a raw sensor."""
    f = tmp_path / "r.parquet"
    physid.simulate("shaft-steady", duration=0.5).write(f)
    crank = physid.read(f, crank_angle=True)
    with pytest.raises(physid.Error, match=r"cylinders = 1099511627776: expected a whole number "
                                           r"from 0 to 4294967295"):
        physid.cycles(crank, cylinders=2**40)
    with pytest.raises(physid.Error, match="cylinders = 4.7: expected a whole number"):
        physid.cycles(crank, cylinders=4.7)
    with pytest.raises(TypeError, match="cylinders: expected a whole number, got the bool"):
        physid.cycles(crank, cylinders=True)
    with pytest.raises(physid.Error, match="seed = -1: expected a whole number"):
        physid.design("shaft", ["K"], seed=-1)
    with pytest.raises(physid.Error, match=r"dwell = 1.84e\+19: expected a whole number"):
        physid.monitor_shaft(physid.read(f), dwell=2**64)
    for given in ({"phase_from": "p_cyl"}, {"step_deg": 2.0}, {"marker": "tdc"},
                  {"tdc_offset": 5.0}, {"stroke": 0.09}):
        name = next(iter(given))
        with pytest.raises(physid.Error, match=f"{name}: for a crank-angle reading — add "
                                               f"crank_angle=True"):
            physid.read(f, **given)
    # With theta_en: which revolution fires, told from p_cyl, or the first TDC taken.
    told = physid.read(f, crank_angle=True, phase_from="p_cyl")
    first = physid.read(f, crank_angle=True, phase_from="none")
    assert np.array_equal(told["p_cyl"], crank["p_cyl"])
    assert len(first) > 0
    # The crank's lengths without tdc_from were ignored; a recording shorter than its first
    # cycle gave an empty recording.
    with pytest.raises(physid.Error, match="stroke and rod are for placing the TDC"):
        physid.read(f, crank_angle=True, stroke=0.09, rod=0.15)
    short = tmp_path / "short.parquet"
    physid.simulate("shaft-steady", duration=0.05).write(short)
    with pytest.raises(physid.Error, match="no sample on a crank-angle basis: the recording "
                                           "ends before its first firing TDC"):
        physid.read(short, crank_angle=True)


def test_an_estimator_used_by_two_threads_at_once_says_so():
    rng = np.random.default_rng(0)
    X, y = rng.normal(size=(400_000, 20)), rng.normal(size=400_000)
    est = physid.RLS(20)
    worker = threading.Thread(target=lambda: est.run(X, y, std_err=False))
    worker.start()
    refused, deadline = 0, time.monotonic() + 60
    while worker.is_alive() and time.monotonic() < deadline:
        try:
            est.update(X[0], y[0])
        except physid.Error as e:
            assert "in use by another thread" in str(e)
            refused += 1
        time.sleep(0.001)
    worker.join()
    assert refused > 0, "the run ended before a second call could meet it"
    assert est.samples >= 400_000


def test_the_package_shows_its_own_names():
    names = dir(physid)
    for private in ("np", "json", "re", "Any", "dataclass"):
        assert private not in names
    for public in ("RLS", "Recording", "identify", "Innovation", "Error", "__version__"):
        assert public in names


def test_the_wheel_runs_on_any_x86_64_v2_machine():
    """The wheel is built for x86-64-v2 (crates/py/.cargo/config.toml), not for the building
    machine's CPU: an AVX instruction (a ymm register) appears only in the functions chosen at
    run time after asking the CPU — the dependencies' (memchr's `*_avx2`, matrixmultiply's
    `kernel_target_avx`/`_fma`, zlib-rs's `avx2`) and physid's linear step's AVX2 copy
    (`step_dim_avx2`, physid_estim's `linear/lanes.rs`)."""
    import re

    objdump = shutil.which("objdump")
    if objdump is None:
        pytest.skip("objdump (binutils) not installed")
    so = physid._physid.__file__
    out = subprocess.run([objdump, "-d", "--no-show-raw-insn", so], capture_output=True,
                         text=True, check=True).stdout
    function, unchecked = "", {}
    for line in out.splitlines():
        m = re.match(r"^[0-9a-f]+ <(.*)>:$", line)
        if m:
            function = m.group(1)
        elif "%ymm" in line and not re.search(r"avx|fma", function, re.I):
            unchecked[function] = unchecked.get(function, 0) + 1
    assert not unchecked, f"AVX outside a run-time-dispatched function: {list(unchecked)[:5]}"
