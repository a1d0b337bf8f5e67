//! An FMU's step never touches the heap once its buffers have grown: the counting global
//! allocator sees no allocation over a thousand communication steps, with the scenario driving
//! the cell and with the importer's inputs set before every step.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use physid_fmu::instance::Instance;
use physid_fmu::variables::{table, Type};
use physid_fmu::Cell;
use physid_sim::scenario::Scenario;
use physid_testkit::{allocations, largest_allocation, reset_largest, Counting};

#[global_allocator]
static GLOBAL: Counting = Counting;

#[test]
fn a_step_does_not_allocate() {
    let mut s = Scenario::load("shaft-steady").unwrap();
    s.duration = 2.0;
    let cell = Cell::new(s, 10_000.0).unwrap();
    let vars = table(&cell);
    let vr = |name: &str| vars.iter().find(|v| v.name == name).unwrap().vr;
    let (omega, torque) = (vr("omega_dy"), vr("demand.torque"));
    for inputs in [false, true] {
        let mut fmu = Instance::of(cell.clone());
        fmu.setup(0.0, Some(2.0)).unwrap();
        fmu.enter_initialization().unwrap();
        fmu.exit_initialization().unwrap();
        if inputs {
            fmu.set(vr("demand.from_scenario"), Type::Boolean, 0.0)
                .unwrap();
            fmu.set(vr("demand.torque_mode"), Type::Boolean, 1.0)
                .unwrap();
        }
        let h = 1e-3;
        let step = |n: usize, fmu: &mut Instance| {
            if inputs {
                let w = fmu.get(omega, Type::Real).unwrap();
                fmu.set(torque, Type::Real, 2.0 * (125.0 - w) + 5.0)
                    .unwrap();
            }
            fmu.do_step(n as f64 * h, h).unwrap();
        };
        // The buffers grow over the first steps (the chunk of steps, the samples ahead).
        for n in 0..500 {
            step(n, &mut fmu);
        }
        let before = allocations();
        for n in 500..1500 {
            step(n, &mut fmu);
        }
        assert_eq!(
            allocations() - before,
            0,
            "inputs from the importer: {inputs}"
        );
    }
}

/// A long communication step holds a bounded number of samples (the ones before the sample
/// it ends on are dropped as they come): one step of 40 s at 10 kHz asks for no block larger
/// than a 65 536-sample column's growth, 1 MB (a column held its 400 000 samples before, in a
/// block of 6.4 MB), and its outputs are those of the same 40 s in 1 s steps, bit for bit. A
/// sample rate whose one solver step's samples would not fit is refused.
#[test]
fn a_long_step_holds_a_bounded_number_of_samples() {
    let mut s = Scenario::load("shaft-steady").unwrap();
    s.duration = 41.0;
    let cell = Cell::new(s, 10_000.0).unwrap();
    let started = || {
        let mut fmu = Instance::of(cell.clone());
        fmu.setup(0.0, Some(41.0)).unwrap();
        fmu.enter_initialization().unwrap();
        fmu.exit_initialization().unwrap();
        fmu
    };
    let outputs = |fmu: &mut Instance| -> Vec<f64> {
        table(&cell)
            .iter()
            .filter(|v| v.ty == Type::Real)
            .map(|v| fmu.get(v.vr, Type::Real).unwrap())
            .collect()
    };
    let mut long = started();
    reset_largest();
    long.do_step(0.0, 40.0).unwrap();
    let largest = largest_allocation();
    assert!(largest <= 1 << 20, "{largest} bytes");
    let mut short = started();
    for n in 0..40 {
        short.do_step(f64::from(n), 1.0).unwrap();
    }
    assert_eq!(outputs(&mut long), outputs(&mut short));
    let e = Cell::new(Scenario::load("shaft-steady").unwrap(), 1e12).unwrap_err();
    assert!(e.contains("expected > 0 and at most 10000000 Hz"), "{e}");
}
