use thiserror::Error;

/// Errors of the laser positioning library.
#[derive(Debug, Error)]
pub enum LrfError {
    /// A file could not be read.
    #[error("cannot read {path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// The cause.
        source: std::io::Error,
    },
    /// A file could not be read or is not what it should be (names the file and position).
    #[error(transparent)]
    File(#[from] odocal_core::FileError),
    /// The landmark map is invalid.
    #[error("map {path}: {message}")]
    Map {
        /// The map file (or "<memory>").
        path: String,
        /// What is wrong and what to do.
        message: String,
    },
    /// A scan file is invalid at a given place.
    #[error("{path}, line {line}, column {column}: {message}")]
    Scan {
        /// The scan file.
        path: String,
        /// 1-based line number (the header is line 1).
        line: usize,
        /// Column name.
        column: String,
        /// What is wrong and what to do.
        message: String,
    },
    /// A truth file is invalid.
    #[error("{path}, line {line}: {message}")]
    Truth {
        /// The truth file.
        path: String,
        /// 1-based line number.
        line: usize,
        /// What is wrong.
        message: String,
    },
    /// Settings or inputs that do not fit together (what is wrong and what to do).
    #[error("{0}")]
    Config(String),
}
