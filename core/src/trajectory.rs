//! Trajectory files: CSV `t,x,y,theta,quality`, floor frame, metres and radians, one row per
//! frame with a detection; missed frames are absent, and rows of quality 0 (samples a motion
//! capture lost) are read as absent too. Written by the tracker (or the simulator
//! with `--frames none`), read by the dataset builder; see ARCHITECTURE.md for the conventions.
//!
//! The tracker adds three columns, `sigma_x,sigma_y,sigma_theta` (metres, metres, radians): the
//! standard deviation of each fix. Files without them (older tracks, synthetic truth) still
//! read; their rows have no σ. A file has the σ columns on every row or on none.

use std::path::Path;

use crate::file_error::{read_text, FileError};
use crate::pose::{wrap_angle, Pose2};
use crate::table::{csv_table, numeric_row};
use nalgebra::Point2;

/// Header of a trajectory CSV.
pub const TRAJECTORY_HEADER: [&str; 5] = ["t", "x", "y", "theta", "quality"];

/// Header of a trajectory CSV whose rows carry their standard deviations.
pub const TRAJECTORY_SIGMA_HEADER: [&str; 8] = [
    "t",
    "x",
    "y",
    "theta",
    "quality",
    "sigma_x",
    "sigma_y",
    "sigma_theta",
];

/// Rows of a reference this close in time (seconds) to an estimate are taken as its own time.
pub const SAME_TIME_S: f64 = 1e-4;

/// The widest gap between reference rows (seconds) interpolated across: over 25 ms a robot
/// accelerating at 1 m/s² strays 0.08 mm from the straight line between the rows, a third of
/// the tracker's own error. A truth sampled at 40 Hz or more (motion capture) qualifies.
pub const REFERENCE_MAX_GAP_S: f64 = 0.025;

/// A reference pose at an estimate's time (see [`Trajectory::reference_at`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Reference {
    /// The reference's pose at that time (the floor pose of the body it follows).
    pub pose: Pose2,
    /// The reference row at that very time; None when interpolated between two rows.
    pub row: Option<usize>,
}

/// Standard deviations of a floor pose along the floor axes and of its heading.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PoseSigma {
    /// σ of x, metres.
    pub x_m: f64,
    /// σ of y, metres.
    pub y_m: f64,
    /// σ of the heading, radians.
    pub theta_rad: f64,
}

/// One detected frame: camera-clock time and the robot's floor pose.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrajectoryRow {
    /// Camera-clock time, seconds.
    pub t_s: f64,
    /// Robot pose in the floor frame (maps the robot's body frame into the floor frame).
    pub pose: Pose2,
    /// Detection quality in [0, 1] (tracker-defined; 1 for synthetic truth).
    pub quality: f64,
    /// The pose's standard deviations, when known (the tracker's; none for truth and old files).
    pub sigma: Option<PoseSigma>,
}

/// A camera trajectory: rows in strictly increasing time.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Trajectory {
    /// The rows, strictly increasing in time.
    pub rows: Vec<TrajectoryRow>,
}

impl Trajectory {
    /// Builds a trajectory, checking that times increase strictly and values are finite.
    pub fn new(rows: Vec<TrajectoryRow>) -> Result<Self, FileError> {
        let t = Self { rows };
        t.validate("<trajectory>", |i| i as u64 + 2)?;
        Ok(t)
    }

    /// Reads a trajectory CSV.
    pub fn read_csv(path: &Path) -> Result<Self, FileError> {
        let text = read_text(path)?;
        Self::parse_csv(&text, &path.display().to_string())
    }

