//! Conversions between nalgebra types and OpenCV's.

use nalgebra::{
    Isometry3, Matrix3, Point2, Point3, Rotation3, Translation3, UnitQuaternion, Vector3,
};
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

/// A rotation vector and translation vector (OpenCV's rvec, tvec) as an isometry.
pub fn isometry_from_rt(rvec: &Mat, tvec: &Mat) -> Result<Isometry3<f64>, CalibError> {
    let mut r = Mat::default();
    opencv::calib3d::rodrigues(rvec, &mut r, &mut core::no_array())?;
    let mut m = Matrix3::zeros();
    for i in 0..3 {
        for j in 0..3 {
            m[(i, j)] = at(&r, i as i32, j as i32)?;
        }
    }
    let rot = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix(&m));
    let t = flat(tvec)?;
    Ok(Isometry3::from_parts(
        Translation3::new(t[0], t[1], t[2]),
        rot,
    ))
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
