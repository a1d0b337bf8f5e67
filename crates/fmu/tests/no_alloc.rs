//! An FMU's step never touches the heap once its buffers have grown: the counting global
//! allocator sees no allocation over a thousand communication steps, with the scenario driving
//! the cell and with the importer's inputs set before every step.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use physid_fmu::instance::Instance;
use physid_fmu::variables::{table, Type};
use physid_fmu::Cell;
use physid_sim::scenario::Scenario;
use physid_testkit::{allocations, Counting};

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
