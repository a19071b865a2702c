//! The arena file (`odocal.arena/1`): every camera's calibration with its pose in the common
//! floor frame, and how well the cameras agree where their views overlap.

use std::path::Path;

use nalgebra::{Matrix2x3, Matrix3, Point2, Vector2};
use odocal_calib::{
    check_pose_covariance, CameraFile, FloorToCamera, MAX_POSE_SHIFT_SIGMA_M,
    MAX_POSE_TURN_SIGMA_RAD,
};
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

/// How well the arena's floor frame is placed on the real floor: the covariance of a small
/// turn of the whole frame about the vertical and shift along the floor. The frame is the
/// first camera's floor frame, located from that camera's floor boards with its intrinsics;
/// the part of their error stated here moves every fix of every camera alike, by one turn
/// and shift. The fixes' σ include it, as they include the rest of the first floor's
/// uncertainty: a fix is where the robot is in the frame the first camera's floor boards
/// defined, to within its σ. A run aligned to its odometry takes the common move up, so on
/// an arena whose fixes' σ are mostly this part the aligned runs are better than their σ.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct FramePlacement {
    /// Covariance of (turn about the vertical in radians, shift along x in metres, shift along
    /// y in metres) of the frame about its origin (the first floor board's first corner), in
    /// the frame's own axes, row by row.
    pub covariance: [[f64; 3]; 3],
}

impl FramePlacement {
    /// σ of the frame's heading, radians.
    pub fn heading_sigma_rad(&self) -> f64 {
        self.covariance[0][0].sqrt()
    }

    /// σ of the frame's origin along x and y, metres.
    pub fn origin_sigma_m(&self) -> Vector2<f64> {
        Vector2::new(self.covariance[1][1].sqrt(), self.covariance[2][2].sqrt())
    }

    /// σ of where the frame's move puts a floor point `at` (metres, in the frame), √(σx² +
    /// σy²), metres: the shift's, and the turn's times the point's distance from the origin.
    pub fn sigma_at_m(&self, at: &Point2<f64>) -> f64 {
        let c = Matrix3::from_fn(|i, j| self.covariance[i][j]);
        let j = Matrix2x3::new(-at.y, 1.0, 0.0, at.x, 0.0, 1.0);
        (j * c * j.transpose()).trace().max(0.0).sqrt()
    }

    fn check(&self) -> Result<(), String> {
        let c = &self.covariance;
        let symmetric = (0..3).all(|i| {
            (0..3).all(|j| {
                (c[i][j] - c[j][i]).abs()
                    <= 1e-9 * (c[i][i] * c[j][j]).sqrt().max(f64::MIN_POSITIVE)
            })
        });
        if c.iter().flatten().any(|v| !v.is_finite()) || (0..3).any(|i| c[i][i] < 0.0) || !symmetric
        {
            return Err("frame_placement.covariance is not a covariance (finite, symmetric, variances 0 or more)".into());
        }
        if self.heading_sigma_rad() > MAX_POSE_TURN_SIGMA_RAD
            || self.origin_sigma_m().max() > MAX_POSE_SHIFT_SIGMA_M
        {
            return Err(format!(
                "frame_placement gives the floor frame's heading a σ of {:.1} mrad and its origin one of {:.0} mm: no floor calibration is that unsure",
                self.heading_sigma_rad() * 1e3,
                self.origin_sigma_m().max() * 1e3
            ));
        }
        Ok(())
    }
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
    /// How well the floor frame itself is placed (from the first camera's floor
    /// uncertainty); None when its camera file does not keep the floor's covariance, and in
    /// arena files written before it was kept.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub frame_placement: Option<FramePlacement>,
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
            // Every fix of this camera takes its σ from it.
            if let Some(pc) = &c.pose_covariance {
                check_pose_covariance(
                    &format!("cameras[{k}].pose_covariance"),
                    pc,
                    &c.calibration.camera,
                )?;
            }
            let height = iso.inverse().translation.vector.z;
            if !(height.is_finite() && height > 0.0 && height < 100.0) {
                return Err(format!(
                    "cameras[{k}].arena_to_camera puts the camera {height} m above the floor (0 to 100 m)"
                ));
            }
        }
        if let Some(f) = &self.frame_placement {
            f.check()?;
        }
        // A camera taken out of the file by hand leaves its pairs behind, which the report
        // would list as pairs of cameras the arena does not have.
        let n = self.cameras.len();
        for (i, pair) in self.pairs.iter().enumerate() {
            let (a, b) = pair.cameras;
            if a >= n || b >= n {
                return Err(format!(
                    "pairs[{i}] names cameras {a} and {b}, but the arena has {n} camera(s), numbered 0 to {}: a camera was removed or the file edited",
                    n - 1
                ));
            }
            if a == b {
                return Err(format!("pairs[{i}] pairs camera {a} with itself"));
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
