"""Identifiability from Python against the thesis's Example 5.1 and statsmodels' OLS; the
virtual test cell from Python."""
import numpy as np
import pytest

import physid

EX51 = "sin(A)*x + B^2*y*cos(x) + sqrt(C)*x^2 + D*y^2 + E*x/y + F*2*x/y"
NOMINAL = {"A": 1.0, "B": 2.0, "C": 3.0, "D": 4.0, "E": 5.0, "F": 6.0}


def example_5_1(seed=3):
    """The inputs physid's Example 5.1 documents (crates/apps/src/example_5_1.rs), made here."""
    rng = np.random.default_rng(seed)
    t = np.arange(2000) / 100.0
    x = 30 * np.sin(0.7 * t) + rng.normal(size=t.size)
    y = 30 + 3 * np.cos(0.45 * t) + rng.normal(size=t.size)
    return {"x": x, "y": y}


def test_example_5_1_ranks_as_the_thesis_and_e_is_not_identifiable():
    r = physid.identify(EX51, NOMINAL, example_5_1())
    # Thesis Example 5.1: D, C, B, A, F estimable in that order; E's sensitivity x/y is half of
    # F's 2x/y, so E is not.
    assert r.estimable == ["D", "C", "B", "A", "F"]
    assert r.unidentifiable == ["E"]
    assert r.ranking[-1] == "E" and r.relative[-1] < 1e-20
    assert r.report["rows"] == 2000
    assert set(r.to_dict()) >= {"ranking", "unidentifiable", "rows"}


def test_the_fit_and_its_precision_equal_statsmodels_ols():
    import statsmodels.api as sm

    rng = np.random.default_rng(12)
    u, v = rng.normal(size=300), rng.uniform(0, 5, 300)
    z = 2.0 * u - 0.5 * v + 1.2 + rng.normal(0, 0.3, 300)
    r = physid.identify("a*u + b*v + c", {"a": 1.0, "b": 1.0, "c": 1.0}, {"u": u, "v": v, "z": z},
                        y="z")
    ols = sm.OLS(z, np.column_stack([u, v, np.ones(300)])).fit()
    for k, name in enumerate("abc"):
        assert r.values[name] == pytest.approx(ols.params[k], rel=1e-8)
        assert r.std_err[name] == pytest.approx(ols.bse[k], rel=1e-6)
        lo, hi = ols.conf_int()[k]
        assert r.ci95[name] == pytest.approx((lo, hi), rel=1e-6)


def test_identify_takes_a_recording_and_names_a_missing_input(golden):
    rec = physid.Recording([("x", np.linspace(1, 2, 50)), ("y", np.linspace(2, 3, 50))])
    r = physid.identify("A*x + B*y", {"A": 1.0, "B": 1.0}, rec)
    assert sorted(r.ranking) == ["A", "B"]
    with pytest.raises(physid.Error, match="input 'w'"):
        physid.identify("A*w", {"A": 1.0}, rec)
    bad = {"x": np.array([1.0, np.nan, 3.0])}
    with pytest.raises(physid.Error, match="row 1"):
        physid.identify("A*x", {"A": 1.0}, bad)
    with pytest.raises(physid.Error, match="scaling"):
        physid.identify("A*x", {"A": 1.0}, {"x": np.ones(3)}, scaling="odd")


def test_simulate_gives_the_virtual_cell_s_recording():
    rec = physid.simulate("shaft-steady", duration=1.0, set={"shaft.k": 1340.0})
    assert rec.basis == "time" and len(rec) == 10001
    assert {"t", "theta_en", "theta_dy", "omega_en", "torque_shaft", "true_shaft_k"} <= set(rec.channels)
    np.testing.assert_allclose(rec["true_shaft_k"], 1340.0)
    np.testing.assert_allclose(np.diff(rec.t), 1e-4, rtol=1e-9)
    f = physid.simulate("shaft-steady", duration=2.0, faults=["shaft.k=1000@1"], rate=1000.0)
    k = f["true_shaft_k"]
    assert k[0] != 1000.0 and k[-1] == 1000.0 and len(f) == 2001
    crank = physid.simulate("shaft-steady", duration=1.0, basis="crank_angle")
    assert crank.basis == "crank_angle" and "crank_deg" in crank
    with pytest.raises(physid.Error, match="built-in scenario"):
        physid.simulate("no-such-scenario")
    with pytest.raises(physid.Error):
        physid.simulate("shaft-steady", faults=["nonsense"])


def test_the_shaft_stiffness_is_tracked_from_a_simulated_run():
    """The walk-through of docs/python.md: a shaft run, RLSF on Eq. 6.1's regressor."""
    rec = physid.simulate("shaft-steady", duration=4.0)
    phi = np.column_stack([rec["theta_dy"] - rec["theta_en"], rec["omega_dy"] - rec["omega_en"]])
    r = physid.RLSF(["K", "B"], lam=0.9995).run(phi, rec["torque_shaft"])
    k_true = rec["true_shaft_k"][-1]
    assert r.estimate[0] == pytest.approx(k_true, rel=0.05)
