//! What the renderer knows about each frame, and the truth CSV written beside a video.

use super::*;

/// The truth of one rendered frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FrameTruth {
    /// Frame index, from 0.
    pub index: usize,
    /// Frame time (centre of the exposure), seconds.
    pub t_s: f64,
    /// The marker's floor pose at `t_s`: the tag frame (x to the right of the
    /// tag image, y up the tag image) mapped into the floor frame. The robot's
    /// pose, since the tag is mounted centred and aligned with the robot.
    pub pose: Pose2,
    /// Whether the whole tag, including its white border, is inside the image
    /// (with a 2-pixel margin) during the exposure.
    pub tag_visible: bool,
    /// Pixel row (from 0 at the top, fractional) where the tag's centre is read: under a
    /// rolling shutter the row whose own exposure time puts the tag's centre on it.
    pub tag_row_px: f64,
    /// Centre of the exposure of that row, seconds: `t_s + tag_row_px · rolling_shutter_s /
    /// height_px` (equal to `t_s` with a global shutter).
    pub t_tag_row_s: f64,
    /// The marker's floor pose at `t_tag_row_s`: what a tracker that times each fix by the
    /// rows where the tag was read should find.
    pub pose_tag_row: Pose2,
    /// Length of the motion blur, pixels: the largest distance a corner of the printed plate
    /// moves in the image during the tag row's exposure.
    pub blur_px: f64,
    /// Fraction of the printed plate that a person walking through hides from the camera at
    /// `t_tag_row_s` (0: in full view).
    pub hidden_fraction: f64,
    /// The camera dropped this frame: it is not in the file.
    pub dropped: bool,
}

impl FrameTruth {
    /// Whether anything hides part of the tag in this frame.
    pub fn occluded(&self) -> bool {
        self.hidden_fraction > 0.0
    }
}

/// Header of [`frames_csv`].
pub const FRAMES_CSV_HEADER: &str = "frame,t,dropped,occluded,hidden_fraction,tag_visible,blur_px,tag_row_px,t_tag_row,x,y,theta,x_tag_row,y_tag_row,theta_tag_row";

/// The camera's truth per frame as CSV ([`FRAMES_CSV_HEADER`]; SI units, booleans 0/1):
/// frame index; its timestamp `t` (s, centre of row 0's exposure); whether it was dropped
/// (absent from the file); whether a person hides part of the tag and which fraction;
/// whether the tag is fully inside the image; the blur's length (px); the row where the
/// tag's centre is read and that row's time (s); the marker's floor pose at `t` and at
/// `t_tag_row` (m, m, rad). Every frame has a row, dropped ones included.
pub fn frames_csv(truths: &[FrameTruth]) -> String {
    let mut s = String::from(FRAMES_CSV_HEADER);
    s.push('\n');
    for t in truths {
        s.push_str(&format!(
            "{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}\n",
            t.index,
            t.t_s,
            u8::from(t.dropped),
            u8::from(t.occluded()),
            t.hidden_fraction,
            u8::from(t.tag_visible),
            t.blur_px,
            t.tag_row_px,
            t.t_tag_row_s,
            t.pose.x_m,
            t.pose.y_m,
            t.pose.theta_rad,
            t.pose_tag_row.x_m,
            t.pose_tag_row.y_m,
            t.pose_tag_row.theta_rad
        ));
    }
    s
}

/// Truth rows as trajectory CSV text (`t,x,y,theta,quality`, quality 1); only
/// frames whose tag is fully visible when `visible_only`.
pub fn truth_csv(truths: &[FrameTruth], visible_only: bool) -> String {
    let mut s = String::from("t,x,y,theta,quality\n");
    for t in truths.iter().filter(|t| !visible_only || t.tag_visible) {
        s.push_str(&format!(
            "{},{},{},{},1\n",
            t.t_s, t.pose.x_m, t.pose.y_m, t.pose.theta_rad
        ));
    }
    s
}
