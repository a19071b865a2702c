//! The tracker's error type.

use thiserror::Error;

/// Everything that can stop tracking (per-frame misses are gaps, not errors).
#[derive(Debug, Error)]
pub enum TrackError {
    /// A file or folder could not be read or written.
    #[error("{path}: {reason}")]
    Io {
        /// The file.
        path: String,
        /// What went wrong.
        reason: String,
    },
    /// The input video, image folder or timestamp file is unusable.
    #[error("{path}: {reason}")]
    BadInput {
        /// The file or folder.
        path: String,
        /// What is wrong and what to do.
        reason: String,
    },
    /// The inputs do not fit together (e.g. camera.json image size ≠ video size).
    #[error("{0}")]
    Mismatch(String),
    /// No frame gave a confident fix of the requested tag: the message names the main
    /// rejection reason with its figures; the result holds every frame's record (for the report).
    #[error("{message}")]
    NoFix {
        /// What was seen and why it was rejected.
        message: String,
        /// The tracking run, every frame a gap.
        result: Box<crate::TrackResult>,
    },
    /// A setting is invalid.
    #[error("{0}")]
    Options(String),
    /// The camera file is unusable.
    #[error(transparent)]
    Calib(#[from] odocal_calib::CalibError),
    /// OpenCV reported an error.
    #[error("OpenCV: {0}")]
    OpenCv(#[from] opencv::Error),
}

impl TrackError {
    /// A [`TrackError::BadInput`] for `path`.
    pub fn bad_input(path: impl AsRef<std::path::Path>, reason: impl Into<String>) -> Self {
        Self::BadInput {
            path: path.as_ref().display().to_string(),
            reason: reason.into(),
        }
    }

    /// A [`TrackError::Io`] for `path`.
    pub fn io(path: impl AsRef<std::path::Path>, e: impl std::fmt::Display) -> Self {
        Self::Io {
            path: path.as_ref().display().to_string(),
            reason: e.to_string(),
        }
    }
}
