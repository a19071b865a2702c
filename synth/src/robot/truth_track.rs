//! The true trajectory of a simulated recording as `synth experiment` writes it beside each
//! run (`truth/<id>.true.csv`): `t_robot,t_camera,x,y,theta,visible` at 100 Hz, on both
//! clocks, floor frame, metres and radians; `visible` is 0 while the robot is carried.

use std::fmt::Write as _;

use odocal_core::{csv_table_with_header, numeric_row, FileError, Pose2, TextFormat};

use super::SimulatedRecording;

/// The header of a truth track.
pub const TRUTH_TRACK_HEADER: &str = "t_robot,t_camera,x,y,theta,visible";

/// One true pose.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TruthTrackRow {
    /// Robot-clock time, seconds.
    pub t_robot_s: f64,
    /// Camera-clock time, seconds (t_robot + the recording's clock offset).
    pub t_camera_s: f64,
    /// The robot's floor pose.
    pub pose: Pose2,
    /// Whether the robot is on the floor (not carried).
    pub visible: bool,
}

/// The true trajectory of one recording.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct TruthTrack {
    /// The rows in time order.
    pub rows: Vec<TruthTrackRow>,
}

impl TruthTrack {
    /// Every second 200 Hz truth sample of a recording (100 Hz).
    pub fn of_recording(rec: &SimulatedRecording) -> Self {
        let rows = rec
            .truth
            .iter()
            .step_by(2)
            .map(|p| TruthTrackRow {
                t_robot_s: p.t_robot_s,
                t_camera_s: p.t_robot_s + rec.clock_offset_s,
                pose: p.pose,
                visible: p.visible,
            })
            .collect();
        Self { rows }
    }

    /// The track as CSV text (times to 1 ms / 1 µs, poses to 1 µm and 1 µrad).
    pub fn to_csv(&self) -> String {
        let mut csv = format!("{TRUTH_TRACK_HEADER}\n");
        for r in &self.rows {
            let _ = writeln!(
                csv,
                "{:.3},{:.6},{:.6},{:.6},{:.6},{}",
                r.t_robot_s,
                r.t_camera_s,
                r.pose.x_m,
                r.pose.y_m,
                r.pose.theta_rad,
                u8::from(r.visible)
            );
        }
        csv
    }
}

impl TextFormat for TruthTrack {
    /// Parses truth-track text; `name` starts every message.
    fn parse(text: &str, name: &str) -> Result<Self, FileError> {
        let table = csv_table_with_header(text, name, "truth track")?;
        let (line, header) = &table.header;
        let fields: Vec<&str> = header.iter().collect();
        if fields.join(",") != TRUTH_TRACK_HEADER {
            return Err(FileError::parse(
                name,
                *line,
                1,
                format!(
                    "header is \"{}\", expected \"{TRUTH_TRACK_HEADER}\"",
                    fields.join(",")
                ),
            ));
        }
        let mut rows = Vec::with_capacity(table.rows.len());
        for (line, rec) in &table.rows {
            let v: [f64; 6] = numeric_row(name, *line, rec)?;
            rows.push(TruthTrackRow {
                t_robot_s: v[0],
                t_camera_s: v[1],
                pose: Pose2::new(v[2], v[3], v[4]),
                visible: v[5] != 0.0,
            });
        }
        Ok(Self { rows })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_and_errors_are_located() {
        let t = TruthTrack::parse(
            "t_robot,t_camera,x,y,theta,visible\n0.000,0.100000,1.000000,2.000000,0.100000,1\n0.020,0.120000,1.000000,2.000000,0.100000,0\n",
            "a.csv",
        )
        .unwrap();
        assert_eq!(t.rows.len(), 2);
        assert!(!t.rows[1].visible);
        assert_eq!(TruthTrack::parse(&t.to_csv(), "a.csv").unwrap(), t);
        let e = TruthTrack::parse(
            "t_robot,t_camera,x,y,theta,visible\n0,0,zz,0,0,1\n",
            "b.csv",
        )
        .unwrap_err();
        assert_eq!(e.to_string(), "b.csv:2:3: \"zz\" is not a number");
    }
}
