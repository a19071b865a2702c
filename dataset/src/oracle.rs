//! The oracle: dead reckoning with a run's true effective wheel geometry (known only for
//! synthetic experiments). Its error is the floor set by the random error.

use std::path::Path;

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
}

impl OracleFile {
    /// An oracle file of `runs`.
    pub fn new(runs: Vec<OracleRun>) -> Self {
        Self {
            format: ORACLE_FORMAT.to_string(),
            runs,
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
