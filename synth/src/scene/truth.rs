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
    /// tag image, y up the tag image) mapped into the floor frame. It is the robot's
    /// pose where the tag is mounted centred and aligned with the robot (`synth track`
    /// with `--tag-offset`/`--tag-yaw` writes the robot's axle pose here instead).
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

/// The camera's truth of a whole video, as [`frames_csv`] writes it (frames.csv of
/// `synth track`, `truth/<id>.frames.csv` of `synth experiment`); read with
/// [`odocal_core::TextFormat::read`].
#[derive(Debug, Clone, PartialEq)]
pub struct FramesTruth {
    /// Every frame, dropped ones included, in order.
    pub frames: Vec<FrameTruth>,
}

impl FramesTruth {
    /// The true trajectory to compare a track with: every frame in the file (not dropped) at
    /// its own time and, under a rolling shutter, also at the time its tag's rows were read,
    /// so a fix finds its truth whichever way the tracker timed it.
    pub fn trajectory(&self) -> Result<odocal_core::Trajectory, odocal_core::FileError> {
        let row = |t_s: f64, pose: Pose2| odocal_core::TrajectoryRow {
            t_s,
            pose,
            quality: 1.0,
            sigma: None,
        };
        let mut rows = Vec::new();
        for f in self.frames.iter().filter(|f| !f.dropped) {
            rows.push(row(f.t_s, f.pose));
            if (f.t_tag_row_s - f.t_s).abs() > 1e-6 {
                rows.push(row(f.t_tag_row_s, f.pose_tag_row));
            }
        }
        rows.sort_by(|a, b| a.t_s.total_cmp(&b.t_s));
        rows.dedup_by(|a, b| (a.t_s - b.t_s).abs() < 1e-9);
        odocal_core::Trajectory::new(rows)
    }

    /// Frames in the file (not dropped).
    pub fn frames_in_file(&self) -> usize {
        self.frames.iter().filter(|f| !f.dropped).count()
    }
}

impl odocal_core::TextFormat for FramesTruth {
    fn parse(text: &str, name: &str) -> Result<Self, odocal_core::FileError> {
        use odocal_core::{csv_table_with_header, numeric_row};
        let table = csv_table_with_header(text, name, "frames truth")?;
        let header: Vec<&str> = table.header.1.iter().collect();
        if header.join(",") != FRAMES_CSV_HEADER {
            return Err(odocal_core::FileError::parse(
                name,
                table.header.0,
                1,
                format!("expected the header {FRAMES_CSV_HEADER}"),
            ));
        }
        let frames = table
            .rows
            .iter()
            .map(|(line, rec)| {
                let v = numeric_row::<15>(name, *line, rec)?;
                Ok(FrameTruth {
                    index: v[0] as usize,
                    t_s: v[1],
                    dropped: v[2] != 0.0,
                    hidden_fraction: v[4],
                    tag_visible: v[5] != 0.0,
                    blur_px: v[6],
                    tag_row_px: v[7],
                    t_tag_row_s: v[8],
                    pose: Pose2::new(v[9], v[10], v[11]),
                    pose_tag_row: Pose2::new(v[12], v[13], v[14]),
                })
            })
            .collect::<Result<Vec<_>, odocal_core::FileError>>()?;
        Ok(Self { frames })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use odocal_core::TextFormat;

    #[test]
    fn frames_csv_reads_back_exactly() {
        let f = |index: usize, dropped: bool, hidden: f64| FrameTruth {
            index,
            t_s: index as f64 / 30.0,
            pose: Pose2::new(0.1 * index as f64, -0.25, 1.0 / 3.0),
            tag_visible: index != 2,
            tag_row_px: 351.25,
            t_tag_row_s: index as f64 / 30.0 + 0.0146,
            pose_tag_row: Pose2::new(0.1 * index as f64 + 0.01, -0.25, 0.3),
            blur_px: 3.5,
            hidden_fraction: hidden,
            dropped,
        };
        let frames = vec![f(0, false, 0.0), f(1, true, 0.25), f(2, false, 1.0)];
        let text = frames_csv(&frames);
        let back = FramesTruth::parse(&text, "frames.csv").unwrap();
        assert_eq!(back.frames, frames);
        let bad = text.replace("t_tag_row", "t_row");
        let e = FramesTruth::parse(&bad, "frames.csv")
            .unwrap_err()
            .to_string();
        assert!(e.contains("frames.csv") && e.contains("header"), "{e}");
    }
}
