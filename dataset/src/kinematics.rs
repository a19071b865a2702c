//! Differential-drive dead reckoning with the source's kinematics and the feature rule.
//!
//! Sign convention (stated once for odocal): rotation is counter-clockwise positive, so a step
//! with wheel travels v_l, v_r turns by d_rot = (v_r - v_l) / b. The source writes
//! d_rot = (v_l - v_r) / b (right turns positive); its rotations compare with ours negated.
//! Per step: d_trans = (v_l + v_r) / 2, x += d_trans cos(theta + d_rot / 2),
//! y += d_trans sin(theta + d_rot / 2), theta += d_rot.

use odocal_core::Pose2;
use serde::{Deserialize, Serialize};

use crate::{RobotParams, N_INPUTS};

/// Wheel geometry used to turn wheel revolutions into motion (nominal or calibrated).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct WheelGeometry {
    /// Effective left wheel diameter, metres.
    pub left_wheel_diameter_m: f64,
    /// Effective right wheel diameter, metres.
    pub right_wheel_diameter_m: f64,
    /// Effective wheel base, metres.
    pub wheel_base_m: f64,
}

impl WheelGeometry {
    /// The nominal geometry of a robot: both wheels of the nominal diameter.
    pub fn nominal(robot: &RobotParams) -> Self {
        Self {
            left_wheel_diameter_m: robot.wheel_diameter_m,
            right_wheel_diameter_m: robot.wheel_diameter_m,
            wheel_base_m: robot.wheel_base_m,
        }
    }
}

/// One dead-reckoning step from `pose` with wheel travels `v_l`, `v_r` (metres), base `b` (metres).
pub fn step(pose: &Pose2, v_l: f64, v_r: f64, b: f64) -> Pose2 {
    let d_trans = 0.5 * (v_l + v_r);
    let d_rot = (v_r - v_l) / b;
    let mid = pose.theta_rad + 0.5 * d_rot;
    Pose2::new(
        pose.x_m + d_trans * mid.cos(),
        pose.y_m + d_trans * mid.sin(),
        pose.theta_rad + d_rot,
    )
}

/// Dead-reckons cumulative wheel revolutions; returns one pose per row, the first at the origin.
/// Poses map the robot's body frame into the frame of the first row (the run's start frame);
/// headings are not wrapped.
pub fn dead_reckon(rev: &[[f64; 2]], geom: &WheelGeometry) -> Vec<Pose2> {
    let cl = std::f64::consts::PI * geom.left_wheel_diameter_m;
    let cr = std::f64::consts::PI * geom.right_wheel_diameter_m;
    let mut out = Vec::with_capacity(rev.len());
    let mut pose = Pose2::default();
    out.push(pose);
    for w in rev.windows(2) {
        pose = step(
            &pose,
            (w[1][0] - w[0][0]) * cl,
            (w[1][1] - w[0][1]) * cr,
            geom.wheel_base_m,
        );
        out.push(pose);
    }
    out
}

/// The odometry of one run: log rows from t_b (last row at rest before motion) to t_e (first
/// row at rest after the last encoder change), revolutions relative to the row at t_b.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct RunOdometry {
    /// Robot-clock times of the rows, seconds; first is t_b, last is t_e.
    pub t_s: Vec<f64>,
    /// Cumulative wheel revolutions [left, right] since t_b.
    pub rev: Vec<[f64; 2]>,
}

impl RunOdometry {
    /// Run start time t_b on the robot clock, seconds (NaN when empty).
    pub fn t_b(&self) -> f64 {
        self.t_s.first().copied().unwrap_or(f64::NAN)
    }

    /// Run end time t_e on the robot clock, seconds (NaN when empty).
    pub fn t_e(&self) -> f64 {
        self.t_s.last().copied().unwrap_or(f64::NAN)
    }

    /// Dead-reckoned poses in the start frame, one per row.
    pub fn poses(&self, geom: &WheelGeometry) -> Vec<Pose2> {
        dead_reckon(&self.rev, geom)
    }

    /// Dead-reckoned end position (x, y) in the start frame, metres.
    pub fn end_m(&self, geom: &WheelGeometry) -> [f64; 2] {
        let p = self.poses(geom);
        p.last().map(|q| [q.x_m, q.y_m]).unwrap_or([0.0, 0.0])
    }

