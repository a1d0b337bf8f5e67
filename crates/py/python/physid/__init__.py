"""physid from Python: qualitative adaptive identification for powertrains.

physid's own library (Rust, through the extension module ``physid._physid``), with numpy
arrays in and out:

* :func:`read` a recording (CSV, text, Parquet, MDF4) into a :class:`Recording`; write one
  with :meth:`Recording.write`; :meth:`Recording.to_pandas`.
* The recursive estimators of the thesis's §5.3: :class:`RLS` (Alg. 5.2), :class:`RLSF`
  (Alg. 5.3), :class:`DSFC` (Alg. 5.5), :class:`KalmanRW` (Eq. 5.19) for models linear in
  their parameters ``y = φᵀϑ + ε`` (Eq. 5.14); :class:`EKF` (Alg. 5.6), :class:`UKF` and
  :class:`SRUKF` (Alg. 5.7) over a formula model ``y = h(u, ϑ)``. ``update`` takes one
  sample, ``run`` whole arrays (without the GIL) and returns the estimate and standard-error
  tracks.
* :func:`identify`: which parameters the data can resolve (Alg. 5.1, Eq. 5.9–5.13).
* :func:`simulate`: the virtual test cell.

Errors are :class:`Error` (a ``ValueError``) carrying physid's message: the file, the
channel, the sample or row.

Recordings and estimators copy (``copy.copy``, ``copy.deepcopy``: independent copies) and
pickle (``pickle``, ``joblib``, ``multiprocessing``). An estimator is for one thread at a
time: a second thread calling it while ``run`` works raises :class:`Error` (give each thread
its own copy).
"""
from __future__ import annotations

import json as _json
import re as _re
from dataclasses import dataclass, field
from typing import Any, Iterable, Mapping, Sequence

import numpy as np

from . import _physid
from ._physid import Error, Recording

__version__ = _physid.__version__

__all__ = [
    "Error",
    "Innovation",
    "Recording",
    "read",
    "RLS",
    "RLSF",
    "DSFC",
    "KalmanRW",
    "EKF",
    "UKF",
    "SRUKF",
    "Run",
    "identify",
    "Identification",
    "simulate",
]


def _mapping(name: str, x: Any) -> Mapping:
    """``x`` as a mapping (``None``: an empty one); anything else is refused with a
    :class:`TypeError` naming the argument (a list used to end in an ``AttributeError`` on
    ``.items``)."""
    if x is None:
        return {}
    if isinstance(x, Mapping):
        return x
    shown = " ".join(repr(x).split())[:80]
    raise TypeError(f"{name}: expected a mapping such as {{'name': value}}, got "
                    f"{type(x).__name__} {shown}")


_U32 = 2**32 - 1
_U64 = 2**64 - 1


def _count(name: str, x: Any, hi: int = _U64) -> int:
    """``x`` as a whole number from 0 to ``hi`` (the native side's integer type), naming ``name``
    when it is not: a float is taken only when it is whole (``4.0``, not ``4.7``), a bool not at
    all; beyond the range a :class:`physid.Error` (PyO3's own ``OverflowError`` names no
    argument)."""
    if isinstance(x, bool):
        raise TypeError(f"{name}: expected a whole number, got the bool {x}")
    if isinstance(x, (float, np.floating)):
        if not float(x).is_integer():
            raise Error(f"{name} = {x}: expected a whole number")
        x = int(x)
    try:
        n = int(x.__index__())
    except (AttributeError, TypeError):
        shown = " ".join(repr(x).split())[:80]
        raise TypeError(f"{name}: expected a whole number, got {type(x).__name__} {shown}") from None
    if not 0 <= n <= hi:
        shown = f"{n}" if abs(n) < 10**15 else f"{float(n):.3g}"
        raise Error(f"{name} = {shown}: expected a whole number from 0 to {hi}")
    return n


def _array(name: str, x: Any, ndim: int) -> np.ndarray:
    """``x`` as a C-contiguous float64 array of ``ndim`` dimensions, or :class:`Error` saying
    what was wrong (numbers are converted, non-contiguous arrays copied, pandas' nullable
    columns taken with a missing value as NaN)."""
    if hasattr(x, "to_numpy"):
        try:
            x = x.to_numpy(dtype="float64", na_value=np.nan)
        except (TypeError, ValueError):
            x = x.to_numpy()
    a = np.asarray(x)
    if a.dtype.kind == "O":
        try:
            a = a.astype(np.float64)
        except (TypeError, ValueError):
            pass
    if a.dtype.kind not in "biuf":
        raise Error(f"{name}: expected numbers, got an array of dtype {a.dtype}")
    if a.ndim != ndim:
        raise Error(f"{name}: expected a {ndim}-D array, got shape {a.shape}")
    return np.ascontiguousarray(a, dtype=np.float64)


