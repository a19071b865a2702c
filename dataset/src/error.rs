//! Typed errors of the dataset crate: every message says what was wrong and where.

use thiserror::Error;

/// Why reading or processing odometry, trajectories, manifests or datasets failed.
#[derive(Debug, Error)]
pub enum DatasetError {
    /// A file could not be read.
    #[error("cannot read {path}")]
    Io {
        /// The file.
        path: String,
        /// The operating system's reason.
        #[source]
        source: std::io::Error,
    },
    /// A malformed value in a CSV or JSON file, with its position (1-based line and column).
    #[error("{path}:{line}:{column}: {message}")]
    Parse {
        /// The file.
        path: String,
        /// 1-based line number.
        line: u64,
        /// 1-based column (CSV field or JSON character).
        column: u64,
        /// What was wrong and what to do.
        message: String,
    },
    /// A file that parses but whose content is unusable (wrong format tag, too few rows, ...).
    #[error("{path}: {message}")]
    Content {
        /// The file.
        path: String,
        /// What was wrong and what to do.
        message: String,
    },
    /// Inputs that do not fit together (e.g. a log that cannot overlap its trajectory).
    #[error("{0}")]
    Mismatch(String),
}

impl DatasetError {
    /// Builds a [`DatasetError::Parse`].
    pub(crate) fn parse(path: &str, line: u64, column: u64, message: impl Into<String>) -> Self {
        Self::Parse {
            path: path.to_string(),
            line,
            column,
            message: message.into(),
        }
    }

    /// Builds a [`DatasetError::Content`].
    pub(crate) fn content(path: &str, message: impl Into<String>) -> Self {
        Self::Content {
            path: path.to_string(),
            message: message.into(),
        }
    }
}

impl From<odocal_core::FileError> for DatasetError {
    fn from(e: odocal_core::FileError) -> Self {
        use odocal_core::FileError as F;
        match e {
            F::Io { path, source } => Self::Io { path, source },
            F::Parse {
                path,
                line,
                column,
                message,
            } => Self::Parse {
                path,
                line,
                column,
                message,
            },
            F::Content { path, message } => Self::Content { path, message },
        }
    }
}

/// Reads a whole text file, mapping the error to [`DatasetError::Io`].
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
