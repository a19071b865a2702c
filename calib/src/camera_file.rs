//! camera.json: the calibration result, read by every later stage.

use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::{ArucoDictionary, CalibError, CameraModel, FloorToCamera};

/// The `format` tag of camera.json files.
pub const CAMERA_FORMAT: &str = "odocal.camera/1";

/// A calibration board: inner-corner counts, square size and what is printed on it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct BoardSpec {
    /// Inner corners along a row (the board's x axis); a ChArUco board of 11x8 squares has
    /// 10x7 inner corners.
    pub cols: u32,
    /// Inner corners along a column (the board's y axis).
    pub rows: u32,
    /// Side of one square, metres.
    pub square_m: f64,
    /// A plain checkerboard or a ChArUco board (absent in files written before odocal read
    /// ChArUco boards: those were checkerboards).
    #[serde(default)]
    pub target: BoardTarget,
}

/// What is printed on a calibration board.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "lowercase")]
pub enum BoardTarget {
    /// Black and white squares; every inner corner must be in view.
    #[default]
    Checkerboard,
    /// OpenCV's ChArUco board: ArUco markers in the white squares name every corner, so a
    /// board partly outside the image still counts.
    Charuco {
        /// Side of one marker, metres.
        marker_m: f64,
        /// The markers' dictionary.
        dictionary: ArucoDictionary,
    },
}

impl BoardSpec {
    /// A checkerboard of `cols` x `rows` inner corners and `square_m` squares.
    pub fn checkerboard(cols: u32, rows: u32, square_m: f64) -> Self {
        Self {
            cols,
            rows,
            square_m,
            target: BoardTarget::Checkerboard,
        }
    }

    /// Whether this is a ChArUco board.
    pub fn is_charuco(&self) -> bool {
        matches!(self.target, BoardTarget::Charuco { .. })
    }
}

impl std::fmt::Display for BoardSpec {
    /// "9x6 checkerboard (inner corners), 0.05 m squares" or "11x8-square ChArUco board,
    /// 0.04 m squares, 0.03 m 4X4_50 markers".
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self.target {
            BoardTarget::Checkerboard => write!(
                f,
                "{}x{} checkerboard (inner corners), {} m squares",
                self.cols, self.rows, self.square_m
            ),
            BoardTarget::Charuco {
                marker_m,
                dictionary,
            } => write!(
                f,
                "{}x{}-square ChArUco board, {} m squares, {marker_m} m {dictionary} markers",
                self.cols + 1,
                self.rows + 1,
                self.square_m
            ),
        }
    }
}

/// One standard deviation of each estimated intrinsic parameter (from the Jacobian at the
/// optimum, scaled by the residual, with the board poses marginalised out).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct IntrinsicsStd {
    /// σ of fx, pixels.
    pub fx: f64,
    /// σ of fy, pixels.
    pub fy: f64,
    /// σ of cx, pixels.
    pub cx: f64,
    /// σ of cy, pixels.
    pub cy: f64,
    /// σ of the distortion coefficients, in the lens model's OpenCV order.
    pub distortion: Vec<f64>,
}

/// Reprojection error of one calibration view.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ViewResidual {
    /// The image file of the view.
    pub image: String,
    /// RMS reprojection error of its corners, pixels.
    pub rms_px: f64,
    /// RMS reprojection error of its corners when the view was left out of the calibration
    /// (its board pose fitted alone to the calibration of the other views), pixels.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub held_out_rms_px: Option<f64>,
    /// The detected inner corners (u, v), pixels: where the views covered the image (absent in
    /// files written before odocal stored them).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub corners_px: Vec<[f64; 2]>,
}

/// A calibration image that was not used, and why.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SkippedView {
    /// The image file.
    pub image: String,
    /// Why it was skipped.
    pub reason: String,
}

/// The floor plane: where the floor frame (origin and axes fixed by the first
/// floor view, z up towards the camera) sits in the camera frame.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FloorPlane {
    /// Floor frame to camera frame.
    pub floor_to_camera: FloorToCamera,
    /// RMS distance of all floor-board corners from the fitted plane, metres.
    pub plane_rms_m: f64,
    /// Camera height above the floor, metres.
    pub camera_height_m: f64,
    /// Floor views used.
    pub views: Vec<String>,
}