def read(
    path: str | "os.PathLike[str]",
    channels: Sequence[str] | None = None,
    map: Mapping[str, str] | None = None,
    columns: Sequence[str] | None = None,
    scale: Mapping[str, tuple[float, float]] | None = None,
    *,
    crank_angle: bool = False,
    step_deg: float = 1.0,
    wheel: str | None = None,
    quadrature: str | None = None,
    encoders: Sequence[str] | None = None,
    marker: str | None = None,
    tdc_offset: float = 0.0,
    phase_from: str | None = None,
    tdc_from: str | None = None,
    stroke: float | None = None,
    rod: float | None = None,
    edge: str = "rising",
    threshold: tuple[float, float] | None = None,
    encoder_raw: str | None = None,
    index_raw: str | None = None,
) -> Recording:
    """Read a recording: CSV (also ``;`` with decimal commas, header-less text with
    ``columns``), Parquet or MDF4, by extension.

    ``channels``: the physid names to read (after ``map``; all if ``None``). ``map``:
    ``{name: "COLUMN[:UNIT]"}`` — read the file's column as the channel, stating its unit.
    ``scale``: ``{name: (gain, offset)}`` — a sensor's calibration. Standard channels
    (``omega_en``, ``p_cyl`` …) are converted to SI on reading, as every physid verb does.

    On a crank-angle basis (``crank_angle=True``, implied by ``wheel``, ``quadrature``, ``encoder_raw``,
    ``encoders`` and ``tdc_from``), as ``physid convert --crank-angle`` reads it: one sample
    every ``step_deg`` degrees with ``cycle`` and ``crank_deg``, the engine angle from the
    file's ``theta_en``, from an encoder's counts and TDC marker (``encoders``:
    ``["count_en=360", …]``, ``marker``), or decoded from a raw sensor's signal — a trigger
    wheel (``wheel="enc=60-2"``: channel, tooth pitches, missing teeth; ``edge`` ``"rising"`` or
    ``"falling"``; ``threshold=(level, hysteresis)`` instead of the automatic level) or a
    quadrature encoder (``quadrature="enc_a,enc_b,enc_z=500"``) or a single-channel pulse
    encoder with its index (``encoder_raw="enc=360", index_raw="tdc"``). The firing TDC lies
    ``tdc_offset`` degrees after the sensor's reference, or is placed from the motored
    cylinder pressure ``tdc_from`` (with ``stroke`` and ``rod`` [m]); ``phase_from`` (a
    pressure or cam channel, ``":low"`` for a cam marking the other revolution) says which
    revolution fires — by default ``p_cyl`` when the file has it; ``"none"`` takes the first
    TDC. What the decoding found is in ``meta["angle"]`` (and
    ``meta["tdc_from"]``).
    """
    import os

    if not (crank_angle or wheel or quadrature or encoder_raw or encoders or tdc_from):
        # Each of these shapes a crank-angle reading only: given without one, it would be
        # ignored without a word.
        unused = [name for name, value, default in (
            ("step_deg", step_deg, 1.0), ("marker", marker, None), ("tdc_offset", tdc_offset, 0.0),
            ("phase_from", phase_from, None), ("stroke", stroke, None), ("rod", rod, None),
            ("edge", edge, "rising"), ("threshold", threshold, None), ("index_raw", index_raw, None),
        ) if (value is not None if default is None
              else not (isinstance(value, (int, float, str)) and value == default))]
        if unused:
            raise Error(f"{', '.join(unused)}: for a crank-angle reading — add crank_angle=True "
                        f"(or give wheel, quadrature, encoder_raw or encoders)")
    return _physid.read(
        os.fspath(path),
        list(channels) if channels is not None else None,
        dict(map) if map is not None else None,
        list(columns) if columns is not None else None,
        {k: (float(g), float(o)) for k, (g, o) in _mapping("scale", scale).items()} if scale else None,
        crank_angle=bool(crank_angle),
        step_deg=float(step_deg),
        wheel=wheel,
        quadrature=quadrature,
        encoders=list(encoders) if encoders is not None else None,
        marker=marker,
        tdc_offset=float(tdc_offset),
        phase_from=phase_from,
        tdc_from=tdc_from,
        stroke=float(stroke) if stroke is not None else None,
        rod=float(rod) if rod is not None else None,
        edge=edge,
        threshold=f"{float(threshold[0])},{float(threshold[1])}" if threshold is not None else None,
        encoder_raw=encoder_raw,
        index_raw=index_raw,
    )


def _recording_to_pandas(self: Recording):
    """The recording as a ``pandas.DataFrame``: indexed by the time ``t`` [s] (when the
    recording has it), a column per other channel; units in ``df.attrs["units"]``, the basis
    in ``df.attrs["basis"]``. Needs pandas."""
    import pandas as pd

    index = pd.Index(self["t"], name="t") if "t" in self else None
    df = pd.DataFrame({name: self[name] for name in self.channels if index is None or name != "t"},
                      index=index)
    df.attrs["units"] = self.units
    df.attrs["basis"] = self.basis
    df.attrs["meta"] = self.meta
    return df


def _recording_t(self: Recording) -> np.ndarray:
    """The time channel ``t`` [s]."""
    return self["t"]


def _recording_from_pandas(df, units: Mapping[str, str] | None = None, basis: str = "time") -> Recording:
    """A recording from a ``pandas.DataFrame`` (numeric columns; a named index, such as the
    ``t`` of :meth:`Recording.to_pandas`, first), units from ``units`` or
    ``df.attrs["units"]``."""
    units = dict(units if units is not None else df.attrs.get("units", {}))
    named = df.index.name is not None and df.index.name not in df.columns
    index = [(str(df.index.name), _array(str(df.index.name), df.index, 1))] if named else []
    return Recording(
        index + [(str(c), _array(str(c), df[c], 1)) for c in df.columns],
        units=units,
        basis=df.attrs.get("basis", basis),
    )


Recording.to_pandas = _recording_to_pandas
Recording.t = property(_recording_t)
Recording.from_pandas = staticmethod(_recording_from_pandas)


@dataclass
class Run:
    """What :meth:`RLS.run` (and every estimator's ``run``) returns.

    ``theta`` and ``std_err``: n × p arrays, the estimate and its standard error after each
    row (NaN while not estimable yet); ``errors``: the a-priori prediction error per row;
    ``skipped``: rows refused and skipped (``skip_bad=True``); ``names``: the parameters.
    """

    theta: np.ndarray
    std_err: np.ndarray
    errors: np.ndarray
    skipped: list[int]
    names: list[str]

    @property
    def estimate(self) -> np.ndarray:
        """The final estimate (the last row of ``theta``)."""
        return self.theta[-1].copy()

    def to_pandas(self, t: Any = None):
        """The tracks as a ``pandas.DataFrame``: a column per parameter, ``NAME_std_err`` per
        parameter and ``error``; indexed by ``t`` (the rows' times, e.g. ``rec.t``) when given,
        else by row. Needs pandas."""
        import pandas as pd

        cols = {n: self.theta[:, k] for k, n in enumerate(self.names)}
        cols.update({f"{n}_std_err": self.std_err[:, k] for k, n in enumerate(self.names)})
        cols["error"] = self.errors
        index = None
        if t is not None:
            t = _array("t", t, 1)
            if t.shape[0] != self.theta.shape[0]:
                raise Error(f"t has {t.shape[0]} values for {self.theta.shape[0]} rows")
            index = pd.Index(t, name="t")
        return pd.DataFrame(cols, index=index)

    def to_dict(self) -> dict:
        return {
            "names": self.names,
            "theta": self.theta.tolist(),
            "std_err": self.std_err.tolist(),
            "errors": self.errors.tolist(),
            "skipped": self.skipped,
        }


class Innovation(float):
    """What :meth:`update` returns: the a-priori prediction error ``e = y − ŷ`` (this number
    itself, so it is used as one), with ``variance``, the innovation variance ``Var(e)``
    (the RLS family and DSFC: in units of the noise variance σ²; the filters: absolute), and
    ``standardized``, the standardised recursive residual ``e/√Var(e)`` (Brown, Durbin & Evans
    1975; the CUSUM's input)."""

    variance: float

    def __new__(cls, error: float, variance: float):
        self = super().__new__(cls, error)
        self.variance = variance
        return self

    @property
    def error(self) -> float:
        """The prediction error ``e``."""
        return float(self)

    @property
    def standardized(self) -> float:
        """``e/√Var(e)``."""
        return float(self) / np.sqrt(self.variance)

    def __repr__(self) -> str:
        return f"Innovation(error={float(self)!r}, variance={self.variance!r})"


