//! The arena's errors: each message names the file or camera and says what to do.

use thiserror::Error;

/// What goes wrong while building an arena or tracking across it.
#[derive(Debug, Error)]
pub enum ArenaError {
    /// A file could not be read or is not what it should be.
    #[error(transparent)]
    File(#[from] odocal_core::FileError),
    /// A camera file or board detection failed.
    #[error(transparent)]
    Calib(#[from] odocal_calib::CalibError),
    /// Tracking failed.
    #[error(transparent)]
    Track(#[from] odocal_tracker::TrackError),
    /// The inputs as a whole cannot give an arena (names what is missing and what to do).
    #[error("{0}")]
    Input(String),
    /// The data do not support the result (the figure that fails, and its limit).
    #[error("{0}")]
    Refused(String),
    /// A camera's video is turned half a turn against its calibration (named by its index;
    /// [`crate::TurnedCamera::message`] names it by its video).
    #[error("{0}")]
    Turned(crate::TurnedCamera),
}
