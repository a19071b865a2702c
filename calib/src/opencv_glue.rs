//! Conversions between nalgebra types and OpenCV's.

use nalgebra::{Isometry3, Point2, Point3, Translation3, UnitQuaternion, Vector3};
use opencv::core::{self, Mat, MatTraitConst, Point2f, Point3f, Vector};
use opencv::prelude::*;

use crate::{CalibError, CameraModel};

/// K as an OpenCV 3x3 CV_64F matrix.
pub fn camera_matrix(camera: &CameraModel) -> Result<Mat, CalibError> {
    let k = camera.intrinsics;
    Ok(Mat::from_slice_2d(&[
        [k.fx, 0.0, k.cx],
        [0.0, k.fy, k.cy],
        [0.0, 0.0, 1.0],
    ])?)
}

/// Distortion coefficients as an OpenCV 1x5 CV_64F row.
pub fn dist_coeffs(camera: &CameraModel) -> Result<Mat, CalibError> {
    Ok(Mat::from_slice(&camera.distortion.to_opencv())?.try_clone()?)
}

/// Image points as OpenCV's float points.
pub fn points2f(points: &[Point2<f64>]) -> Vector<Point2f> {
    points
        .iter()
        .map(|p| Point2f::new(p.x as f32, p.y as f32))
        .collect()
}

/// Object points as OpenCV's float points.
pub fn points3f(points: &[Point3<f64>]) -> Vector<Point3f> {
    points
        .iter()
        .map(|p| Point3f::new(p.x as f32, p.y as f32, p.z as f32))
        .collect()
}

/// Reads element (r, c) of a CV_64F matrix.
pub fn at(m: &Mat, r: i32, c: i32) -> Result<f64, CalibError> {
    Ok(*m.at_2d::<f64>(r, c)?)
}

/// A rotation vector and translation vector (OpenCV's rvec, tvec) as an isometry, or `None`
/// when either holds a value that is not finite (a fit that diverged).
pub fn isometry_from_rt(rvec: &Mat, tvec: &Mat) -> Result<Option<Isometry3<f64>>, CalibError> {
    let (r, t) = (flat(rvec)?, flat(tvec)?);
    if !r.iter().chain(t.iter()).all(|v| v.is_finite()) {
        // Turned into a rotation matrix first, a NaN never converges to the nearest rotation.
        return Ok(None);
    }
    // A Rodrigues vector is the rotation's axis scaled by its angle.
    Ok(Some(Isometry3::from_parts(
        Translation3::from(t),
        UnitQuaternion::from_scaled_axis(r),
    )))
}

/// The three values of a 3x1 or 1x3 CV_64F matrix.
pub fn flat(m: &Mat) -> Result<Vector3<f64>, CalibError> {
    let data = m.data_typed::<f64>()?;
    if data.len() < 3 {
        return Err(CalibError::Input(format!(
            "expected 3 values from OpenCV, got {}",
            data.len()
        )));
    }
    Ok(Vector3::new(data[0], data[1], data[2]))
}