/// The contents of camera.json.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CameraFile {
    /// Always [`CAMERA_FORMAT`].
    pub format: String,
    /// The estimated camera.
    pub camera: CameraModel,
    /// Overall RMS reprojection error, pixels.
    pub rms_px: f64,
    /// Standard deviations of the intrinsics, if estimated.
    pub std: Option<IntrinsicsStd>,
    /// Per-view reprojection errors.
    pub views: Vec<ViewResidual>,
    /// Views that were skipped, with the reason.
    pub skipped: Vec<SkippedView>,
    /// The calibration board.
    pub board: Option<BoardSpec>,
    /// The floor plane, if floor views were given.
    pub floor: Option<FloorPlane>,
    /// Covariance of the intrinsic parameters in the order of
    /// [`CameraModel::parameter_names`] (fx fy cx cy, then the distortion coefficients),
    /// row by row (absent in files written before odocal stored it).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub covariance: Option<Vec<Vec<f64>>>,
    /// The lens models compared by held-out reprojection error (`--model auto`).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub model_comparison: Vec<crate::select::ModelScore>,
    /// How uncertain the floor point seen at each pixel is, from the covariance and the
    /// floor boards (absent without floor views or in older files).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub floor_uncertainty: Option<crate::FloorUncertaintyMap>,
}

impl CameraFile {
    /// A camera file for a known camera (used for synthetic truth).
    pub fn from_model(camera: CameraModel, floor: Option<FloorPlane>) -> Self {
        Self {
            format: CAMERA_FORMAT.into(),
            camera,
            rms_px: 0.0,
            std: None,
            views: vec![],
            skipped: vec![],
            board: None,
            floor,
            covariance: None,
            model_comparison: vec![],
            floor_uncertainty: None,
        }
    }

    /// The intrinsics' covariance as a matrix, if the file has one.
    pub fn covariance_matrix(&self) -> Option<nalgebra::DMatrix<f64>> {
        let c = self.covariance.as_ref()?;
        let n = c.len();
        Some(nalgebra::DMatrix::from_fn(n, n, |i, j| c[i][j]))
    }

    /// Reads and validates a camera.json ([`CameraFile::check`]); errors name the file.
    pub fn load(path: &Path) -> Result<Self, CalibError> {
        let name = path.display().to_string();
        let text = odocal_core::read_text(path)?;
        // The OpenCV and ROS exports are for other tools; given back to odocal they read as
        // "invalid JSON at line 1, column 1", which names no way out.
        let yaml = text.trim_start().starts_with("%YAML")
            || text
                .lines()
                .any(|l| l.starts_with("camera_matrix:") || l.starts_with("image_width:"));
        if yaml {
            return Err(CalibError::BadFile {
                path: name,
                reason: "is a YAML camera file (OpenCV's or ROS's), which odocal writes for other tools but does not read: pass the camera.json `odocal calibrate` wrote with it".into(),
            });
        }
        let file: CameraFile = odocal_core::parse_tagged_json(
            &text,
            &name,
            CAMERA_FORMAT,
            "expected a camera.json written by `odocal calibrate`",
        )?;
        let mut file = file;
        file.check().map_err(|reason| CalibError::BadFile {
            path: name,
            reason: format!("{reason}; recalibrate with `odocal calibrate` or fix the file"),
        })?;
        if let Some(f) = &mut file.floor {
            let q = f.floor_to_camera.0.rotation.into_inner();
            f.floor_to_camera.0.rotation = nalgebra::UnitQuaternion::new_normalize(q);
        }
        Ok(file)
    }

