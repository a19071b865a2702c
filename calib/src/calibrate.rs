//! Zhang calibration through OpenCV's calibrateCamera, with parameter
//! standard deviations, per-view residuals and checks for degenerate sets.

use nalgebra::{Point3, Vector3};
use opencv::calib3d;
use opencv::core::{self, Mat, Size, TermCriteria, Vector};
use opencv::prelude::*;

use crate::opencv_glue::{at, isometry_from_rt, points2f, points3f};
use crate::{
    BoardSpec, BoardToCamera, BoardView, CalibError, CameraModel, Distortion, Intrinsics,
    IntrinsicsStd, ViewResidual,
};

/// The outcome of Zhang calibration.
#[derive(Debug, Clone)]
pub struct Calibration {
    /// The estimated camera.
    pub camera: CameraModel,
    /// Overall RMS reprojection error, pixels.
    pub rms_px: f64,
    /// One standard deviation of each intrinsic parameter.
    pub std: IntrinsicsStd,
    /// RMS reprojection error of each view, pixels, in input order.
    pub views: Vec<ViewResidual>,
    /// The board pose of each view, in input order.
    pub poses: Vec<BoardToCamera>,
}

/// The board's inner corners in its own frame (z = 0), row by row, metres.
pub fn board_points(board: &BoardSpec) -> Vec<Point3<f64>> {
    (0..board.rows)
        .flat_map(|r| {
            (0..board.cols).map(move |c| {
                Point3::new(c as f64 * board.square_m, r as f64 * board.square_m, 0.0)
            })
        })
        .collect()
}

/// Minimum spread of board tilts (degrees) for the focal length to be observable.
const MIN_TILT_DEG: f64 = 8.0;

/// Calibrates from at least three views of the board (Zhang's method).
pub fn calibrate(views: &[BoardView], board: &BoardSpec) -> Result<Calibration, CalibError> {
    if views.len() < 3 {
        return Err(CalibError::Input(format!(
            "only {} usable view(s); Zhang calibration needs at least 3 (10-20 recommended), \
             with the board tilted differently in each",
            views.len()
        )));
    }
    let (w, h) = views[0].size;
    if let Some(v) = views.iter().find(|v| v.size != (w, h)) {
        return Err(CalibError::Input(format!(
            "{} is {}x{} but {} is {}x{}: all calibration images must come from the same camera at one resolution",
            v.image, v.size.0, v.size.1, views[0].image, w, h
        )));
    }
    let mut object_points = Vector::<Vector<core::Point3f>>::new();
    let mut image_points = Vector::<Vector<core::Point2f>>::new();
    for v in views {
        check_view_points(v, board)?;
        object_points.push(points3f(&v.object_points));
        image_points.push(points2f(&v.corners));
    }
    let mut k = Mat::default();
    let mut dist = Mat::default();
    let mut rvecs = Vector::<Mat>::new();
    let mut tvecs = Vector::<Mat>::new();
    let mut std_intr = Mat::default();
    let mut std_extr = Mat::default();
    let mut per_view = Mat::default();
    let criteria = TermCriteria::new(
        core::TermCriteria_Type::COUNT as i32 + core::TermCriteria_Type::EPS as i32,
        100,
        f64::EPSILON,
    )?;
    let rms = calib3d::calibrate_camera_extended(
        &object_points,
        &image_points,
        Size::new(w as i32, h as i32),
        &mut k,
        &mut dist,
        &mut rvecs,
        &mut tvecs,
        &mut std_intr,
        &mut std_extr,
        &mut per_view,
        0,
        criteria,
    )
    .map_err(|e| {
        CalibError::Input(format!(
            "calibration failed ({e}); the views are probably degenerate: tilt the board 20-45° in several views"
        ))
    })?;

    let mut poses = Vec::with_capacity(views.len());
    for (r, t) in rvecs.iter().zip(tvecs.iter()) {
        poses.push(BoardToCamera(isometry_from_rt(&r, &t)?));
    }
    check_tilt(&poses)?;

    let d = dist.data_typed::<f64>()?;
    let coeff = |i: usize| d.get(i).copied().unwrap_or(0.0);
    let camera = CameraModel {
        width: w,
        height: h,
        intrinsics: Intrinsics {
            fx: at(&k, 0, 0)?,
            fy: at(&k, 1, 1)?,
            cx: at(&k, 0, 2)?,
            cy: at(&k, 1, 2)?,
        },
        distortion: Distortion::from_opencv([coeff(0), coeff(1), coeff(2), coeff(3), coeff(4)]),
    };
    let s = std_intr.data_typed::<f64>()?;
    let sd = |i: usize| s.get(i).copied().unwrap_or(f64::NAN);
    let std = IntrinsicsStd {
        fx: sd(0),
        fy: sd(1),
        cx: sd(2),
        cy: sd(3),
        distortion: [sd(4), sd(5), sd(6), sd(7), sd(8)],
    };
    let errs = per_view.data_typed::<f64>()?;
    let views = views
        .iter()
        .enumerate()
        .map(|(i, v)| ViewResidual {
            image: v.image.clone(),
            rms_px: errs.get(i).copied().unwrap_or(f64::NAN),
            corners_px: v.corners.iter().map(|p| [p.x, p.y]).collect(),
        })
        .collect();
    if !camera.intrinsics.fx.is_finite() || camera.intrinsics.fx <= 0.0 || !rms.is_finite() {
        return Err(CalibError::Input(
            "calibration diverged; the views are probably degenerate: tilt the board 20-45° in several views".into(),
        ));
    }
    Ok(Calibration {
        camera,
        rms_px: rms,
        std,
        views,
        poses,
    })
}

/// Rejects sets whose boards are all (nearly) parallel to the image plane:
/// with them the focal length cannot be separated from the distance.
fn check_tilt(poses: &[BoardToCamera]) -> Result<(), CalibError> {
    let normals: Vec<Vector3<f64>> = poses.iter().map(|p| p.0.rotation * Vector3::z()).collect();
    let max_tilt = normals
        .iter()
        .map(|n| n.z.abs().clamp(-1.0, 1.0).acos().to_degrees())
        .fold(0.0f64, f64::max);
    if max_tilt < MIN_TILT_DEG {
        return Err(CalibError::Input(format!(
            "degenerate view set: every board is within {max_tilt:.1}° of facing the camera, so the focal length \
             cannot be estimated; add views with the board tilted 20-45° in different directions"
        )));
    }
    Ok(())
}

/// Each view's corners must come with their places on the board, at least 4 of them (a
/// homography's worth): a ChArUco view may hold only part of the board.
fn check_view_points(view: &BoardView, board: &BoardSpec) -> Result<(), CalibError> {
    if view.object_points.len() != view.corners.len() {
        return Err(CalibError::Input(format!(
            "{}: {} corners but {} board positions",
            view.image,
            view.corners.len(),
            view.object_points.len()
        )));
    }
    if view.corners.len() < 4 {
        return Err(CalibError::Input(format!(
            "{}: only {} corner(s) of the {}; a view needs at least 4",
            view.image,
            view.corners.len(),
            crate::charuco::board_name(board)
        )));
    }
    Ok(())
}
