//! Odometry logs, differential-drive kinematics, camera/robot alignment and
//! the training samples of the odometry corrector (`dataset.json`).

pub mod align;
pub mod build;
pub mod counter_wrap;
pub mod error;
pub mod frame_glitch;
mod from_manifest;
pub mod glitch;
pub mod heading;
pub mod kinematics;
pub mod lost_rows;
pub mod manifest;
pub mod mount;
pub mod odometry;
pub mod oracle;
pub mod sample;
pub mod segment;
pub mod speed_label;
pub mod turn_sides;
pub mod twitch;
pub mod units;
pub mod windows;

pub use build::{
    assemble, features_from_log, process_recording, BuildOptions, Recording, RunFeatures,
    RunOutcome,
};
pub use error::DatasetError;
pub use from_manifest::{
    build_from_manifest, errors_against_truth, log_fits_camera, swapped_with, trajectory_mismatch,
    TruthErrors, VideoTracker, TRUTH_MISMATCH_M, TRUTH_MISMATCH_S,
};
pub use kinematics::{dead_reckon, RunOdometry, WheelGeometry};
pub use manifest::{Manifest, ManifestRow};
pub use odocal_core::{Trajectory, TrajectoryRow};
pub use odometry::{LogKind, OdometryLog};
pub use oracle::{OracleFile, OracleRun};
pub use sample::{
    relative_end_error, Dataset, DatasetSummary, RejectedRun, RobotParams, Sample, DATASET_FORMAT,
    FEATURE_RULE, N_INPUTS,
};
pub use windows::{window_samples, Layout, WindowOptions, WINDOW_RULE};
