"""The three applications from Python on the virtual test cell's runs: the shaft monitor
finds the injected stiffness fault (and gives what `physid monitor shaft` gives on the same
file), the friction fit predicts the simulated friction, the cyclic-torque fit's estimable
parameters."""
import json
import os
import subprocess

import numpy as np
import pytest

import physid


@pytest.fixture(scope="module")
def shaft_run():
    return physid.simulate("shaft-steady", duration=10.0, faults=["shaft.k=1100@5+0.5"])


def test_the_shaft_monitor_raises_the_stiffness_alarm_after_the_fault(shaft_run):
    r = physid.monitor_shaft(shaft_run)
    assert isinstance(r, physid.ShaftMonitorResult)
    assert [a["param"] for a in r.alarms] == ["K"]
    alarm = r.alarms[0]
    assert 5.0 < alarm["t_raised_s"] < 6.5 and alarm["change"] == pytest.approx(-0.12, abs=0.02)
    assert r.final["K"] == pytest.approx(1100.0, rel=0.01)
    t = r.tracks
    assert len(t["t"]) == len(t["K"]) == len(t["K_std_err"]) == len(t["K_true"])
    assert t["K_true"][-1] == 1100.0
    assert r.to_dict()["final"]["K"] == r.final["K"]
    with pytest.raises(AttributeError, match="has no 'nope'"):
        r.nope
    with pytest.raises(physid.Error, match="method"):
        physid.monitor_shaft(shaft_run, method="magic")
    with pytest.raises(physid.Error, match="healthy"):
        physid.monitor_shaft(shaft_run, healthy=(1.0,))
    # 'rls', the shaft monitor's old name of RLS with forgetting: the same estimator, warned.
    with pytest.warns(DeprecationWarning, match="say 'rlsf'"):
        old_name = physid.monitor_shaft(shaft_run, method="rls")
    assert old_name.final == r.final


@pytest.mark.skipif(not os.environ.get("PHYSID_BIN"), reason="PHYSID_BIN (physid's binary) not given")
def test_the_shaft_monitor_gives_what_the_command_line_gives(shaft_run, tmp_path):
    f = tmp_path / "run.parquet"
    shaft_run.write(f)
    j = json.loads(subprocess.run([os.environ["PHYSID_BIN"], "monitor", "shaft", "--data", str(f),
                                   "--json"], check=True, capture_output=True, text=True).stdout)
    r = physid.monitor_shaft(shaft_run)
    for k in ("K", "B"):
        assert r.final[k] == pytest.approx(j["final"][k], rel=1e-12)
    assert [a["t_raised_s"] for a in r.alarms] == [a["t_raised_s"] for a in j["alarms"]]


def test_the_friction_fit_predicts_the_simulated_friction():
    rec = physid.simulate("friction-sweep")
    r = physid.friction_fit(rec, preset="cell", source="shaft")
    assert isinstance(r, physid.FrictionFitResult)
    assert len(r.estimable) >= 3 and set(r.estimable) <= {f"c{i}" for i in range(1, 21)}
    # Against the simulated truth the prediction stays within 5 % after the transient.
    assert r.prediction_error_pct["max_after_transient_vs_truth"] < 5.0
    t = r.tracks
    assert len(t["measured"]) == len(t["predicted"]) == len(t["truth"]) > 10
    with pytest.raises(physid.Error, match="preset"):
        physid.friction_fit(rec, preset="none")


def test_the_cyclic_torque_fit_estimates_the_supported_parameters():
    rec = physid.simulate("torque-steady", basis="crank_angle", duration=4.0)
    r = physid.torque_fit(rec)
    assert isinstance(r, physid.TorqueFitResult)
    assert "delta" not in r.estimable and len(r.estimable) >= 3
    assert r.nmse_after < r.nmse_before
    for p in r.estimable:
        assert len(r.tracks[p]) == len(r.tracks["t"]) == len(r.tracks[f"{p}_std_err"])
    with pytest.raises(physid.Error, match="nominal 'bogus'"):
        physid.torque_fit(rec, nominal={"bogus": 1.0})


