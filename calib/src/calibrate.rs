//! Zhang calibration through OpenCV (calibrateCamera, or cv::fisheye for the
//! fisheye model), with the parameters' covariance, per-view residuals and
//! checks for degenerate sets.

use nalgebra::{DMatrix, Point2, Point3, Vector3};
use opencv::calib3d;
use opencv::core::{self, Mat, Size, TermCriteria, Vector};
use opencv::prelude::*;

use crate::opencv_glue::{at, isometry_from_rt, points2f, points3f};
use crate::{
    BoardSpec, BoardToCamera, BoardView, CalibError, CameraModel, Distortion, Intrinsics,
    IntrinsicsStd, LensModel, ViewResidual,
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
    /// Covariance of [`CameraModel::parameters`] (the board poses marginalised out).
    pub covariance: DMatrix<f64>,
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

/// Calibrates from at least three views of the board (Zhang's method) with the lens model
/// `model`: OpenCV's calibrateCamera for the five-coefficient and rational models,
/// `cv::fisheye::calibrate` for the fisheye model. The parameters' covariance is computed
/// by odocal for every model ([`crate::uncertainty`]), since OpenCV's fisheye calibration
/// gives none and its pinhole calibration only the diagonal.
pub fn calibrate(
    views: &[BoardView],
    board: &BoardSpec,
    model: LensModel,
) -> Result<Calibration, CalibError> {
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
    for v in views {
        check_view_points(v, board)?;
    }
    let (camera, poses) = opencv_calibrate(views, (w, h), model)?;
    check_tilt(&poses)?;
    if !camera.parameters().iter().all(|v| v.is_finite()) || camera.intrinsics.fx <= 0.0 {
        return Err(diverged());
    }
    let observations: Vec<Observation> = views
        .iter()
        .zip(&poses)
        .map(|(v, p)| Observation {
            pose: *p,
            object: &v.object_points,
            image: &v.corners,
        })
        .collect();
    let fit = crate::uncertainty::covariance(&camera, &observations);
    let views = views
        .iter()
        .zip(&fit.view_rms_px)
        .map(|(v, rms)| ViewResidual {
            image: v.image.clone(),
            rms_px: *rms,
            held_out_rms_px: None,
            corners_px: v.corners.iter().map(|p| [p.x, p.y]).collect(),
        })
        .collect();
    let sd: Vec<f64> = (0..fit.covariance.nrows())
        .map(|i| fit.covariance[(i, i)].max(0.0).sqrt())
        .collect();
    let std = IntrinsicsStd {
        fx: sd[0],
        fy: sd[1],
        cx: sd[2],
        cy: sd[3],
        distortion: sd[4..].to_vec(),
    };
    if !fit.rms_px.is_finite() {
        return Err(diverged());
    }
    Ok(Calibration {
        camera,
        rms_px: fit.rms_px,
        std,
        covariance: fit.covariance,
        views,
        poses,
    })
}

/// One view's part of the fit: the board pose, the board points and where they were seen.
pub struct Observation<'a> {
    /// The board's pose in this view.
    pub pose: BoardToCamera,
    /// Board-frame points, metres.
    pub object: &'a [Point3<f64>],
    /// Their detected pixels, in the same order.
    pub image: &'a [Point2<f64>],
}

