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
        let nadir = nadir(floor);
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

/// A tag side this far (as a share) from `--tag-size` may be flagged: what a marker height
/// 2 mm off gives under a 2.2 m ceiling, or a side a tenth of a millimetre off. The median
/// side over a run is known to a few thousandths of a percent on a clean video, so the
/// floor is set by what calibrations and prints differ by, not by the measurement.
pub const TAG_SIDE_TOLERANCE: f64 = 0.001;

/// A side off by this many of its median's standard errors is the run's, not its noise.
const TAG_SIDE_SIGNIFICANCE: f64 = 5.0;

/// A side off is flagged when the parallax of the marker height it would mean moves the
/// typical fix by this many times the typical fix's σ: less hides within the σ.
const TAG_SIDE_SHIFT_OVER_SIGMA: f64 = 3.0;

/// A change of the side from the image's centre to its edge beyond this share is the
/// mapping's (a size, height or focal length scales every square alike).
const LENS_SIDE_SPREAD: f64 = 0.003;

/// Corners moving at most this far between frames, pixels, leave the square's side as it
/// is at rest: a smear no longer than this (the exposure is at most a frame period) moves
/// each edge's fitted line by less than the noise (80.002 mm for an 80 mm tag smeared 1.5–2.5
/// px; 79.84 mm, −0.2 %, at 4.5–6 px).
pub const STILL_MOTION_PX: f64 = 2.5;

/// Fixes this still are enough to give the side without a smear.
const STILL_FIXES: usize = 20;

/// How much a smear beyond [`STILL_MOTION_PX`] may shrink the side, share per pixel: the
/// −0.2 % at 4.5–6 px, rounded up, taking the motion between frames for the smear (an
/// exposure shorter than the frame period smears less).
const BLUR_SHRINK_PER_PX: f64 = 0.001;