def test_a_dropout_leaves_out_the_cycle_it_cuts():
    """A NaN in the cylinder pressure (a sensor's dropout) leaves out the cycle it cuts in
    cycles() and torque_fit(), listed in ``dropouts``; every other cycle is the clean one's."""
    rec = physid.simulate("torque-steady", basis="crank_angle", duration=2.0)
    df = rec.to_pandas()
    row = int(np.flatnonzero((df["cycle"] == 5) & (df["crank_deg"] >= 100.0))[0])
    p = df["p_cyl"].to_numpy().copy()
    p[row] = np.nan
    df["p_cyl"] = p
    bad = physid.Recording.from_pandas(df, units=rec.units, basis="crank_angle")
    clean, got = physid.cycles(rec).to_pandas(), physid.cycles(bad)
    assert got.dropouts == [{"channel": "p_cyl", "sample": row, "t_s": df.index[row],
                             "value": "NaN"}]
    assert list(got.to_pandas()["cycle"]) == [c for c in clean["cycle"] if c != 5]
    kept = clean[clean["cycle"] != 5].reset_index(drop=True)
    assert got.to_pandas().equals(kept)
    fit = physid.torque_fit(bad)
    assert fit.samples + 720 == physid.torque_fit(rec).samples
    assert [d["sample"] for d in fit.dropouts] == [row]


def _wiebe(golden, name):
    """One of gen_wiebe.py's crank-angle CSV files (a units row under the names), by pandas."""
    import pandas as pd
    df = pd.read_csv(golden(f"crates/apps/tests/golden/{name}"), skiprows=[1])
    units = {"t": "s", "cycle": "-", "crank_deg": "deg", "p_cyl": "Pa"}
    return physid.Recording.from_pandas(df, units=units, basis="crank_angle")


def test_cycles_flags_a_partial_burn_and_a_misfire_and_takes_any_burn_fractions(golden):
    """gen_wiebe.py's wiebe_flags.csv: the 250 J cycle is a partial burn, the empty one a
    misfire; --mfb's fractions as columns; knock asked for on 1° steps says what step it needs."""
    truth = json.loads(golden("crates/apps/tests/golden/wiebe.json").read_text())
    heat = truth["flags_heat_j"]
    r = physid.cycles(_wiebe(golden, "wiebe_flags.csv"), bore=truth["bore"],
                      stroke=truth["stroke"], rod=truth["rod"],
                      compression_ratio=truth["compression_ratio"], mfb=(5, 50, 95),
                      knock=True)
    df = r.to_pandas()
    for _, row in df.iterrows():
        q = heat[int(row["cycle"])]
        assert row["misfire"] == (1.0 if q == 0 else 0.0)
        assert row["partial_burn"] == (1.0 if 0 < q < 0.5 * heat[1] else 0.0)
    assert {"mfb5_deg", "mfb50_deg", "mfb95_deg", "pmep", "mapo", "knock"} <= set(df.columns)
    assert "mfb10_deg" not in df.columns
    assert any("knock left out" in n for n in r.notes), r.notes


