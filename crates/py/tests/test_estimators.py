"""The recursive estimators from Python against references that share no code with physid:
closed-form least squares (numpy), statsmodels' RecursiveLS, filterpy's Kalman filter and
UKF — the users' own tools — and physid's own command line on the same data."""
import json
import os
import subprocess

import numpy as np
import pytest

import physid


def data(n=400, seed=1, noise=0.1):
    rng = np.random.default_rng(seed)
    X = np.column_stack([rng.normal(size=n), rng.uniform(-2, 2, n)])
    y = X @ np.array([1.5, -0.7]) + rng.normal(0, noise, n)
    return X, y


def test_run_is_update_row_by_row():
    X, y = data()
    a, b = physid.RLSF(2, lam=0.99), physid.RLSF(2, lam=0.99)
    r = a.run(X, y)
    for i in range(len(y)):
        b.update(X[i], y[i])
        np.testing.assert_array_equal(b.estimate, r.theta[i])
    np.testing.assert_array_equal(b.std_err, r.std_err[-1])
    assert r.theta.shape == (400, 2) and r.std_err.shape == (400, 2) and r.skipped == []
    assert b.samples == 400 and r.names == ["theta0", "theta1"]


def test_rls_is_least_squares_and_rlsf_is_exponentially_weighted_least_squares():
    X, y = data()
    # A diffuse start: after every row the estimate is the least-squares fit of the rows so far.
    r = physid.RLS(2, p0=1e10).run(X, y)
    for k in (5, 50, 399):
        ls = np.linalg.lstsq(X[: k + 1], y[: k + 1], rcond=None)[0]
        np.testing.assert_allclose(r.theta[k], ls, rtol=1e-6)
    # Standard errors: sqrt(σ²·diag((XᵀX)⁻¹)) with σ² = RSS/(n − p).
    res = y - X @ r.theta[-1]
    s2 = res @ res / (len(y) - 2)
    se = np.sqrt(s2 * np.diag(np.linalg.inv(X.T @ X)))
    np.testing.assert_allclose(r.std_err[-1], se, rtol=0.02)
    # Forgetting: the weighted fit with weights λ^(k−i).
    lam = 0.95
    r = physid.RLSF(2, lam=lam, p0=1e10).run(X, y)
    w = lam ** np.arange(len(y) - 1, -1, -1)
    sw = np.sqrt(w)
    wls = np.linalg.lstsq(X * sw[:, None], y * sw, rcond=None)[0]
    np.testing.assert_allclose(r.theta[-1], wls, rtol=1e-6)


def test_dsfc_gives_rlsf_s_estimates():
    X, y = data()
    a = physid.RLSF(2, lam=0.98).run(X, y)
    b = physid.DSFC(2, lam=0.98).run(X, y)
    np.testing.assert_allclose(b.theta, a.theta, rtol=1e-8, atol=1e-10)


