//! Tracks for the report's run figures, in either the camera trajectory format or the
//! simulator's truth format.

use odocal_core::{Pose2, TextFormat, Trajectory};

use crate::ReportError;

/// Which clock a track's times are on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Clock {
    /// The robot's clock (the odometry log's times).
    Robot,
    /// The camera's clock: t_camera = t_robot + clock offset.
    Camera,
}

/// A floor-frame track of the robot: times and poses (metres, radians).
#[derive(Debug, Clone, PartialEq)]
pub struct TrackFile {
    /// The clock of `t_s`.
    pub clock: Clock,
    /// Times, seconds.
    pub t_s: Vec<f64>,
    /// Poses of the robot in the floor frame.
    pub poses_floor: Vec<Pose2>,
    /// What the track is ("true trajectory", "camera trajectory").
    pub source: &'static str,
}

/// Parses a track: the simulator's truth (`t_robot,t_camera,x,y,theta,visible`) or a camera
/// trajectory (`t,x,y,theta,quality`).
pub fn parse_track_csv(text: &str, name: &str) -> Result<TrackFile, ReportError> {
    let first = text.lines().next().unwrap_or("");
    if first.split(',').next().map(str::trim) != Some("t_robot") {
        let tr = Trajectory::parse_csv(text, name)?;
        return Ok(TrackFile {
            clock: Clock::Camera,
            t_s: tr.rows.iter().map(|r| r.t_s).collect(),
            poses_floor: tr.rows.iter().map(|r| r.pose).collect(),
            source: "camera trajectory",
        });
    }
    let truth = odocal_synth::robot::TruthTrack::parse(text, name)?;
    let shown = || truth.rows.iter().filter(|r| r.visible);
    Ok(TrackFile {
        clock: Clock::Robot,
        t_s: shown().map(|r| r.t_robot_s).collect(),
        poses_floor: shown().map(|r| r.pose).collect(),
        source: "true trajectory",
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn truth_track_skips_hidden_rows() {
        let t = parse_track_csv(
            "t_robot,t_camera,x,y,theta,visible\n0.0,0.1,1,2,0.1,1\n0.02,0.12,1,2,0.1,0\n",
            "a.csv",
        )
        .unwrap();
        assert_eq!(t.clock, Clock::Robot);
        assert_eq!(t.t_s, vec![0.0]);
        let e = parse_track_csv(
            "t_robot,t_camera,x,y,theta,visible\n0,0,zz,0,0,1\n",
            "b.csv",
        )
        .unwrap_err();
        assert_eq!(e.to_string(), "b.csv:2:3: \"zz\" is not a number");
    }
}
