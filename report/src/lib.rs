//! One self-contained HTML report of the odocal pipeline: calibration residuals and coverage,
//! real vs odometry vs corrected trajectories, heading oscillation, the corrector's fit across
//! runs, the trainer's Tables 1 and 2, and laser poses against the truth. Plots are inline SVG
//! made with `plotters`; the page has no scripts and loads nothing.

mod assemble;
pub mod chart;
pub mod html;
pub mod inputs;
pub mod sections;

pub use assemble::{assemble, ReportInputs};
pub use chart::{Chart, Mark, Series};
pub use html::{Block, Report, Section, Table};
pub use inputs::{parse_track_csv, Clock, TrackFile};
pub use sections::{
    calibration_section, conditions_section, corrector_section, heading_section, laser_section,
    pick_runs, training_section, trajectory_section, CalibInput, CalibView, ConditionRow,
    LaserInput, RunView,
};

/// Errors of report building.
#[derive(Debug, thiserror::Error)]
pub enum ReportError {
    /// An input file could not be read or is not what it should be.
    #[error(transparent)]
    File(#[from] odocal_core::FileError),
    /// camera.json is unusable.
    #[error(transparent)]
    Calib(#[from] odocal_calib::CalibError),
    /// dataset.json is unusable.
    #[error(transparent)]
    Dataset(#[from] odocal_dataset::DatasetError),
    /// model.json or the training report is unusable.
    #[error(transparent)]
    Train(#[from] odocal_trainer::TrainError),
    /// A laser file is unusable.
    #[error(transparent)]
    Lrf(#[from] odocal_lrf::LrfError),
    /// Inputs that do not fit together.
    #[error("{0}")]
    Mismatch(String),
    /// A plot could not be drawn.
    #[error("plot {0}")]
    Plot(String),
    /// An input file is malformed: file, line, what is wrong.
    #[error("{path}: line {line}: {message}")]
    Input {
        /// File name.
        path: String,
        /// 1-based line number (0 = whole file).
        line: usize,
        /// What is wrong and what to do.
        message: String,
    },
}
