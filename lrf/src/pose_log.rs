//! The pose log `odocal lrf localize --out` writes and the report reads: one row per scan,
//! `t,x,y,theta,status,n_landmarks,n_detections,n_hypotheses,score,mode,scan`, with x, y, theta
//! empty when the scan was lost. Metres and radians in the map frame, seconds.

use std::fmt::Write as _;

use nalgebra::Matrix3;
use odocal_core::{
    csv_table_with_header, FileError, Pose2, PoseSigma, TextFormat, Trajectory, TrajectoryRow,
};

use crate::eval::EstimatedPose;
use crate::search::Status;

/// The header of a pose log.
pub const POSE_LOG_HEADER: &str =
    "t,x,y,theta,status,n_landmarks,n_detections,n_hypotheses,score,mode,scan";

/// One localised scan.
#[derive(Debug, Clone, PartialEq)]
pub struct PoseLogRow {
    /// Scan time, seconds.
    pub t_s: f64,
    /// The sensor's pose in the map frame; None when lost.
    pub pose: Option<Pose2>,
    /// How confident the pose is.
    pub status: Status,
    /// Landmarks matched.
    pub n_landmarks: usize,
    /// Reflector detections in the scan.
    pub n_detections: usize,
    /// Hypotheses considered.
    pub n_hypotheses: usize,
    /// Score of the best hypothesis: landmarks matched minus landmarks in view from its pose
    /// that were not detected (a count; 0 when lost).
    pub score: f64,
    /// How the pose was found ("global", "tracking", ...).
    pub mode: String,
    /// The scan's id.
    pub scan: u64,
    /// Covariance of the pose (x, y, θ; m², m·rad, rad²), its Cramér–Rao bound; kept in
    /// memory for the evaluation, not written to the file.
    pub pose_cov: Option<Matrix3<f64>>,
}

/// A pose log: the localisation of every scan, in time order.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct PoseLog {
    /// The rows, one per scan.
    pub rows: Vec<PoseLogRow>,
}

impl PoseLog {
    /// The log as CSV text (times to 0.1 ms, positions to 10 µm, headings to 1 µrad).
    pub fn to_csv(&self) -> String {
        let mut csv = format!("{POSE_LOG_HEADER}\n");
        for r in &self.rows {
            let (x, y, th) = match r.pose {
                Some(p) => (
                    format!("{:.5}", p.x_m),
                    format!("{:.5}", p.y_m),
                    format!("{:.6}", p.theta_rad),
                ),
                None => (String::new(), String::new(), String::new()),
            };
            let _ = writeln!(
                csv,
                "{},{x},{y},{th},{},{},{},{},{:.1},{},{}",
                r.t_s,
                r.status,
                r.n_landmarks,
                r.n_detections,
                r.n_hypotheses,
                r.score,
                r.mode,
                r.scan
            );
        }
        csv
    }

    /// The `ok` poses as a trajectory (quality 1, σ from each pose's Cramér–Rao covariance):
    /// laser ground truth in the format `odocal dataset` and `odocal evaluate` read. Ambiguous
    /// and lost scans have no pose to give and leave gaps, as a hidden tag does in `track`.
    pub fn to_trajectory(&self) -> Result<Trajectory, FileError> {
        let ok: Vec<&PoseLogRow> = self
            .rows
            .iter()
            .filter(|r| r.status == Status::Ok)
            .collect();
        // σ on every row or on none: the trajectory format takes no mixture.
        let all_cov = ok.iter().all(|r| r.pose_cov.is_some());
        let rows = ok
            .iter()
            .filter_map(|r| {
                let pose = r.pose?;
                let sigma = r.pose_cov.filter(|_| all_cov).map(|c| PoseSigma {
                    x_m: c[(0, 0)].max(0.0).sqrt(),
                    y_m: c[(1, 1)].max(0.0).sqrt(),
                    theta_rad: c[(2, 2)].max(0.0).sqrt(),
                });
                Some(TrajectoryRow {
                    t_s: r.t_s,
                    pose,
                    quality: 1.0,
                    sigma,
                })
            })
            .collect();
        Trajectory::new(rows)
    }

    /// The rows as [`crate::evaluate`] takes them.
    pub fn for_evaluation(&self) -> Vec<EstimatedPose> {
        self.rows
            .iter()
            .map(|r| EstimatedPose {
                t_s: r.t_s,
                status: r.status,
                pose: r.pose,
                n_landmarks: r.n_landmarks,
                cov: r.pose_cov,
            })
            .collect()
    }
}

