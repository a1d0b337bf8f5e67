"""Every function of the package driven with arguments out of reason, one at a time: ±1e300,
1e-300, NaN, ±inf, 0, −1, 2⁶⁴, wrong types, empty and mis-shaped arrays, malformed live
controls, odd recordings and sensor options. Each call runs in its own interpreter held to
6 GB of address space and 120 s; a finding is an exit other than 0, an exception other than
physid.Error, ValueError, TypeError, KeyError, OverflowError, IndexError or OSError (a
PanicException, a MemoryError, an AttributeError), a run of 40 digits in what it printed, or
a call over 60 s. Not part of the test suite (≈ 8 minutes); every finding it made has its own
test in tests/. Run from a venv with the wheel installed:

    python crates/py/fuzz_args.py [FUNCTION …]
"""
import os
import re
import resource
import subprocess
import sys
import tempfile
import time

PY = sys.executable
DIR = tempfile.mkdtemp(prefix="physid-fuzz-args-")
FIXTURES = r'''
import numpy as np, physid, os, math, warnings
warnings.simplefilter("ignore")
D = os.environ["PHYSID_FUZZ_DIR"]
def rec_time():
    p = f"{D}/ss.parquet"
    if not os.path.exists(p):
        physid.simulate("shaft-steady", duration=1.5).write(p)
    return physid.read(p)
def rec_fired():
    p = f"{D}/fs.parquet"
    if not os.path.exists(p):
        physid.simulate("fired-steady", duration=0.5).write(p)
    return physid.read(p)
def rec_crank():
    p = f"{D}/fc.parquet"
    if not os.path.exists(p):
        physid.simulate("fired-steady", duration=0.5, basis="crank").write(p)
    return physid.read(p)
def rec_torque():
    p = f"{D}/ts.parquet"
    if not os.path.exists(p):
        physid.simulate("torque-steady", duration=1.0, basis="crank").write(p)
    return physid.read(p)
def rec_fric():
    p = f"{D}/fr.parquet"
    if not os.path.exists(p):
        physid.simulate("friction-sweep", duration=6.0).write(p)
    return physid.read(p)
'''

