//! The ceiling-camera scene: a mildly textured floor and a small round robot
//! carrying a tag36h11 marker on a horizontal plate, moving along a timed
//! trajectory. Rendered by ray casting through the calibrated camera model
//! (anti-aliasing by supersampling, motion blur by temporal supersampling over
//! the exposure, slow lighting change, sensor noise) and written as an MJPG
//! AVI, an H.264 MP4 or a PNG sequence with a timestamp CSV.
//!
//! A realistic camera ([`CameraEffects`], `sensor.rs`: rolling shutter, flicker, exposure
//! drift, vignetting, a paper tag, a person walking through, dropped frames, H.264 at a set
//! bitrate) is off by default.
//!
//! Only the robot moves, so the floor is rendered once per video and each frame
//! re-renders just the pixels the robot can cover during the exposure.

mod encode;
mod paths;
mod render;
mod sensor;
mod tag;
mod truth;
mod video;
mod walker;

pub use paths::{demo_trajectory, frame_times, pose_at, straight_trajectory};
pub use render::SceneRenderer;
pub use sensor::{
    dropped_frames, AutoExposure, CameraEffects, Flicker, PaperTag, LAMP_FROM_CAMERA_M,
    REALISTIC_BLUR_STEP_PX, REALISTIC_EXPOSURE_S, ROW_TIME_CONVENTION,
};
pub use tag::tag36h11_pattern;
pub use truth::{frames_csv, truth_csv, FrameTruth, FramesTruth, FRAMES_CSV_HEADER};
pub use video::{
    png_name, png_timestamps, render_frames, render_video, render_video_with_progress, VideoFormat,
};

use std::path::{Path, PathBuf};
use std::sync::Arc;

use image::GrayImage;
use nalgebra::{Isometry3, Point2, Point3, Translation3, UnitQuaternion, Vector2, Vector3};
use odocal_calib::{CameraModel, FloorToCamera};
use odocal_core::{wrap_angle, Pose2};
use opencv::core::{Mat, Size};
use opencv::prelude::*;
use opencv::videoio;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use thiserror::Error;

use crate::raycast::{expose, FastNoise, RayRows, Sensor};
use sensor::Photometry;
use walker::{PersonAt, Walker};

/// Everything that can go wrong while rendering a scene.
#[derive(Debug, Error)]
pub enum SceneError {
    /// The scene or trajectory description is unusable.
    #[error("{0}")]
    Input(String),
    /// A file could not be written.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// The underlying error.
        source: std::io::Error,
    },
    /// An image could not be encoded.
    #[error("{path}: {reason}")]
    Encode {
        /// The file.
        path: String,
        /// What went wrong.
        reason: String,
    },
    /// OpenCV reported an error.
    #[error("OpenCV: {0}")]
    OpenCv(#[from] opencv::Error),
}

/// Slow global lighting change: gain(t) = 1 + amplitude · sin(2π t / period_s).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Lighting {
    /// Relative amplitude of the gain change (0.1 = ±10 %).
    pub amplitude: f64,
    /// Period of the change, seconds.
    pub period_s: f64,
}

/// The robot and its marker.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RobotLook {
    /// Id of the tag36h11 marker.
    pub tag_id: u32,
    /// Side of the tag's black square (the detector's corners), metres.
    pub tag_size_m: f64,
    /// Height of the marker plane above the floor, metres.
    pub marker_height_m: f64,
    /// Radius of the robot's round body, metres.
    pub body_radius_m: f64,
    /// Tilt of the tag plate on the robot, radians: its front edge (the tag's +x side) raised
    /// by this about the tag's y axis through its centre (0: level, as the tracker assumes).
    pub tag_tilt_rad: f64,
}

/// A ceiling-camera scene description.
#[derive(Debug, Clone, PartialEq)]
pub struct SceneConfig {
    /// The camera (image size, intrinsics, distortion).
    pub camera: CameraModel,
    /// Floor frame to camera frame.
    pub floor: FloorToCamera,
    /// The robot and marker.
    pub robot: RobotLook,
    /// Exposure time (motion blur), seconds; 0 for a sharp frame.
    pub exposure_s: f64,
    /// Temporal samples over the exposure (≥ 1).
    pub motion_samples: u32,
    /// Spatial sub-samples per pixel along each axis (anti-aliasing).
    pub supersample: u32,
    /// Optical blur and sensor noise.
    pub sensor: Sensor,
    /// Slow lighting change.
    pub lighting: Lighting,
    /// What a real camera adds (rolling shutter, flicker, a person walking through, ...):
    /// all off by default.
    pub effects: CameraEffects,
}

/// The default camera of the synthetic world, the same as `synth calib`'s
/// (1280×720, 70° horizontal field of view, mild barrel distortion), so a
/// calibration of `synth calib` output applies to rendered videos.
pub fn default_camera() -> CameraModel {
    crate::board::CalibScene::default().camera()
}

/// The default floor pose, the same as `synth calib`'s: camera 2.2 m above the
/// floor, looking down, tilted by about 2°.
pub fn default_floor() -> FloorToCamera {
    crate::board::CalibScene::default().floor()
}

/// The floor point straight below the camera centre, metres.
pub fn nadir(floor: &FloorToCamera) -> Point2<f64> {
    let c = floor.0.inverse().translation.vector;
    Point2::new(c.x, c.y)
}

/// A camera `height_m` above the floor origin looking down, with small tilts
/// about the floor x and y axes and a turn about z (degrees). Image right is
/// roughly floor +x and image up roughly floor +y.
pub fn ceiling_camera(
    height_m: f64,
    tilt_x_deg: f64,
    tilt_y_deg: f64,
    yaw_deg: f64,
) -> FloorToCamera {
    // Camera axes in the floor frame for a straight-down view: x_c = +x, y_c = -y, z_c = -z.
    let down = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI);
    let tilt = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), yaw_deg.to_radians())
        * UnitQuaternion::from_axis_angle(&Vector3::y_axis(), tilt_y_deg.to_radians())
        * UnitQuaternion::from_axis_angle(&Vector3::x_axis(), tilt_x_deg.to_radians());
    // camera → floor: rotation tilt·down, camera centre at (0, 0, height).
    let camera_to_floor = Isometry3::from_parts(Translation3::new(0.0, 0.0, height_m), tilt * down);
    FloorToCamera(camera_to_floor.inverse())
}

impl Default for SceneConfig {
    fn default() -> Self {
        Self {
            camera: default_camera(),
            floor: default_floor(),
            robot: RobotLook {
                tag_id: 0,
                tag_size_m: 0.08,
                marker_height_m: 0.08,
                body_radius_m: 0.06,
                tag_tilt_rad: 0.0,
            },
            exposure_s: 0.004,
            motion_samples: 5,
            supersample: 3,
            sensor: Sensor {
                blur_px: 0.0,
                noise_sigma: 2.0,
            },
            lighting: Lighting {
                amplitude: 0.12,
                period_s: 6.0,
            },
            effects: CameraEffects::default(),
        }
    }
}