/// The side of the tag's black square on the marker plane, as the fixes' corners span it.
/// The planar fit holds the square at `--tag-size` and takes the height from
/// `--marker-height`, so a side off has three causes that differ in what they do to the
/// positions: a size off leaves them alone but shows in every fix's misfit, which the
/// fixes' σ take for noise (a 1 % error makes every σ five times too large, with no word);
/// a height off moves every fix by the parallax, radially from the point under the camera;
/// a focal length off (a video scaled after recording) scales every fix's distance from
/// it. Those two move a fix by the same share of that distance, the side's share off. A
/// camera file that does not map the image (another camera's, or an image shifted after
/// recording) may change the side too, but moves the fixes by what the side cannot tell
/// (105 mm RMS for a 40 px shift that changed it 0.9 %). A lens distortion that is not the lens's (another
/// camera's calibration, or one without its distortion) scales the square more towards
/// the image's edge.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TagSide {
    /// Median over the fixes of the square's side on the marker plane, metres.
    pub side_m: f64,
    /// Standard error of that median, metres (from the sides' median absolute deviation).
    pub side_sigma_m: f64,
    /// Fixes the median is taken over.
    pub fixes: usize,
    /// The camera's height above the marker plane, metres.
    pub camera_above_marker_m: f64,
    /// Median and largest horizontal distance of a fix from the point under the camera,
    /// metres.
    pub distance_m: (f64, f64),
    /// Median over the fixes of their position σ (x and y together), metres.
    pub position_sigma_m: f64,
    /// Median side over the third of the fixes nearest the image centre, metres, and their
    /// median distance from it, pixels.
    pub inner: (f64, f64),
    /// The same over the third farthest from the image centre.
    pub outer: (f64, f64),
    /// Standard error of `outer`'s side less `inner`'s, metres, from each third's own
    /// spread (the whole run's spread holds the change across the image itself).
    pub inner_outer_sigma_m: f64,
    /// How much a smear shrank the median side, as a share: how far it falls short of the
    /// side of the fixes whose corners move at most [`STILL_MOTION_PX`] between frames (when
    /// there are [`STILL_FIXES`] of them; else of the slowest third, from 3 × that many
    /// fixes), at most [`BLUR_SHRINK_PER_PX`] per pixel of the fixes' median motion beyond
    /// [`STILL_MOTION_PX`].
    pub blur_shrink: f64,
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
        // (corner motion between frames in pixels per frame, distance of the tag from the
        // image centre in pixels, side in metres)
        let mut all: Vec<(f64, f64, f64)> = motion_between_frames(result)
            .into_iter()
            .zip(&fixes)
            .step_by(step)
            .filter_map(|(m, f)| {
                let p = planar_pose(camera, floor, &f.corners_px, tag_size_m, marker_height_m)?;
                let c = f
                    .corners_px
                    .iter()
                    .fold(Point2::origin(), |s, q| s + q.coords / 4.0);
                Some((m.unwrap_or(f64::INFINITY), (c - centre).norm(), p.size_m))
            })
            .filter(|(_, _, s)| s.is_finite())
            .collect();
        // A tag smeared by its motion during the exposure spans a smaller square. The side
        // without a smear is the still fixes' when there are enough, else the slowest
        // third's; where the whole run's side falls short of it, a smear took that off.
        all.sort_by(|a, b| a.0.total_cmp(&b.0));
        let still = all.iter().filter(|x| x.0 <= STILL_MOTION_PX).count();
        let third = all.len() / 3;
        let side_of = |part: &[(f64, f64, f64)]| {
            let mut s: Vec<f64> = part.iter().map(|x| x.2).collect();
            median(&mut s)
        };
        let mut motions: Vec<f64> = all.iter().map(|x| x.0).filter(|m| m.is_finite()).collect();
        let blur_shrink = if all.is_empty() || motions.is_empty() {
            0.0
        } else {
            let unsmeared = if still >= STILL_FIXES {
                side_of(&all[..still])
            } else if third >= STILL_FIXES {
                side_of(&all[..third])
            } else {
                side_of(&all)
            };
            let shortfall = ((unsmeared - side_of(&all)) / tag_size_m).max(0.0);
            let beyond_px = (median(&mut motions) - STILL_MOTION_PX).max(0.0);
            shortfall.min(BLUR_SHRINK_PER_PX * beyond_px)
        };
        let mut by_radius: Vec<(f64, f64)> = all.iter().map(|x| (x.1, x.2)).collect();
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
        // A median's standard error is 1.25 σ/√n, σ being 1.48 median absolute deviations.
        let median_sigma = |sides: &mut Vec<f64>| {
            let m = median(sides);
            let mut deviations: Vec<f64> = sides.iter().map(|s| (s - m).abs()).collect();
            1.25 * 1.4826 * median(&mut deviations) / (sides.len() as f64).sqrt()
        };
        let third_sigma =
            |part: &[(f64, f64)]| median_sigma(&mut part.iter().map(|x| x.1).collect::<Vec<f64>>());
        let inner_outer_sigma_m =
            third_sigma(&by_radius[..third]).hypot(third_sigma(&by_radius[n - third..]));
        let mut sides: Vec<f64> = by_radius.iter().map(|x| x.1).collect();
        let side_m = median(&mut sides);
        let side_sigma_m = median_sigma(&mut sides);
        let nadir = nadir(floor);
        let mut distances: Vec<f64> = fixes
            .iter()
            .map(|f| (f.pose.position() - nadir).norm())
            .collect();
        let mut sigmas: Vec<f64> = fixes
            .iter()
            .map(|f| f.sigma.x_m.hypot(f.sigma.y_m))
            .collect();
        Some(Self {
            side_m,
            side_sigma_m,
            fixes: n,
            camera_above_marker_m: floor.0.inverse().translation.vector.z - marker_height_m,
            distance_m: (
                median(&mut distances),
                distances.iter().copied().fold(0.0, f64::max),
            ),
            position_sigma_m: median(&mut sigmas),
            inner,
            outer,
            inner_outer_sigma_m,
            blur_shrink,
        })
    }

    /// A warning when the side is not `tag_size_m`: the lens distortion when the side
    /// changes from the image's centre to its edge, else the size, the marker height
    /// `marker_height_m` or the focal length, with what each does to the positions.
    pub fn warning(&self, tag_size_m: f64, marker_height_m: f64) -> Option<String> {
        // A change of the side over 50 px or more from the centre outwards is the mapping's,
        // when the two thirds' medians differ by more than their noise (a 640x360 H.264
        // video's 27 fixes put a right calibration's thirds 0.34 % apart).
        let spread = (self.outer.0 - self.inner.0) / tag_size_m;
        let spread_sigma = self.inner_outer_sigma_m / tag_size_m;
        if self.outer.1 - self.inner.1 > 50.0
            && spread.abs() > LENS_SIDE_SPREAD
            && spread.abs() > TAG_SIDE_SIGNIFICANCE * spread_sigma
        {
            // How far the fixes are off the square cannot say: an image shifted or cropped
            // after recording moves every fix by centimetres with the square nearly unchanged.
            return Some(format!(
                "the tag's black square spans {:.2} mm on the marker plane nearer the image's centre (about {:.0} px from it) but {:.2} mm farther out (about {:.0} px; medians of a third of {} fixes each): the camera file does not map this camera's image onto the floor (another camera's calibration, one without its lens distortion, or an image cropped, shifted or scaled after recording), so the fixes are off by an amount the square's size cannot tell (a shifted image moves every fix with the square nearly unchanged); give the camera.json calibrated for this camera and this image",
                self.inner.0 * 1e3,
                self.inner.1,
                self.outer.0 * 1e3,
                self.outer.1,
                self.fixes,
            ));
        }
        // A smear shortens the square: a short side is judged with what it took off given back.
        let side_m = if self.side_m < tag_size_m {
            self.side_m + self.blur_shrink * tag_size_m
        } else {
            self.side_m
        };
        let ratio = side_m / tag_size_m;
        // A height or focal length off by the side's share moves a fix by that share of its
        // distance from the point under the camera (the parallax of a marker higher by δ,
        // seen (D − δ)/D as large, is δ/D of that distance).
        let share = (1.0 - 1.0 / ratio).abs();
        let off = (ratio - 1.0).abs();
        if off <= TAG_SIDE_TOLERANCE
            || off * tag_size_m <= TAG_SIDE_SIGNIFICANCE * self.side_sigma_m
            || share * self.distance_m.0 <= TAG_SIDE_SHIFT_OVER_SIGMA * self.position_sigma_m
        {
            return None;
        }
        let height_m = marker_height_m + self.camera_above_marker_m * (1.0 - 1.0 / ratio);
        Some(format!(
            "the tag's black square spans {:.2} mm on the marker plane (median of {} fixes, ± {:.3} %), {:+.2} % from --tag-size {:.2} mm. Either the size is off (a print scaled to fit the page; measure the square and give --tag-size {:.4}): positions are then right, but every fix's σ takes the misfit for noise and is too large; or the marker sits at {:.4} m, not --marker-height {marker_height_m:.4} m, or the camera file's focal length is not this image's (a video scaled or zoomed after recording), either of which moves every fix by {:.2} % of its distance from the point under the camera, {:.1} mm for the typical fix and up to {:.1} mm, against a typical σ of {:.2} mm; or the camera file does not map this image at all (another camera's calibration, or an image cropped or shifted after recording), which moves the fixes by an amount the square's size cannot tell",
            side_m * 1e3,
            self.fixes,
            100.0 * self.side_sigma_m / tag_size_m,
            (ratio - 1.0) * 100.0,
            tag_size_m * 1e3,
            side_m,
            height_m,
            100.0 * share,
            share * self.distance_m.0 * 1e3,
            share * self.distance_m.1 * 1e3,
            self.position_sigma_m * 1e3,
        ))
    }
}

