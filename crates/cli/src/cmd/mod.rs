//! One module per verb.

pub mod bench;
pub mod estimate;
pub mod example;
pub mod friction;