def test_cycles_gives_the_burn_angles_of_a_wiebe_burn(golden):
    truth = json.loads(golden("crates/apps/tests/golden/wiebe.json").read_text())
    r = physid.cycles(_wiebe(golden, "wiebe_cycles.csv"), bore=truth["bore"],
                      stroke=truth["stroke"], rod=truth["rod"],
                      compression_ratio=truth["compression_ratio"], gamma=truth["gamma"])
    df = r.to_pandas()
    assert list(df["cycle"]) == [1.0]
    for k in ("10", "50", "90"):
        assert df[f"mfb{k}_deg"][0] == pytest.approx(truth["mfb_deg"][k], abs=0.01)
    assert df["heat_release"][0] == pytest.approx(truth["heat_j"], rel=1e-4)
    assert df["fired"][0] == 1.0
    # Rassweiler & Withrow's burn angles: numpy's computation of the method (gen_wiebe.py).
    rw = physid.cycles(_wiebe(golden, "wiebe_cycles.csv"), bore=truth["bore"],
                       stroke=truth["stroke"], rod=truth["rod"],
                       compression_ratio=truth["compression_ratio"], gamma=truth["gamma"],
                       mfb_method="rw", rw_exponent=truth["rw_exponent"]).to_pandas()
    for k in ("10", "50", "90"):
        assert rw[f"mfb{k}_deg"][0] == pytest.approx(truth["rw_mfb_deg"][k], abs=1e-9)
    with pytest.raises(physid.Error, match="--mfb-method rw"):
        physid.cycles(_wiebe(golden, "wiebe_cycles.csv"), rw_exponent=1.3)
    # A brake torque of 12.5 N*m on a four-cylinder engine: BMEP = 4*pi*T/(4*V_d), FMEP the rest.
    import pandas as pd
    df_t = pd.read_csv(golden("crates/apps/tests/golden/wiebe_cycles.csv"), skiprows=[1])
    df_t["brake"] = 12.5
    rec_t = physid.Recording.from_pandas(
        df_t, units={"t": "s", "cycle": "-", "crank_deg": "deg", "p_cyl": "Pa", "brake": "N*m"},
        basis="crank_angle")
    b = physid.cycles(rec_t, bore=truth["bore"], stroke=truth["stroke"], rod=truth["rod"],
                      compression_ratio=truth["compression_ratio"], brake_torque="brake",
                      cylinders=4).to_pandas()
    vd = np.pi / 4 * truth["bore"] ** 2 * truth["stroke"]
    assert b["bmep"][0] == pytest.approx(4 * np.pi * 12.5 / (4 * vd), rel=1e-12)
    assert b["fmep"][0] == pytest.approx(b["imep"][0] - b["bmep"][0], rel=1e-12)
    # The friction model's FMEP beside it: the model at the cycle's speed, without pumping —
    # physid friction eval's cfmep + rfmep + vfmep + afmep at that point, when the binary is here.
    m = physid.cycles(rec_t, bore=truth["bore"], stroke=truth["stroke"], rod=truth["rod"],
                      compression_ratio=truth["compression_ratio"], brake_torque="brake",
                      friction_model="thesis", friction_set={"oil": "SAE30"},
                      friction_p_int=60.0, friction_oil_temp=70.0).to_pandas()
    assert np.isfinite(m["fmep_model"][0]) and m["fmep_model"][0] > 0
    if os.environ.get("PHYSID_BIN"):
        e = json.loads(subprocess.run(
            [os.environ["PHYSID_BIN"], "friction", "eval", "--n", repr(float(m["rpm"][0])),
             "--p-int", "60", "--t-oil", "70", "--set", "oil=SAE30", "--json"],
            check=True, capture_output=True, text=True).stdout)
        f = e["fmep_kpa"]
        want = (f["cfmep"] + f["rfmep"] + f["vfmep"] + f["afmep"]) * 1e3
        assert m["fmep_model"][0] == pytest.approx(want, rel=1e-9)
    # The gross heat release: Woschni's wall heat, with its combustion term (default) and
    # without (the motored form) — the values are checked against numpy's in Rust
    # (woschni_s_combustion_term_is_numpy_s); here, that the binding passes them: the gross above
    # the net, more with the combustion term, a negative C2 refused.
    wos = json.loads(golden("crates/apps/tests/golden/woschni.json").read_text())
    geo = dict(bore=truth["bore"], stroke=truth["stroke"], rod=truth["rod"],
               compression_ratio=truth["compression_ratio"],
               gas_temperature=(truth["ivc_deg"], wos["t_ivc_k"]))
    wiebe_rec = _wiebe(golden, "wiebe_cycles.csv")
    net = physid.cycles(wiebe_rec, **geo).to_pandas()["heat_release"][0]
    gross = {c2: physid.cycles(wiebe_rec, wall_heat=wos["t_wall_k"], woschni_c2=c2,
                               **geo).to_pandas()["heat_release"][0]
             for c2 in (0.0, wos["c2"])}
    assert net < gross[0.0] < gross[wos["c2"]]
    assert gross[0.0] - net < sum(wos["wall_c1"]) < gross[wos["c2"]] - net
    with pytest.raises(physid.Error, match="--woschni-c2"):
        physid.cycles(wiebe_rec, wall_heat=420.0, woschni_c2=-1.0, **geo)
    with pytest.raises(physid.Error, match="no such preset"):
        physid.cycles(rec_t, friction_model="nope")
    with pytest.raises(physid.Error, match="need friction_model"):
        physid.cycles(rec_t, friction_p_int=50.0)
    # The pressure's low-pass: scipy's filtering of the same noisy cycle (gen_wiebe_noisy.py).
    noisy = json.loads(golden("crates/apps/tests/golden/wiebe_noisy.json").read_text())
    f = physid.cycles(_wiebe(golden, "wiebe_noisy.csv"), bore=truth["bore"],
                      stroke=truth["stroke"], rod=truth["rod"],
                      compression_ratio=truth["compression_ratio"],
                      pressure_lowpass=noisy["cutoff_hz"]).to_pandas()
    assert f["imep"][0] == pytest.approx(noisy["imep_pa"], rel=1e-9)
    assert f["p_max"][0] == pytest.approx(noisy["p_max_pa"], rel=1e-12)
    # Without the geometry: no IMEP or heat release, and the geometry is all or nothing.
    bare = physid.cycles(_wiebe(golden, "wiebe_cycles.csv"))
    assert np.isnan(bare.tracks["imep"]).all() and np.isnan(bare.tracks["heat_release"]).all()
    with pytest.raises(physid.Error, match="bore, stroke, rod and compression_ratio"):
        physid.cycles(_wiebe(golden, "wiebe_cycles.csv"), bore=0.086)
    with pytest.raises(physid.Error, match="polytropic"):
        physid.cycles(_wiebe(golden, "wiebe_cycles.csv"), peg="polytropic=3")


