//! Benchmark: lrf (in progress).
fn main() {}
