//! Typed errors of the dataset crate: every message says what was wrong and where.

use thiserror::Error;

/// Why reading or processing odometry, trajectories, manifests or datasets failed.
#[derive(Debug, Error)]
pub enum DatasetError {
    /// A file could not be read or is malformed (names the file, line and column).
    #[error(transparent)]
    File(#[from] odocal_core::FileError),
    /// Inputs that do not fit together (e.g. a log that cannot overlap its trajectory).
    #[error("{0}")]
    Mismatch(String),
    /// No clock offset between a recording's log and its camera: the camera saw too little of
    /// the motion, or saw it ambiguously. Its runs are rejected with this reason; the build
    /// goes on.
    #[error("{0}")]
    NoClockOffset(String),
}

impl DatasetError {
    /// A malformed value at a 1-based line and column of a file.
    pub(crate) fn parse(path: &str, line: u64, column: u64, message: impl Into<String>) -> Self {
        Self::File(odocal_core::FileError::parse(path, line, column, message))
    }

    /// A file whose content is unusable.
    pub(crate) fn content(path: &str, message: impl Into<String>) -> Self {
        Self::File(odocal_core::FileError::content(path, message))
    }
}

/// Reads a whole text file; the error names it.
pub(crate) fn read_text(path: &std::path::Path) -> Result<String, DatasetError> {
    Ok(odocal_core::read_text(path)?)
}

/// Parses a JSON document carrying `"format": "<expected>"`, rejecting other formats clearly.
pub(crate) fn parse_json_with_format<T: serde::de::DeserializeOwned>(
    text: &str,
    name: &str,
    expected: &str,
) -> Result<T, DatasetError> {
    Ok(odocal_core::parse_tagged_json(
        text,
        name,
        expected,
        "is this the right file?",
    )?)
}
