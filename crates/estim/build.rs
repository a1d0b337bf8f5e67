//! `cfg(avx2_copy)`: the build is for x86-64 below AVX2 (the Python wheel: x86-64-v2), so the
//! linear step carries a second copy compiled for AVX2, chosen at run time
//! (`src/linear/lanes.rs`). A build for a CPU with AVX2 (`target-cpu=native` here) has one step.

fn main() {
    println!("cargo::rustc-check-cfg=cfg(avx2_copy)");
    println!("cargo::rerun-if-changed=build.rs");
    let arch = std::env::var("CARGO_CFG_TARGET_ARCH").unwrap_or_default();
    let features = std::env::var("CARGO_CFG_TARGET_FEATURE").unwrap_or_default();
    if arch == "x86_64" && !features.split(',').any(|f| f == "avx2") {
        println!("cargo::rustc-cfg=avx2_copy");
    }
}