    /// Distance travelled by the wheels' midpoint, metres (sum of |d_trans|).
    pub fn travel_m(&self, geom: &WheelGeometry) -> f64 {
        let cl = std::f64::consts::PI * geom.left_wheel_diameter_m;
        let cr = std::f64::consts::PI * geom.right_wheel_diameter_m;
        self.rev
            .windows(2)
            .map(|w| (0.5 * ((w[1][0] - w[0][0]) * cl + (w[1][1] - w[0][1]) * cr)).abs())
            .sum()
    }

    /// How far the run turned, without a robot file: the largest difference the two wheels'
    /// revolutions reach from the start, over the mean revolutions both turned (a straight
    /// run's ticks stay within a percent of each other; a turn in place adds all of its
    /// travel). None when the wheels did not turn.
    pub fn turn_share(&self) -> Option<f64> {
        let first = self.rev.first()?;
        let travel: f64 = self
            .rev
            .windows(2)
            .map(|w| 0.5 * ((w[1][0] - w[0][0]).abs() + (w[1][1] - w[0][1]).abs()))
            .sum();
        let apart = self
            .rev
            .iter()
            .map(|r| ((r[1] - first[1]) - (r[0] - first[0])).abs())
            .fold(0.0, f64::max);
        (travel > 0.0).then(|| apart / travel)
    }

    /// The 18 inputs of [`crate::FEATURE_RULE`] computed with `geom`.
    pub fn features(&self, geom: &WheelGeometry) -> [f64; N_INPUTS] {
        features_from_poses(&self.t_s, &self.poses(geom))
    }
}

/// The feature rule on dead-reckoned poses at times `t_s` (first t_b, last t_e): positions at
/// t_b + i/9 (t_e - t_b), i = 1..8, linearly interpolated in time between rows, then t_b, t_e.
pub fn features_from_poses(t_s: &[f64], poses: &[Pose2]) -> [f64; N_INPUTS] {
    let mut f = [0.0; N_INPUTS];
    let n = t_s.len().min(poses.len());
    if n == 0 {
        return f;
    }
    let (tb, te) = (t_s[0], t_s[n - 1]);
    let mut j = 0;
    for i in 1..=8 {
        let t = tb + (i as f64) / 9.0 * (te - tb);
        while j + 2 < n && t_s[j + 1] < t {
            j += 1;
        }
        let (x, y) = if n == 1 {
            (poses[0].x_m, poses[0].y_m)
        } else {
            let span = t_s[j + 1] - t_s[j];
            let a = if span > 0.0 {
                ((t - t_s[j]) / span).clamp(0.0, 1.0)
            } else {
                0.0
            };
            (
                poses[j].x_m + a * (poses[j + 1].x_m - poses[j].x_m),
                poses[j].y_m + a * (poses[j + 1].y_m - poses[j].y_m),
            )
        };
        f[2 * (i - 1)] = x;
        f[2 * (i - 1) + 1] = y;
    }
    f[16] = tb;
    f[17] = te;
    f
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn right_wheel_faster_turns_counter_clockwise() {
        let p = step(&Pose2::default(), 0.09, 0.11, 0.1);
        assert!((p.theta_rad - 0.2).abs() < 1e-12);
        assert!(p.y_m > 0.0);
        assert!((p.x_m - 0.1 * 0.1f64.cos()).abs() < 1e-12);
    }

    #[test]
    fn straight_run_and_features() {
        // 10 rows, 0.2 s apart, one revolution per step on both wheels.
        let t: Vec<f64> = (0..10).map(|k| 1.0 + 0.2 * k as f64).collect();
        let rev: Vec<[f64; 2]> = (0..10).map(|k| [k as f64, k as f64]).collect();
        let run = RunOdometry { t_s: t, rev };
        let g = WheelGeometry::nominal(&RobotParams::default());
        let circ = std::f64::consts::PI * 0.043;
        let end = run.end_m(&g);
        assert!((end[0] - 9.0 * circ).abs() < 1e-12 && end[1].abs() < 1e-12);
        let f = run.features(&g);
        // t_e - t_b = 1.8 s; i/9 of it is exactly row i.
        for i in 1..=8 {
            assert!((f[2 * (i - 1)] - i as f64 * circ).abs() < 1e-12);
        }
        assert_eq!(f[16], 1.0);
        assert!((f[17] - 2.8).abs() < 1e-12);
        assert!((run.travel_m(&g) - 9.0 * circ).abs() < 1e-12);
    }
}
