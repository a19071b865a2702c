//! The odometry corrector of the reference experiment: an 18-k-2 perceptron trained by
//! Levenberg–Marquardt or back-propagation, its cross-validated experiments
//! (Tables 1 and 2), baselines on the same folds, and model files.

pub mod baseline;
mod correct_log;
pub mod crossval;
pub mod data;
pub mod domain;
pub mod error;
pub mod evaluate;
mod fit_model;
pub mod kernel_ridge;
pub mod log_steps;
pub mod metrics;
pub mod model;
pub mod net;
pub mod path_model;
mod path_model_file;
pub mod report;
pub mod train;
pub mod umbmark;

pub use baseline::{KinematicCalibration, LinearRegression, RosMultipliers};
pub use correct_log::CorrectedRun;
pub use crossval::{sweep, SweepReport, SweepSettings};
pub use data::{parse_dataset, sha256_hex};
pub use error::TrainError;
pub use fit_model::{fit_model, oracle_ends, FittedModel};
pub use kernel_ridge::{KernelRidge, KernelRidgeParams};
pub use metrics::{MeanSd, Metrics, SPREAD_NOTE};
pub use model::{ModelFile, ModelMetrics, MODEL_FORMAT};
pub use net::{Normalisation, Perceptron};
pub use path_model_file::{CorrectedPath, PathModelFile, PATH_MODEL_FORMAT};
pub use train::{
    drives_backwards, train, train_runs, Method, TrainSettings, TrainedNet, MAX_WEIGHT_DECAY,
};