NUM = ['float("nan")', 'float("inf")', 'float("-inf")', '0.0', '-1.0', '1e300', '-1e300', '1e-300', '2**64', '-2**63', 'True', '"x"', 'None', '[]']
STR = ['""', '"\\x00"', '"a"*100000', '"1e300"', 'None', '5', '"nan"', '"rls;drop"']
INT = ['-1', '0', '2**63', '2**64', '1e300', 'float("nan")', '"3"', 'None']
PAIR = ['(float("nan"), 1.0)', '(1.0,)', '(1e300, -1e300)', '()', '(0.0, 0.0)', '"ab"', 'None', '(-1.0, -2.0)']
ARR = ['[]', '[float("nan")]', 'np.zeros((0,))', 'np.zeros((3,3))', 'np.full(5, np.inf)', '"abc"', 'None', '[1e300]*3']
MAP = ['{}', '{"x": float("nan")}', '{"shaft.k": -1.0}', '{"": 1.0}', 'None', '{"shaft.k": 1e300}', '[1,2]', '{"solver.step_deg": 1e-9}']
CASES = [
 ("monitor_shaft", "rec_time()", dict(method=('"rlsf"', STR), lam=('0.98', NUM), p0=('1000.0', NUM), healthy=('(1250.0, 0.95)', PAIR), theta0=('(0.0,0.0,0.0)', PAIR), bound=('0.1', NUM), dwell=('200', INT), cutoff_hz=('500.0', NUM), rate_hz=('2000.0', NUM), settle_s=('1.0', NUM), supervise=('False', ['None', '2', '"yes"']))),
 ("friction_fit", "rec_fric()", dict(preset=('"thesis"', STR), set=('None', MAP), source=('"engine"', STR), cutoff=('"repeat"', STR), s0=('10.0', NUM), lam=('1.0', NUM), transient_s=('1.0', NUM), p_atm_kpa=('None', NUM), estimate=('None', ARR + ['["c1","c1"]', '["zz"]']))),
 ("torque_fit", "rec_torque()", dict(method=('"ukf"', STR), nominal=('None', MAP + ['{"M_rec": float("nan")}', '{"b": 0.0}']), fixed=('("delta",)', ARR + ['["zz"]']), cutoff=('None', STR), p0=('0.01', NUM), r2=('None', NUM), track=('None', MAP), estimate=('None', ARR))),
 ("cycles", "rec_crank()", dict(channel=('"p_cyl"', STR), bore=('None', NUM), stroke=('None', NUM), rod=('None', NUM), compression_ratio=('None', NUM), peg=('None', STR), gamma=('1.35', NUM), mfb=('(10.0, 50.0, 90.0)', PAIR + ['(50.0, 10.0)', '(101.0,)']), knock=('True', ['None', '2']), knock_band=('(5e3, 20e3)', PAIR), knock_window=('(0.0, 60.0)', PAIR), knock_threshold=('1e5', NUM), gas_temperature=('None', NUM + STR), wall_heat=('None', NUM), woschni_c2=('3.24e-3', NUM), mfb_method=('"heat"', STR), rw_exponent=('None', NUM), brake_torque=('None', STR), cylinders=('1', INT), pressure_lowpass=('None', NUM), friction_model=('None', STR), friction_set=('None', MAP), friction_p_int=('None', NUM), friction_p_atm=('101.0', NUM), friction_oil_temp=('90.0', NUM))),
 ("simulate", '"shaft-steady"', dict(duration=('0.1', NUM), faults=('()', ARR + ['["shaft.k=nan@0"]', '["shaft.k=1e300@0.05"]', '["x"]']), set=('None', MAP), basis=('"time"', STR), rate=('None', NUM), step_deg=('1.0', NUM))),
 ("design", '', dict(app=('"shaft"', STR), params=('None', ARR + ['["K","K"]']), criterion=('"d"', STR), target_rel_se=('None', NUM), limits=('""', STR + MAP), duration=('5.0', NUM), candidates=('2', INT), seed=('1', INT), threads=('1', INT), method=('"rlsf"', STR), lam=('None', NUM), cutoff_hz=('500.0', NUM), rate_hz=('2000.0', NUM), sample_rate=('None', NUM), set=('None', MAP), band=('(0.05, 2.0)', PAIR))),
 ("identify", '"A*sin(x)+B"', dict(params=('{"A": 1.0, "B": 0.5}', MAP + ['{"A": float("nan"), "B": 1.0}', '{"A": 0.0, "B": 0.0}']), data=('{"x": np.linspace(0, 10, 200)}', MAP + ['{"x": np.zeros(200)}', '{"x": np.full(200, np.nan)}']), y=('np.sin(np.linspace(0,10,200))+0.5', ARR + ['"x"', '"zz"']), scaling=('"thesis"', STR), cutoff=('"repeat"', STR + ['"rel:nan"', '"rel:-1"', '"-1"']), free=('None', ARR + ['["A","A"]']), sigma=('None', NUM))),
 ("twin_check", "rec_time()", dict(calibrated=('{"shaft.k": 1250.0}', MAP), channels=('None', ARR + ['["zz"]']), set=('None', MAP), demand=('None', STR))),
 ("live_all", '', dict(scenario=('"shaft-steady"', STR), duration=('0.2', NUM), faults=('()', ARR + ['["shaft.k=nan@0"]']), set=('None', MAP), pace=('"max"', STR + NUM), rate=('10000.0', NUM), chunk_s=('0.05', NUM), estimate_every_s=('0.1', NUM))),
 ("RLS_run", '', dict(p=('2', INT + ARR), lam=('1.0', NUM), p0=('1000.0', NUM + ARR), theta0=('None', ARR + NUM), X=('np.ones((10,2))', ARR + ['np.ones((10,3))', 'np.ones((0,2))']), y=('np.ones(10)', ARR + ['np.ones(9)']))),
 ("KF_run", '', dict(p=('2', INT), r1=('0.0', NUM + ARR), r2=('1.0', NUM), p0=('1000.0', NUM + ARR), X=('np.ones((10,2))', ARR), y=('np.ones(10)', ARR))),
 ("EKF_run", '', dict(cls=('physid.EKF', ['physid.UKF', 'physid.SRUKF']), expr=('"A*sin(x)"', STR + ['"A*sin("', '"A/0"', '"A^1e300"', '"x"']), params=('{"A": 1.0}', MAP), p0=('100.0', NUM + ARR), r1=('0.0', NUM), r2=('1.0', NUM), alpha=('1.0', NUM), beta=('2.0', NUM), kappa=('None', NUM), X=('np.ones((10,1))', ARR), y=('np.ones(10)', ARR))),
 ("Recording", '', dict(channels=('{"t": np.arange(5.0), "a": np.ones(5)}', MAP + ['{"t": np.arange(5.0), "a": np.ones(4)}', '{"t": np.full(5, np.nan)}', '[("t", [1,2]), ("t", [1,2])]', '{"t": np.zeros((2,2))}']), units=('None', MAP + ['{"a": "\\x00"}', '{"zz": "m"}']), basis=('"time"', STR), meta=('None', MAP))),
 ("read", '', dict(path=('f"{DIR}/ss.parquet"', STR + ['"/dev/zero"', '"/tmp"', 'f"{DIR}/nonexist.csv"']), channels=('None', ARR + ['["zz"]']), map=('None', MAP), columns=('None', ARR), scale=('None', MAP + ['{"t": (float("nan"), 0.0)}', '{"theta_en": (1e300, 0.0)}']), crank_angle=('False', ['True']), step_deg=('1.0', NUM), tdc_offset=('0.0', NUM), phase_from=('None', STR))),
]
def code(fn, first, kw):
    if fn == "live_all":
        args = ", ".join(f"{k}={v}" for k, v in kw.items())
        return f"s = physid.live({args})\nn = 0\nfor m in s:\n    n += 1\n    assert n < 10**6\nprint('events', n)"
    if fn in ("RLS_run", "KF_run"):
        X, y = kw.pop("X"), kw.pop("y")
        cls = "physid.RLS" if fn == "RLS_run" else "physid.KalmanRW"
        args = ", ".join(f"{k}={v}" for k, v in kw.items())
        return f"e = {cls}({args})\nr = e.run({X}, {y})\ne.update({X}[0] if hasattr({X}, '__len__') and len({X}) else {X}, 1.0)\nprint(e.estimate)"
    if fn == "EKF_run":
        X, y, cls = kw.pop("X"), kw.pop("y"), kw.pop("cls")
        args = ", ".join(f"{k}={v}" for k, v in kw.items())
        return f"e = {cls}({args})\nr = e.run({X}, {y})\nprint(e.estimate)"
    if fn == "Recording":
        args = ", ".join(f"{k}={v}" for k, v in kw.items())
        return f"r = physid.Recording({args})\nr.write(DIR + '/out.parquet')\nprint(len(r), r['t'])\nphysid.read(DIR + '/out.parquet')"
    args = ", ".join(([first] if first else []) + [f"{k}={v}" for k, v in kw.items()])
    return f"r = physid.{fn}({args})\nprint(str(r)[:200])"

