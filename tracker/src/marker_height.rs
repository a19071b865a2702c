//! The marker's height above the floor as the tag's apparent size says it. The planar pose
//! takes the height from the user (`--marker-height`) and the tag's size only for its shape,
//! so a wrong height moves every fix sideways by the parallax (the height error times the
//! fix's distance from the point under the camera, over the camera's height above the
//! marker) while the corners still fit within the reprojection gate. solvePnP on the same
//! corners places the tag in depth from its size alone, which says whether the height (or
//! the size) is what was given.

use nalgebra::Point2;
use odocal_calib::{CameraModel, FloorToCamera};

use crate::pose::pnp_tag_to_floor;
use crate::TrackResult;

/// Fixes sampled, evenly over the run: the median settles long before.
const MAX_SAMPLES: usize = 300;

/// A marker height this far from the tag's apparent one is flagged, metres: about what a
/// tag printed 2 % off its nominal size gives from a 2.2 m ceiling, and well beyond the
/// median's own noise (millimetres).
pub const MARKER_HEIGHT_TOLERANCE_M: f64 = 0.04;

/// The tag's height above the floor by its apparent size, over a tracking run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MarkerHeight {
    /// Median over the fixes of the tag centre's height above the floor by solvePnP, metres.
    pub height_m: f64,
    /// Fixes the median is taken over.
    pub fixes: usize,
    /// Largest horizontal distance of a fix from the point under the camera, metres.
    pub reach_m: f64,
    /// The camera's height above the floor, metres.
    pub camera_height_m: f64,
}

impl MarkerHeight {
    /// The height of `result`'s fixes, read through `camera` over `floor` with the tag's black
    /// square `tag_size_m` on a side (None without a fix solvePnP can place).
    pub fn of(
        result: &TrackResult,
        camera: &CameraModel,
        floor: &FloorToCamera,
        tag_size_m: f64,
    ) -> Option<Self> {
        let fixes: Vec<_> = result.fixes().map(|(_, f)| f).collect();
        let step = fixes.len().div_ceil(MAX_SAMPLES).max(1);
        let mut heights: Vec<f64> = fixes
            .iter()
            .step_by(step)
            .filter_map(|f| pnp_tag_to_floor(camera, floor, &f.corners_px, tag_size_m).ok())
            .map(|t| t.translation.vector.z)
            .filter(|h| h.is_finite())
            .collect();
        if heights.is_empty() {
            return None;
        }
        heights.sort_by(f64::total_cmp);
        let camera_in_floor = floor.0.inverse().translation.vector;
        let nadir = Point2::new(camera_in_floor.x, camera_in_floor.y);
        let reach_m = fixes
            .iter()
            .map(|f| (f.pose.position() - nadir).norm())
            .fold(0.0, f64::max);
        Some(Self {
            height_m: heights[heights.len() / 2],
            fixes: heights.len(),
            reach_m,
            camera_height_m: camera_in_floor.z,
        })
    }

    /// How far the farthest fix moves sideways when the marker is taken at `given_m` instead
    /// of this height, metres.
    pub fn shift_m(&self, given_m: f64) -> f64 {
        (given_m - self.height_m).abs() * self.reach_m / (self.camera_height_m - given_m).max(1e-3)
    }

    /// A warning when the given marker height `given_m` is not the tag's apparent one.
    pub fn warning(&self, given_m: f64, tag_size_m: f64) -> Option<String> {
        if (self.height_m - given_m).abs() <= MARKER_HEIGHT_TOLERANCE_M {
            return None;
        }
        Some(format!(
            "the tag's apparent size puts it {:.3} m above the floor (median of {} fixes), but --marker-height is {given_m:.3} m, which moves the fixes up to {:.0} mm sideways if the size is right; measure the tag's height above the floor and the side of its black square (--tag-size {tag_size_m} m: each 1 % it is off moves the apparent height by {:.0} mm), and that the camera file is this camera's (its focal length scales the apparent height as the size does)",
            self.height_m,
            self.fixes,
            self.shift_m(given_m) * 1e3,
            0.01 * (self.camera_height_m - self.height_m) * 1e3
        ))
    }
}