/// Locates a planar or 3-D target in the camera frame from its image: maps target-frame
/// points into the camera frame. OpenCV's solvePnP (with `method`, e.g. `SOLVEPNP_ITERATIVE`)
/// starts from the ideal normalised coordinates that odocal's camera model gives every lens
/// model (OpenCV's own undistortion iterates too few times for wide lenses and knows no
/// fisheye), and the pose is then refined by Levenberg–Marquardt on the pixel residuals.
pub fn solve_pnp(
    camera: &CameraModel,
    object: &[Point3<f64>],
    image: &[Point2<f64>],
    method: i32,
) -> Result<Option<Isometry3<f64>>, CalibError> {
    // Only corners whose ideal coordinates the model maps back onto them start the pose: a
    // model calibrated without a view reaching the image's edge may turn over before it (a
    // rational lens's radial factor, extrapolated), and no ray maps there; such corners' ideal
    // coordinates are wherever its inversion stopped, and put the board behind the camera.
    // They are kept for the refinement, which judges every corner.
    let start_pairs: Vec<(Point3<f64>, core::Point2d)> = object
        .iter()
        .zip(image)
        .filter_map(|(o, p)| {
            let u = camera.unproject(p);
            let back = camera.project(&Point3::new(u.x, u.y, 1.0))?;
            ((back - p).norm() < ROUND_TRIP_PX).then(|| (*o, core::Point2d::new(u.x, u.y)))
        })
        .collect();
    let (object_cv, ideal): (Vector<core::Point3d>, Vector<core::Point2d>) =
        if start_pairs.len() >= 6 {
            (
                start_pairs
                    .iter()
                    .map(|(o, _)| core::Point3d::new(o.x, o.y, o.z))
                    .collect(),
                start_pairs.iter().map(|(_, u)| *u).collect(),
            )
        } else {
            (
                points3d(object),
                image
                    .iter()
                    .map(|p| {
                        let u = camera.unproject(p);
                        core::Point2d::new(u.x, u.y)
                    })
                    .collect(),
            )
        };
    let eye = Mat::from_slice_2d(&[[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])?;
    let mut rvec = Mat::default();
    let mut tvec = Mat::default();
    let ok = opencv::calib3d::solve_pnp(
        &object_cv,
        &ideal,
        &eye,
        &core::no_array(),
        &mut rvec,
        &mut tvec,
        false,
        method,
    )?;
    if !ok {
        return Ok(None);
    }
    let Some(start) = isometry_from_rt(&rvec, &tvec)? else {
        return Ok(None);
    };
    let moved = |p: &[f64]| {
        let rot = UnitQuaternion::from_scaled_axis(Vector3::new(p[0], p[1], p[2]));
        Isometry3::from_parts(
            Translation3::from(start.translation.vector + Vector3::new(p[3], p[4], p[5])),
            rot * start.rotation,
        )
    };
    let residuals = |p: &[f64]| -> Vec<f64> {
        let pose = moved(p);
        object
            .iter()
            .zip(image)
            .flat_map(|(o, x)| match camera.project(&(pose * o)) {
                Some(q) => [q.x - x.x, q.y - x.y],
                None => [f64::NAN, f64::NAN],
            })
            .collect()
    };
    if residuals(&[0.0; 6]).iter().any(|v| !v.is_finite()) {
        return Ok(Some(start));
    }
    let (p, _) = odocal_core::lsq::minimize(&residuals, vec![0.0; 6], 50);
    Ok(Some(moved(&p)))
}

/// A corner whose ideal coordinates project back this far from it, pixels, has none the lens
/// model maps onto it (its inversion stopped short): far beyond any corner's noise, far below
/// a misplaced start.
const ROUND_TRIP_PX: f64 = 0.01;

/// Object points as OpenCV's double points.
pub fn points3d(points: &[Point3<f64>]) -> Vector<core::Point3d> {
    points
        .iter()
        .map(|p| core::Point3d::new(p.x, p.y, p.z))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_pose_is_the_rodrigues_vectors_rotation_and_a_diverged_one_is_none() {
        let rvec = Mat::from_slice(&[0.1f64, -0.2, 0.3])
            .unwrap()
            .try_clone()
            .unwrap();
        let tvec = Mat::from_slice(&[1.0f64, 2.0, 3.0])
            .unwrap()
            .try_clone()
            .unwrap();
        let pose = isometry_from_rt(&rvec, &tvec).unwrap().unwrap();
        let mut r = Mat::default();
        opencv::calib3d::rodrigues(&rvec, &mut r, &mut core::no_array()).unwrap();
        let m = pose.rotation.to_rotation_matrix();
        for i in 0..3 {
            for j in 0..3 {
                assert!((m[(i, j)] - at(&r, i as i32, j as i32).unwrap()).abs() < 1e-15);
            }
        }
        assert_eq!(pose.translation.vector, Vector3::new(1.0, 2.0, 3.0));
        let nan = Mat::from_slice(&[f64::NAN, 0.0, 0.0])
            .unwrap()
            .try_clone()
            .unwrap();
        assert!(isometry_from_rt(&nan, &tvec).unwrap().is_none());
        assert!(isometry_from_rt(&rvec, &nan).unwrap().is_none());
    }
}