def run(src, timeout=120):
    """`src` in a fresh interpreter with the fixtures: (exit code, stdout, stderr, seconds)."""
    full = ("import os\nos.environ['PHYSID_FUZZ_DIR'] = DIR = " + repr(DIR) + "\n" + FIXTURES
            + "try:\n" + "\n".join("    " + l for l in src.split("\n"))
            + "\nexcept physid.Error as e:\n    print('ERR physid.Error', str(e)[:400])"
            + "\nexcept (ValueError, TypeError, KeyError, OverflowError, IndexError, OSError) as e:"
            + "\n    print('ERR', type(e).__name__, str(e)[:400])"
            + "\nexcept BaseException as e:\n    print('BAD', type(e).__module__, type(e).__name__, str(e)[:400])\n")

    def limit():
        resource.setrlimit(resource.RLIMIT_AS, (6 << 30, 6 << 30))

    t0 = time.time()
    try:
        p = subprocess.run([PY, "-c", full], capture_output=True, text=True, timeout=timeout,
                           preexec_fn=limit)
        return p.returncode, p.stdout[-1500:], p.stderr[-1500:], time.time() - t0
    except subprocess.TimeoutExpired:
        return "timeout", "", "", timeout


def finding(rc, out, err, dt):
    return (rc != 0 or "BAD" in out or "panick" in (out + err)
            or re.search(r"\d{40}", out) is not None or dt > 60)


CTRL = ['""', '"{}"', '"null"', '"[1,2]"', '"{\\"cmd\\": 5}"', '"{\\"cmd\\": \\"fault\\", \\"spec\\": \\"shaft.k=1e300@0\\"}"', '"{\\"cmd\\": \\"speed\\", \\"rpm\\": 1e300}"', '"{\\"cmd\\": \\"speed\\", \\"rpm\\": -1}"', '"{\\"cmd\\": \\"throttle\\", \\"deg\\": 1e300}"', '"x" * 10**7', '"{\\"cmd\\": \\"record\\", \\"path\\": \\"/dev/full\\"}"', '"{\\"cmd\\": \\"fault\\", \\"spec\\": \\"shaft.b=1e6@0.1\\"}"', '"\\ud800"', 'None', '5']
def live_ctrl(msg):
    return f"s = physid.live(scenario='shaft-steady', duration=0.5, pace='max')\nn = 0\nfor m in s:\n    n += 1\n    if n == 2:\n        try:\n            s.control({msg})\n        except (physid.Error, ValueError, TypeError) as e:\n            print('ctrl refused', str(e)[:200])\n    assert n < 10**6\nprint('events', n)"
