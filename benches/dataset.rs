//! Benchmark: building the dataset from trajectories (131 runs of the default experiment) and
//! from ceiling videos (a few rendered runs).
//!
//! Trajectories: parsing alone (baseline), the full build sequentially and in parallel (rayon),
//! as medians of several repetitions, with ratios against the baseline. Videos: decoding the
//! frames alone (baseline) against `odocal dataset --camera` (decode, track, align, build), in
//! frames per second of video.

mod common;

use common::timed;
use std::path::Path;
use std::process::Command;
use std::time::Instant;

use odocal_dataset::build::{assemble, process_recording, BuildOptions, Recording};
use odocal_dataset::{OdometryLog, Trajectory};
use odocal_synth::robot::{simulate_recording, RobotSimConfig};
use odocal_tracker::{open_source, SourceOptions};
use rayon::prelude::*;

/// Median wall seconds of `f` over `reps` runs.
fn wall(reps: usize, f: impl FnMut()) -> f64 {
    timed(reps, f).0
}

fn main() {
    let cfg = RobotSimConfig::default();
    let runs = 131;
    let t_sim = Instant::now();
    // (odometry CSV, trajectory CSV) per run, as `synth experiment --frames none` writes them.
    let files: Vec<(String, String)> = (0..runs)
        .into_par_iter()
        .map(|r| {
            let rec =
                simulate_recording(&cfg, &[cfg.speed_of_run(r)], 1, r as u64).expect("simulate");
            let log = rec.odometry_log().expect("log");
            let track = rec
                .camera_track(&cfg.camera, 1, (1 << 32) + r as u64)
                .expect("trajectory");
            (log.to_csv(), track.to_csv())
        })
        .collect();
    println!(
        "simulated {runs} runs in {:.3} s",
        t_sim.elapsed().as_secs_f64()
    );
    let frames: usize = files.iter().map(|f| f.1.lines().count() - 1).sum();
    let opts = BuildOptions::default();
    let parse = |f: &(String, String)| {
        (
            OdometryLog::parse_csv(&f.0, "log").expect("log"),
            Trajectory::parse_csv(&f.1, "trajectory").expect("trajectory"),
        )
    };
    let one = |f: &(String, String)| {
        let (log, cam) = parse(f);
        let rec = Recording {
            id: "r",
            speed_mps: None,
            log: &log,
            camera: &cam,
        };
        process_recording(&rec, &opts).expect("build")
    };
    let reps = 5;
    let t_parse = wall(reps, || {
        let n: usize = files.iter().map(|f| parse(f).1.rows.len()).sum();
        assert_eq!(n, frames);
    });
    let t_seq = wall(reps, || {
        let ds = assemble(opts.robot, files.iter().map(one).collect());
        assert_eq!(ds.samples.len(), runs);
    });
    let t_par = wall(reps, || {
        let ds = assemble(opts.robot, files.par_iter().map(one).collect());
        assert_eq!(ds.samples.len(), runs);
    });
    println!("dataset from trajectories: {runs} runs, {frames} camera frames, median of {reps}");
    println!("  parse CSV only (baseline) {:8.1} ms", 1e3 * t_parse);
    println!(
        "  build, sequential         {:8.1} ms  ({:.1} ms/run, {:.1}x baseline)",
        1e3 * t_seq,
        1e3 * t_seq / runs as f64,
        t_seq / t_parse
    );
    println!(
        "  build, parallel ({} thr)   {:8.1} ms  ({:.2}x faster than sequential)",
        rayon::current_num_threads(),
        1e3 * t_par,
        t_seq / t_par
    );
    videos();
}

fn odocal(args: &[&str]) {
    let out = Command::new(env!("CARGO_BIN_EXE_odocal"))
        .args(args)
        .output()
        .expect("run odocal");
    assert!(
        out.status.success(),
        "odocal {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// Frames in the videos of `dir`/runs, decoding them all (the baseline's work).
fn decode_all(dir: &Path) -> usize {
    let mut n = 0;
    for entry in std::fs::read_dir(dir.join("runs")).expect("runs") {
        let path = entry.expect("entry").path();
        if path.extension().is_some_and(|e| e == "avi") {
            let mut src = open_source(&path, &SourceOptions::default()).expect("video");
            loop {
                let batch = src.next_batch(32).expect("frames");
                if batch.is_empty() {
                    break;
                }
                n += batch.len();
            }
        }
    }
    n
}

fn videos() {
    let runs = 3;
    let dir = tempfile::tempdir().expect("temporary directory");
    let d = dir.path();
    let p = |x: &Path| x.to_str().expect("utf-8 path").to_string();
    let t = Instant::now();
    odocal(&[
        "synth",
        "experiment",
        "--out",
        &p(d),
        "--runs",
        &runs.to_string(),
        "--seed",
        "3",
        "--frames",
        "video",
    ]);
    println!(
        "\nrendered {runs} runs as 1280x720 videos in {:.1} s (not timed below)",
        t.elapsed().as_secs_f64()
    );
    let reps = 3;
    let mut frames = 0;
    let t_decode = wall(reps, || frames = decode_all(d));
    let camera = p(&d.join("calib/camera_true.json"));
    let manifest = p(&d.join("manifest.json"));
    let out = p(&d.join("dataset.json"));
    let t_build = wall(reps, || {
        odocal(&[
            "dataset",
            "--manifest",
            &manifest,
            "--camera",
            &camera,
            "--out",
            &out,
        ])
    });
    println!("dataset from videos: {runs} runs, {frames} frames, median of {reps}");
    println!(
        "  decode only (baseline)    {:8.1} ms  ({:.0} frames/s)",
        1e3 * t_decode,
        frames as f64 / t_decode
    );
    println!(
        "  odocal dataset --camera   {:8.1} ms  ({:.0} frames/s, {:.2}x the baseline's time)",
        1e3 * t_build,
        frames as f64 / t_build,
        t_build / t_decode
    );
}