def test_rls_matches_statsmodels_recursive_ls():
    from statsmodels.regression.recursive_ls import RecursiveLS

    X, y = data(n=300, seed=4)
    res = RecursiveLS(y, X).fit()
    sm = np.asarray(res.recursive_coefficients.filtered).T  # n × p
    r = physid.RLS(2, p0=1e10).run(X, y)
    # After the diffuse part (p rows), the same estimates row by row.
    np.testing.assert_allclose(r.theta[5:], sm[5:], rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(r.theta[-1], res.params, rtol=1e-8)
    np.testing.assert_allclose(r.std_err[-1], res.bse, rtol=0.01)


def test_kalman_random_walk_matches_filterpy():
    from filterpy.kalman import KalmanFilter

    X, y = data(n=300, seed=5)
    r1, r2, p0 = 1e-4, 0.01, 10.0
    kf = KalmanFilter(dim_x=2, dim_z=1)
    kf.x = np.zeros((2, 1))
    kf.P = p0 * np.eye(2)
    kf.F = np.eye(2)
    kf.Q = r1 * np.eye(2)
    kf.R = np.array([[r2]])
    e = physid.KalmanRW(2, r1=r1, r2=r2, p0=p0)
    for i in range(len(y)):
        # Eq. 5.19 adds R1 after the measurement update: filterpy's update, then predict.
        kf.update(y[i], H=X[i].reshape(1, 2))
        kf.predict()
        e.update(X[i], y[i])
        np.testing.assert_allclose(e.estimate, kf.x.ravel(), rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(e.std_err, np.sqrt(np.diag(kf.P)), rtol=1e-9)


def test_ukf_matches_filterpy_on_a_model_non_linear_in_its_parameters():
    from filterpy.kalman import MerweScaledSigmaPoints, UnscentedKalmanFilter

    rng = np.random.default_rng(7)
    u = rng.uniform(-2, 2, 300)
    z = 2.0 * np.exp(-0.5 * u) + 0.5 * u ** 2 + rng.normal(0, 0.05, 300)
    expr = "A*exp(-B*u) + C*u^2"
    start = {"A": 1.0, "B": 0.3, "C": 1.0}
    ukf = physid.UKF(expr, start, p0=1.0, r2=0.05 ** 2)
    assert ukf.inputs == ["u"]
    points = MerweScaledSigmaPoints(n=3, alpha=1.0, beta=2.0, kappa=0.0)  # κ = 3 − l
    ref = UnscentedKalmanFilter(
        dim_x=3, dim_z=1, dt=1.0, points=points,
        fx=lambda x, dt: x,
        hx=lambda x, u: np.array([x[0] * np.exp(-x[1] * u) + x[2] * u ** 2]),
    )
    ref.x = np.array(list(start.values()))
    ref.P = np.eye(3)
    ref.Q = np.zeros((3, 3))
    ref.R = np.array([[0.05 ** 2]])
    r = ukf.run(u[:, None], z)
    track = []
    for i in range(len(u)):
        ref.predict()
        ref.update(z[i], u=u[i])
        track.append(ref.x.copy())
    np.testing.assert_allclose(r.theta, np.array(track), rtol=1e-7, atol=1e-9)
    np.testing.assert_allclose(r.estimate, [2.0, 0.5, 0.5], rtol=0.02)


def test_ekf_and_srukf_recover_the_parameters():
    rng = np.random.default_rng(8)
    u = rng.uniform(-2, 2, 500)
    z = 2.0 * np.sin(u) + 0.5 * u ** 2 + rng.normal(0, 0.01, 500)
    for cls in (physid.EKF, physid.SRUKF):
        e = cls("A*sin(u) + B*u^2", {"A": 1.0, "B": 1.0}, r2=1e-4)
        np.testing.assert_allclose(e.run(u[:, None], z).estimate, [2.0, 0.5], rtol=1e-2)


def test_bad_input_is_refused_naming_what_and_where():
    X, y = data(n=20)
    e = physid.RLS(2)
    with pytest.raises(physid.Error, match="not finite"):
        e.update([1.0, np.nan], 1.0)
    assert e.samples == 0  # the refused sample left it as it was
    Xb = X.copy()
    Xb[7, 1] = np.inf
    with pytest.raises(physid.Error, match="row 7"):
        physid.RLS(2).run(Xb, y)
    r = physid.RLS(2).run(Xb, y, skip_bad=True)
    assert r.skipped == [7]
    np.testing.assert_array_equal(r.theta[7], r.theta[6])
    with pytest.raises(physid.Error, match="3 columns for 2 inputs"):
        e.run(np.ones((4, 3)), np.ones(4))
    with pytest.raises(physid.Error, match="2-D"):
        e.run(np.ones(4), np.ones(4))
    with pytest.raises(physid.Error, match="rows"):
        e.run(np.ones((4, 2)), np.ones(5))
    with pytest.raises(physid.Error, match="dtype"):
        e.run(np.array([["a", "b"]]), np.ones(1))
    with pytest.raises(physid.Error, match="outside"):
        physid.RLSF(2, lam=1.5)
    with pytest.raises(physid.Error):
        physid.EKF("A*sin(u", {"A": 1.0})
    # Integers and non-contiguous (Fortran-ordered, strided) arrays are taken as they are.
    Xf = np.asfortranarray(X)
    np.testing.assert_array_equal(physid.RLS(2).run(Xf, y).theta, physid.RLS(2).run(X, y).theta)
    strided = np.column_stack([X[:, 0], np.zeros(20), X[:, 1]])[:, ::2]
    np.testing.assert_array_equal(physid.RLS(2).run(strided, y).theta,
                                  physid.RLS(2).run(X, y).theta)
    physid.RLS(2).run(np.ones((3, 2), dtype=np.int32), np.arange(3))


@pytest.mark.skipif(not os.environ.get("PHYSID_BIN"), reason="PHYSID_BIN (physid's binary) not given")
def test_the_same_estimates_as_physid_estimate(tmp_path):
    X, y = data(n=500, seed=9)
    f = tmp_path / "d.csv"
    np.savetxt(f, np.column_stack([np.arange(500) * 1e-3, X, y]), delimiter=",",
               header="t,a,b,y", comments="")
    out = subprocess.run(
        [os.environ["PHYSID_BIN"], "estimate", "--data", str(f), "--y", "y", "--phi", "a,b",
         "--method", "rlsf", "--lambda", "0.98", "--json"],
        check=True, capture_output=True, text=True).stdout
    j = json.loads(out)
    r = physid.RLSF(["a", "b"], lam=0.98).run(X, y)
    np.testing.assert_allclose([j["params"]["a"], j["params"]["b"]], r.estimate, rtol=1e-12)


def _step_paths_script(p):
    """A script printing the estimates and standard errors of each linear method at `p` (hex of
    their bytes): the same in this process and in one whose step is told to stay off AVX2."""
    return f"""
import numpy as np, physid
rng = np.random.default_rng({p})
X = rng.uniform(-1, 1, size=(300, {p}))
y = X @ np.arange(1.0, {p} + 1) + 0.01 * rng.normal(size=300)
for e in (physid.RLS({p}), physid.RLSF({p}, lam=0.97), physid.DSFC({p}, lam=0.97),
          physid.KalmanRW({p}, r1=1e-6, r2=1e-4)):
    r = e.run(X, y)
    print(r.theta.tobytes().hex(), r.std_err.tobytes().hex())
"""


@pytest.mark.parametrize("p", [3, 5, 8, 20, 23])
def test_the_avx2_step_and_the_portable_step_give_the_same_digits(p):
    """The wheel is built for x86-64-v2 and carries a second copy of the linear step compiled
    for AVX2, chosen at run time where the CPU has it (physid_estim's `linear/lanes.rs`):
    every estimate and standard error of RLS, RLSF, DSFC and the Kalman filter, over 300 rows,
    bit for bit the same as the SSE2 step's (`PHYSID_DISABLE_CPU_FEATURES=AVX2`): the copy
    runs from p = 8 (whole and partial blocks of four lanes at 8, 20, 23; 23 beyond the sizes
    compiled for their own p); at 3 and 5 both are the SSE2 step."""
    import sys
    run = lambda env: subprocess.run([sys.executable, "-c", _step_paths_script(p)], check=True,
                                     capture_output=True, text=True, env=env).stdout
    default = run(dict(os.environ))
    portable = run({**os.environ, "PHYSID_DISABLE_CPU_FEATURES": "AVX2"})
    assert default.count("\n") == 4 and default == portable


@pytest.mark.skipif(not os.environ.get("PHYSID_BIN"), reason="PHYSID_BIN (physid's binary) not given")
@pytest.mark.parametrize("method", ["rlsf", "dsfc"])
def test_the_wheel_and_the_native_binary_give_the_same_digits_at_p_20(tmp_path, method):
    """The wheel (x86-64-v2, its AVX2 step where the CPU has it) and physid's binary built for
    the building machine (`target-cpu=native`): the same estimates at p = 20, bit for bit —
    the kernels' lanes and sums are in an order written out, the same on every CPU."""
    p, n = 20, 500
    rng = np.random.default_rng(20)
    X = rng.uniform(-1, 1, size=(n, p))
    y = X @ np.arange(1.0, p + 1) + 0.01 * rng.normal(size=n)
    names = [f"x{i}" for i in range(p)]
    f = tmp_path / "d.csv"
    np.savetxt(f, np.column_stack([np.arange(n) * 1e-3, X, y]), delimiter=",",
               header=",".join(["t", *names, "y"]), comments="")
    j = json.loads(subprocess.run(
        [os.environ["PHYSID_BIN"], "estimate", "--data", str(f), "--y", "y", "--phi",
         ",".join(names), "--method", method, "--lambda", "0.98", "--json"],
        check=True, capture_output=True, text=True).stdout)
    cls = physid.RLSF if method == "rlsf" else physid.DSFC
    r = cls(names, lam=0.98).run(X, y)
    assert [j["params"][k] for k in names] == r.estimate.tolist()
