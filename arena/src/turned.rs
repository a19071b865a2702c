//! A camera whose video is turned half a turn against its calibration: a recorder that flipped
//! it (`hflip,vflip`), or a camera mounted the other way round from how it was calibrated.
//! Its tag fixes land at the floor point mirrored through its image centre's, which no clock
//! offset explains: it never lines up with the other cameras (the clock fit refuses it,
//! naming its clock), or where it happens to, it disagrees with them far beyond σ.
//!
//! Where the cameras' fixes are compared, each suspect camera's fixes are turned back about
//! the image centre and compared again: a camera whose turned fixes agree with the other
//! cameras' fused pose, where as recorded they did not, is named ([`TurnedCamera`]), and the
//! run refused, since every fix of that camera is wrong (a fix where no other camera saw the
//! robot would go into the trajectory unjudged).

use std::fmt;

use nalgebra::Point2;
use odocal_tracker::{planar_pose, Fix};

use crate::ArenaCamera;

/// Share of a camera's comparisons with the others' fused pose that may lie beyond
/// [`crate::DISAGREE_SIGMAS`] for it to agree with them (its turned fixes).
pub(crate) const AGREE_SHARE: f64 = 0.1;

/// Share of its comparisons beyond [`crate::DISAGREE_SIGMAS`] above which a camera that was
/// placed in time disagrees with the others (as recorded).
pub(crate) const DISAGREE_SHARE: f64 = 0.5;

/// A camera whose fixes agree with the other cameras' only with its image turned half a turn.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TurnedCamera {
    /// The camera's index in the arena.
    pub camera: usize,
    /// Its turned fixes compared with the other cameras' fused pose at the same instants.
    pub compared: usize,
    /// Their RMS distance from the others' fused pose, metres.
    pub turned_rms_m: f64,
    /// Their RMS distance in σ (RMS per axis; NaN without σ).
    pub turned_sigmas_rms: f64,
    /// As recorded: the RMS distance of its fixes from the others' fused pose, metres, or
    /// none where they never lined up with another camera's at any clock offset searched.
    pub recorded_rms_m: Option<f64>,
    /// The clock offsets searched, seconds either way.
    pub max_offset_s: f64,
}

impl TurnedCamera {
    /// The message naming the camera by `name` (its video), what was seen and what to do.
    pub fn message(&self, name: &str) -> String {
        let recorded = match self.recorded_rms_m {
            None => format!(
                "as recorded they line up with no other camera's at any clock offset within ±{} s",
                self.max_offset_s
            ),
            Some(m) => format!(
                "as recorded they are {:.1} mm RMS from the others'",
                m * 1e3
            ),
        };
        let sigmas = if self.turned_sigmas_rms.is_nan() {
            String::new()
        } else {
            format!(", {:.1} σ RMS", self.turned_sigmas_rms)
        };
        format!(
            "{name} looks turned 180°: its tag fixes agree with the other cameras' when its image is turned about the centre ({} fixes {:.2} mm RMS{sigmas} from the others' fused pose), while {recorded}, so every fix of this camera would be wrong (not a clock offset); turn the video back with ffmpeg -vf hflip,vflip (each image of a frame folder alike), or recalibrate that camera on turned views and run `odocal arena` again",
            self.compared,
            self.turned_rms_m * 1e3,
        )
    }
}

impl fmt::Display for TurnedCamera {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.message(&format!("camera {}", self.camera)))
    }
}

/// Fix `f` of camera `cam` as it is with the image turned half a turn about its centre
/// (each corner at (w − 1 − x, h − 1 − y), as `hflip,vflip` moves pixels): its pose fitted again
/// to the turned corners through the camera's calibration and arena pose. None where a
/// corner's ray misses the marker plane.
pub(crate) fn turned_fix(cam: &ArenaCamera, f: &Fix, marker_height_m: f64) -> Option<Fix> {
    let model = &cam.calibration.camera;
    let (w, h) = (f64::from(model.width) - 1.0, f64::from(model.height) - 1.0);
    let corners = f.corners_px.map(|p| Point2::new(w - p.x, h - p.y));
    let floor = &cam.arena_to_camera;
    // The square's size measured from the fix's own corners: the fitted pose does not depend
    // on it, only the fit's residual figures do.
    let size_m = planar_pose(model, floor, &f.corners_px, 1.0, marker_height_m)?.size_m;
    let turned = planar_pose(model, floor, &corners, size_m, marker_height_m)?;
    Some(Fix {
        pose: turned.pose,
        corners_px: corners,
        ..*f
    })
}