    /// Checks the camera for physical sense: image size, focal lengths and principal point,
    /// finite distortion, and a floor pose with a unit rotation and the camera above the floor.
    /// The message names the field.
    pub fn check(&self) -> Result<(), String> {
        let c = &self.camera;
        if c.width == 0 || c.height == 0 || c.width > 100_000 || c.height > 100_000 {
            return Err(format!(
                "camera size {}x{} px is not a camera's (1..100000 each)",
                c.width, c.height
            ));
        }
        let k = &c.intrinsics;
        for (field, v) in [("fx", k.fx), ("fy", k.fy)] {
            if !(v.is_finite() && v > 0.0) {
                return Err(format!(
                    "camera.intrinsics.{field} = {v} must be > 0 (pixels)"
                ));
            }
        }
        // Even a 220° fisheye's focal length is a fifth of its image's width; a few pixels
        // is a focal length in millimetres typed into a pixels field.
        let min_f = MIN_FOCAL_SHARE * c.width.max(c.height) as f64;
        for (field, v) in [("fx", k.fx), ("fy", k.fy)] {
            if v < min_f {
                return Err(format!(
                    "camera.intrinsics.{field} = {v} px is the field of view of no camera on a {}x{} px image (at least {min_f:.0} px): focal lengths are in pixels (millimetres divided by the pixel pitch), not millimetres",
                    c.width, c.height
                ));
            }
        }
        // A field of view under half a degree is a telescope's, not a ceiling camera's: such
        // a value is a typing slip or a focal length in other units (micrometres).
        let max_f = MAX_FOCAL_SHARE * c.width.max(c.height) as f64;
        for (field, v) in [("fx", k.fx), ("fy", k.fy)] {
            if v > max_f {
                return Err(format!(
                    "camera.intrinsics.{field} = {v:.6e} px gives a field of view under 0.6 degrees on a {}x{} px image (at most {max_f:.0} px): focal lengths are in pixels (millimetres divided by the pixel pitch)",
                    c.width, c.height
                ));
            }
        }
        // Pixels are square to within a few per cent on any camera a lab would mount.
        if k.fx / k.fy > MAX_PIXEL_ASPECT || k.fy / k.fx > MAX_PIXEL_ASPECT {
            return Err(format!(
                "camera.intrinsics.fx = {} px and fy = {} px differ by more than a factor {MAX_PIXEL_ASPECT}: no camera's pixels are that far from square (was one of them edited?)",
                k.fx, k.fy
            ));
        }
        for (field, v, size) in [("cx", k.cx, c.width), ("cy", k.cy, c.height)] {
            if !(v.is_finite() && v >= 0.0 && v <= size as f64) {
                return Err(format!(
                    "camera.intrinsics.{field} = {v} is outside the image (0..{size} px)"
                ));
            }
        }
        if !c.distortion.to_opencv().iter().all(|v| v.is_finite()) {
            return Err("camera.distortion has a coefficient that is not a finite number".into());
        }
        if let Some(cov) = &self.covariance {
            let n = c.parameters().len();
            if cov.len() != n || cov.iter().any(|r| r.len() != n) {
                return Err(format!(
                    "covariance must be {n}x{n} for the {} model ({})",
                    c.distortion.model,
                    c.parameter_names().join(" ")
                ));
            }
            if cov.iter().flatten().any(|v| !v.is_finite()) {
                return Err("covariance has a value that is not a finite number".into());
            }
        }
        if !(self.rms_px.is_finite() && self.rms_px >= 0.0) {
            return Err(format!("rms_px = {} must be >= 0", self.rms_px));
        }
        if let Some(f) = &self.floor {
            let iso = &f.floor_to_camera.0;
            let norm = iso.rotation.quaternion().norm();
            // Rounded to five decimals by hand the norm is 1 ± 1e-5: read as a rotation
            // (normalised on loading); further off it is not one.
            if (norm - 1.0).abs() >= QUATERNION_NORM_TOLERANCE || norm.is_nan() {
                return Err(format!(
                    "floor.floor_to_camera rotation has norm {norm}, not a rotation (a unit quaternion)"
                ));
            }
            let t = &iso.translation.vector;
            if !t.iter().all(|v| v.is_finite()) {
                return Err("floor.floor_to_camera translation is not finite".into());
            }
            if !(f.camera_height_m.is_finite() && f.camera_height_m > 0.0) {
                return Err(format!(
                    "floor.camera_height_m = {} must be > 0 (the camera is above the floor)",
                    f.camera_height_m
                ));
            }
            // The pose puts the camera where the height says: an edited pose would map every
            // fix through a floor the camera is not above.
            let z = iso.inverse().translation.vector.z;
            if (z - f.camera_height_m).abs() > 0.01 {
                return Err(format!(
                    "floor.floor_to_camera puts the camera {z:.3} m above the floor, but floor.camera_height_m says {:.3} m",
                    f.camera_height_m
                ));
            }
        }
        if let Some(map) = &self.floor_uncertainty {
            check_floor_uncertainty(map, c)?;
        }
        if let Some(b) = &self.board {
            if !(2..=1000).contains(&b.cols) || !(2..=1000).contains(&b.rows) {
                return Err(format!(
                    "board is {}x{}: a board has 2 to 1000 inner corners each way",
                    b.cols, b.rows
                ));
            }
            if !(b.square_m.is_finite() && b.square_m > 0.0 && b.square_m <= 1.0) {
                return Err(format!(
                    "board.square_m = {} must be a square's side in metres (above 0, at most 1)",
                    b.square_m
                ));
            }
            if let BoardTarget::Charuco { marker_m, .. } = b.target {
                if !(marker_m.is_finite() && marker_m > 0.0 && marker_m < b.square_m) {
                    return Err(format!(
                        "board marker_m = {marker_m} must be above 0 and smaller than square_m = {}",
                        b.square_m
                    ));
                }
            }
        }
        Ok(())
    }

