//! The `dataset.json` contract shared by the dataset builder and the trainer.

use odocal_core::Pose2;
use serde::{Deserialize, Serialize};

use crate::kinematics::RunOdometry;

/// The `format` tag of dataset.json files.
pub const DATASET_FORMAT: &str = "odocal.dataset/1";

/// Number of inputs per sample: eight intermediate odometry positions, t_b and t_e.
pub const N_INPUTS: usize = 18;

/// The feature rule, exactly; a model trained on one rule refuses logs built with another.
/// t_b is the last log row at rest before the run's first encoder change, t_e the first row
/// after its last change; positions are dead-reckoned from the row at t_b with the nominal
/// [`RobotParams`] and the source kinematics (counter-clockwise positive), then linearly
/// interpolated in time between log rows.
pub const FEATURE_RULE: &str = "odocal.features/1: x_i,y_i of dead-reckoned odometry (start frame, metres) at t_b + i/9 (t_e - t_b), i=1..8, then t_b, t_e (seconds, robot clock); t_b = last log row at rest before the first encoder change, t_e = first row at rest after the last change; nominal wheels, CCW-positive source kinematics, linear interpolation in time between rows";

/// Physical parameters of a differential-drive robot used for dead reckoning.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct RobotParams {
    /// Nominal wheel diameter, metres.
    pub wheel_diameter_m: f64,
    /// Encoder counts per wheel revolution.
    pub ticks_per_rev: f64,
    /// Nominal distance between the wheels' contact points, metres.
    pub wheel_base_m: f64,
    /// Odometry logging period, seconds.
    pub period_s: f64,
}

impl Default for RobotParams {
    /// The small robot of the reference experiment.
    fn default() -> Self {
        Self {
            wheel_diameter_m: 0.043,
            ticks_per_rev: 12.0,
            wheel_base_m: 0.10,
            period_s: 0.2,
        }
    }
}

/// One training sample: one straight run.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct Sample {
    /// Run identifier from the manifest.
    pub run_id: String,
    /// Commanded speed, m/s: the manifest's `speed_mps`, or the odometry's cruise speed
    /// when the manifest gives none ([`Self::speed_commanded`] false).
    pub speed_mps: f64,
    /// Whether `speed_mps` is the manifest's commanded speed. The odometry's cruise speeds
    /// differ run to run by noise, so grouping errors by them would pretend as many commands
    /// as there are runs. Datasets written before this was recorded read as commanded.
    #[serde(default = "commanded")]
    pub speed_commanded: bool,
    /// The 18 inputs in the source's order (see [`FEATURE_RULE`]).
    pub inputs: Vec<f64>,
    /// Target: the real end position (x, y) in the run's start frame, metres.
    pub target_m: [f64; 2],
    /// Raw odometry end position (x, y) in the run's start frame, metres.
    pub raw_end_m: [f64; 2],
    /// Real path length of the run, metres.
    pub path_length_m: f64,
    /// Estimated clock offset, seconds: t_camera = t_robot + offset.
    pub clock_offset_s: f64,
    /// RMS residual of the time alignment (speed profiles), m/s.
    pub alignment_residual_mps: f64,
    /// The recording's robot clock rate against the camera's (camera seconds per robot
    /// second; `clock_offset_s` is then the offset at the log's time 0) where it was told
    /// apart from 1; absent for 1.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub clock_rate: Option<f64>,
    /// Manifest row (recording) the run came from; equals `run_id` for one run per recording.
    #[serde(default)]
    pub recording_id: String,
    /// RMS residual of the time alignment (travel fit), metres.
    #[serde(default)]
    pub alignment_residual_m: f64,
    /// Peak speed-profile correlation of the recording's coarse alignment.
    #[serde(default)]
    pub speed_correlation: f64,
    /// Cruise speed seen by odometry (median log-interval speed while moving), m/s.
    #[serde(default)]
    pub odometry_speed_mps: f64,
    /// Camera pose at rest before the run, floor frame: the run's start frame.
    #[serde(default)]
    pub start_pose_floor: Pose2,
    /// Real end heading in the run's start frame, radians.
    #[serde(default)]
    pub target_theta_rad: f64,
    /// Camera frames averaged for the start and end poses.
    #[serde(default)]
    pub rest_frames: [usize; 2],
    /// σ of `target_m` (x, y), metres, from the trajectory's per-pose σ (absent when the
    /// trajectory has none, e.g. synthetic truth or files written before odocal gave σ).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub target_sigma_m: Option<[f64; 2]>,
    /// σ of `target_theta_rad`, radians (absent like `target_sigma_m`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub target_sigma_theta_rad: Option<f64>,
    /// The run's odometry (rows t_b..t_e, wheel revolutions since t_b), to re-dead-reckon with
    /// other wheel geometry (calibration baselines, the oracle).
    #[serde(default)]
    pub odometry: RunOdometry,
}

