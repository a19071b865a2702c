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

/// Reads a whole text file, mapping the error to [`DatasetError::Io`].
pub(crate) fn read_text(path: &std::path::Path) -> Result<String, DatasetError> {
    std::fs::read_to_string(path).map_err(|source| DatasetError::Io {
        path: path.display().to_string(),
        source,
    })
}

/// Parses a JSON document carrying `"format": "<expected>"`, rejecting other formats clearly.
pub(crate) fn parse_json_with_format<T: serde::de::DeserializeOwned>(
    text: &str,
    name: &str,
    expected: &str,
) -> Result<T, DatasetError> {
    let value: serde_json::Value = serde_json::from_str(text).map_err(|e| {
        DatasetError::parse(
            name,
            e.line() as u64,
            e.column() as u64,
            format!("invalid JSON: {e}"),
        )
    })?;
    match value.get("format").and_then(|f| f.as_str()) {
        Some(f) if f == expected => {}
        Some(f) => {
            return Err(DatasetError::content(
                name,
                format!("format is \"{f}\", expected \"{expected}\"; is this the right file?"),
            ))
        }
        None => {
            return Err(DatasetError::content(
                name,
                format!("no \"format\" field, expected \"{expected}\"; is this the right file?"),
            ))
        }
    }
    serde_json::from_str(text)
        .map_err(|e| DatasetError::parse(name, e.line() as u64, e.column() as u64, format!("{e}")))
}
