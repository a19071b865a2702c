//! Benchmark of the trainer: one training of 18-8-2 on 131 samples (targets < 50 ms) and
//! the full sweep 7 sizes x 10 restarts x 5 folds (target < 10 s on 2 cores; since Table 2
//! chooses k by nested cross-validation it also runs 7 sizes x 10 fold pairs of inner
//! trainings on 3/5 of the samples, and kernel ridge regression's inner CV), with the
//! default LM and back-propagation, against baselines in the same process: fitting the
//! linear regression, and LM with MATLAB's early stopping (6 failed validation checks,
//! any decrease counts as an improvement). The trust-region settings of the crate are the
//! same in both (see `LM_STEP_BOUND` in trainer/src/train.rs).
//!
//! The 131 samples come from the robot simulator of `odocal synth experiment` (seed 1), with
//! the true end points as targets (no camera, no alignment): the trainer's work is the same.

mod common;

use common::cpu_s;
use std::time::{Duration, Instant};

use odocal_dataset::{features_from_log, Dataset, RobotParams, Sample};
use odocal_synth::robot::{simulate_recording, RobotSimConfig};
use odocal_trainer::{
    crossval, sweep, train, LinearRegression, Method, SweepSettings, TrainSettings,
};

fn sim_dataset(n: usize, seed: u64) -> Dataset {
    let cfg = RobotSimConfig::default();
    let robot = RobotParams::default();
    let mut samples = Vec::new();
    for i in 0..n {
        let Ok(rec) = simulate_recording(&cfg, &[cfg.speed_of_run(i)], seed, i as u64) else {
            continue;
        };
        let Ok(log) = rec.odometry_log() else {
            continue;
        };
        let (Ok(f), Some(run)) = (features_from_log(&log, &robot), rec.runs.first()) else {
            continue;
        };
        samples.push(Sample {
            run_id: format!("run{:03}", i + 1),
            speed_mps: run.speed_mps,
            speed_commanded: true,
            inputs: f.inputs.to_vec(),
            target_m: [run.end_in_start_frame.x_m, run.end_in_start_frame.y_m],
            raw_end_m: f.raw_end_m,
            path_length_m: run.path_length_m,
            odometry: f.odometry,
            ..Default::default()
        });
    }
    Dataset::new(robot, samples, Vec::new(), n)
}

/// The 1-minute load average (other work on the machine inflates wall times).
fn load_avg() -> String {
    std::fs::read_to_string("/proc/loadavg")
        .ok()
        .and_then(|s| s.split_whitespace().next().map(str::to_string))
        .unwrap_or_else(|| "?".into())
}

fn median(mut v: Vec<Duration>) -> Duration {
    v.sort();
    v[v.len() / 2]
}

fn time<F: FnMut()>(reps: usize, mut f: F) -> Duration {
    median(
        (0..reps)
            .map(|_| {
                let t = Instant::now();
                f();
                t.elapsed()
            })
            .collect(),
    )
}

/// LM with MATLAB's early stopping: 6 failed validation checks, no improvement threshold.
fn lm_matlab_stop(hidden: usize) -> TrainSettings {
    let mut s = TrainSettings::new(hidden, Method::Lm);
    s.max_fail = 6;
    s.min_improvement = 0.0;
    s
}

