//! Odometry logs, differential-drive kinematics, camera/robot alignment and
//! the training samples of the odometry corrector (`dataset.json`).

pub mod sample;

pub use sample::{Dataset, RejectedRun, RobotParams, Sample, DATASET_FORMAT, FEATURE_RULE, N_INPUTS};