fn commanded() -> bool {
    true
}

/// A run that could not be turned into a sample, and why.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RejectedRun {
    /// Run identifier from the manifest.
    pub run_id: String,
    /// Why the run was not used.
    pub reason: String,
}

/// The training set written to dataset.json.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Dataset {
    /// Always [`DATASET_FORMAT`].
    pub format: String,
    /// The feature rule the inputs follow, [`FEATURE_RULE`].
    pub feature_rule: String,
    /// Robot parameters used for dead reckoning.
    pub robot: RobotParams,
    /// The usable runs.
    pub samples: Vec<Sample>,
    /// Runs that could not be used, with reasons.
    pub rejected: Vec<RejectedRun>,
    /// Summary figures of the build.
    #[serde(default)]
    pub summary: DatasetSummary,
    /// What was done to the inputs that their owner should know (encoder-counter wraps
    /// unwrapped, twitches at rest set back), one line each naming the file.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub notes: Vec<String>,
    /// What the data says is likely wrong with it but cannot prove (a trajectory's point off
    /// the wheel axle, say), one line each with the figure and the option that mends it.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub warnings: Vec<String>,
}

/// Summary figures of a dataset build.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct DatasetSummary {
    /// Manifest rows (recordings) read.
    pub recordings: usize,
    /// Runs detected in the logs (samples + rejected).
    pub runs: usize,
    /// Raw odometry relative end-point error, see [`relative_end_error`].
    pub raw_relative_error: f64,
    /// RMS raw odometry end-point error, metres.
    pub raw_rms_error_m: f64,
    /// Mean real path length, metres.
    pub mean_path_length_m: f64,
    /// Largest speed-profile alignment residual, m/s.
    pub max_alignment_residual_mps: f64,
    /// A window dataset's wheel travel against the camera's over its recordings (absent for
    /// straight runs, whose end points give the scale, and in older files).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub travel_scale: Option<TravelScale>,
}

/// The wheels' travel against the camera's over a dataset's recordings.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TravelScale {
    /// The wheels' travel (nominal robot) over the camera's.
    pub ratio: f64,
    /// The camera's travel compared, metres.
    pub camera_m: f64,
    /// Recordings compared.
    pub recordings: usize,
}

impl Dataset {
    /// A dataset of `samples` and `rejected` runs with its summary computed.
    pub fn new(
        robot: RobotParams,
        samples: Vec<Sample>,
        rejected: Vec<RejectedRun>,
        recordings: usize,
    ) -> Self {
        let ends: Vec<[f64; 2]> = samples.iter().map(|s| s.raw_end_m).collect();
        let n = samples.len().max(1) as f64;
        let summary = DatasetSummary {
            recordings,
            runs: samples.len() + rejected.len(),
            raw_relative_error: relative_end_error(&samples, &ends),
            raw_rms_error_m: (samples
                .iter()
                .map(|s| {
                    (s.raw_end_m[0] - s.target_m[0]).powi(2)
                        + (s.raw_end_m[1] - s.target_m[1]).powi(2)
                })
                .sum::<f64>()
                / n)
                .sqrt(),
            mean_path_length_m: samples.iter().map(|s| s.path_length_m).sum::<f64>() / n,
            max_alignment_residual_mps: samples
                .iter()
                .map(|s| s.alignment_residual_mps)
                .fold(0.0, f64::max),
            travel_scale: None,
        };
        Self {
            format: DATASET_FORMAT.to_string(),
            feature_rule: FEATURE_RULE.to_string(),
            robot,
            samples,
            rejected,
            summary,
            notes: Vec::new(),
            warnings: Vec::new(),
        }
    }

