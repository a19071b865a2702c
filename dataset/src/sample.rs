//! The `dataset.json` contract shared by the dataset builder and the trainer.

use serde::{Deserialize, Serialize};

/// The `format` tag of dataset.json files.
pub const DATASET_FORMAT: &str = "odocal.dataset/1";

/// Number of inputs per sample: eight intermediate odometry positions, t_b and t_e.
pub const N_INPUTS: usize = 18;

/// Name of the feature rule; a model trained on one rule refuses logs built with another.
pub const FEATURE_RULE: &str = "odocal.features/1: x_i,y_i of dead-reckoned odometry (start frame, metres) at t_b + i/9 (t_e - t_b), i=1..8, then t_b, t_e (seconds, robot clock)";

/// Physical parameters of a differential-drive robot used for dead reckoning.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct RobotParams {
    /// Nominal wheel diameter, metres.
    pub wheel_diameter_m: f64,
    /// Encoder counts per wheel revolution.
    pub ticks_per_rev: f64,
    /// Nominal distance between the wheels' contact points, metres.
    pub wheel_base_m: f64,
    /// Odometry logging period, seconds.
    pub period_s: f64,
}

impl Default for RobotParams {
    /// The small robot of the reference experiment.
    fn default() -> Self {
        Self {
            wheel_diameter_m: 0.043,
            ticks_per_rev: 12.0,
            wheel_base_m: 0.10,
            period_s: 0.2,
        }
    }
}

/// One training sample: one straight run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Sample {
    /// Run identifier from the manifest.
    pub run_id: String,
    /// Commanded speed, m/s.
    pub speed_mps: f64,
    /// The 18 inputs in the source's order (see [`FEATURE_RULE`]).
    pub inputs: Vec<f64>,
    /// Target: the real end position (x, y) in the run's start frame, metres.
    pub target_m: [f64; 2],
    /// Raw odometry end position (x, y) in the run's start frame, metres.
    pub raw_end_m: [f64; 2],
    /// Real path length of the run, metres.
    pub path_length_m: f64,
    /// Estimated clock offset, seconds: t_camera = t_robot + offset.
    pub clock_offset_s: f64,
    /// RMS residual of the time alignment (speed profiles), m/s.
    pub alignment_residual_mps: f64,
}

/// A run that could not be turned into a sample, and why.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RejectedRun {
    /// Run identifier from the manifest.
    pub run_id: String,
    /// Why the run was not used.
    pub reason: String,
}

/// The training set written to dataset.json.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Dataset {
    /// Always [`DATASET_FORMAT`].
    pub format: String,
    /// The feature rule the inputs follow, [`FEATURE_RULE`].
    pub feature_rule: String,
    /// Robot parameters used for dead reckoning.
    pub robot: RobotParams,
    /// The usable runs.
    pub samples: Vec<Sample>,
    /// Runs that could not be used, with reasons.
    pub rejected: Vec<RejectedRun>,
}