REC = ['rec_time()["zz"]', 'rec_time()[5]', 'rec_time()[None]', 'rec_time().write("/dev/full/x.parquet")', 'rec_time().write("/tmp")', 'rec_time().write("" + DIR + "/x.unknown")', 'rec_time().write("")', 'physid.Recording.from_pandas(__import__("pandas").DataFrame({"t": [0.0, float("nan")], "a": [1, 2]}))', 'physid.Recording.from_pandas(__import__("pandas").DataFrame({"a": ["x", "y"]}))', 'physid.Recording.from_pandas(__import__("pandas").DataFrame())', 'physid.Recording({"t": np.arange(3.0), "a": np.array(["a","b","c"])})', 'physid.Recording({"t": np.arange(3.0), "a": np.array([1+1j, 2, 3])})', 'physid.Recording({"t": np.array([0.0, 0.0, 0.0])}).write("" + DIR + "/y.csv")', 'physid.Recording({"t": np.arange(3.0)}, basis="crank_angle").write("" + DIR + "/y.parquet")', 'physid.Recording({"t": np.arange(3.0)}, units={"t": "x"*100000})', 'physid.Recording({"t\\n,x": np.arange(3.0)}).write("" + DIR + "/z.csv"); print(physid.read("" + DIR + "/z.csv"))', 'physid.Recording({"": np.arange(3.0)})', 'physid.Recording({"t": np.arange(3.0)}, meta={"k": "v"*10**6}).write("" + DIR + "/m.parquet")']
RD = ['physid.read("" + DIR + "/fs.parquet", wheel="x")', 'physid.read("" + DIR + "/fs.parquet", wheel="theta_en=60-2")', 'physid.read("" + DIR + "/fs.parquet", wheel="p_cyl=1000000000-2")', 'physid.read("" + DIR + "/fs.parquet", quadrature="a,b,c=0")', 'physid.read("" + DIR + "/fs.parquet", quadrature="p_cyl,p_int,p_exh=1e300")', 'physid.read("" + DIR + "/fs.parquet", encoders=["theta_en=0"])', 'physid.read("" + DIR + "/fs.parquet", encoders=["count_en=1e18"])', 'physid.read("" + DIR + "/fs.parquet", crank_angle=True, marker="p_cyl")', 'physid.read("" + DIR + "/fs.parquet", crank_angle=True, tdc_from="zz")', 'physid.read("" + DIR + "/fs.parquet", crank_angle=True, step_deg=1e-300)', 'physid.read("" + DIR + "/fs.parquet", crank_angle=True, stroke=-1.0, rod=1e300)', 'physid.read("" + DIR + "/fs.parquet", wheel="theta_en=60-2", threshold="nan,1")', 'physid.read("" + DIR + "/fs.parquet", wheel="theta_en=60-2", edge="sideways")', 'physid.read("" + DIR + "/fs.parquet", phase_from="p_cyl:1e300")', 'physid.read("" + DIR + "/fs.parquet", scale={"theta_en": (1e300, 0.0)}, crank_angle=True)', 'physid.cycles(rec_fired(), bore=1e300, stroke=1e-300, rod=1.0, compression_ratio=1.0)', 'physid.cycles(rec_fired(), cylinders=2**40)', 'physid.cycles(rec_time())', 'physid.torque_fit(rec_time())', 'physid.monitor_shaft(rec_crank())', 'physid.friction_fit(rec_crank())', 'physid.twin_check(rec_crank(), calibrated={"shaft.k": float("nan")})', 'physid.twin_check(rec_crank(), calibrated={"zz": 1.0})', 'physid.twin_check(rec_crank(), calibrated={"params": {"x": {"value": 1e300, "estimable": True}}})', 'physid.twin_check(rec_crank(), calibrated={"params": 5})']

def main(only):
    total = findings = 0
    for fn, first, params in CASES:
        if only and fn not in only:
            continue
        base = {k: v[0] for k, v in params.items()}
        rc, out, err, dt = run(code(fn, first, dict(base)))
        print(f"== {fn} base rc={rc} {dt:.1f}s {out.strip()[:150]!r}", flush=True)
        for k, (_, vals) in params.items():
            for v in vals:
                kw = dict(base)
                kw[k] = v
                rc, out, err, dt = run(code(fn, first, kw))
                total += 1
                if finding(rc, out, err, dt):
                    findings += 1
                    print(f"!! {fn} {k}={v[:60]} rc={rc} {dt:.1f}s out={out.strip()[-600:]!r} "
                          f"err={err.strip()[-600:]!r}", flush=True)
    if not only or "extra" in only:
        calls = [f"r = {x}\nprint(str(r)[:200])" for x in REC + RD]
        for src in [live_ctrl(m) for m in CTRL] + ["rec_fired()\n" + c for c in calls]:
            rc, out, err, dt = run(src)
            total += 1
            if finding(rc, out, err, dt):
                findings += 1
                print(f"!! {src.splitlines()[-1][:90]} rc={rc} {dt:.1f}s out={out.strip()[-600:]!r}",
                      flush=True)
    print("total", total, "findings", findings)
    return findings


if __name__ == "__main__":
    sys.exit(1 if main(sys.argv[1:]) else 0)
