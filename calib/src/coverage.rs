//! Where a calibration needs more views: parts of the image no board corner reached, where
//! the lens model is extrapolated rather than measured (worst at the corners of wide lenses).

use nalgebra::Point2;

use crate::{BoardView, CameraModel};

/// Corners farther than this from a spot leave it unmeasured, pixels at 1280 px width
/// (scaled with the image width).
pub const REACH_PX_AT_1280: f64 = 150.0;

/// One line per unmeasured spot (the image's four corners and four edge midpoints), naming it
/// and how far the nearest detected corner is.
pub fn coverage_notes(camera: &CameraModel, views: &[BoardView]) -> Vec<String> {
    let (w, h) = (camera.width as f64 - 1.0, camera.height as f64 - 1.0);
    let reach = REACH_PX_AT_1280 * camera.width as f64 / 1280.0;
    let spots = [
        ("top-left corner", 0.0, 0.0),
        ("top edge's middle", w / 2.0, 0.0),
        ("top-right corner", w, 0.0),
        ("right edge's middle", w, h / 2.0),
        ("bottom-right corner", w, h),
        ("bottom edge's middle", w / 2.0, h),
        ("bottom-left corner", 0.0, h),
        ("left edge's middle", 0.0, h / 2.0),
    ];
    let corners: Vec<&Point2<f64>> = views.iter().flat_map(|v| v.corners.iter()).collect();
    if corners.is_empty() {
        return vec![];
    }
    spots
        .iter()
        .filter_map(|(name, x, y)| {
            let spot = Point2::new(*x, *y);
            let nearest = corners
                .iter()
                .map(|c| (*c - spot).norm())
                .fold(f64::INFINITY, f64::min);
            (nearest > reach).then(|| {
                format!(
                    "warning: no corners within {reach:.0} px of the image's {name} (nearest {nearest:.0} px away): \
                     the lens model is extrapolated there; add views with the board reaching it"
                )
            })
        })
        .collect()
}
