//! Interlaced video whose stream does not say so: each frame weaves two fields taken half a
//! frame apart, so a moving tag's rows alternate between two places (a comb). Its fixes were
//! 3.2 mm RMS off with error/σ 6.6 and no word. Adjacent rows, one from each field, then
//! differ more than rows two apart, of one field; in a progressive frame they differ less
//! (an edge spreads over rows in both).

use crate::{Frame, FrameRecord, Outcome};

/// Adjacent rows' differences over rows two apart at or above this are fields woven
/// together: a progressive tag's edges give 0.54, a 60 fps synth interlaced to 30i 1.42.
pub(crate) const COMBED: f64 = 0.9;

/// Fixes whose tag moves at least this many pixels from the previous fix are read.
const MIN_MOTION_PX: f64 = 2.0;

/// Frames read (the first ones with a moving tag).
const FRAMES: usize = 20;

/// Sums of adjacent-row and two-row differences around the moving tag in the first frames.
#[derive(Default)]
pub(crate) struct CombProbe {
    adjacent: f64,
    two_apart: f64,
    frames: usize,
    last_centre: Option<nalgebra::Point2<f64>>,
}

impl CombProbe {
    pub(crate) fn offer(&mut self, frame: &Frame, rec: &FrameRecord) {
        let Outcome::Fix(fix) = &rec.outcome else {
            self.last_centre = None;
            return;
        };
        let c = &fix.corners_px;
        let centre =
            nalgebra::Point2::from((c[0].coords + c[1].coords + c[2].coords + c[3].coords) / 4.0);
        let moved = self
            .last_centre
            .is_some_and(|l| (centre - l).norm() >= MIN_MOTION_PX);
        self.last_centre = Some(centre);
        if !moved || self.frames >= FRAMES {
            return;
        }
        let img = &frame.image;
        let (w, h) = (img.width as usize, img.height as usize);
        let pad = 4.0;
        let lo = |v: f64| (v - pad).max(0.0) as usize;
        let x0 = lo(c.iter().map(|p| p.x).fold(f64::INFINITY, f64::min));
        let y0 = lo(c.iter().map(|p| p.y).fold(f64::INFINITY, f64::min));
        let x1 = ((c.iter().map(|p| p.x).fold(f64::NEG_INFINITY, f64::max) + pad) as usize).min(w);
        let y1 = ((c.iter().map(|p| p.y).fold(f64::NEG_INFINITY, f64::max) + pad) as usize)
            .min(h.saturating_sub(2));
        if x1 <= x0 || y1 <= y0 {
            return;
        }
        let px = |x: usize, y: usize| f64::from(img.data[y * w + x]);
        for y in y0..y1 {
            for x in x0..x1 {
                self.adjacent += (px(x, y) - px(x, y + 1)).abs();
                self.two_apart += (px(x, y) - px(x, y + 2)).abs();
            }
        }
        self.frames += 1;
    }

    /// The ratio over the frames read; None before a few of them.
    pub(crate) fn ratio(&self) -> Option<f64> {
        (self.frames >= 3 && self.two_apart > 0.0).then(|| self.adjacent / self.two_apart)
    }
}
