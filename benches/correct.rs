//! Benchmark of the path corrector: correcting a one-hour 200 ms log (18 000 rows) of a
//! random tour with a trained path model (target < 50 ms), against plain nominal dead
//! reckoning of the same log in the same process.
//!
//! The model is fitted on window samples cut from 12 simulated tours whose camera trajectory
//! is the truth (as `odocal synth experiment --paths tours --frames none` writes it).

mod common;

use common::timed;
use odocal_dataset::build::{BuildOptions, Recording, RunOutcome};
use odocal_dataset::{
    dead_reckon, window_samples, Dataset, RobotParams, WheelGeometry, WindowOptions,
};
use odocal_synth::robot::{simulate_plan, Plan, RobotSimConfig};
use odocal_trainer::PathModelFile;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

fn main() {
    let cfg = RobotSimConfig::default();
    let robot = RobotParams::default();
    let opts = BuildOptions::default();
    let mut samples = Vec::new();
    for r in 0..12u64 {
        let mut rng = ChaCha8Rng::seed_from_u64(r);
        let plan = Plan::tour(10, 3.0, &cfg.protocol.speeds_mps, &mut rng);
        let rec = simulate_plan(&cfg, &plan, 1, r).expect("simulated tour");
        let log = rec.odometry_log().expect("log");
        let camera = rec.camera_track(&cfg.camera, 1, r).expect("camera track");
        let id = format!("tour{r}");
        let rec = Recording {
            id: &id,
            speed_mps: None,
            log: &log,
            camera: &camera,
        };
        for o in window_samples(&rec, &opts, &WindowOptions::default()).expect("windows") {
            if let RunOutcome::Sample(s) = o {
                samples.push(*s);
            }
        }
    }
    let mut ds = Dataset::new(robot, samples, Vec::new(), 12);
    ds.feature_rule = odocal_dataset::WINDOW_RULE.to_string();
    let model = PathModelFile::fit(&ds, "bench", 2, 1, 1).expect("path model");

    // One hour of driving: a tour long enough, cut to 18 000 rows.
    let mut rng = ChaCha8Rng::seed_from_u64(99);
    let plan = Plan::tour(600, 3.0, &cfg.protocol.speeds_mps, &mut rng);
    let rec = simulate_plan(&cfg, &plan, 99, 0).expect("one-hour tour");
    let mut log = rec.odometry_log().expect("log");
    let n = log.t_s.len().min(18_000);
    log.t_s.truncate(n);
    log.left.truncate(n);
    log.right.truncate(n);
    println!(
        "correcting a {:.0} min log ({n} rows of 200 ms) with a path model 2-2-3 fitted on {} windows",
        log.t_s[n - 1] / 60.0,
        model.n_windows
    );
    let (base_wall, _) = timed(20, || {
        let revs = log.wheel_revs(&robot);
        std::hint::black_box(dead_reckon(&revs.rev, &WheelGeometry::nominal(&robot)));
    });
    let (wall, cpu) = timed(20, || {
        std::hint::black_box(
            model
                .correct_log(&log, &robot, "bench", true)
                .expect("corrected"),
        );
    });
    println!(
        "path correction: {:.2} ms wall ({:.2} ms CPU), median of 20 (target < 50 ms); nominal dead reckoning of the same log {:.2} ms (ratio {:.1}x)",
        1e3 * wall,
        1e3 * cpu,
        1e3 * base_wall,
        wall / base_wall
    );
}
