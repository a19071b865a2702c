//! Benchmark: calib (in progress).
fn main() {}