    /// The floor plane, or an error naming the file if it has none.
    pub fn require_floor(&self, path: &Path) -> Result<&FloorToCamera, CalibError> {
        self.floor
            .as_ref()
            .map(|f| &f.floor_to_camera)
            .ok_or_else(|| CalibError::BadFile {
                path: path.display().to_string(),
                reason: "has no floor plane: calibrate again with --floor images of a board lying on the floor".into(),
            })
    }
}

/// The smallest focal length a camera file may give, as a share of the image's larger side.
const MIN_FOCAL_SHARE: f64 = 0.05;

/// The largest focal length a camera file may give, as a share of the image's larger side
/// (a field of view of 0.57°).
const MAX_FOCAL_SHARE: f64 = 100.0;

/// The largest ratio of fx to fy (or fy to fx) a camera file may give.
const MAX_PIXEL_ASPECT: f64 = 2.0;

/// How far from 1 the floor rotation's quaternion norm may be (hand-typed values rounded to
/// five decimals are within 1e-5).
const QUATERNION_NORM_TOLERANCE: f64 = 1e-4;

/// The largest σ of a pose's turn a camera or arena file may give, radians: a floor or camera
/// 6° unsure is not located (real calibrations give a milliradian or less).
pub const MAX_POSE_TURN_SIGMA_RAD: f64 = 0.1;
/// The largest σ of a pose's shift a camera or arena file may give, metres.
pub const MAX_POSE_SHIFT_SIGMA_M: f64 = 1.0;