impl TextFormat for PoseLog {
    /// Parses pose-log text; `name` starts every message. Columns are found by name, so
    /// logs with only `t,x,y,theta,status,n_landmarks` read too (the other counts are 0).
    fn parse(text: &str, name: &str) -> Result<Self, FileError> {
        let table = csv_table_with_header(text, name, "pose log")?;
        let (hline, header) = &table.header;
        let col = |n: &str| header.iter().position(|c| c == n);
        let need = |n: &str| {
            col(n).ok_or_else(|| {
                FileError::parse(
                    name,
                    *hline,
                    1,
                    format!(
                        "header lacks column '{n}'; is this the --out of `odocal lrf localize`?"
                    ),
                )
            })
        };
        let (it, ix, iy, ith, is, il) = (
            need("t")?,
            need("x")?,
            need("y")?,
            need("theta")?,
            need("status")?,
            need("n_landmarks")?,
        );
        let (idet, ihyp, iscore, imode, iscan) = (
            col("n_detections"),
            col("n_hypotheses"),
            col("score"),
            col("mode"),
            col("scan"),
        );
        let mut rows = Vec::with_capacity(table.rows.len());
        for (line, rec) in &table.rows {
            let get = |i: usize| rec.get(i).unwrap_or("");
            let num = |i: usize, what: &str| {
                get(i)
                    .parse::<f64>()
                    .ok()
                    .filter(|v| v.is_finite())
                    .ok_or_else(|| {
                        FileError::parse(
                            name,
                            *line,
                            i as u64 + 1,
                            format!("{what} \"{}\" is not a finite number", get(i)),
                        )
                    })
            };
            let count = |i: Option<usize>, what: &str| match i {
                None => Ok(0),
                Some(i) => get(i).parse::<usize>().map_err(|_| {
                    FileError::parse(
                        name,
                        *line,
                        i as u64 + 1,
                        format!("{what} \"{}\" is not a count", get(i)),
                    )
                }),
            };
            let pose = if get(ix).is_empty() {
                None
            } else {
                Some(Pose2::new(num(ix, "x")?, num(iy, "y")?, num(ith, "theta")?))
            };
            let status = match get(is) {
                "ok" => Status::Ok,
                "ambiguous" => Status::Ambiguous,
                "lost" => Status::Lost,
                other => {
                    return Err(FileError::parse(
                        name,
                        *line,
                        is as u64 + 1,
                        format!("status '{other}' is not ok, ambiguous or lost"),
                    ))
                }
            };
            rows.push(PoseLogRow {
                t_s: num(it, "t")?,
                pose,
                status,
                n_landmarks: count(Some(il), "n_landmarks")?,
                n_detections: count(idet, "n_detections")?,
                n_hypotheses: count(ihyp, "n_hypotheses")?,
                score: match iscore {
                    Some(i) => num(i, "score")?,
                    None => 0.0,
                },
                mode: imode.map(|i| get(i).to_string()).unwrap_or_default(),
                scan: count(iscan, "scan")? as u64,
                pose_cov: None,
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
        let log = PoseLog {
            rows: vec![
                PoseLogRow {
                    t_s: 0.1,
                    pose: Some(Pose2::new(1.0, 2.0, 0.5)),
                    status: Status::Ok,
                    n_landmarks: 4,
                    n_detections: 5,
                    n_hypotheses: 1,
                    score: 4.0,
                    mode: "global".into(),
                    scan: 0,
                    pose_cov: None,
                },
                PoseLogRow {
                    t_s: 0.2,
                    pose: None,
                    status: Status::Lost,
                    n_landmarks: 0,
                    n_detections: 1,
                    n_hypotheses: 0,
                    score: 0.0,
                    mode: "tracking".into(),
                    scan: 1,
                    pose_cov: None,
                },
            ],
        };
        let back = PoseLog::parse(&log.to_csv(), "p.csv").unwrap();
        assert_eq!(back, log);
        let short = PoseLog::parse(
            "t,x,y,theta,status,n_landmarks\n0.1,1,2,0.5,ok,4\n",
            "p.csv",
        )
        .unwrap();
        assert_eq!(short.rows[0].n_landmarks, 4);
        assert!(PoseLog::parse("a,b\n1,2\n", "p.csv").is_err());
        let e = PoseLog::parse("t,x,y,theta,status,n_landmarks\n0,1,1,1,maybe,1\n", "p.csv")
            .unwrap_err();
        assert_eq!(
            e.to_string(),
            "p.csv:2:5: status 'maybe' is not ok, ambiguous or lost"
        );
    }
}