fn main() {
    let ds = sim_dataset(131, 1);
    let x: Vec<Vec<f64>> = ds.samples.iter().map(|s| s.inputs.clone()).collect();
    let t: Vec<[f64; 2]> = ds.samples.iter().map(|s| s.target_m).collect();
    println!(
        "dataset: {} samples from the robot simulator (seed 1); load average {}",
        ds.samples.len(),
        load_avg()
    );
    let refs: Vec<&Sample> = ds.samples.iter().collect();
    let base = time(20, || {
        let _ = LinearRegression::fit(&refs);
    });
    println!(
        "baseline: linear regression fit {:.3} ms",
        base.as_secs_f64() * 1e3
    );

    let reps = 15;
    let mut lm_before_ms = f64::NAN;
    for (name, s) in [
        (
            "LM, MATLAB's early stopping (max_fail 6)",
            lm_matlab_stop(8),
        ),
        ("LM (default)", TrainSettings::new(8, Method::Lm)),
        ("back-propagation", TrainSettings::new(8, Method::Backprop)),
    ] {
        let mut epochs = Vec::new();
        let mut seed = 0;
        let c0 = cpu_s();
        let d = time(reps, || {
            seed += 1;
            if let Ok(net) = train(&x, &t, &s, seed) {
                epochs.push(net.epochs_run);
            }
        });
        let cpu_ms = (cpu_s() - c0) / reps as f64 * 1e3;
        let ms = d.as_secs_f64() * 1e3;
        if lm_before_ms.is_nan() {
            lm_before_ms = ms;
        }
        println!(
            "one training 18-8-2, {name}: median wall {ms:.1} ms over {reps} seeds (mean CPU {cpu_ms:.1} ms; \
             epochs run {epochs:?}) = {:.0}x linear regression, {:.2}x MATLAB's early stopping; target < 50 ms: {}",
            d.as_secs_f64() / base.as_secs_f64(),
            ms / lm_before_ms,
            if ms < 50.0 { "met" } else { "MISSED" }
        );
    }

    let threads = rayon::current_num_threads();
    for (name, train_settings, restarts) in [
        ("LM, MATLAB's early stopping", lm_matlab_stop(8), 1),
        ("LM (default)", TrainSettings::new(8, Method::Lm), 10),
    ] {
        let settings = SweepSettings {
            hidden_sizes: (6..=12).collect(),
            restarts,
            folds: 5,
            train: train_settings,
            seed: 1,
        };
        let t0 = Instant::now();
        let c0 = cpu_s();
        let rep = sweep(&ds, "bench", &settings, None, &|| {});
        let d = t0.elapsed().as_secs_f64();
        let cpu = cpu_s() - c0;
        let full = d * 10.0 / restarts as f64;
        let full_cpu = cpu * 10.0 / restarts as f64;
        let accuracy = match &rep {
            Ok(r) => {
                let t1 = r
                    .table1
                    .iter()
                    .find(|row| row.hidden == r.best_hidden)
                    .map(|row| {
                        format!(
                            "Table 1's best k = {}, cross-validated relative error {:.2} %",
                            row.hidden,
                            100.0 * row.val_rel_error.mean
                        )
                    })
                    .unwrap_or_default();
                let t2 = |name: &str| {
                    crossval::row(&r.table2, name)
                        .map_or(f64::NAN, |row| 100.0 * row.rel_error.mean)
                };
                format!(
                    "{t1}; Table 2: perceptron with k by nested CV {:.2} % (k per outer fold {:?}, \
                     {} inner restart(s) x 7 sizes x 10 fold pairs), kernel ridge regression {:.2} %",
                    t2(crossval::NESTED_NET),
                    r.nested.iter().map(|c| c.hidden).collect::<Vec<_>>(),
                    r.inner_restarts,
                    t2(crossval::KERNEL_RIDGE)
                )
            }
            Err(e) => format!("failed: {e}"),
        };
        println!(
            "sweep 7 sizes x {restarts} restarts x 5 folds, {name}, {threads} threads: wall {d:.2} s, CPU {cpu:.2} s \
             (full 10 restarts: wall {full:.1} s, CPU {full_cpu:.1} s = {:.1} s on 2 idle cores); {accuracy}; \
             load average {}; target < 10 s: {}",
            full_cpu / 2.0,
            load_avg(),
            if full < 10.0 {
                "met"
            } else if full_cpu / 2.0 < 10.0 {
                "met on CPU time, wall time inflated by load"
            } else {
                "MISSED"
            }
        );
    }
}