    /// Reads dataset.json (see [`Dataset::parse`]).
    pub fn read(path: &std::path::Path) -> Result<Self, crate::DatasetError> {
        let text = crate::error::read_text(path)?;
        Self::parse(&text, &path.display().to_string())
    }

    /// Parses dataset.json text and checks it ([`Dataset::check`]); `name` starts every
    /// message. The one reader of dataset.json: the trainer and the report use it too.
    pub fn parse(text: &str, name: &str) -> Result<Self, crate::DatasetError> {
        let ds: Dataset = crate::error::parse_json_with_format(text, name, DATASET_FORMAT)?;
        ds.check()
            .map_err(|message| crate::DatasetError::content(name, message))?;
        Ok(ds)
    }

    /// Checks that the dataset is this build's and physically sensible: the feature rule, the
    /// robot parameters (positive, finite), and per sample 18 finite inputs, finite target and
    /// raw end point, a positive path length and a finite speed. The message names the sample.
    pub fn check(&self) -> Result<(), String> {
        let windows = self.feature_rule == crate::WINDOW_RULE;
        if self.feature_rule != FEATURE_RULE && !windows {
            return Err(format!(
                "feature rule \"{}\" is neither of this build's (\"{FEATURE_RULE}\", \"{}\"); rebuild the dataset",
                self.feature_rule,
                crate::WINDOW_RULE
            ));
        }
        self.robot.check().map_err(|e| format!("robot.{e}"))?;
        for (i, s) in self.samples.iter().enumerate() {
            check_sample(s, windows)
                .map_err(|e| format!("sample {i} (run '{}'): {e}", s.run_id))?;
        }
        if !windows {
            check_target_reach(&self.samples)?;
        }
        Ok(())
    }

    /// Whether the samples are windows of any motion ([`crate::WINDOW_RULE`]) rather than
    /// straight runs.
    pub fn is_windows(&self) -> bool {
        self.feature_rule == crate::WINDOW_RULE
    }
}

/// Refuses straight-run targets beyond twice their run's path length from its start (the
/// camera's end point of a run cannot lie further than the run went): a single one is named
/// (another run's, or an edit), most of them are a unit (`train` checks the unit of targets
/// that stay within reach against the odometry).
fn check_target_reach(samples: &[Sample]) -> Result<(), String> {
    let over = |s: &Sample| s.target_m[0].hypot(s.target_m[1]) / (2.0 * s.path_length_m + 0.05);
    let far: Vec<(usize, &Sample)> = samples
        .iter()
        .enumerate()
        .filter(|(_, s)| over(s) > 1.0)
        .collect();
    let Some(&(i, s)) = far.first() else {
        return Ok(());
    };
    if far.len() * 2 > samples.len() {
        let mut ratios: Vec<f64> = far.iter().map(|(_, s)| 2.0 * over(s)).collect();
        ratios.sort_by(f64::total_cmp);
        let ratio = ratios[ratios.len() / 2];
        let unit = if (500.0..=2000.0).contains(&ratio) {
            "are the trajectories in millimetres? "
        } else if (50.0..=200.0).contains(&ratio) {
            "are the trajectories in centimetres? "
        } else {
            ""
        };
        return Err(format!(
            "{} of {} targets lie about {ratio:.0} times their run's path length from its start, where a run's end can lie no further than it went: {unit}odocal expects trajectories in metres; fix them and rebuild the dataset",
            far.len(),
            samples.len()
        ));
    }
    Err(format!(
        "sample {i} (run '{}'): its target ({}, {}) m lies beyond twice the run's path length ({:.3} m) from its start, where a run's end can lie no further than it went: another run's, or in another unit? rebuild the dataset with `odocal dataset`",
        s.run_id, s.target_m[0], s.target_m[1], s.path_length_m
    ))
}

