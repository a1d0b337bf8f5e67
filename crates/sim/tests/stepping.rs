//! The stepping run ([`Run`]): stepped in any increments it gives the very recording
//! `simulate` gives, and inputs changed between steps act exactly as the same inputs scheduled
//! from the start — what the paced live cell relies on.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use physid_core::Recording;
use physid_sim::run::{simulate, OutputBasis, Run, RunOptions};
use physid_sim::scenario::{named, Fault, Profile, Shape};
use std::f64::consts::PI;

fn options(duration: f64) -> RunOptions {
    RunOptions {
        duration: Some(duration),
        basis: OutputBasis::Time(2000.0),
        ..Default::default()
    }
}

fn assert_same(a: &Recording, b: &Recording) {
    assert_eq!(a.names(), b.names());
    for name in a.names() {
        assert_eq!(
            a.values(name).unwrap(),
            b.values(name).unwrap(),
            "channel {name}"
        );
    }
    assert_eq!(a.meta, b.meta);
}

#[test]
fn stepped_in_uneven_increments_it_is_simulate_exactly() {
    let scenario = named("shaft-ramp").unwrap();
    let opts = options(0.6);
    let whole = simulate(&scenario, &opts, |_| {}).unwrap();
    let mut run = Run::new(&scenario, &opts).unwrap();
    // Before the recording starts, through the settling second, then 1 ms, 17 ms, … steps.
    run.step_until(-0.5).unwrap();
    assert!(run.time() > -0.5 && run.time() < -0.49, "{}", run.time());
    let mut t = 0.0;
    for k in 0.. {
        if run.is_done() {
            break;
        }
        t += [0.001, 0.017, 0.0003, 0.05][k % 4];
        run.step_until(t).unwrap();
        assert!(run.is_done() || run.time() > t);
    }
    assert!(run.time() > 0.6);
    assert_same(&run.finish().unwrap(), &whole);
}

/// A stiffness step injected through `add_fault` while the run is at 0.2 s, and a speed demand
/// changed there, give the recording of the same fault and profile given up front.
#[test]
fn inputs_changed_between_steps_act_as_if_scheduled() {
    let scenario = named("shaft-steady").unwrap();
    let opts = options(0.5);
    let fault = Fault::parse("shaft.k=1000@0.3").unwrap();
    let ramped = Profile::constant(1000.0, 0.25).then(
        0.25,
        Shape::Ramp {
            v0: 1000.0,
            v1: 1100.0,
        },
    );
    let mut planned = scenario.clone();
    planned.speed = ramped.clone();
    let planned_opts = RunOptions {
        faults: vec![fault.clone()],
        ..options(0.5)
    };
    let want = simulate(&planned, &planned_opts, |_| {}).unwrap();

    let mut run = Run::new(&scenario, &opts).unwrap();
    run.step_until(0.2).unwrap();
    run.add_fault(fault);
    run.set_speed(ramped);
    run.step_until(f64::INFINITY).unwrap();
    let got = run.finish().unwrap();
    assert_same(&got, &want);
    // And the fault did act: the true stiffness steps from 1250 to 1000 N·m/rad at 0.3 s.
    let t = got.values("t").unwrap();
    let k = got.values("true_shaft_k").unwrap();
    let at = |time: f64| k[t.iter().position(|&ti| ti >= time).unwrap()];
    assert_eq!((at(0.29), at(0.31)), (1250.0, 1000.0));
}

/// A streaming run drained as it goes — as recordings (`drain`) and straight into columns
/// (`drain_into`, in turn) —: the chunks, put end to end, are the recording `simulate` gives;
/// and a run far longer than memory would hold is accepted.
#[test]
fn drained_chunks_put_end_to_end_are_the_recording() {
    let scenario = named("shaft-ramp").unwrap();
    let whole = simulate(&scenario, &options(0.4), |_| {}).unwrap();
    let opts = RunOptions {
        stream: true,
        ..options(0.4)
    };
    let mut run = Run::new(&scenario, &opts).unwrap();
    let mut columns: Vec<Vec<f64>> = vec![Vec::new(); whole.names().len()];
    let names: Vec<&str> = physid_sim::run::channels(opts.basis).map(|c| c.0).collect();
    assert_eq!(names, whole.names());
    let mut t = 0.0;
    let mut chunks = 0;
    while !run.is_done() {
        t += 0.013;
        run.step_until(t).unwrap();
        chunks += 1;
        if chunks % 2 == 0 {
            run.drain_into(&mut columns);
            continue;
        }
        let c = run.drain().unwrap();
        assert_eq!(c.names(), whole.names());
        for (col, name) in columns.iter_mut().zip(whole.names()) {
            col.extend_from_slice(c.values(name).unwrap());
        }
    }
    let last = run.finish().unwrap(); // what was not drained yet
    for (col, name) in columns.iter_mut().zip(whole.names()) {
        col.extend_from_slice(last.values(name).unwrap());
        assert_eq!(&col[..], whole.values(name).unwrap(), "{name}");
    }
    assert!(chunks > 20);
    let long = RunOptions {
        stream: true,
        duration: Some(1e7),
        ..options(1.0)
    };
    assert!(Run::new(&scenario, &long).is_ok());
    assert!(simulate(
        &scenario,
        &RunOptions {
            stream: false,
            ..long
        },
        |_| {}
    )
    .is_err());
}