/// OpenCV's calibration for `model`: the camera and every view's board pose.
fn opencv_calibrate(
    views: &[BoardView],
    (w, h): (u32, u32),
    model: LensModel,
) -> Result<(CameraModel, Vec<BoardToCamera>), CalibError> {
    let mut object_points = Vector::<Vector<core::Point3f>>::new();
    let mut image_points = Vector::<Vector<core::Point2f>>::new();
    for v in views {
        object_points.push(points3f(&v.object_points));
        image_points.push(points2f(&v.corners));
    }
    let mut k = Mat::default();
    let mut dist = Mat::default();
    let mut rvecs = Vector::<Mat>::new();
    let mut tvecs = Vector::<Mat>::new();
    let criteria = TermCriteria::new(
        core::TermCriteria_Type::COUNT as i32 + core::TermCriteria_Type::EPS as i32,
        100,
        f64::EPSILON,
    )?;
    let degenerate = |e: opencv::Error| {
        // OpenCV's message spans lines; the first says what failed, after its version, source
        // file and line, which say nothing to a user.
        let first = e.message.lines().next().unwrap_or("").trim();
        let first = match first.split_once("Assertion failed)") {
            Some((_, what)) => format!("OpenCV's check {} did not hold", what.trim()),
            None => first.to_string(),
        };
        CalibError::Input(format!(
            "{model} calibration failed ({first}); the views are probably degenerate: tilt the board 20-45° in several views"
        ))
    };
    let size = Size::new(w as i32, h as i32);
    // One OpenCV fit of these corners with its own output buffers and flags.
    let pinhole_fit =
        |k: &mut Mat, d: &mut Mat, r: &mut Vector<Mat>, t: &mut Vector<Mat>, flags: i32| {
            calib3d::calibrate_camera(
                &object_points,
                &image_points,
                size,
                k,
                d,
                r,
                t,
                flags,
                criteria,
            )
        };
    let fisheye_fit =
        |k: &mut Mat, d: &mut Mat, r: &mut Vector<Mat>, t: &mut Vector<Mat>, flags: i32| {
            calib3d::calibrate(
                &object_points,
                &image_points,
                size,
                k,
                d,
                r,
                t,
                flags,
                criteria,
            )
        };
    match model {
        LensModel::Fisheye => {
            let flags =
                calib3d::Fisheye_CALIB_RECOMPUTE_EXTRINSIC | calib3d::Fisheye_CALIB_FIX_SKEW;
            let first = fisheye_fit(&mut k, &mut dist, &mut rvecs, &mut tvecs, flags);
            let finite = |m: &Mat| {
                m.data_typed::<f64>()
                    .is_ok_and(|v| !v.is_empty() && v.iter().all(|x| x.is_finite()))
            };
            // On a failed start cv::fisheye can return its initial guess with boards behind
            // the camera and no error.
            let in_front = tvecs.iter().all(|t| {
                t.data_typed::<f64>()
                    .is_ok_and(|v| v.len() == 3 && v[2] > 0.0 && v.iter().all(|x| x.is_finite()))
            });
            if !(matches!(first, Ok(rms) if rms.is_finite())
                && in_front
                && finite(&k)
                && finite(&dist))
            {
                // cv::fisheye's own start (a focal length from the image size alone) diverges
                // on some view sets with boards near the edge of a wide image; started from
                // OpenCV's rational fit of the same corners (which follows a fisheye closely
                // enough to be a start) it converges.
                let (mut kr, mut dr) = (Mat::default(), Mat::default());
                let (mut rr, mut tr) = (Vector::<Mat>::new(), Vector::<Mat>::new());
                pinhole_fit(
                    &mut kr,
                    &mut dr,
                    &mut rr,
                    &mut tr,
                    calib3d::CALIB_RATIONAL_MODEL,
                )
                .map_err(degenerate)?;
                k = kr;
                dist = Mat::from_slice(&[0.0f64; 4])?.try_clone()?;
                rvecs = Vector::new();
                tvecs = Vector::new();
                fisheye_fit(
                    &mut k,
                    &mut dist,
                    &mut rvecs,
                    &mut tvecs,
                    flags | calib3d::Fisheye_CALIB_USE_INTRINSIC_GUESS,
                )
                .map_err(degenerate)?;
            }
        }
        LensModel::Pinhole5 => {
            pinhole_fit(&mut k, &mut dist, &mut rvecs, &mut tvecs, 0).map_err(degenerate)?;
        }
        LensModel::Rational => {
            // OpenCV starts the rational fit from a distortion-free homography guess, which a
            // wide lens seen through partial boards near the image's edge can lead into a
            // wrong minimum (fx 12 % off on 110° ChArUco views); started from the
            // five-coefficient fit it finds the right one (and never a worse one on the
            // synthetic lenses). OpenCV's own start remains the fallback.
            let seeded = (|| -> Option<f64> {
                let (mut k5, mut d5) = (Mat::default(), Mat::default());
                let (mut r5, mut t5) = (Vector::<Mat>::new(), Vector::<Mat>::new());
                pinhole_fit(&mut k5, &mut d5, &mut r5, &mut t5, 0).ok()?;
                let c = d5.data_typed::<f64>().ok()?.to_vec();
                let mut d8 = [0.0f64; 8];
                for (d, v) in d8.iter_mut().zip(&c) {
                    *d = *v;
                }
                dist = Mat::from_slice(&d8).ok()?.try_clone().ok()?;
                k = k5;
                pinhole_fit(
                    &mut k,
                    &mut dist,
                    &mut rvecs,
                    &mut tvecs,
                    calib3d::CALIB_RATIONAL_MODEL | calib3d::CALIB_USE_INTRINSIC_GUESS,
                )
                .ok()
                .filter(|rms| rms.is_finite())
            })();
            if seeded.is_none() {
                (k, dist) = (Mat::default(), Mat::default());
                (rvecs, tvecs) = (Vector::new(), Vector::new());
                pinhole_fit(
                    &mut k,
                    &mut dist,
                    &mut rvecs,
                    &mut tvecs,
                    calib3d::CALIB_RATIONAL_MODEL,
                )
                .map_err(degenerate)?;
            }
        }
    }
    let mut poses = Vec::with_capacity(views.len());
    for (r, t) in rvecs.iter().zip(tvecs.iter()) {
        poses.push(BoardToCamera(
            isometry_from_rt(&r, &t)?.ok_or_else(diverged)?,
        ));
    }
    let d = dist.data_typed::<f64>()?.to_vec();
    let camera = CameraModel {
        width: w,
        height: h,
        intrinsics: Intrinsics {
            fx: at(&k, 0, 0)?,
            fy: at(&k, 1, 1)?,
            cx: at(&k, 0, 2)?,
            cy: at(&k, 1, 2)?,
        },
        distortion: Distortion::new(model, &d),
    };
    Ok((camera, poses))
}

/// The error for a fit that left the finite numbers.
fn diverged() -> CalibError {
    CalibError::Input(
        "calibration diverged; the views are probably degenerate: tilt the board 20-45° in several views"
            .into(),
    )
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