def _one_thread(e: RuntimeError) -> Error:
    """pyo3's "Already borrowed" as physid's error: an estimator used by two threads at once."""
    return Error("this estimator is in use by another thread (an estimator is for one thread "
                 "at a time: give each thread its own copy.copy(est))")


class _Estimator:
    """The methods every recursive estimator has."""

    _e: Any
    _width: int

    def _call(self, f, *args):
        try:
            return f(*args)
        except RuntimeError as e:
            if "borrow" in str(e).lower():
                raise _one_thread(e) from None
            raise

    @property
    def names(self) -> list[str]:
        """The estimated parameters' names."""
        names = self.__dict__.get("_names")
        if names is None:
            names = self.__dict__["_names"] = self._call(lambda: self._e.names)
        return list(names)

    @property
    def method(self) -> str:
        """The method's name (``rls``, ``rlsf``, ``dsfc``, ``kf``, ``ekf``, ``ukf``,
        ``srukf``)."""
        return self._call(lambda: self._e.method)

    @property
    def estimate(self) -> np.ndarray:
        """The current estimate ϑ."""
        return self._call(lambda: self._e.estimate)

    @property
    def std_err(self) -> np.ndarray:
        """The current standard errors (NaN while not estimable yet)."""
        return self._call(lambda: self._e.std_err)

    @property
    def covariance(self) -> np.ndarray:
        """The covariance P over the estimated parameters (the RLS family: in units of the
        noise variance σ²; the filters: absolute, in their coordinates)."""
        return self._call(lambda: self._e.covariance)

    @property
    def samples(self) -> int:
        """Samples taken."""
        return self._call(lambda: self._e.samples)

    def update(self, x: Any, y: float) -> Innovation:
        """One sample: the regressor φ (linear estimators) or the model's inputs (filters),
        and the measured output ``y``. Returns the :class:`Innovation`: the a-priori prediction
        error, with its variance and the standardised residual. A sample the estimator refuses
        (NaN, infinite) raises :class:`Error` and leaves it as it was."""
        x = _array("x", x, 1)
        y = float(y)
        e, var = self._call(self._e.update, x, y)
        return Innovation(e, var)

    def reset(self) -> None:
        """Back to the estimator as it was built: its starting estimate and covariance, no
        sample taken."""
        self._call(self._e.reset)

    def __copy__(self):
        new = object.__new__(type(self))
        new.__dict__.update(self.__dict__)
        new._e = self._call(self._e.__copy__)
        return new

    def __deepcopy__(self, memo):
        return self.__copy__()

    def run(self, X: Any, y: Any, skip_bad: bool = False, std_err: bool = True) -> Run:
        """All rows of ``X`` (n × inputs) and ``y`` (n), in Rust without the GIL. Returns a
        :class:`Run` with the estimate and standard-error tracks. A refused row raises
        :class:`Error` naming it, or with ``skip_bad=True`` is skipped (its track row repeats
        the previous one) and listed in ``Run.skipped``. ``std_err=False`` skips the
        standard-error track (left NaN) where only the estimates are wanted."""
        X = _array("X", X, 2)
        y = _array("y", y, 1)
        if X.shape[0] != y.shape[0]:
            raise Error(f"X has {X.shape[0]} rows, y {y.shape[0]}")
        theta, se, errors, skipped = self._call(self._e.run, X, y, skip_bad, std_err)
        return Run(theta, se, errors, list(skipped), self.names)

    def __repr__(self) -> str:
        return f"<physid.{type(self).__name__} of {', '.join(self.names)}: {self.samples} samples>"


#: The most parameters an estimator is built for from a count (a covariance of 80 GB; the
#: estimator itself refuses one the machine's memory cannot hold).
_MAX_PARAMS = 100_000


def _names(p: int | Sequence[str], names: Sequence[str] | None) -> list[str]:
    """The parameters' names from ``p`` (their number, or their names) or ``names``."""
    if names is not None:
        if isinstance(names, str):
            raise Error(f"names={names!r}: expected a list of names, e.g. ['K', 'B']")
        return [str(n) for n in names]
    if isinstance(p, (int, np.integer)) and not isinstance(p, bool):
        if p < 1:
            raise Error(f"p = {p}: expected at least one parameter")
        if p > _MAX_PARAMS:
            raise Error(f"p = {p}: at most {_MAX_PARAMS} parameters (their covariance holds p² "
                        f"numbers: {_MAX_PARAMS}² take 80 GB)")
        return [f"theta{i}" for i in range(int(p))]
    if isinstance(p, str):
        raise Error(f"p={p!r}: expected the number of parameters or a list of their names, "
                    f"e.g. ['K', 'B'] (a text is not split into names)")
    if isinstance(p, Sequence) and p and all(isinstance(n, str) for n in p):
        return list(p)
    raise Error(f"p={p!r}: expected the number of parameters (an integer) or a list of their "
                f"names")


def _theta0(names: list[str], theta0: Any) -> list[float]:
    if theta0 is None:
        return [0.0] * len(names)
    t = _array("theta0", theta0, 1)
    if t.shape[0] != len(names):
        raise Error(f"theta0: {t.shape[0]} values for {len(names)} parameters")
    return t.tolist()


def _p0(p0: Any) -> Any:
    return float(p0) if np.isscalar(p0) else np.asarray(p0, dtype=float).tolist()


class RLS(_Estimator):
    """Recursive least squares (thesis Alg. 5.2) for ``y = φᵀϑ + ε`` (Eq. 5.14):
    ``K = Pφ/(λ + φᵀPφ)``, ``ϑ ← ϑ + K(y − φᵀϑ)``, ``P ← (P − KφᵀP)/λ``.

    ``p``: the number of parameters, or their names. ``lam``: the forgetting factor λ ∈ (0, 1]
    (1: none; below 1 this is :class:`RLSF`). ``p0``: the initial covariance P(0) — a number
    (``p0·I``), a diagonal or a matrix (default 1000·I). ``theta0``: the starting estimate
    (zeros). Standard errors are ``√(σ̂²·P_ii)`` with σ̂² from the prediction errors.
    """

    _method = "rls"

    def __init__(self, p: int | Sequence[str], lam: float = 1.0, p0: Any = 1000.0,
                 theta0: Any = None, names: Sequence[str] | None = None):
        names = _names(p, names)
        method = self._method if lam == 1.0 or self._method != "rls" else "rlsf"
        self._e = _physid.Estimator.linear(method, names, _theta0(names, theta0), float(lam), _p0(p0))
        self._width = len(names)