fn check_sample(s: &Sample, windows: bool) -> Result<(), String> {
    if windows {
        // One [left, right] pair per step, and the rows the steps came from.
        if s.inputs.is_empty() || !s.inputs.len().is_multiple_of(2) {
            return Err(format!(
                "{} inputs, expected one left/right pair per step",
                s.inputs.len()
            ));
        }
        if s.odometry.rev.len() != s.inputs.len() / 2 + 1
            || s.odometry.t_s.len() != s.odometry.rev.len()
        {
            return Err("the window's odometry rows do not match its steps".into());
        }
        if !s.target_theta_rad.is_finite() {
            return Err("target heading is not finite".into());
        }
    } else if s.inputs.len() != N_INPUTS {
        return Err(format!("{} inputs, expected {N_INPUTS}", s.inputs.len()));
    }
    if let Some(c) = s.inputs.iter().position(|v| !v.is_finite()) {
        return Err(format!("input {c} is not a finite number"));
    }
    if s.target_m
        .iter()
        .chain(s.raw_end_m.iter())
        .any(|v| !v.is_finite())
    {
        return Err("target or raw end point is not finite".into());
    }
    if !(s.path_length_m.is_finite() && s.path_length_m > 0.0) {
        return Err(format!("path length {} must be > 0", s.path_length_m));
    }
    if !windows {
        // A straight run's odometry positions and camera end lie within its path of the
        // start (odometry off by tens of percent at most); beyond twice it, a value is
        // another run's, another unit's, or an edit's (an input of 1e300 was taken, and
        // normalised to nothing).
        let reach_m = 2.0 * s.path_length_m + 0.05;
        let far = |x: f64, y: f64| x.hypot(y) > reach_m;
        if let Some(i) = (0..8).find(|&i| far(s.inputs[2 * i], s.inputs[2 * i + 1])) {
            return Err(format!(
                "inputs {} and {} (odometry position x{} = {}, y{} = {}) lie beyond twice the run's path length ({:.3} m) from its start: not a position of this run; rebuild the dataset with `odocal dataset`",
                2 * i,
                2 * i + 1,
                i + 1,
                s.inputs[2 * i],
                i + 1,
                s.inputs[2 * i + 1],
                s.path_length_m
            ));
        }
    }
    if !s.speed_mps.is_finite() {
        return Err("speed is not finite".into());
    }
    Ok(())
}

/// The relative end-point error of a set: mean over samples of |end - target| / path length.
pub fn relative_end_error(samples: &[Sample], ends: &[[f64; 2]]) -> f64 {
    let n = samples.len().min(ends.len());
    if n == 0 {
        return 0.0;
    }
    samples
        .iter()
        .zip(ends)
        .map(|(s, e)| (e[0] - s.target_m[0]).hypot(e[1] - s.target_m[1]) / s.path_length_m)
        .sum::<f64>()
        / n as f64
}

/// The `format` tag of robot parameter files.
pub const ROBOT_FORMAT: &str = "odocal.robot/1";

#[derive(Deserialize)]
struct RobotFile {
    #[allow(dead_code)]
    format: String,
    #[serde(flatten)]
    robot: RobotParams,
}

/// The smallest wheel diameter taken for a robot's, metres.
const MIN_WHEEL_DIAMETER_M: f64 = 0.005;

impl RobotParams {
    /// Reads robot parameters from a small JSON file with `"format": "odocal.robot/1"`.
    pub fn read(path: &std::path::Path) -> Result<Self, crate::DatasetError> {
        let text = crate::error::read_text(path)?;
        let name = path.display().to_string();
        let f: RobotFile = crate::error::parse_json_with_format(&text, &name, ROBOT_FORMAT)?;
        // A parameter odocal does not read (a gear ratio, a wheel radius) would be passed
        // over while its writer expects it used; notes are welcome.
        if let Ok(serde_json::Value::Object(fields)) =
            serde_json::from_str(odocal_core::without_bom(&text))
        {
            let known = [
                "format",
                "wheel_diameter_m",
                "ticks_per_rev",
                "wheel_base_m",
                "period_s",
                "name",
                "comment",
                "description",
            ];
            if let Some(k) = fields.keys().find(|k| !known.contains(&k.as_str())) {
                return Err(crate::DatasetError::content(
                    &name,
                    format!(
                        "\"{k}\" is not a robot parameter odocal reads (it reads wheel_diameter_m, ticks_per_rev counted per wheel revolution after any gearbox, wheel_base_m and period_s; \"name\", \"comment\" and \"description\" are kept as notes): fold it into those, or remove it"
                    ),
                ));
            }
        }
        f.robot.check().map_err(|e| {
            crate::DatasetError::content(
                &name,
                format!("{e}; robot parameters must be positive finite numbers"),
            )
        })?;
        Ok(f.robot)
    }

