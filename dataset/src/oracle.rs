//! The oracle: dead reckoning with a run's true effective wheel geometry (known only for
//! synthetic experiments). Its error is the floor set by the random error.

use std::path::Path;

use odocal_core::Pose2;
use serde::{Deserialize, Serialize};

use crate::error::{parse_json_with_format, read_text, DatasetError};
use crate::kinematics::WheelGeometry;
use crate::Sample;

/// The `format` tag of oracle files.
pub const ORACLE_FORMAT: &str = "odocal.oracle/1";

/// Truth of one run, as far as the trainer's comparisons need it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct OracleRun {
    /// Run id, as the dataset names it.
    pub run_id: String,
    /// True effective wheel geometry of the run (diameters include the speed-dependent slip).
    pub geometry: WheelGeometry,
    /// True end position in the run's start frame, metres.
    pub true_end_m: [f64; 2],
    /// True clock offset, seconds: t_camera = t_robot + offset.
    pub clock_offset_s: f64,
}

/// Per-run truth written by `odocal synth experiment` (truth/oracle.json).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct OracleFile {
    /// Always [`ORACLE_FORMAT`].
    pub format: String,
    /// One entry per run.
    pub runs: Vec<OracleRun>,
    /// The robot's true kinematics, for paths other than the straight runs (whose speed
    /// varies along the path, so one effective geometry per run does not describe them).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub kinematics: Option<TrueKinematics>,
}

/// The true kinematics of a simulated robot: wheel diameters and base, and each wheel's slip
/// that grows with its ground speed (slip fraction = coefficient × speed).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TrueKinematics {
    /// True left wheel diameter, metres.
    pub left_wheel_diameter_m: f64,
    /// True right wheel diameter, metres.
    pub right_wheel_diameter_m: f64,
    /// True effective wheel base, metres.
    pub wheel_base_m: f64,
    /// Left wheel slip fraction per m/s of its ground speed, s/m.
    pub left_slip_per_mps: f64,
    /// Right wheel slip fraction per m/s of its ground speed, s/m.
    pub right_slip_per_mps: f64,
}

impl TrueKinematics {
    /// Dead-reckons cumulative wheel revolutions logged every `period_s` with the true
    /// kinematics: each step's wheel travel shrinks by its slip at the step's speed. One pose
    /// per row, the first at the origin.
    pub fn dead_reckon(&self, rev: &[[f64; 2]], period_s: f64) -> Vec<Pose2> {
        let c = [
            std::f64::consts::PI * self.left_wheel_diameter_m,
            std::f64::consts::PI * self.right_wheel_diameter_m,
        ];
        let k = [self.left_slip_per_mps, self.right_slip_per_mps];
        let mut out = Vec::with_capacity(rev.len());
        let mut pose = Pose2::default();
        out.push(pose);
        for w in rev.windows(2) {
            let mut d = [0.0; 2];
            for j in 0..2 {
                let roll = (w[1][j] - w[0][j]) * c[j];
                // Slip reduces the ground travel; it grows with the wheel's ground speed,
                // which is about its rolled speed.
                d[j] = roll * (1.0 - k[j] * roll.abs() / period_s);
            }
            pose = crate::kinematics::step(&pose, d[0], d[1], self.wheel_base_m);
            out.push(pose);
        }
        out
    }
}

impl OracleFile {
    /// An oracle file of `runs`.
    pub fn new(runs: Vec<OracleRun>) -> Self {
        Self {
            format: ORACLE_FORMAT.to_string(),
            runs,
            kinematics: None,
        }
    }

    /// Reads an oracle file, rejecting other formats.
    pub fn read(path: &Path) -> Result<Self, DatasetError> {
        let text = read_text(path)?;
        parse_json_with_format(&text, &path.display().to_string(), ORACLE_FORMAT)
    }

    /// The entry of a run.
    pub fn get(&self, run_id: &str) -> Option<&OracleRun> {
        self.runs.iter().find(|r| r.run_id == run_id)
    }

    /// The oracle's end point of a sample: its odometry dead-reckoned with the true geometry.
    pub fn end_m(&self, sample: &Sample) -> Option<[f64; 2]> {
        self.get(&sample.run_id)
            .map(|r| sample.odometry.end_m(&r.geometry))
    }
}