class RLSF(RLS):
    """RLS with a constant forgetting factor λ (thesis Alg. 5.3): old samples weigh λᵏ, so the
    estimate tracks slowly changing parameters. Same arguments as :class:`RLS`, ``lam``
    defaulting to 0.98 (the thesis's ch. 6 value)."""

    _method = "rlsf"

    def __init__(self, p: int | Sequence[str], lam: float = 0.98, p0: Any = 1000.0,
                 theta0: Any = None, names: Sequence[str] | None = None):
        super().__init__(p, lam=lam, p0=p0, theta0=theta0, names=names)


class DSFC(RLS):
    """The DSFC square-root filter with forgetting λ (thesis Alg. 5.5): RLS with forgetting
    carried by the Cholesky factor S of P — the same estimates as :class:`RLSF` where both are
    well conditioned, and still positive definite where RLS loses it. ``p0``: P(0) (S(0) is
    its Cholesky factor)."""

    _method = "dsfc"

    def __init__(self, p: int | Sequence[str], lam: float = 0.98, p0: Any = 1000.0,
                 theta0: Any = None, names: Sequence[str] | None = None):
        super().__init__(p, lam=lam, p0=p0, theta0=theta0, names=names)


class KalmanRW(_Estimator):
    """The Kalman filter for random-walk parameters (thesis Eq. 5.19): ``ϑ(t) = ϑ(t−1) + w``,
    ``Cov w = R1``, ``y = φᵀϑ + e``, ``Var e = R2``. ``r1``: a number (``r1·I``), a diagonal or
    a matrix; ``r2`` > 0; ``p0`` as :class:`RLS`. P is absolute: standard errors ``√P_ii``."""

    def __init__(self, p: int | Sequence[str], r1: Any = 0.0, r2: float = 1.0, p0: Any = 1000.0,
                 theta0: Any = None, names: Sequence[str] | None = None):
        names = _names(p, names)
        self._e = _physid.Estimator.linear("kf", names, _theta0(names, theta0), 1.0, _p0(p0),
                                           _p0(r1), float(r2))
        self._width = len(names)


class EKF(_Estimator):
    """The extended Kalman filter (thesis Alg. 5.6) of the parameters of a formula model
    ``y = h(u, ϑ)``, e.g. ``"A*sin(x) + B*y^2"``: the names not among ``params`` are the
    inputs, in the order of :attr:`inputs` (``update(u, y)`` takes them in that order).

    ``params``: ``{name: starting value}``. ``free``: the names estimated (all if ``None``).
    ``p0``: the initial covariance (default 100·I, thesis ch. 8); ``r1``: the parameters'
    random walk (0); ``r2``: the measurement variance (1). ``scaled``: estimate ϑ/ϑ0 (the
    thesis's scaled coordinates). Jacobians are exact (automatic differentiation).
    """

    _method = "ekf"

    def __init__(self, expr: str, params: Mapping[str, float], free: Sequence[str] | None = None,
                 p0: Any = 100.0, r1: Any = 0.0, r2: float = 1.0, scaled: bool = False,
                 alpha: float = 1.0, beta: float = 2.0, kappa: float | None = None):
        params = _mapping("params", params)
        names = list(params.keys())
        theta0 = [float(v) for v in params.values()]
        self._e = _physid.Estimator.model(self._method, expr, names, theta0,
                                          list(free) if free is not None else None,
                                          _p0(p0), _p0(r1), float(r2), bool(scaled),
                                          float(alpha), float(beta), kappa)
        self._width = len(self._e.inputs)

    @property
    def inputs(self) -> list[str]:
        """The model's inputs, in the order ``update`` and ``run`` take them."""
        return self._e.inputs


class UKF(EKF):
    """The unscented Kalman filter (thesis Alg. 5.7) over a formula model: sigma points with
    spread ``alpha`` (1), ``beta`` (2, Gaussian), ``kappa`` (3 − l), covariance repair. Same
    arguments as :class:`EKF`."""

    _method = "ukf"


class SRUKF(EKF):
    """The square-root UKF (van der Merwe & Wan 2001): :class:`UKF` carrying the Cholesky
    factor of P — the robust option. Same arguments as :class:`EKF`."""

    _method = "srukf"


@dataclass
class Identification:
    """What :func:`identify` found.

    ``ranking``: every analysed parameter, most estimable first (Alg. 5.1); ``estimable``: the
    first K (the cut-off's); ``unidentifiable``: the rest; ``residual_ss`` and ``relative``:
    each one's residual sum of squares at its selection (and relative to the first), in
    ranking order; ``values``, ``std_err``, ``ci95``: the estimable ones' fitted (or nominal)
    values and precision (Eq. 5.12–5.13); ``collinearity``: the collinearity index of the
    estimable set; ``report``: physid's whole identify report (as ``physid identify --json``).
    """

    ranking: list[str]
    estimable: list[str]
    unidentifiable: list[str]
    residual_ss: list[float]
    relative: list[float]
    values: dict[str, float]
    std_err: dict[str, float]
    ci95: dict[str, tuple[float, float]]
    collinearity: float | None
    report: dict = field(repr=False)

    def to_dict(self) -> dict:
        return dict(self.report)


def _num(x):
    """A number of physid's JSON: finite ones as numbers, the others as text ("inf")."""
    if isinstance(x, (int, float)):
        return float(x)
    try:
        return float(x)
    except (TypeError, ValueError):
        return None


def identify(
    expr: str,
    params: Mapping[str, float],
    data: Recording | Mapping[str, Any],
    y: str | Any | None = None,
    scaling: str = "thesis",
    cutoff: str = "repeat",
    free: Sequence[str] | None = None,
    sigma: float | None = None,
) -> Identification:
    """Which parameters of the formula model ``expr`` the data can resolve.

    ``params``: ``{name: nominal value}``; the other names in ``expr`` are inputs, taken from
    ``data`` (a :class:`Recording` or ``{name: array}``). ``y``: the measured output (a
    channel name or an array) — then the estimable parameters are fitted and their precision
    comes from the residuals; without it, from ``sigma`` (the noise's standard deviation) or
    1. ``scaling``: ``thesis`` (Eq. 5.11, ``J·ϑ0/y``), ``sigma`` or ``none``; ``cutoff``:
    ``repeat`` (the thesis's code), ``wu`` (Wu et al.), ``rel:F`` or an absolute residual;
    ``free``: the parameters analysed (all if ``None``).
    """
    params = _mapping("params", params)
    names = list(params.keys())
    nominal = [float(v) for v in params.values()]

    if not isinstance(data, Recording):
        data = _mapping("data", data)
    keys = list(data.channels if isinstance(data, Recording) else data.keys())
    have = ", ".join(map(str, keys)) or "no channels"
    y_name = y if isinstance(y, str) else None

    def column(name: str, what: str) -> np.ndarray:
        if name not in keys:
            raise Error(f"{what} '{name}' is not in the data; the data have: {have}")
        return _array(name, data[name], 1)

    # Only the columns the formula names (a recording's other channels are not copied).
    inputs = {k: column(k, "the formula's input")
              for k in _physid.formula_inputs(expr, names) if k != y_name}
    if y_name is not None:
        yv = column(y_name, "y: the channel")
    elif y is None:
        yv = None
    else:
        yv = _array("y", y, 1)
    text = _physid.identify(expr, names, nominal, inputs, yv, list(free or []), scaling, cutoff,
                            float(sigma) if sigma is not None else None)
    r = _json.loads(text)
    steps = list(r.get("ranking", [])) + list(r.get("remainder", []))
    estimable = [s["param"] for s in r.get("ranking", [])]
    values = {k: _num(v) for k, v in (r.get("params") or {}).items()}
    se = {k: _num(v) for k, v in (r.get("std_err") or {}).items()}
    ci = {k: tuple(v) for k, v in (r.get("ci95") or {}).items()}
    return Identification(
        ranking=[s["param"] for s in steps],
        estimable=estimable,
        unidentifiable=list(r.get("unidentifiable", [])),
        residual_ss=[s["residual_ss"] for s in steps],
        relative=[s["relative"] for s in steps],
        values=values,
        std_err=se,
        ci95=ci,
        collinearity=_num(r.get("collinearity")),
        report=r,
    )


