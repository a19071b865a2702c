//! Benchmark: track (in progress).
fn main() {}
