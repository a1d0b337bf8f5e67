"""The live service's event stream from Python: the virtual cell's run with a stiffness fault
raises the alarm as the command line's does; a control message stops a paced run; a bad
scenario is an error at once."""
import time

import pytest

import physid


def test_the_live_events_of_a_faulty_run():
    seen = {}
    with physid.live(duration=3.0, faults=["shaft.k=1100@1.5"]) as s:
        for e in s:
            seen.setdefault(e["type"], []).append(e)
    alarm = seen["alarm"][0]
    assert alarm["param"] == "K" and 1.5 < alarm["t_s"] < 2.5
    assert seen["end"][-1]["samples"] == 30001
    assert len(seen["estimate"]) >= 20 and "cycle" in seen


def test_a_control_message_stops_a_paced_run():
    t0 = time.monotonic()
    with physid.live(duration=60.0, pace=4) as s:
        for e in s:
            if e["type"] == "estimate":
                s.control({"cmd": "stop"})
                break
        rest = list(s)
    assert time.monotonic() - t0 < 20
    assert any(e["type"] == "control" for e in rest), rest
    end = [e for e in rest if e["type"] == "end"]
    assert end and end[0]["t_s"] < 30


def test_a_bad_scenario_is_an_error_at_once():
    with pytest.raises(physid.Error, match="built-in scenario"):
        physid.live("no-such-scenario")
    with pytest.raises(physid.Error, match="pace"):
        physid.live(pace="fast")