def simulate(
    scenario: str,
    duration: float | None = None,
    faults: Iterable[str] = (),
    set: Mapping[str, float] | None = None,
    basis: str = "time",
    rate: float | None = None,
    step_deg: float = 1.0,
) -> Recording:
    """Run the virtual test cell: a built-in scenario (``physid simulate --list``) or a
    scenario file, for ``duration`` seconds (the scenario's by default), with ``faults``
    (``"PATH=VALUE@T[+RAMP]"``, e.g. ``"shaft.k=1100@5+0.5"``) and parameter settings ``set``
    (``{"shaft.k": 1340}``), on a time basis at ``rate`` Hz (10 kHz) or one sample per
    ``step_deg`` crank degrees (``basis="crank_angle"``)."""
    return _physid.simulate(scenario, duration, list(faults), dict(_mapping("set", set)) if set else None, basis,
                            rate, float(step_deg))


class Result:
    """An application's result: the fields of its summary (as ``physid … --json`` prints them)
    as attributes, ``tracks`` (``{name: array}``: what it tracked, over time or cycles), and
    ``to_dict()`` (the summary)."""

    def __init__(self, summary: dict, tracks: dict):
        self._summary = summary
        self.tracks = tracks

    def __getattr__(self, name: str):
        try:
            return self.__dict__["_summary"][name]
        except KeyError:
            raise AttributeError(
                f"{type(self).__name__} has no '{name}'; it has {', '.join(self._summary)} and tracks"
            ) from None

    def __dir__(self):
        return sorted(set(super().__dir__()) | set(self._summary))

    def to_dict(self) -> dict:
        return _json.loads(_json.dumps(self._summary))

    def __repr__(self) -> str:
        return f"<physid.{type(self).__name__}: {', '.join(self._summary)}; tracks {', '.join(self.tracks)}>"


class ShaftMonitorResult(Result):
    """:func:`monitor_shaft`'s result: ``method``, ``final`` (K, B, tau0), ``std_err``,
    ``alarms`` (param, t_start_s, t_raised_s, relative_error, change), ``nmse`` and
    ``within_5pct_s`` against the truth of simulated data; ``tracks``: ``t``, ``K``, ``B``,
    ``tau0``, ``K_std_err``, ``B_std_err`` (and ``K_true``, ``B_true`` when known)."""


class FrictionFitResult(Result):
    """:func:`friction_fit`'s result: ``estimable``, ``ranking``, ``params``, ``nominal``,
    ``std_err`` (by coefficient c1 … c20), ``prediction_error_pct``, ``nmse``, ``cycles``,
    ``dropouts`` (each sample that was not a number, left out with the cycle it cuts:
    ``channel``, ``sample``, ``t_s``, ``value`` as text);
    ``tracks`` per steady cycle: ``t``, ``cycle``, ``n_rpm``, ``p_int_kpa``, ``t_oil_c``,
    ``measured``, ``predicted``, ``nominal``, ``error_pct`` (and ``truth``)."""


class TorqueFitResult(Result):
    """:func:`torque_fit`'s result: ``method``, ``estimable``, ``ranking``, ``params``,
    ``std_err``, ``nmse_before``/``after``, ``nrmse_before``/``after``, ``r2``, ``repairs``,
    ``samples``, ``dropouts`` (as :class:`FrictionFitResult`'s); ``tracks``: ``t``,
    ``measured``, ``predicted`` torque and each estimated
    parameter with its ``_std_err``."""


def _pair(x, n: int, what: str) -> tuple:
    t = tuple(float(v) for v in x)
    if len(t) != n:
        raise Error(f"{what}: expected {n} numbers, got {len(t)}")
    return t


def monitor_shaft(
    rec: Recording,
    method: str = "rlsf",
    lam: float = 0.98,
    p0: float = 1000.0,
    healthy: Sequence[float] = (1250.0, 0.95),
    theta0: Sequence[float] = (0.0, 0.0, 0.0),
    bound: float = 0.1,
    dwell: int = 200,
    cutoff_hz: float = 500.0,
    rate_hz: float = 2000.0,
    settle_s: float = 1.0,
    supervise: bool = False,
) -> ShaftMonitorResult:
    """Application 1 (thesis ch. 6): monitor the coupling shaft's stiffness K and damping B
    (Eq. 6.1) in a time-basis recording — low-passed at ``cutoff_hz``, taken at ``rate_hz``,
    tracked by ``method`` (``rlsf``: RLS with forgetting ``lam``; ``rlsvf``; ``dsfc``) from
    ``theta0`` (K, B, τ0) with ``P0 = p0·I``; an alarm when the relative error against
    ``healthy`` (K, B) stays beyond ``bound`` for ``dwell`` samples (Eq. 6.3) after
    ``settle_s``. ``supervise``: freeze K or B while the data no longer resolve them.
    ``method="rls"``, the old name of ``rlsf`` here, is still taken, with a DeprecationWarning
    (``rls`` is RLS without forgetting everywhere else: docs/cli.md)."""
    if method == "rls":
        import warnings
        warnings.warn("monitor_shaft(method='rls') is RLS with forgetting here: say 'rlsf' "
                      "(the old name is taken for this release only)", DeprecationWarning,
                      stacklevel=2)
    s, tracks = _physid.monitor_shaft(rec, method, float(lam), float(p0),
                                      _pair(healthy, 2, "healthy"), _pair(theta0, 3, "theta0"),
                                      float(bound), _count("dwell", dwell), float(cutoff_hz),
                                      float(rate_hz),
                                      float(settle_s), bool(supervise))
    return ShaftMonitorResult(_json.loads(s), dict(tracks))