    /// Parses trajectory CSV text; `name` is used in error messages.
    pub fn parse_csv(text: &str, name: &str) -> Result<Self, FileError> {
        let Some(table) = csv_table(text, name)? else {
            return Err(FileError::content(
                name,
                "empty trajectory file (no header)",
            ));
        };
        let (line, header) = &table.header;
        let fields: Vec<&str> = header.iter().collect();
        let with_sigma = fields == TRAJECTORY_SIGMA_HEADER;
        // A motion-capture export or a hand-made truth often has no quality: every row is
        // then a sure pose, as laser truths read it.
        let without_quality = fields == TRAJECTORY_HEADER[..4];
        if fields != TRAJECTORY_HEADER && !with_sigma && !without_quality {
            // The laser's pose log is ground truth too, in its own format.
            let hint = if fields.get(4) == Some(&"status") {
                "; this is the pose log of `odocal lrf localize`: its --trajectory FILE writes the poses as a trajectory"
            } else {
                ""
            };
            return Err(FileError::parse(
                name,
                *line,
                1,
                format!(
                    "header is \"{}\", expected \"t,x,y,theta,quality\", \"t,x,y,theta,quality,sigma_x,sigma_y,sigma_theta\" or \"t,x,y,theta\" (every row of quality 1){hint}",
                    fields.join(",")
                ),
            ));
        }
        let mut rows = Vec::new();
        let mut lines = Vec::new();
        for &(line, ref rec) in &table.rows {
            // Quality 0 marks a sample the source lost (a motion capture writes its last
            // pose, the origin or NaN): no pose at all, as a frame the tracker missed.
            let lost = !without_quality
                && rec.get(4).and_then(|q| q.trim().parse::<f64>().ok()) == Some(0.0);
            if lost {
                continue;
            }
            let row = if with_sigma {
                let v: [f64; 8] = numeric_row(name, line, rec)?;
                if let Some(c) = v[5..].iter().position(|s| *s <= 0.0) {
                    return Err(FileError::parse(
                        name,
                        line,
                        c as u64 + 6,
                        format!(
                            "σ {} is not positive: a standard deviation is above 0",
                            v[5 + c]
                        ),
                    ));
                }
                TrajectoryRow {
                    t_s: v[0],
                    pose: Pose2::new(v[1], v[2], v[3]),
                    quality: v[4],
                    sigma: Some(PoseSigma {
                        x_m: v[5],
                        y_m: v[6],
                        theta_rad: v[7],
                    }),
                }
            } else if without_quality {
                let v: [f64; 4] = numeric_row(name, line, rec)?;
                TrajectoryRow {
                    t_s: v[0],
                    pose: Pose2::new(v[1], v[2], v[3]),
                    quality: 1.0,
                    sigma: None,
                }
            } else {
                let v: [f64; 5] = numeric_row(name, line, rec)?;
                TrajectoryRow {
                    t_s: v[0],
                    pose: Pose2::new(v[1], v[2], v[3]),
                    quality: v[4],
                    sigma: None,
                }
            };
            rows.push(row);
            lines.push(line);
        }
        if rows.is_empty() && !table.rows.is_empty() {
            return Err(FileError::content(
                name,
                "every row has quality 0, which marks a sample the source lost: there is no pose in it (write 1 for a sure pose when the source gives no quality)",
            ));
        }
        let t = Self { rows };
        t.validate(name, |i| lines.get(i).copied().unwrap_or(0))?;
        Ok(t)
    }

    fn validate(&self, name: &str, line_of: impl Fn(usize) -> u64) -> Result<(), FileError> {
        let with_sigma = self.rows.first().is_some_and(|r| r.sigma.is_some());
        for (i, r) in self.rows.iter().enumerate() {
            if r.sigma.is_some() != with_sigma {
                return Err(FileError::parse(
                    name,
                    line_of(i),
                    6,
                    "some rows have σ and some not: give σ on every row or on none",
                ));
            }
            if let Some(s) = r.sigma {
                if ![s.x_m, s.y_m, s.theta_rad]
                    .iter()
                    .all(|v| v.is_finite() && *v > 0.0)
                {
                    return Err(FileError::parse(
                        name,
                        line_of(i),
                        6,
                        "σ must be finite and above 0",
                    ));
                }
            }
            let vals = [r.t_s, r.pose.x_m, r.pose.y_m, r.pose.theta_rad, r.quality];
            if let Some(c) = vals.iter().position(|v| !v.is_finite()) {
                return Err(FileError::parse(
                    name,
                    line_of(i),
                    c as u64 + 1,
                    "value is not a finite number",
                ));
            }
            if !(0.0..=1.0).contains(&r.quality) {
                return Err(FileError::parse(
                    name,
                    line_of(i),
                    5,
                    format!(
                        "quality {} is outside 0 to 1 (1 for a sure pose; write 1 when the source gives none)",
                        r.quality
                    ),
                ));
            }
            if i > 0 {
                let a = self.rows[i - 1].t_s;
                if r.t_s == a {
                    return Err(FileError::parse(
                        name,
                        line_of(i),
                        1,
                        format!("duplicated timestamp {a}; one row per frame"),
                    ));
                }
                if r.t_s < a {
                    return Err(FileError::parse(
                        name,
                        line_of(i),
                        1,
                        format!("timestamp {} goes back in time (previous row {a}); rows must be in time order", r.t_s),
                    ));
                }
            }
        }
        Ok(())
    }