    /// Checks that every parameter is a positive finite number; the message names the first
    /// that is not.
    pub fn check(&self) -> Result<(), String> {
        for (name, v) in [
            ("wheel_diameter_m", self.wheel_diameter_m),
            ("ticks_per_rev", self.ticks_per_rev),
            ("wheel_base_m", self.wheel_base_m),
            ("period_s", self.period_s),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(format!("{name} = {v} must be > 0"));
            }
        }
        // A small wheeled robot: a length beyond these is in another unit.
        for (name, v, max) in [
            ("wheel_diameter_m", self.wheel_diameter_m, 1.0),
            ("wheel_base_m", self.wheel_base_m, 3.0),
        ] {
            if v > max {
                return Err(format!(
                    "{name} = {v} m is not a small wheeled robot's (at most {max} m): is it in millimetres? it must be in metres"
                ));
            }
        }
        // Wheels under 5 mm, or an axle shorter than half a wheel across, are a length in
        // another unit or another length (a radius, one wheel's width): with a wheel base a
        // tenth of the true one, raw odometry turned 15 % off and nothing said so.
        if self.wheel_diameter_m < MIN_WHEEL_DIAMETER_M {
            return Err(format!(
                "wheel_diameter_m = {} m is less than the {} m of the smallest robot wheels: is it in another unit? it must be in metres",
                self.wheel_diameter_m, MIN_WHEEL_DIAMETER_M
            ));
        }
        if self.wheel_base_m < 0.5 * self.wheel_diameter_m {
            return Err(format!(
                "wheel_base_m = {} m is less than half the wheel diameter ({} m): it is the distance between the two wheels' contact points, across the robot (centre to centre); is it in another unit, or another length?",
                self.wheel_base_m, self.wheel_diameter_m
            ));
        }
        if self.period_s > 10.0 {
            return Err(format!(
                "period_s = {} s: odometry is logged several times a second (0.2 s in the reference experiment); is it in milliseconds? it must be in seconds",
                self.period_s
            ));
        }
        Ok(())
    }

    /// The parameters as robot-file JSON (with its format tag).
    pub fn to_json(&self) -> String {
        let mut v = serde_json::to_value(self).unwrap_or_default();
        if let Some(o) = v.as_object_mut() {
            o.insert("format".into(), ROBOT_FORMAT.into());
        }
        serde_json::to_string_pretty(&v).unwrap_or_default()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dataset() -> Dataset {
        let text = include_str!("../../tests/data/parsers/dataset.json");
        Dataset::parse(text, "dataset.json").expect("the test dataset parses")
    }

    /// An input of 1e300 was taken and normalised to nothing, and one target 1000 times too
    /// far was blamed on the whole dataset's unit: each is now named by its sample.
    #[test]
    fn positions_beyond_a_runs_reach_are_named_by_sample() {
        assert!(dataset().check().is_ok());
        let mut ds = dataset();
        ds.samples[2].inputs[4] = 1e300;
        let e = ds.check().unwrap_err();
        assert!(
            e.starts_with("sample 2 (run '")
                && e.contains("inputs 4 and 5 (odometry position x3 = 1000"),
            "{e}"
        );
        let mut ds = dataset();
        ds.samples[1].target_m[0] *= 1e3;
        let e = ds.check().unwrap_err();
        assert!(
            e.starts_with("sample 1 (run '") && e.contains("another run's, or in another unit?"),
            "{e}"
        );
        let mut ds = dataset();
        for s in &mut ds.samples {
            s.target_m = s.target_m.map(|v| v * 100.0);
        }
        let e = ds.check().unwrap_err();
        assert!(
            e.contains("4 of 4 targets lie about") && e.contains("in centimetres?"),
            "{e}"
        );
    }
}