@pytest.mark.skipif(not os.environ.get("PHYSID_BIN"), reason="PHYSID_BIN (physid's binary) not given")
def test_cycles_gives_what_the_command_line_gives(golden):
    truth = json.loads(golden("crates/apps/tests/golden/wiebe.json").read_text())
    geometry = dict(bore=truth["bore"], stroke=truth["stroke"], rod=truth["rod"],
                    compression_ratio=truth["compression_ratio"])
    f = golden("crates/apps/tests/golden/wiebe_mixed.csv")
    flags = [a for k, v in geometry.items() for a in (f"--{k.replace('_', '-')}", str(v))]
    j = json.loads(subprocess.run([os.environ["PHYSID_BIN"], "cycles", str(f), "--units-row",
                                   "--json", *flags], check=True, capture_output=True,
                                  text=True).stdout)
    r = physid.cycles(_wiebe(golden, "wiebe_mixed.csv"), **geometry)
    assert [c["cycle"] for c in j["cycles"]] == list(r.tracks["cycle"])
    assert [c["fired"] for c in j["cycles"]] == [bool(v) for v in r.tracks["fired"]]
    assert [c["imep_pa"] for c in j["cycles"]] == list(r.tracks["imep"])
    assert [c.get("mfb50_deg", float("nan")) for c in j["cycles"]] == pytest.approx(
        list(r.tracks["mfb50_deg"]), nan_ok=True, rel=0, abs=0)
    assert j["cov_imep"] == r.cov_imep and j["notes"] == r.notes


def test_design_predicts_what_the_monitor_achieves_on_the_designed_test(tmp_path):
    """physid.design: the designed profile and its predicted errors as arrays; the test, run on
    the cell with noise (10 seeds) and monitored, has a spread of K and B about the truth
    within ×1.5 of the predicted (pooled over every 0.1 s after the start-up)."""
    r = physid.design(params=["K", "B"], limits={"speed": (800, 1600), "dspeed": 400},
                      duration=3.0, candidates=5, seed=2)
    assert isinstance(r, physid.DesignResult)
    t = r.tracks
    assert len(t["t"]) == len(t["speed_demand_rpm"]) == len(t["throttle_deg"])
    assert 800 <= t["speed_demand_rpm"].min() and t["speed_demand_rpm"].max() <= 1600
    assert len(t["curve_t"]) == len(t["K"]) == len(t["B"])
    assert t["K"][-1] == pytest.approx(r.predicted_std_err["K"])
    path = tmp_path / "designed.toml"
    path.write_text(r.scenario_toml)
    at = t["curve_t"] >= 1.5
    z = {"K": [], "B": []}
    for seed in range(1, 11):
        m = physid.monitor_shaft(physid.simulate(str(path), set={"sensors.seed": seed}))
        j = np.searchsorted(m.tracks["t"], t["curve_t"][at] - 1e-9)
        assert np.allclose(m.tracks["t"][j], t["curve_t"][at])
        for p, truth in (("K", 1250.0), ("B", 0.95)):
            z[p].extend((m.tracks[p][j] - truth) / t[p][at])
    for p in ("K", "B"):
        rms = float(np.sqrt(np.mean(np.square(z[p]))))
        assert 1 / 1.5 < rms < 1.5, (p, rms, len(z[p]))


def test_design_for_the_friction_fit_runs_and_is_fitted(tmp_path):
    """physid.design(app="friction"): the coefficients' predicted errors as arrays; the
    designed test simulated and fitted with those coefficients (friction_fit(estimate=…))."""
    r = physid.design(app="friction", params=("c4", "c17"),
                      limits={"speed": (750, 1500), "throttle": (1, 90)},
                      duration=40.0, candidates=5)
    t = r.tracks
    assert len(t["curve_t"]) == len(t["c4"]) == len(t["c17"]) > 0
    assert t["c17"][-1] == pytest.approx(r.predicted_std_err["c17"])
    path = tmp_path / "friction.toml"
    path.write_text(r.scenario_toml)
    f = physid.friction_fit(physid.simulate(str(path)), preset="cell", estimate=["c4", "c17"])
    assert f.estimable == ["c4", "c17"]
    with pytest.raises(physid.Error, match="needs params"):
        physid.design(app="friction")


