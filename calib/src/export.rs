//! Exports of a calibration for other tools: OpenCV FileStorage YAML (through
//! OpenCV itself) and ROS camera_info YAML.

use opencv::core::{FileStorage, FileStorage_Mode, Mat};
use opencv::prelude::*;

use crate::opencv_glue::{camera_matrix, dist_coeffs};
use crate::{CalibError, CameraFile};

/// The calibration as an OpenCV FileStorage YAML file (the layout of
/// OpenCV's calibration sample: camera_matrix, distortion_coefficients, ...).
/// The text is returned, for the caller to write with its other outputs.
pub fn opencv_yaml(cam: &CameraFile) -> Result<String, CalibError> {
    {
        // In memory: OpenCV picks the format from this name's extension.
        let mut fs = FileStorage::new(
            ".yaml",
            FileStorage_Mode::WRITE as i32 | FileStorage_Mode::MEMORY as i32,
            "",
        )?;
        fs.write_i32("image_width", cam.camera.width as i32)?;
        fs.write_i32("image_height", cam.camera.height as i32)?;
        fs.write_mat("camera_matrix", &camera_matrix(&cam.camera)?)?;
        let d: Mat = dist_coeffs(&cam.camera)?;
        fs.write_mat("distortion_coefficients", &d)?;
        // Which of OpenCV's functions the coefficients are for: the fisheye ones
        // (cv::fisheye) or the pinhole ones (5 or 8 coefficients).
        fs.write_str("distortion_model", cam.camera.distortion.model.name())?;
        fs.write_f64("avg_reprojection_error", cam.rms_px)?;
        if let Some(floor) = &cam.floor {
            let iso = floor.floor_to_camera.0;
            let r = iso.rotation.to_rotation_matrix();
            let rows: Vec<[f64; 3]> = (0..3).map(|i| [r[(i, 0)], r[(i, 1)], r[(i, 2)]]).collect();
            fs.write_mat("floor_rotation", &Mat::from_slice_2d(&rows)?)?;
            let t = iso.translation.vector;
            fs.write_mat(
                "floor_translation",
                &Mat::from_slice(&[t.x, t.y, t.z])?.try_clone()?,
            )?;
        }
        Ok(fs.release_and_get_string()?)
    }
}

/// The calibration as a ROS camera_info YAML file (`plumb_bob`, `rational_polynomial` or
/// `equidistant`, by the lens model).
pub fn ros_yaml(cam: &CameraFile, camera_name: &str) -> String {
    let k = cam.camera.intrinsics;
    let d = cam.camera.distortion.to_opencv();
    let fmt = |v: &[f64]| {
        v.iter()
            .map(|x| format!("{x:.10}"))
            .collect::<Vec<_>>()
            .join(", ")
    };
    let text = format!(
        "image_width: {w}\nimage_height: {h}\ncamera_name: {camera_name}\n\
         camera_matrix:\n  rows: 3\n  cols: 3\n  data: [{km}]\n\
         distortion_model: {model}\n\
         distortion_coefficients:\n  rows: 1\n  cols: {n}\n  data: [{dm}]\n\
         rectification_matrix:\n  rows: 3\n  cols: 3\n  data: [1, 0, 0, 0, 1, 0, 0, 0, 1]\n\
         projection_matrix:\n  rows: 3\n  cols: 4\n  data: [{pm}]\n",
        w = cam.camera.width,
        h = cam.camera.height,
        km = fmt(&[k.fx, 0.0, k.cx, 0.0, k.fy, k.cy, 0.0, 0.0, 1.0]),
        model = cam.camera.distortion.model.ros_name(),
        n = d.len(),
        dm = fmt(&d),
        pm = fmt(&[k.fx, 0.0, k.cx, 0.0, 0.0, k.fy, k.cy, 0.0, 0.0, 0.0, 1.0, 0.0]),
    );
    text
}
