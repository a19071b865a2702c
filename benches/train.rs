//! Benchmark: train (in progress).
fn main() {}