/// For each of `result`'s fixes in order, the largest distance any of its corners moved to
/// the fix in the frame before or after, pixels per frame (None for a fix with no fix within
/// two frames either side).
fn motion_between_frames(result: &TrackResult) -> Vec<Option<f64>> {
    let fixes: Vec<_> = result.fixes().map(|(r, f)| (r.index, f)).collect();
    let per_frame = |a: &(usize, &crate::Fix), b: &(usize, &crate::Fix)| {
        let frames = a.0.abs_diff(b.0);
        (1..=2).contains(&frames).then(|| {
            a.1.corners_px
                .iter()
                .zip(&b.1.corners_px)
                .map(|(p, q)| (p - q).norm())
                .fold(0.0, f64::max)
                / frames as f64
        })
    };
    (0..fixes.len())
        .map(|i| {
            let before = i
                .checked_sub(1)
                .and_then(|j| per_frame(&fixes[j], &fixes[i]));
            let after = fixes.get(i + 1).and_then(|n| per_frame(&fixes[i], n));
            match (before, after) {
                (Some(a), Some(b)) => Some(a.max(b)),
                (a, b) => a.or(b),
            }
        })
        .collect()
}

/// The point on the floor under the camera.
pub(crate) fn nadir(floor: &FloorToCamera) -> Point2<f64> {
    let camera_in_floor = floor.0.inverse().translation.vector;
    Point2::new(camera_in_floor.x, camera_in_floor.y)
}

/// The median of `v` (sorted in place); `v` is not empty.
fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The side's change from the image's centre outwards names the camera file only when it
    /// exceeds the two thirds' noise: a right calibration's 27-fix thirds of a 640x360 H.264
    /// video, 0.34 % apart, were named as another camera's.
    #[test]
    fn a_change_across_the_image_within_its_noise_is_not_named() {
        let side = |inner_outer_sigma_m: f64| TagSide {
            side_m: 0.1603,
            side_sigma_m: 0.0002,
            fixes: 27,
            camera_above_marker_m: 2.5,
            distance_m: (1.0, 1.5),
            position_sigma_m: 0.001,
            inner: (0.16008, 178.0),
            outer: (0.16062, 284.0),
            inner_outer_sigma_m,
            blur_shrink: 0.0,
        };
        assert_eq!(side(0.0003).warning(0.16, 0.0), None);
        let named = side(0.00005).warning(0.16, 0.0).unwrap_or_default();
        assert!(
            named.contains("the camera file does not map this camera's image"),
            "{named}"
        );
    }
}