    /// Whether the rows carry standard deviations.
    pub fn has_sigma(&self) -> bool {
        self.rows.first().is_some_and(|r| r.sigma.is_some())
    }

    /// The trajectory as CSV text with its header (full round-trip precision); the σ columns
    /// are written when the rows have them.
    pub fn to_csv(&self) -> String {
        let with_sigma = self.has_sigma();
        let mut s = if with_sigma {
            TRAJECTORY_SIGMA_HEADER.join(",")
        } else {
            TRAJECTORY_HEADER.join(",")
        };
        s.push('\n');
        for r in &self.rows {
            s.push_str(&format!(
                "{},{},{},{},{}",
                r.t_s, r.pose.x_m, r.pose.y_m, r.pose.theta_rad, r.quality
            ));
            if let (true, Some(g)) = (with_sigma, r.sigma) {
                s.push_str(&format!(",{},{},{}", g.x_m, g.y_m, g.theta_rad));
            }
            s.push('\n');
        }
        s
    }

    /// The trajectory in TUM format (`timestamp tx ty tz qx qy qz qw`, z = 0) for `evo`.
    pub fn to_tum(&self) -> String {
        let mut s = String::from("# timestamp tx ty tz qx qy qz qw\n");
        for r in &self.rows {
            let h = 0.5 * r.pose.theta_rad;
            s.push_str(&format!(
                "{:.6} {:.6} {:.6} 0 0 0 {:.9} {:.9}\n",
                r.t_s,
                r.pose.x_m,
                r.pose.y_m,
                h.sin(),
                h.cos()
            ));
        }
        s
    }

    /// Time of the first row, seconds (NaN when empty).
    pub fn start_s(&self) -> f64 {
        self.rows.first().map(|r| r.t_s).unwrap_or(f64::NAN)
    }

    /// Time of the last row, seconds (NaN when empty).
    pub fn end_s(&self) -> f64 {
        self.rows.last().map(|r| r.t_s).unwrap_or(f64::NAN)
    }

    /// Index i with rows[i].t <= t < rows[i+1].t, if t lies inside the trajectory.
    fn bracket(&self, t: f64) -> Option<usize> {
        let n = self.rows.len();
        if n < 2 || !(t >= self.rows[0].t_s && t <= self.rows[n - 1].t_s) {
            return None;
        }
        let i = self.rows.partition_point(|r| r.t_s <= t);
        Some(i.saturating_sub(1).min(n - 2))
    }

    /// Position at time `t`, linearly interpolated between neighbouring frames; None outside the
    /// trajectory or across a gap between frames longer than `max_gap_s`.
    pub fn position_at(&self, t: f64, max_gap_s: f64) -> Option<Point2<f64>> {
        let i = self.bracket(t)?;
        let (a, b) = (&self.rows[i], &self.rows[i + 1]);
        let span = b.t_s - a.t_s;
        if span > max_gap_s {
            return None;
        }
        let w = (t - a.t_s) / span;
        Some(Point2::new(
            a.pose.x_m + w * (b.pose.x_m - a.pose.x_m),
            a.pose.y_m + w * (b.pose.y_m - a.pose.y_m),
        ))
    }

    /// Pose at time `t`: position and heading (shortest way round) linearly interpolated; None
    /// outside the trajectory or across a gap longer than `max_gap_s`.
    pub fn pose_at(&self, t: f64, max_gap_s: f64) -> Option<Pose2> {
        let i = self.bracket(t)?;
        let (a, b) = (&self.rows[i], &self.rows[i + 1]);
        let span = b.t_s - a.t_s;
        if span > max_gap_s {
            return None;
        }
        Some(a.pose.lerp(&b.pose, (t - a.t_s) / span))
    }

    /// Whether every gap between frames within [t0, t1] is at most `max_gap_s` and the
    /// trajectory covers the interval.
    pub fn covers(&self, t0: f64, t1: f64, max_gap_s: f64) -> bool {
        let (Some(i0), Some(i1)) = (self.bracket(t0), self.bracket(t1)) else {
            return false;
        };
        (i0..=i1).all(|i| self.rows[i + 1].t_s - self.rows[i].t_s <= max_gap_s)
    }

    /// Rows with time in [t0, t1].
    pub fn rows_between(&self, t0: f64, t1: f64) -> &[TrajectoryRow] {
        let a = self.rows.partition_point(|r| r.t_s < t0);
        let b = self.rows.partition_point(|r| r.t_s <= t1);
        &self.rows[a..b.max(a)]
    }

