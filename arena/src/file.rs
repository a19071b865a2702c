//! The arena file (`odocal.arena/1`): every camera's calibration with its pose in the common
//! floor frame, and how well the cameras agree where their views overlap.

use std::path::Path;

use odocal_calib::{CameraFile, FloorToCamera};
use serde::{Deserialize, Serialize};

use crate::ArenaError;

/// The `format` tag of arena files.
pub const ARENA_FORMAT: &str = "odocal.arena/1";

/// One camera of the arena.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ArenaCamera {
    /// The camera.json it came from, as given on the command line.
    pub source: String,
    /// That file's content (its own floor plane is kept as it was calibrated).
    pub calibration: CameraFile,
    /// Maps points of the arena's floor frame (the first camera's floor frame) into this
    /// camera's frame: the pose the tracker uses for this camera.
    pub arena_to_camera: FloorToCamera,
    /// Shared views this camera took part in.
    pub shared_views: usize,
    /// RMS pixel residual of this camera's shared-view corners after the fit, pixels.
    pub rms_px: f64,
    /// Joint covariance of a small correction to `arena_to_camera` (rotation vector, then
    /// translation, in metres and radians, applied before the pose) and of the intrinsics
    /// (`CameraModel::parameters`): what the calibrations' uncertainty, carried through the
    /// shared boards, leaves uncertain in where this camera's pixels land on the arena's
    /// floor. None for the first camera (its floor uncertainty map describes it) and in
    /// arena files written before it was kept.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pose_covariance: Option<Vec<Vec<f64>>>,
}

/// How far apart two cameras put one floor point (a shared board's corner seen by both).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Consistency {
    /// RMS distance, millimetres.
    pub rms_mm: f64,
    /// Largest distance, millimetres.
    pub max_mm: f64,
    /// Floor points compared (a corner seen by n cameras counts once per pair).
    pub points: usize,
}

/// [`Consistency`] for one pair of cameras.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PairConsistency {
    /// The two cameras (indices into [`ArenaFile::cameras`]).
    pub cameras: (usize, usize),
    /// Their agreement.
    pub consistency: Consistency,
}

/// The contents of an arena file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ArenaFile {
    /// Always [`ARENA_FORMAT`].
    pub format: String,
    /// The cameras, the first fixing the floor frame.
    pub cameras: Vec<ArenaCamera>,
    /// Shared views used (their names).
    pub shared_views: Vec<String>,
    /// Agreement of all pairs of cameras over the shared boards.
    pub consistency: Consistency,
    /// Agreement of each pair that shares a board.
    pub pairs: Vec<PairConsistency>,
}

impl ArenaFile {
    /// Reads and checks an arena file; errors name the file.
    pub fn load(path: &Path) -> Result<Self, ArenaError> {
        let file: ArenaFile = odocal_core::read_tagged_json(
            path,
            ARENA_FORMAT,
            "expected an arena.json written by `odocal arena`",
        )?;
        file.check().map_err(|reason| {
            ArenaError::File(odocal_core::FileError::content(
                &path.display().to_string(),
                format!("{reason}; build it again with `odocal arena`"),
            ))
        })?;
        Ok(file)
    }

    /// Checks every camera and pose for physical sense; the message names the field.
    pub fn check(&self) -> Result<(), String> {
        if self.cameras.is_empty() {
            return Err("cameras is empty: an arena has at least one camera".into());
        }
        for (k, c) in self.cameras.iter().enumerate() {
            c.calibration
                .check()
                .map_err(|e| format!("cameras[{k}].calibration: {e}"))?;
            let iso = &c.arena_to_camera.0;
            let norm = iso.rotation.quaternion().norm();
            if (norm - 1.0).abs() >= 1e-6 || norm.is_nan() {
                return Err(format!(
                    "cameras[{k}].arena_to_camera rotation has norm {norm}, not a unit quaternion"
                ));
            }
            let height = iso.inverse().translation.vector.z;
            if !(height.is_finite() && height > 0.0 && height < 100.0) {
                return Err(format!(
                    "cameras[{k}].arena_to_camera puts the camera {height} m above the floor (0 to 100 m)"
                ));
            }
        }
        let c = &self.consistency;
        if !(c.rms_mm.is_finite() && c.rms_mm >= 0.0 && c.max_mm >= c.rms_mm) {
            return Err(format!(
                "consistency rms_mm {} / max_mm {} are not distances",
                c.rms_mm, c.max_mm
            ));
        }
        Ok(())
    }
}