class DesignResult(Result):
    """:func:`design`'s result: ``params``, ``criterion``, ``scenario`` (the designed test, as
    a scenario file holds it; ``scenario_toml``, the file's text, which :func:`simulate`
    and ``physid simulate --scenario`` run), ``predicted_std_err`` (``{"K": σ, …}`` at the test's end),
    ``chosen`` (its evaluation: ``median_rel_std_err``, ``time_to_target_s``, …),
    ``baselines`` (the application's thesis tests judged alike), ``ranking``, ``failed``,
    ``unidentifiable``, ``collinear``; ``tracks``: the profile ``t``, ``speed_demand_rpm``
    (``torque_demand_nm`` in torque mode), ``throttle_deg`` and the predicted standard errors ``curve_t`` and one array per
    parameter."""


def design(
    app: str = "shaft",
    params: Iterable[str] | None = None,
    criterion: str = "d",
    target_rel_se: float | None = None,
    limits: str | Mapping[str, Any] = "",
    duration: float | None = None,
    candidates: int = 200,
    seed: int = 1,
    threads: int = 0,
    method: str = "rlsf",
    lam: float | None = None,
    cutoff_hz: float = 500.0,
    rate_hz: float = 2000.0,
    s0: float = 10.0,
    source: str = "engine",
    sample_rate: float | None = None,
    set: Mapping[str, float] | None = None,
    alongside: Iterable[str] | None = None,
    band: tuple[float, float] = (0.05, 2.0),
) -> DesignResult:
    """Experiment design (``physid design``, docs/design.md): which profile of the cell's speed
    demand and throttle, within ``limits`` (``"speed=800:3000,throttle=0:60,dspeed=500"`` or
    ``{"speed": (800, 3000), "throttle": (0, 60), "dspeed": 500}``), makes ``params`` estimable
    by the ``app``'s recursive estimator on a recording at ``sample_rate`` — ``shaft``: the
    shaft monitor (``method``, ``lam`` 0.98, its low-pass ``cutoff_hz`` and update rate
    ``rate_hz``; ``params`` K, B, tau0, default K, B); ``friction``: the friction fit's DSFC
    (``lam`` 1, ``s0``, the motoring torque from ``source``; ``params`` the coefficients it will
    estimate, e.g. ``("c4", "c17")``); ``torque``: the cyclic-torque fit's UKF on 1° samples
    (``params`` e.g. ``("M_rec", "b", "L")``, estimated with ``alongside``, default ``("c1",)``,
    the friction level; ``()`` for none) — ranked by ``criterion`` (``d``, ``a``, ``e`` or
    ``time`` with ``target_rel_se``) over ``candidates`` profiles of ``duration`` s (120; 5 for
    ``torque``, the thesis's ramp T2) drawn from ``seed``; the cell with ``set``. The recording's
    ``sample_rate`` (10 kHz) is the shaft's and the friction fit's. With ``"torque": (lo, hi)``
    [N·m] in ``limits`` the candidates are the dynamometer's torque demands (torque mode, the
    engine kept within the speed range); multisines are drawn in ``band`` [Hz]."""
    if app not in ("shaft", "friction", "torque"):
        raise Error(f"app '{app}': expected shaft, friction or torque")
    if params is None:
        if app == "friction":
            raise Error("app 'friction' needs params: the coefficients the fit will estimate, "
                        "e.g. ('c4', 'c17')")
        if app == "torque":
            raise Error("app 'torque' needs params: the parameters the fit will estimate, "
                        "e.g. ('M_rec', 'b', 'L')")
        params = ("K", "B")
    if app == "torque":
        if sample_rate is not None:
            raise Error("sample_rate: the cyclic-torque fit reads one sample per crank degree")
        if lam is not None:
            raise Error("lam: the cyclic-torque filter does not forget")
        alongside = ("c1",) if alongside is None else tuple(alongside)
    elif alongside is not None:
        raise Error("alongside is the cyclic-torque fit's setting")
    if duration is None:
        duration = 5.0 if app == "torque" else 120.0
    if sample_rate is None:
        sample_rate = 10_000.0
    if isinstance(limits, Mapping):
        items = []
        for k, v in limits.items():
            if isinstance(v, (tuple, list)):
                lo, hi = _pair(v, 2, f"limits[{k!r}]")
                items.append(f"{k}={lo}:{hi}")
            else:
                items.append(f"{k}={float(v)}")
        limits = ",".join(items)
    s, tracks = _physid.design(str(app), [str(p) for p in params], str(criterion),
                               None if target_rel_se is None else float(target_rel_se),
                               str(limits), float(duration), _count("candidates", candidates),
                               _count("seed", seed), _count("threads", threads), str(method),
                               None if lam is None else float(lam),
                               float(cutoff_hz), float(rate_hz), float(s0), str(source),
                               float(sample_rate),
                               {str(k): float(v) for k, v in _mapping("set", set).items()},
                               [str(a) for a in (alongside or ())],
                               _pair(band, 2, "band"))
    return DesignResult(_json.loads(s), dict(tracks))


def friction_fit(
    rec: Recording,
    preset: str = "thesis",
    set: Mapping[str, Any] | None = None,
    source: str = "engine",
    cutoff: str = "repeat",
    s0: float = 10.0,
    lam: float = 1.0,
    transient_s: float = 5.0,
    p_atm_kpa: float | None = None,
    estimate: Iterable[str] | None = None,
) -> FrictionFitResult:
    """Application 2 (thesis §7.3): the engine's friction from a motored recording — the
    cycle-mean motoring torque (``source``: ``engine`` load cell or ``shaft``), the ranking of
    the regression coefficients c1 … c20 of the mean-value model (``preset``: thesis,
    sandoval2002, cell; ``set``: design overrides, e.g. ``{"B": 56, "oil": "SAE30"}``) with
    ``cutoff`` (or the coefficients in ``estimate``, e.g. those a test was designed for with
    ``design(app="friction")``), DSFC (λ = ``lam``, S0 = ``s0``·I) on the estimable ones, the prediction error
    after ``transient_s``."""
    s, tracks = _physid.friction_fit(rec, preset, {k: str(v) for k, v in _mapping("set", set).items()},
                                     source, cutoff, float(s0), float(lam), float(transient_s),
                                     p_atm_kpa,
                                     None if estimate is None else [str(c) for c in estimate])
    return FrictionFitResult(_json.loads(s), dict(tracks))


