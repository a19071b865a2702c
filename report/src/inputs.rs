//! Tracks for the report's run figures, in either the camera trajectory format or the
//! simulator's truth format.

use odocal_core::Pose2;
use odocal_dataset::Trajectory;

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
        let tr = Trajectory::parse_csv(text, name).map_err(|e| ReportError::Input {
            path: name.to_string(),
            line: 0,
            message: e.to_string(),
        })?;
        return Ok(TrackFile {
            clock: Clock::Camera,
            t_s: tr.rows.iter().map(|r| r.t_s).collect(),
            poses_floor: tr.rows.iter().map(|r| r.pose).collect(),
            source: "camera trajectory",
        });
    }
    let cols: Vec<&str> = first.split(',').map(str::trim).collect();
    let col = |n: &str| {
        cols.iter()
            .position(|c| *c == n)
            .ok_or_else(|| ReportError::Input {
                path: name.to_string(),
                line: 1,
                message: format!(
                    "header lacks column '{n}'; expected t_robot,t_camera,x,y,theta,visible"
                ),
            })
    };
    let (it, ix, iy, ith) = (col("t_robot")?, col("x")?, col("y")?, col("theta")?);
    let iv = cols.iter().position(|c| *c == "visible");
    let mut out = TrackFile {
        clock: Clock::Robot,
        t_s: Vec::new(),
        poses_floor: Vec::new(),
        source: "true trajectory",
    };
    for (k, line) in text.lines().enumerate().skip(1) {
        if line.trim().is_empty() {
            continue;
        }
        let f: Vec<&str> = line.split(',').map(str::trim).collect();
        let num = |i: usize, what: &str| -> Result<f64, ReportError> {
            f.get(i)
                .and_then(|s| s.parse::<f64>().ok())
                .filter(|v| v.is_finite())
                .ok_or_else(|| ReportError::Input {
                    path: name.to_string(),
                    line: k + 1,
                    message: format!("column {} ({what}) is not a finite number", i + 1),
                })
        };
        if let Some(iv) = iv {
            if f.get(iv).map(|s| *s == "0").unwrap_or(false) {
                continue;
            }
        }
        out.t_s.push(num(it, "t_robot")?);
        out.poses_floor
            .push(Pose2::new(num(ix, "x")?, num(iy, "y")?, num(ith, "theta")?));
    }
    Ok(out)
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
        assert_eq!(
            e.to_string(),
            "b.csv: line 2: column 3 (x) is not a finite number"
        );
    }
}
