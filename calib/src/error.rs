use thiserror::Error;

/// Everything that can go wrong while calibrating or reading a calibration.
#[derive(Debug, Error)]
pub enum CalibError {
    /// A file could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// The underlying error.
        source: std::io::Error,
    },
    /// A file could not be read or is not what it should be (names the file and position).
    #[error(transparent)]
    File(#[from] odocal_core::FileError),
    /// A file exists but is not what it should be.
    #[error("{path}: {reason}")]
    BadFile {
        /// The file.
        path: String,
        /// What is wrong with it.
        reason: String,
    },
    /// The input set as a whole cannot be calibrated.
    #[error("{0}")]
    Input(String),
    /// OpenCV reported an error.
    #[error("OpenCV: {0}")]
    OpenCv(#[from] opencv::Error),
}