def torque_fit(
    rec: Recording,
    method: str = "ukf",
    nominal: Mapping[str, float] | None = None,
    fixed: Sequence[str] = ("delta",),
    cutoff: str | None = None,
    p0: float = 0.01,
    r2: float | None = None,
    track: Mapping[str, float] | None = None,
    estimate: Iterable[str] | None = None,
) -> TorqueFitResult:
    """Application 3 (thesis ch. 8): the cyclic engine torque model (Eq. 8.2, 15 parameters:
    M_rec, b, L, r, delta, c1 … c10) on a motored recording — the ranking at ``nominal`` (the
    test cell's engine, overridden by name), the estimable ones (``cutoff``: ``rel:1e-6`` by
    default, as ``physid torque fit``; ``fixed`` held; or ``estimate``, the parameters chosen
    beforehand, e.g. those a test was designed for, the others held at ``nominal``)
    estimated by ``method`` (ekf, ukf, srukf) in scaled coordinates with ``P0 = p0·I``, ``r2``
    (the batch fit's residual variance if ``None``) and random walks ``track``
    (``{name: variance per sample}``) for parameters that change."""
    if cutoff is not None and estimate is not None:
        raise Error("give cutoff or estimate, not both")
    s, tracks = _physid.torque_fit(rec, method, dict(nominal or {}), list(fixed), cutoff,
                                   None if estimate is None else [str(e) for e in estimate],
                                   float(p0), r2, dict(track or {}))
    return TorqueFitResult(_json.loads(s), dict(tracks))


class CyclesResult(Result):
    """:func:`cycles`' result: ``channel``, ``unit``, ``cov_imep``, ``lnv_imep`` (over the fired
    cycles when some fired), ``notes``, ``dropouts`` (each pressure or brake torque sample that
    was not a number, left out with the cycles it cuts: ``channel``, ``sample``, ``t_s``,
    ``value`` as text); ``tracks`` per cycle: ``t`` (its firing TDC), ``cycle``,
    ``rpm``, ``p_max``, ``p_max_deg``, ``peg_offset``, ``imep``, ``imep_gross``, ``pmep``,
    ``n_compression``, ``n_expansion``, ``heat_release`` [J], ``fired``, ``misfire``,
    ``partial_burn`` (1/0), ``mfbK_deg`` for each fraction K of ``mfb``, ``dp_max`` [Pa/deg],
    ``dp_max_deg``, ``t_max`` [K] (with ``gas_temperature``), with knock ``mapo`` [Pa], ``mapo_deg``, ``impo`` [Pa·deg], ``knock`` (1/0)
    (NaN where not computed); ``to_pandas()`` gives them as a DataFrame."""

    def to_pandas(self):
        import pandas as pd
        return pd.DataFrame(self.tracks)


def cycles(
    rec: Recording,
    channel: str = "p_cyl",
    bore: float | None = None,
    stroke: float | None = None,
    rod: float | None = None,
    compression_ratio: float | None = None,
    peg: str | None = None,
    gamma: float = 1.35,
    mfb=(10.0, 50.0, 90.0),
    knock: bool = False,
    knock_band=(5e3, 20e3),
    knock_window=(0.0, 60.0),
    knock_threshold: float = 1e5,
    gas_temperature=None,
    wall_heat: float | None = None,
    woschni_c2: float = 3.24e-3,
    mfb_method: str = "heat",
    rw_exponent: float | None = None,
    brake_torque: str | None = None,
    cylinders: int = 1,
    pressure_lowpass: float | None = None,
    friction_model: str | None = None,
    friction_set: Mapping[str, Any] | None = None,
    friction_p_int: float | None = None,
    friction_p_atm: float = 101.0,
    friction_oil_temp: float = 90.0,
) -> CyclesResult:
    """Cylinder pressure per cycle, as ``physid cycles``, of ``channel`` in a crank-angle
    recording (read a time-basis one with ``read(..., crank_angle=True, wheel=...)``): peak and
    its angle, speed; with the geometry (all four, SI: ``bore``, ``stroke``, ``rod``,
    ``compression_ratio``) net and gross IMEP, the polytropic exponents and the combustion —
    apparent net heat release (single zone, constant ``gamma``), MFB10/50/90, fired or motored,
    the steepest pressure rise, PMEP, misfire and partial burn. ``peg``: ``"bdc=P"`` or
    ``"polytropic=N"``; ``mfb``: the burn fractions [%] whose angles are given (``mfbK_deg``);
    ``knock``: MAPO, IMPO and a flag above ``knock_threshold`` [Pa] from the pressure
    band-passed in ``knock_band`` [Hz] within ``knock_window`` [deg ATDC] (a step fine enough
    for the band: docs/data.md); ``gas_temperature=(ivc_deg, t_ivc_k)``: γ(T) at the mean gas
    temperature of the gas trapped at IVC instead of the constant ``gamma``, and its peak
    ``t_max`` [K]; ``wall_heat=T_WALL`` [K] (with ``gas_temperature``): the gross heat release,
    Woschni's wall heat added (its combustion term ``woschni_c2`` [m/(s·K)] from the start of
    combustion; 0: the motored form); ``mfb_method="rw"``: the burn angles by Rassweiler & Withrow's
    pressure-rise method, with ``rw_exponent`` (else each cycle's compression exponent);
    ``brake_torque``: the brake torque channel [N·m, positive when the engine delivers] — each
    cycle's mean ``torque``, ``bmep`` and ``fmep`` (net IMEP less BMEP) for an engine of
    ``cylinders``; ``pressure_lowpass=HZ``: a zero-phase Butterworth low-pass (order 4) on each
    cycle's pressure before its figures, knock's excepted; ``friction_model``: the preset
    (``"thesis"``, ``"sandoval2002"``, ``"cell"``) of the mean-value friction model whose FMEP
    without pumping, at each cycle's speed, is given beside the measured (``fmep_model`` [Pa]),
    with ``friction_set`` overrides (``{"B": 56, "oil": "SAE30"}``, as ``physid friction --set``)
    at the intake manifold pressure ``friction_p_int`` [kPa] (default the ambient
    ``friction_p_atm``) and oil temperature ``friction_oil_temp`` [°C]. A cycle is the
    compression before its firing TDC and the expansion after."""
    given = [v is not None for v in (bore, stroke, rod, compression_ratio)]
    if any(given) and not all(given):
        raise Error("the cylinder's geometry needs bore, stroke, rod and compression_ratio")
    geometry = (float(bore), float(stroke), float(rod), float(compression_ratio)) if all(given) else None
    k = None
    if knock:
        k = (float(knock_band[0]), float(knock_band[1]), float(knock_window[0]),
             float(knock_window[1]), float(knock_threshold))
    g = None if gas_temperature is None else (float(gas_temperature[0]),
                                              float(gas_temperature[1]))
    friction = None
    if friction_model is not None:
        sets = [f"{name}={value}" for name, value in _mapping("friction_set", friction_set).items()]
        p_int = friction_p_atm if friction_p_int is None else friction_p_int
        friction = (str(friction_model), sets, float(p_int), float(friction_p_atm),
                    float(friction_oil_temp))
    elif friction_set is not None or friction_p_int is not None:
        raise Error("friction_set and friction_p_int need friction_model")
    s, tracks = _physid.cycles(rec, channel, geometry, peg, float(gamma),
                               [float(m) for m in mfb], k, g,
                               None if wall_heat is None else (float(wall_heat),
                                                               float(woschni_c2)),
                               str(mfb_method),
                               None if rw_exponent is None else float(rw_exponent),
                               brake_torque, _count("cylinders", cylinders, _U32),
                               None if pressure_lowpass is None else float(pressure_lowpass),
                               friction)
    return CyclesResult(_json.loads(s), dict(tracks))


