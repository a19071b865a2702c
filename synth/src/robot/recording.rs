//! A simulated recording: the truth of every run, the encoder ticks and the camera's view
//! of the true trajectory.

use super::*;

/// Effective wheel geometry of a run (what an oracle dead-reckons with).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct EffectiveGeometry {
    /// Left wheel: true diameter times (1 - slip at the commanded speed), metres.
    pub left_wheel_diameter_m: f64,
    /// Right wheel: true diameter times (1 - slip at the commanded speed), metres.
    pub right_wheel_diameter_m: f64,
    /// True effective wheel base, metres.
    pub wheel_base_m: f64,
}

/// The truth of one run.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct RunTruth {
    /// Commanded speed, m/s.
    pub speed_mps: f64,
    /// Robot-clock time the motion starts, seconds.
    pub motion_start_s: f64,
    /// Robot-clock time the wheels are at rest again, seconds.
    pub motion_end_s: f64,
    /// Pose at rest before the run (floor frame).
    pub start_pose: Pose2,
    /// Pose at rest after the run (floor frame).
    pub end_pose: Pose2,
    /// End pose in the run's start frame (heading wrapped).
    pub end_in_start_frame: Pose2,
    /// Path length of the wheels' midpoint, metres.
    pub path_length_m: f64,
    /// Effective geometry at the commanded speed.
    pub effective: EffectiveGeometry,
}

/// One sample of the true trajectory.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TruePose {
    /// Robot-clock time, seconds.
    pub t_robot_s: f64,
    /// Pose of the wheels' midpoint in the floor frame (heading not wrapped).
    pub pose: Pose2,
    /// False while the robot is carried (the tag is hidden).
    pub visible: bool,
}

/// One row of the 200 ms odometry log.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct TickRow {
    /// Robot-clock time in log periods (t = index * period).
    pub index: u64,
    /// Cumulative left encoder counts.
    pub left_ticks: i64,
    /// Cumulative right encoder counts.
    pub right_ticks: i64,
}

/// A simulated recording: one odometry log, one camera span, one or more runs.
#[derive(Debug, Clone, PartialEq)]
pub struct SimulatedRecording {
    /// Clock offset, seconds: t_camera = t_robot + offset.
    pub clock_offset_s: f64,
    /// Camera time of the last frame's span (frames at k / fps for k / fps <= this), seconds.
    pub camera_end_s: f64,
    /// Log period, seconds.
    pub log_period_s: f64,
    /// The odometry log.
    pub log: Vec<TickRow>,
    /// The true trajectory, every `truth_period_s` of robot time from camera start to end.
    pub truth: Vec<TruePose>,
    /// Period of `truth`, seconds.
    pub truth_period_s: f64,
    /// The runs.
    pub runs: Vec<RunTruth>,
}

impl SimulatedRecording {
    /// Log times, seconds on the robot clock, to the microsecond a robot's clock counts in
    /// (so a log reads "3.8", not the product's "3.8000000000000003").
    pub fn log_time_s(&self, row: &TickRow) -> f64 {
        (row.index as f64 * self.log_period_s * 1e6).round() / 1e6
    }

    /// True pose at a robot-clock time (linear interpolation); None outside or while carried.
    pub fn pose_at_robot_time(&self, t: f64) -> Option<Pose2> {
        let first = self.truth.first()?;
        let f = (t - first.t_robot_s) / self.truth_period_s;
        if f.is_nan() || f < 0.0 {
            return None;
        }
        let i = f.floor() as usize;
        let a = self.truth.get(i)?;
        let b = self.truth.get(i + 1).unwrap_or(a);
        if !a.visible || !b.visible {
            return None;
        }
        let w = (f - i as f64).clamp(0.0, 1.0);
        Some(a.pose.lerp(&b.pose, w))
    }

    /// True pose at a camera-clock time; None outside or while carried.
    pub fn pose_at_camera_time(&self, t_cam: f64) -> Option<Pose2> {
        self.pose_at_robot_time(t_cam - self.clock_offset_s)
    }

    /// Camera frame times, seconds on the camera clock (k / fps from 0 to the end).
    pub fn frame_times(&self, fps: f64) -> Vec<f64> {
        let n = (self.camera_end_s * fps + 1e-9).floor() as usize;
        (0..=n).map(|k| k as f64 / fps).collect()
    }

    /// The robot's 200 ms log as odocal reads it (cumulative ticks on the robot's clock).
    pub fn odometry_log(&self) -> Result<OdometryLog, DatasetError> {
        OdometryLog::from_ticks(
            self.log.iter().map(|row| self.log_time_s(row)).collect(),
            self.log.iter().map(|row| row.left_ticks).collect(),
            self.log.iter().map(|row| row.right_ticks).collect(),
        )
    }

    /// [`SimulatedRecording::camera_trajectory`] as the trajectory a tracker would write (quality 1).
    pub fn camera_track(
        &self,
        camera: &CameraTiming,
        seed: u64,
        stream: u64,
    ) -> Result<Trajectory, FileError> {
        Trajectory::new(
            self.camera_trajectory(camera, seed, stream)
                .into_iter()
                .map(|(t_s, pose)| TrajectoryRow {
                    t_s,
                    pose,
                    quality: 1.0,
                    sigma: None,
                })
                .collect(),
        )
    }

    /// The camera's trajectory without video: the true pose at each frame time (frames where
    /// the tag is hidden are absent), plus Gaussian noise; returns (camera time, pose).
    pub fn camera_trajectory(
        &self,
        camera: &CameraTiming,
        seed: u64,
        stream: u64,
    ) -> Vec<(f64, Pose2)> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        rng.set_stream(stream);
        let mut out = Vec::new();
        for t in self.frame_times(camera.fps) {
            let nx: f64 = rng.sample(StandardNormal);
            let ny: f64 = rng.sample(StandardNormal);
            let nt: f64 = rng.sample(StandardNormal);
            if let Some(p) = self.pose_at_camera_time(t) {
                out.push((
                    t,
                    Pose2::new(
                        p.x_m + camera.position_noise_m * nx,
                        p.y_m + camera.position_noise_m * ny,
                        wrap_angle(p.theta_rad + camera.heading_noise_rad * nt),
                    ),
                ));
            }
        }
        out
    }
}