/// Checks a joint covariance of a small pose correction (rotation vector, then translation)
/// and `camera`'s intrinsics (`CameraModel::parameters`), as camera and arena files keep
/// them: its size, that it is a covariance (finite, symmetric, no negative variance), and
/// that the pose is no more unsure than any calibration leaves it. `field` names it in the
/// message.
pub fn check_pose_covariance(
    field: &str,
    c: &[Vec<f64>],
    camera: &crate::CameraModel,
) -> Result<(), String> {
    let n = 6 + camera.parameters().len();
    if c.len() != n || c.iter().any(|r| r.len() != n) {
        return Err(format!(
            "{field} must be {n}x{n} (the pose's 6 and the {} model's {} parameters)",
            camera.distortion.model,
            n - 6
        ));
    }
    if c.iter().flatten().any(|v| !v.is_finite()) || (0..n).any(|i| c[i][i] < 0.0) {
        return Err(format!(
            "{field} has a value that is not a finite number, or a negative variance"
        ));
    }
    // Written symmetric; 1e-6 leaves room for values rounded by another tool.
    let symmetric = (0..n).all(|i| {
        (0..i).all(|j| {
            (c[i][j] - c[j][i]).abs() <= 1e-6 * (c[i][i] * c[j][j]).sqrt().max(f64::MIN_POSITIVE)
        })
    });
    if !symmetric {
        return Err(format!("{field} is not symmetric, so not a covariance"));
    }
    let turn_sigma_rad = (0..3).map(|i| c[i][i].sqrt()).fold(0.0, f64::max);
    let shift_sigma_m = (3..6).map(|i| c[i][i].sqrt()).fold(0.0, f64::max);
    if turn_sigma_rad > MAX_POSE_TURN_SIGMA_RAD || shift_sigma_m > MAX_POSE_SHIFT_SIGMA_M {
        return Err(format!(
            "{field} gives the pose a σ of {:.1} mrad (turn) and {:.0} mm (shift): no calibration is that unsure (at most {:.0} mrad and {:.0} mm)",
            turn_sigma_rad * 1e3,
            shift_sigma_m * 1e3,
            MAX_POSE_TURN_SIGMA_RAD * 1e3,
            MAX_POSE_SHIFT_SIGMA_M * 1e3
        ));
    }
    Ok(())
}

/// The floor uncertainty map fits the image and holds standard deviations: `track` reads each
/// fix's calibration σ from it, so a cut or edited map would give σ of another pixel or none.
fn check_floor_uncertainty(
    map: &crate::FloorUncertaintyMap,
    camera: &crate::CameraModel,
) -> Result<(), String> {
    let cell = map.cell_px.max(1);
    let (cols, rows) = (camera.width.div_ceil(cell), camera.height.div_ceil(cell));
    if map.cell_px == 0 || map.cols != cols || map.rows != rows {
        return Err(format!(
            "floor_uncertainty is {}x{} cells of {} px, but a {}x{} px image takes {cols}x{rows} cells of {cell} px",
            map.cols, map.rows, map.cell_px, camera.width, camera.height
        ));
    }
    let cells = (cols * rows) as usize;
    if map.sigma_mm.len() != cells
        || !(map.model_spread_mm.is_empty() || map.model_spread_mm.len() == cells)
    {
        return Err(format!(
            "floor_uncertainty has {} sigma_mm and {} model_spread_mm values for its {cells} cells",
            map.sigma_mm.len(),
            map.model_spread_mm.len()
        ));
    }
    let bad = |v: &Option<f64>| v.is_some_and(|v| !(v.is_finite() && v >= 0.0));
    if let Some(i) = map
        .sigma_mm
        .iter()
        .chain(&map.model_spread_mm)
        .position(bad)
    {
        return Err(format!(
            "floor_uncertainty has a value that is not a standard deviation (a number of millimetres, 0 or more) at entry {i} (counting sigma_mm, then model_spread_mm)"
        ));
    }
    if !(map.covariance_mm2.is_empty() || map.covariance_mm2.len() == cells) {
        return Err(format!(
            "floor_uncertainty has {} covariance_mm2 values for its {cells} cells",
            map.covariance_mm2.len()
        ));
    }
    // A covariance is finite, with variances of 0 or more and a correlation within ±1.
    let not_covariance = |c: &Option<[f64; 3]>| {
        c.is_some_and(|[xx, xy, yy]| {
            ![xx, xy, yy].iter().all(|v| v.is_finite())
                || xx < 0.0
                || yy < 0.0
                || xy * xy > xx * yy * (1.0 + 1e-9) + 1e-18
        })
    };
    if let Some(i) = map.covariance_mm2.iter().position(not_covariance) {
        return Err(format!(
            "floor_uncertainty.covariance_mm2 entry {i} is not a covariance (xx, xy, yy in square millimetres: finite, xx and yy 0 or more, xy² at most xx·yy)"
        ));
    }
    // An arena carries the floor pose's covariance to every camera tied to this one: an
    // edited or corrupt value would widen every fix's σ with no other sign.
    if let Some(c) = &map.floor_covariance {
        check_pose_covariance("floor_uncertainty.floor_covariance", c, camera)?;
    }
    Ok(())
}