/// A run that keeps a few channels records them bit for bit as a full run does, noise and a
/// sensor fault included; an unknown channel, or a choice after the start, is refused.
#[test]
fn kept_channels_are_the_full_runs() {
    let mut scenario = named("shaft-ramp").unwrap();
    scenario
        .faults
        .push("sensors.torque_shaft.offset=2@0.1".into());
    let mut opts = options(0.3);
    opts.params.set("sensors.speed.noise", 0.3).unwrap();
    let whole = simulate(&scenario, &opts, |_| {}).unwrap();
    let keep = ["omega_dy", "torque_shaft", "count_en", "tdc"];
    let mut run = Run::new(&scenario, &opts).unwrap();
    run.keep_channels(&keep).unwrap();
    run.step_until(1.0).unwrap();
    let got = run.finish().unwrap();
    assert_eq!(
        got.names(),
        ["t", "omega_dy", "torque_shaft", "count_en", "tdc"]
    );
    for name in got.names() {
        assert_eq!(
            got.values(name).unwrap(),
            whole.values(name).unwrap(),
            "{name}"
        );
    }
    let mut run = Run::new(&scenario, &opts).unwrap();
    let e = run.keep_channels(&["omega_xx"]).unwrap_err().to_string();
    assert!(
        e.contains("no channel 'omega_xx'") && e.contains("omega_dy"),
        "{e}"
    );
    run.step_until(0.01).unwrap();
    assert!(run.keep_channels(&keep).is_err());
}

/// Switched to torque demand at any moment of an engine cycle, the dynamometer holds the
/// torque it had on average over the last whole cycle, so the engine stays near the speed it
/// had: the speed's cycle means over the following 2 s stay within 2 % of 1000 rpm whatever
/// the crank angle at the switch (seven switch times spread over one 120 ms cycle).
#[test]
fn torque_demand_holds_the_cycle_mean_torque_wherever_in_the_cycle() {
    let scenario = named("shaft-steady").unwrap();
    for k in 0..7 {
        let at = 0.5 + k as f64 * 0.017;
        let mut run = Run::new(&scenario, &options(at + 2.0)).unwrap();
        run.step_until(at).unwrap();
        run.set_torque_mode(true);
        run.step_until(f64::INFINITY).unwrap();
        let rec = run.finish().unwrap();
        let t = rec.values("t").unwrap();
        let w = rec.values("omega_en").unwrap();
        // Cycle means: 1000 rpm is 0.12 s per cycle; after the switch, window by window.
        let mut from = t.iter().position(|&ti| ti >= at).unwrap();
        while let Some(to) = t.iter().position(|&ti| ti >= t[from] + 0.12) {
            let rpm = w[from..to].iter().sum::<f64>() / (to - from) as f64 * 30.0 / PI;
            assert!(
                (rpm / 1000.0 - 1.0).abs() < 0.02,
                "switched at {at} s: {rpm} rpm at {} s",
                t[from]
            );
            from = to;
        }
    }
}

/// A live parameter's value out of its range (a twin's estimate gone astray) is refused, named,
/// and changes nothing: the run goes on to the very recording of one never asked.
#[test]
fn a_live_parameter_out_of_range_is_refused_and_changes_nothing() {
    let scenario = named("shaft-steady").unwrap();
    let opts = options(0.3);
    let whole = simulate(&scenario, &opts, |_| {}).unwrap();
    let mut run = Run::new(&scenario, &opts).unwrap();
    run.step_until(0.1).unwrap();
    for (path, value, want) in [
        ("shaft.k", -1.0, "shaft.k = -1: expected > 0"),
        ("shaft.k", f64::NAN, "expected a finite number"),
        ("engine.friction_scale", -0.5, "expected ≥ 0"),
        ("engine.bore", 0.05, "cannot change during a run"),
    ] {
        let e = run.set_live_parameter(path, value).unwrap_err().to_string();
        assert!(e.contains(want), "{path} = {value}: {e}");
    }
    while !run.is_done() {
        run.step_until(run.time() + 0.05).unwrap();
    }
    assert_same(&run.finish().unwrap(), &whole);
}

/// A duration too short for its hundredth to move the time (1e-300 s, through Python's
/// `simulate`) ends: the recording of the one step past the end, as the stream's writer would
/// give it. It used to loop for ever.
#[test]
fn a_vanishing_duration_ends() {
    let scenario = named("shaft-steady").unwrap();
    let r = simulate(&scenario, &options(1e-300), |_| {}).unwrap();
    assert!(r.len() <= 2, "{}", r.len());
    assert_eq!(r.values("t").unwrap()[0], 0.0);
}