    /// The median interval between rows, seconds: the source's period, which a missed frame
    /// does not move. None for fewer than two rows.
    pub fn median_spacing_s(&self) -> Option<f64> {
        let mut dt: Vec<f64> = self.rows.windows(2).map(|w| w[1].t_s - w[0].t_s).collect();
        dt.sort_by(f64::total_cmp);
        dt.get(dt.len() / 2).copied()
    }

    /// This trajectory as a reference to judge an estimate by at time `t`: the row at that
    /// time (within [`SAME_TIME_S`]), else the pose interpolated between neighbouring rows at
    /// most [`REFERENCE_MAX_GAP_S`] apart, so that a motion-capture truth on its own clock
    /// judges fixes taken between its samples. None outside it or across a longer gap.
    pub fn reference_at(&self, t: f64) -> Option<Reference> {
        let i = self.rows.partition_point(|r| r.t_s < t - SAME_TIME_S);
        if let Some(r) = self
            .rows
            .get(i)
            .filter(|r| (r.t_s - t).abs() <= SAME_TIME_S)
        {
            return Some(Reference {
                pose: r.pose,
                row: Some(i),
            });
        }
        // Rows 25 ms apart by their source's clock (40 Hz) read a hair over it in floating
        // point: the same tolerance as for a row at a time.
        self.pose_at(t, REFERENCE_MAX_GAP_S + SAME_TIME_S)
            .map(|pose| Reference { pose, row: None })
    }
}

