//! The trainer's test experiments: straight runs of odocal's robot simulator (odocal-synth), their
//! odometry logs and camera trajectories turned into a dataset by the dataset crate, as
//! `odocal synth experiment --frames none` and `odocal dataset` do, at test sizes.

#![allow(dead_code)]

use std::collections::HashMap;

use odocal_dataset::build::{assemble, process_recording, BuildOptions, Recording};
use odocal_dataset::{Dataset, WheelGeometry};
use odocal_synth::robot::{simulate_recording, RobotSimConfig};
use rayon::prelude::*;

/// A simulated experiment: the dataset, the oracle's end point of each run (its odometry
/// dead-reckoned with the run's true effective geometry) and each run's log as CSV.
pub struct Experiment {
    pub dataset: Dataset,
    pub oracle: HashMap<String, [f64; 2]>,
    pub logs: Vec<(String, String)>,
    /// The simulator's settings (its systematic error is the truth a calibration should find).
    pub config: RobotSimConfig,
}

/// Simulates `n_runs` runs of the default experiment (1.5 m at 0.2, 0.5 and 0.7 m/s in turn).
pub fn experiment(n_runs: usize, seed: u64) -> Experiment {
    let config = RobotSimConfig::default();
    let opts = BuildOptions::default();
    let runs: Vec<_> = (0..n_runs)
        .into_par_iter()
        .map(|r| {
            let id = format!("run{:03}", r + 1);
            let speed = config.speed_of_run(r);
            let rec = simulate_recording(&config, &[speed], seed, r as u64).expect("simulate");
            let log = rec.odometry_log().expect("log");
            let camera = rec
                .camera_track(&config.camera, seed, (1 << 32) + r as u64)
                .expect("trajectory");
            let outcomes = process_recording(
                &Recording {
                    id: &id,
                    speed_mps: Some(speed),
                    log: &log,
                    camera: &camera,
                },
                &opts,
            )
            .expect("dataset");
            let eff = rec.runs[0].effective;
            let geometry = WheelGeometry {
                left_wheel_diameter_m: eff.left_wheel_diameter_m,
                right_wheel_diameter_m: eff.right_wheel_diameter_m,
                wheel_base_m: eff.wheel_base_m,
            };
            (id, log.to_csv(), outcomes, geometry)
        })
        .collect();
    let mut logs = Vec::new();
    let mut outcomes = Vec::new();
    let mut geometry = HashMap::new();
    for (id, csv, o, g) in runs {
        logs.push((id.clone(), csv));
        outcomes.push(o);
        geometry.insert(id, g);
    }
    let dataset = assemble(opts.robot, outcomes);
    assert_eq!(
        dataset.samples.len(),
        n_runs,
        "rejected: {:?}",
        dataset.rejected
    );
    let oracle = dataset
        .samples
        .iter()
        .map(|s| (s.run_id.clone(), s.odometry.end_m(&geometry[&s.run_id])))
        .collect();
    Experiment {
        dataset,
        oracle,
        logs,
        config,
    }
}
