//! Thesis Example 5.1: estimable [D, C, B, A, F], E unidentifiable.
// Test helpers panic on failure by design.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use physid_apps::example_5_1::{example_5_1, example_5_1_data};
use physid_ident::Cutoff;

#[test]
fn estimable_dcbaf_and_e_unidentifiable() {
    for seed in [51, 1, 2] {
        let d = example_5_1_data(seed);
        let a = example_5_1(&d).unwrap();
        let order: Vec<&str> = a
            .ranking
            .steps
            .iter()
            .map(|s| a.names[s.param].as_str())
            .collect();
        assert_eq!(order, ["D", "C", "B", "A", "F", "E"], "seed {seed}");
        assert_eq!(a.estimable(Cutoff::Repeat), 5, "seed {seed}");
        let e = a.ranking.steps[5];
        assert!(e.relative < 1e-25, "{e:?}");
    }
}
