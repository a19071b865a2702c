//! The marker's height above the floor as the tag's apparent size says it. The planar pose
//! takes the height from the user (`--marker-height`) and the tag's size only for its shape,
//! so a wrong height moves every fix sideways by the parallax (the height error times the
//! fix's distance from the point under the camera, over the camera's height above the
//! marker) while the corners still fit within the reprojection gate. solvePnP on the same
//! corners places the tag in depth from its size alone, which says whether the height (or
//! the size) is what was given.

use nalgebra::Point2;
use odocal_calib::{CameraModel, FloorToCamera};

use crate::pose::{planar_pose, pnp_tag_to_floor};
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

/// A tag side this far (as a share) from `--tag-size` is flagged: what a marker height
/// 7 mm off gives under a 2.2 m ceiling, several times a good calibration's focal-length
/// error, and a third of the 1 % of a print scaled to fit the page (which makes every σ
/// five times too large; 0.3 % makes it about twice).
pub const TAG_SIDE_TOLERANCE: f64 = 0.003;

/// The side of the tag's black square on the marker plane, as the fixes' corners span it.
/// The planar fit holds the square at `--tag-size` and takes the height from
/// `--marker-height`, so a size or height a percent off leaves the positions alone but
/// shows in every fix's misfit, which the fixes' σ take for noise (a 1 % error makes every
/// σ five times too large, with no word). Those scale the square alike all over the image;
/// a lens distortion that is not the lens's (another camera's calibration, or one without
/// its distortion) scales it more towards the image's edge, and moves the fixes there.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TagSide {
    /// Median over the fixes of the square's side on the marker plane, metres.
    pub side_m: f64,
    /// Fixes the median is taken over.
    pub fixes: usize,
    /// The camera's height above the marker plane, metres.
    pub camera_above_marker_m: f64,
    /// Median side over the third of the fixes nearest the image centre, metres, and their
    /// median distance from it, pixels.
    pub inner: (f64, f64),
    /// The same over the third farthest from the image centre.
    pub outer: (f64, f64),
}

impl TagSide {
    /// The side of `result`'s tags, read through `camera` over `floor` at `marker_height_m`
    /// (None without a fix).
    pub fn of(
        result: &TrackResult,
        camera: &CameraModel,
        floor: &FloorToCamera,
        tag_size_m: f64,
        marker_height_m: f64,
    ) -> Option<Self> {
        let fixes: Vec<_> = result.fixes().map(|(_, f)| f).collect();
        let step = fixes.len().div_ceil(MAX_SAMPLES).max(1);
        let centre = Point2::new(camera.width as f64 / 2.0, camera.height as f64 / 2.0);
        // (distance of the tag from the image centre in pixels, side in metres)
        let mut by_radius: Vec<(f64, f64)> = fixes
            .iter()
            .step_by(step)
            .filter_map(|f| {
                let p = planar_pose(camera, floor, &f.corners_px, tag_size_m, marker_height_m)?;
                let c = f
                    .corners_px
                    .iter()
                    .fold(Point2::origin(), |s, q| s + q.coords / 4.0);
                Some(((c - centre).norm(), p.size_m))
            })
            .filter(|(_, s)| s.is_finite())
            .collect();
        if by_radius.is_empty() {
            return None;
        }
        by_radius.sort_by(|a, b| a.0.total_cmp(&b.0));
        let third = (by_radius.len() / 3).max(1);
        let medians = |part: &[(f64, f64)]| {
            let mut r: Vec<f64> = part.iter().map(|x| x.0).collect();
            let mut s: Vec<f64> = part.iter().map(|x| x.1).collect();
            (median(&mut s), median(&mut r))
        };
        let n = by_radius.len();
        let inner = medians(&by_radius[..third]);
        let outer = medians(&by_radius[n - third..]);
        let mut sides: Vec<f64> = by_radius.iter().map(|x| x.1).collect();
        Some(Self {
            side_m: median(&mut sides),
            fixes: n,
            camera_above_marker_m: floor.0.inverse().translation.vector.z - marker_height_m,
            inner,
            outer,
        })
    }

    /// A warning when the side is not `tag_size_m`: the lens distortion when the side
    /// changes from the image's centre to its edge, else the size or the marker height
    /// `marker_height_m`, by what each would have to be.
    pub fn warning(&self, tag_size_m: f64, marker_height_m: f64) -> Option<String> {
        // A size, height or focal length off scales every square alike: a change of the
        // side over 50 px or more from the centre outwards is the mapping's.
        let spread = (self.outer.0 - self.inner.0) / tag_size_m;
        if self.outer.1 - self.inner.1 > 50.0 && spread.abs() > TAG_SIDE_TOLERANCE {
            return Some(format!(
                "the tag's black square spans {:.2} mm on the marker plane nearer the image's centre (about {:.0} px from it) but {:.2} mm farther out (about {:.0} px; medians of a third of {} fixes each): the camera file does not map this camera's image onto the floor (another camera's calibration, or one without its lens distortion), and the fixes are off by about {:.1} % of their distance from the point under the camera; give the camera.json calibrated for this camera",
                self.inner.0 * 1e3,
                self.inner.1,
                self.outer.0 * 1e3,
                self.outer.1,
                self.fixes,
                100.0 * (self.side_m / tag_size_m - 1.0).abs().max(spread.abs()),
            ));
        }
        let ratio = self.side_m / tag_size_m;
        if (ratio - 1.0).abs() <= TAG_SIDE_TOLERANCE {
            return None;
        }
        // The side scales with the distance from the camera: a marker higher by δ is seen
        // (D − δ)/D as large at the height given.
        let height_m = marker_height_m + self.camera_above_marker_m * (1.0 - 1.0 / ratio);
        Some(format!(
            "the tag's black square spans {:.2} mm on the marker plane (median of {} fixes), {:+.1} % from --tag-size {:.2} mm: either the size is off (a print scaled to fit the page; measure the square and give --tag-size {:.4}), or the marker sits at {:.3} m, not --marker-height {marker_height_m:.3} m, or the camera file is not this camera's (its focal length scales the square as the size does). Positions are not moved by a size or height off, but every fix's σ takes the misfit for noise and is too large",
            self.side_m * 1e3,
            self.fixes,
            (ratio - 1.0) * 100.0,
            tag_size_m * 1e3,
            self.side_m,
            height_m,
        ))
    }
}

/// The median of `v` (sorted in place); `v` is not empty.
fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}
