//! What the benchmarks share: CPU time of the process and medians of repeated timings.
#![allow(dead_code)] // each benchmark uses its own part

use std::time::Instant;

/// CPU time (user + system) this process has used so far, seconds (Linux /proc).
pub fn cpu_s() -> f64 {
    let stat = std::fs::read_to_string("/proc/self/stat").unwrap_or_default();
    // After the command name (in parentheses) come fields 3.. of proc(5):
    // utime (field 14) and stime (field 15), in clock ticks of 1/100 s.
    let rest = stat.rsplit_once(')').map(|(_, r)| r).unwrap_or("");
    let f: Vec<&str> = rest.split_whitespace().collect();
    let tick = |i: usize| f.get(i).and_then(|x| x.parse::<f64>().ok());
    match (tick(11), tick(12)) {
        (Some(u), Some(s)) => (u + s) / 100.0,
        _ => f64::NAN,
    }
}

/// The median (the upper one for an even count).
pub fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// Wall and CPU seconds of `f`, medians of `reps` runs.
pub fn timed(reps: usize, mut f: impl FnMut()) -> (f64, f64) {
    let (mut wall, mut cpu) = (Vec::new(), Vec::new());
    for _ in 0..reps {
        let c0 = cpu_s();
        let t0 = Instant::now();
        f();
        wall.push(t0.elapsed().as_secs_f64());
        cpu.push(cpu_s() - c0);
    }
    (median(wall), median(cpu))
}