/// Mean of poses: arithmetic mean of positions, circular mean of headings.
pub fn mean_pose(rows: &[TrajectoryRow]) -> Option<Pose2> {
    if rows.is_empty() {
        return None;
    }
    let n = rows.len() as f64;
    let (mut x, mut y, mut s, mut c) = (0.0, 0.0, 0.0, 0.0);
    for r in rows {
        x += r.pose.x_m;
        y += r.pose.y_m;
        s += r.pose.theta_rad.sin();
        c += r.pose.theta_rad.cos();
    }
    Some(Pose2::new(x / n, y / n, wrap_angle(s.atan2(c))))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_and_interpolation() {
        let rows: Vec<TrajectoryRow> = (0..5)
            .map(|i| TrajectoryRow {
                t_s: i as f64 / 30.0,
                pose: Pose2::new(0.1 * i as f64, -0.2, 0.3),
                quality: 1.0,
                sigma: None,
            })
            .collect();
        let t = Trajectory::new(rows).unwrap();
        let back = Trajectory::parse_csv(&t.to_csv(), "t.csv").unwrap();
        assert_eq!(back, t);
        let p = t.position_at(1.5 / 30.0, 0.1).unwrap();
        assert!((p.x - 0.15).abs() < 1e-12);
        assert!(t.position_at(1.0, 0.1).is_none());
        assert!(t.covers(0.0, 4.0 / 30.0, 0.05));
        assert!(!t.covers(0.0, 4.0 / 30.0, 0.01));
        assert_eq!(t.rows_between(0.02, 0.07).len(), 2);
        assert!(t.to_tum().lines().count() == 6);
    }

    #[test]
    fn references_are_rows_or_interpolated_within_the_gap() {
        let row = |t_s: f64, x: f64, theta: f64| TrajectoryRow {
            t_s,
            pose: Pose2::new(x, 0.0, theta),
            quality: 1.0,
            sigma: None,
        };
        // 100 Hz, then a 50 ms gap.
        let t = Trajectory::new(vec![
            row(0.0, 0.0, 3.1),
            row(0.01, 0.01, -3.1),
            row(0.02, 0.02, -3.0),
            row(0.07, 0.07, -3.0),
        ])
        .unwrap();
        assert_eq!(t.median_spacing_s(), Some(0.01));
        let at = t.reference_at(0.01 + 0.5 * SAME_TIME_S).unwrap();
        assert_eq!((at.row, at.pose.x_m), (Some(1), 0.01));
        let between = t.reference_at(0.005).unwrap();
        assert_eq!(between.row, None);
        assert!((between.pose.x_m - 0.005).abs() < 1e-12);
        // Across ±π the heading goes the short way.
        assert!((wrap_angle(between.pose.theta_rad) - std::f64::consts::PI).abs() < 0.06);
        assert!(t.reference_at(0.03).is_none(), "interpolated across 50 ms");
        assert!(t.reference_at(-0.001).is_none() && t.reference_at(0.08).is_none());
        assert!(Trajectory::default().median_spacing_s().is_none());
        // 40 Hz on its own clock: spacings of 0.025000000000000022 s are 25 ms.
        let mocap =
            Trajectory::new((0..40).map(|j| row(j as f64 / 40.0, 0.0, 0.0)).collect()).unwrap();
        let judged = (0..30)
            .filter(|k| mocap.reference_at(*k as f64 / 30.0 + 0.003).is_some())
            .count();
        assert_eq!(judged, 30);
    }

    #[test]
    fn bad_rows_are_located() {
        let e = Trajectory::parse_csv("t,x,y,theta,quality\n0,0,0,0,1\n0.1,0,zz,0,1\n", "tr.csv")
            .unwrap_err();
        assert_eq!(e.to_string(), "tr.csv:3:3: \"zz\" is not a number");
        let e = Trajectory::parse_csv("t,x,y,theta,quality\n0,0,0,0,1\n0,0,0,0,1\n", "tr.csv")
            .unwrap_err();
        assert!(e
            .to_string()
            .starts_with("tr.csv:3:1: duplicated timestamp"));
        let e = Trajectory::parse_csv("t,x,y,theta,quality\n0,0,0,0,5\n", "tr.csv").unwrap_err();
        assert!(
            e.to_string()
                .starts_with("tr.csv:2:5: quality 5 is outside 0 to 1"),
            "{e}"
        );
        // Quality 0 is a sample the source lost: no pose, whatever the row holds.
        let t = Trajectory::parse_csv(
            "t,x,y,theta,quality\n0,1,2,0,1\n0.1,0,0,0,0\n0.2,NaN,NaN,NaN,0\n0.3,1.2,2,0,0.5\n",
            "m.csv",
        )
        .unwrap();
        assert_eq!(t.rows.iter().map(|r| r.t_s).collect::<Vec<_>>(), [0.0, 0.3]);
        let e = Trajectory::parse_csv("t,x,y,theta,quality\n0,0,0,0,0\n", "m.csv").unwrap_err();
        assert!(e.to_string().contains("every row has quality 0"), "{e}");
        // Without quality every row is a sure pose.
        let t = Trajectory::parse_csv("t,x,y,theta\n0,1,2,0.5\n", "tr.csv").unwrap();
        assert_eq!((t.rows[0].pose.y_m, t.rows[0].quality), (2.0, 1.0));
        let e = Trajectory::parse_csv("t,x,y\n", "tr.csv").unwrap_err();
        assert!(e.to_string().contains("expected \"t,x,y,theta,quality\""));
        assert!(!e.to_string().contains("lrf localize"));
        // The laser's pose log is named, with the option that writes it as a trajectory.
        let e = Trajectory::parse_csv("t,x,y,theta,status,n_landmarks\n0,1,2,0,ok,4\n", "p.csv")
            .unwrap_err();
        assert!(
            e.to_string().ends_with(
                "this is the pose log of `odocal lrf localize`: its --trajectory FILE writes the poses as a trajectory"
            ),
            "{e}"
        );
    }

    #[test]
    fn sigma_columns_round_trip_and_old_files_still_read() {
        let text = "t,x,y,theta,quality,sigma_x,sigma_y,sigma_theta\n0,1,2,0.5,0.9,0.001,0.002,0.003\n0.1,1,2,0.5,0.9,0.001,0.002,0.003\n";
        let t = Trajectory::parse_csv(text, "s.csv").unwrap();
        assert!(t.has_sigma());
        assert_eq!(
            t.rows[0].sigma,
            Some(PoseSigma {
                x_m: 0.001,
                y_m: 0.002,
                theta_rad: 0.003
            })
        );
        assert_eq!(Trajectory::parse_csv(&t.to_csv(), "s.csv").unwrap(), t);
        let old = Trajectory::parse_csv("t,x,y,theta,quality\n0,1,2,0.5,0.9\n", "o.csv").unwrap();
        assert!(!old.has_sigma() && old.rows[0].sigma.is_none());
        assert!(old.to_csv().starts_with("t,x,y,theta,quality\n"));
        let e = Trajectory::parse_csv(
            "t,x,y,theta,quality,sigma_x,sigma_y,sigma_theta\n0,1,2,0.5,0.9,0.001,0,0.003\n",
            "z.csv",
        )
        .unwrap_err();
        assert!(
            e.to_string().starts_with("z.csv:2:7: σ 0 is not positive"),
            "{e}"
        );
    }
}