def twin_calibrate(
    rec: Recording,
    params: Iterable[str] | None = None,
    channels: Iterable[str] | None = None,
    set: Mapping[str, float] | None = None,
    max_rel_se: float = 0.05,
    threads: int = 0,
    demand: str | None = None,
) -> dict:
    """The self-calibrated test cell (``physid twin calibrate``, docs/twin.md): which of the
    virtual cell's physical parameters ``rec`` resolves (a crank-angle recording with ``t``,
    ``theta``, ``speed_demand``, ``throttle`` and the ``channels`` matched, by default those of
    omega_en, omega_dy, torque_shaft, p_int, p_cyl it has), their values and 95 % intervals,
    from the cell with ``set`` (the nominal values). ``params`` are ``--list-params`` paths
    (default the eight of ``physid twin calibrate``); one is estimable while its relative
    standard error stays at or below ``max_rel_se``. ``demand`` says what ``speed_demand``
    holds: ``"speed"`` [rad/s] or ``"torque"`` [N·m] (a dynamometer on a torque demand,
    replayed open loop); by default the recording's metadata ``param.dyno.torque_mode``, else a
    speed — refused where its first sample is far from the dynamometer's speed. Returns ``{"params": {path: {"value",
    "nominal", "std_err", "ci95", "estimable", "rank", "held"}}, "channels": [...],
    "collinear": [...], ..., "scenario_toml": the calibrated cell as a scenario file}``."""
    s, toml = _physid.twin_calibrate(
        rec, None if params is None else [str(p) for p in params],
        None if channels is None else [str(c) for c in channels],
        {str(k): float(v) for k, v in _mapping("set", set).items()}, float(max_rel_se),
        _count("threads", threads),
        None if demand is None else str(demand))
    out = _json.loads(s)
    out["scenario_toml"] = toml
    return out


def twin_check(
    rec: Recording,
    calibrated: Mapping[str, Any],
    channels: Iterable[str] | None = None,
    set: Mapping[str, float] | None = None,
    demand: str | None = None,
) -> dict:
    """The calibrated cell against ``rec`` (``physid twin check``): per channel ``nrmse_before``
    (the cell with ``set``), ``nrmse_after`` (with the calibrated values too) and
    ``rms_after``. ``calibrated`` is :func:`twin_calibrate`'s result (its estimable values are
    taken, and its covariance and channel noise give each channel's ``band``: ``sigma``,
    ``param_sd``, ``outside`` — the fraction of samples outside the 95 % band — and
    ``excursions``, where the residual leaves it) or ``{path: value}`` (no band). ``demand``
    as :func:`twin_calibrate`'s."""
    calibration = None
    calibrated = _mapping("calibrated", calibrated)
    if "params" in calibrated and isinstance(calibrated["params"], Mapping):
        values = {p: float(e["value"]) for p, e in calibrated["params"].items() if e["estimable"]}
        if "covariance" in calibrated:
            calibration = _json.dumps({"covariance": calibrated["covariance"],
                                       "channels": calibrated["channels"]})
    else:
        values = {str(k): float(v) for k, v in calibrated.items()}
    s = _physid.twin_check(rec, values, None if channels is None else [str(c) for c in channels],
                           {str(k): float(v) for k, v in _mapping("set", set).items()}, calibration,
                           None if demand is None else str(demand))
    return _json.loads(s)


__all__ += ["Result", "ShaftMonitorResult", "FrictionFitResult", "TorqueFitResult",
            "CyclesResult", "monitor_shaft", "friction_fit", "torque_fit", "cycles",
            "DesignResult", "design", "twin_calibrate", "twin_check"]


class LiveStream:
    """The live service's events as they come (``physid live --headless --json``): iterate
    for one ``dict`` per event (``type``: ``estimate``, ``alarm``, ``cycle``, ``control``,
    ``finding``, ``end`` …); :meth:`control` sends a control message to the running cell
    (``{"cmd": "speed", "rpm": 1200}``, ``{"cmd": "fault", "spec": "shaft.k=1000@2"}``,
    ``{"cmd": "stop"}``); :meth:`close` (or leaving a ``with`` block) stops the run. A run that
    fails raises :class:`Error` when its events are exhausted."""

    def __init__(self, inner):
        self._s = inner

    def __iter__(self):
        return self

    def __next__(self) -> dict:
        line = next(self._s)
        return _json.loads(line)

    def control(self, message: Mapping[str, Any] | str) -> None:
        self._s.control(message if isinstance(message, str) else _json.dumps(dict(message)))

    def close(self) -> None:
        self._s.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
        return False


def live(
    scenario: str | None = None,
    replay: str | "os.PathLike[str]" | None = None,
    duration: float | None = None,
    faults: Iterable[str] = (),
    set: Mapping[str, float] | None = None,
    pace: str | float = "max",
    rate: float = 10_000.0,
    chunk_s: float = 0.05,
    estimate_every_s: float = 0.1,
) -> LiveStream:
    """Start a live run — the virtual cell (``scenario``, ``shaft-steady`` by default, with
    ``duration``, ``faults``, ``set``, sampled at ``rate`` Hz) or a recording replayed
    (``replay``) — through the live service's stages (the shaft monitor and its alarms, the
    cycle statistics), at ``pace`` (``"max"`` or a factor of real time: 1 = real time), and
    iterate over its events (:class:`LiveStream`)."""
    import os

    return LiveStream(_physid.live(
        scenario, os.fspath(replay) if replay is not None else None, duration, list(faults),
        {k: float(v) for k, v in _mapping("set", set).items()}, str(pace), float(rate), float(chunk_s),
        float(estimate_every_s)))


__all__ += ["LiveStream", "live"]


def __dir__() -> list[str]:
    """The package's own names (not the modules it uses)."""
    return sorted(set(__all__) | {"__version__"})
