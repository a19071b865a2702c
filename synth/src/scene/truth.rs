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
