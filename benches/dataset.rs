//! Benchmark: dataset (in progress).
fn main() {}