def test_design_for_the_cyclic_torque_fit_runs_and_is_fitted(tmp_path):
    """physid.design(app="torque"): M_rec, b, L with c1 alongside; the designed test simulated
    one sample per crank degree and fitted with those parameters (torque_fit(estimate=…)); the
    filter's own standard errors within 20 % of the design's prediction."""
    r = physid.design(app="torque", params=("M_rec", "b", "L"),
                      limits={"speed": (800, 1400)}, candidates=5)
    t = r.tracks
    assert len(t["curve_t"]) == len(t["M_rec"]) == len(t["L"]) > 0
    assert r.scenario["duration"] == 5.0
    assert t["b"][-1] == pytest.approx(r.predicted_std_err["b"])
    path = tmp_path / "torque.toml"
    path.write_text(r.scenario_toml)
    rec = physid.simulate(str(path), basis="crank")
    f = physid.torque_fit(rec, estimate=["M_rec", "b", "L", "c1"])
    assert f.estimable == ["M_rec", "b", "L", "c1"]
    for p in ("M_rec", "b", "L"):
        assert f.std_err[p] == pytest.approx(r.predicted_std_err[p], rel=0.2), p
    with pytest.raises(physid.Error, match="needs params"):
        physid.design(app="torque")
    with pytest.raises(physid.Error, match="does not forget"):
        physid.design(app="torque", params=("M_rec",), lam=0.99)


def test_design_with_torque_demands_and_a_band(tmp_path):
    """A torque range in the limits: the candidates are the dynamometer's torque demands (the
    profile as ``torque_demand_nm``), the designed scenario keeps the engine's speed range and
    runs on the cell; a bad band is refused."""
    r = physid.design(params=["K", "B"], limits={"speed": (800, 1600), "torque": (-2, 3)},
                      duration=3.0, candidates=5, band=(0.2, 5.0))
    assert r.scenario["torque_mode"] is True
    assert r.scenario["speed_range"] == [800.0, 1600.0]
    q = r.tracks["torque_demand_nm"]
    assert -2.0 <= q.min() and q.max() <= 3.0
    path = tmp_path / "tm.toml"
    path.write_text(r.scenario_toml)
    rec = physid.simulate(str(path))
    assert len(rec) > 0
    with pytest.raises(physid.Error, match="band"):
        physid.design(params=["K", "B"], duration=2.0, candidates=2, band=(2.0, 1.0))


def test_twin_calibrates_a_perturbed_cell_and_checks_it(tmp_path):
    """physid.twin_calibrate / twin_check: a crank-angle recording of a cell with K −10 % and
    friction ×1.15, calibrated from the nominal cell — both within their 95 % intervals, a
    parameter without information held and said so, the calibrated cell's scenario file runs,
    and the NRMSE on the speeds and shaft torque falls ≥ 10×."""
    rec = physid.simulate("shaft-ramp", duration=2.0, basis="crank_angle",
                          set={"shaft.k": 1125, "engine.friction_scale": 1.15,
                               "sensors.speed.noise": 0.01})
    cal = physid.twin_calibrate(rec, params=["shaft.k", "engine.friction_scale",
                                             "sensors.temperature.lag"])
    for path, truth in (("shaft.k", 1125.0), ("engine.friction_scale", 1.15)):
        p = cal["params"][path]
        assert p["estimable"], p
        assert p["ci95"][0] <= truth <= p["ci95"][1], (path, p)
    lag = cal["params"]["sensors.temperature.lag"]
    assert not lag["estimable"] and "no information" in lag["held"]
    path = tmp_path / "cell.toml"
    path.write_text(cal["scenario_toml"])
    assert len(physid.simulate(str(path), basis="crank_angle")) > 0
    chk = physid.twin_check(rec, cal)
    for ch in ("omega_en", "omega_dy", "torque_shaft"):
        c = chk["channels"][ch]
        assert c["nrmse_before"] >= 10 * c["nrmse_after"], (ch, c)
        # The band from the calibration's covariance and noise: about 5 % of the samples
        # outside it on the recording calibrated on.
        assert 0.02 < c["band"]["outside"] < 0.1 and c["band"]["excursions"] == [], (ch, c)
    assert physid.twin_check(rec, {"shaft.k": 1125.0})["channels"]["omega_en"]["band"] is None
    with pytest.raises(physid.Error, match="list-params"):
        physid.twin_calibrate(rec, params=["shaft.q"])
