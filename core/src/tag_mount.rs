//! Where the tracked body sits on the robot. A camera sees the tag, a laser scanner sees its
//! own centre, a motion-capture system its marker body; the wheels' odometry is the pose of the
//! robot's reference point, the midpoint of its wheel axle, heading forwards. A tag mounted
//! 10 cm ahead of the axle swings 14 cm sideways while the robot turns 90° on the spot, so a
//! trajectory of the tag is the robot's only when the two coincide.
//!
//! [`TagToRobot`] carries the mount and turns tag poses into robot poses (with their σ);
//! [`MountFit`] reads, from a trajectory alone, how far ahead of the axle its point sits and
//! how its heading is turned: the midpoint of a differential drive's axle never moves
//! sideways, any other point on the robot's centre line does, by its distance from the axle
//! times the turn, and the robot drives along its own heading.

use crate::pose::{wrap_angle, Pose2};
use crate::trajectory::{PoseSigma, Trajectory, TrajectoryRow};

/// Largest angle a tag may be turned on its robot, degrees either way: a mount is turned
/// less than a full turn, and a larger number is no angle anyone measured (1e300 degrees used
/// to wrap to some angle, unsaid).
pub const MAX_TAG_YAW_DEG: f64 = 360.0;

/// A tag yaw that is no angle of a mount.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
#[error("--tag-yaw {0:?}: the angle from the robot's front to the tag's x axis is -{max} to {max} degrees, counter-clockwise (90: the tag's x axis points to the robot's left)", max = MAX_TAG_YAW_DEG)]
pub struct TagYawError(pub f64);

/// The tag's pose on the robot: maps points in the tag's frame into the robot's frame
/// (origin the midpoint of the wheel axle, x forwards, y to the left). The identity is a tag
/// centred over the axle with its x axis pointing forwards.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct TagToRobot(pub Pose2);

impl TagToRobot {
    /// A tag centred over the axle midpoint, its x axis forwards.
    pub const IDENTITY: TagToRobot = TagToRobot(Pose2 {
        x_m: 0.0,
        y_m: 0.0,
        theta_rad: 0.0,
    });

    /// A tag whose centre is `ahead_m` in front of the axle midpoint and `left_m` to its left,
    /// its x axis turned `yaw_rad` counter-clockwise from the robot's forward direction.
    pub fn new(ahead_m: f64, left_m: f64, yaw_rad: f64) -> Self {
        Self(Pose2::new(ahead_m, left_m, wrap_angle(yaw_rad)))
    }

    /// [`Self::new`] with the yaw in degrees as a user gives it, refused unless finite and
    /// within [`MAX_TAG_YAW_DEG`] either way.
    pub fn from_degrees(ahead_m: f64, left_m: f64, yaw_deg: f64) -> Result<Self, TagYawError> {
        if !yaw_deg.is_finite() || yaw_deg.abs() > MAX_TAG_YAW_DEG {
            return Err(TagYawError(yaw_deg));
        }
        Ok(Self::new(ahead_m, left_m, yaw_deg.to_radians()))
    }

    /// Whether the tag is the robot (no offset, no turn).
    pub fn is_identity(&self) -> bool {
        self.0 == Pose2::default() || *self == Self::IDENTITY
    }

    /// The robot's pose (robot frame → floor) from the tag's (tag frame → floor).
    pub fn robot_pose(&self, tag_to_floor: &Pose2) -> Pose2 {
        let p = tag_to_floor.compose(&self.0.inverse());
        Pose2::new(p.x_m, p.y_m, wrap_angle(p.theta_rad))
    }

    /// The tag's pose (tag frame → floor) on a robot at `robot_to_floor`.
    pub fn tag_pose(&self, robot_to_floor: &Pose2) -> Pose2 {
        let p = robot_to_floor.compose(&self.0);
        Pose2::new(p.x_m, p.y_m, wrap_angle(p.theta_rad))
    }

    /// The σ of [`Self::robot_pose`] from the tag's: the heading's σ swings the lever from the
    /// tag to the axle, adding its length times σθ across it (the tag's position and heading
    /// errors taken as independent).
    pub fn robot_sigma(&self, tag_to_floor: &Pose2, sigma: &PoseSigma) -> PoseSigma {
        // The axle midpoint in the tag frame, and the floor-frame derivative of its position
        // with respect to the tag's heading.
        let q = self.0.inverse();
        let (s, c) = tag_to_floor.theta_rad.sin_cos();
        let dx = -s * q.x_m - c * q.y_m;
        let dy = c * q.x_m - s * q.y_m;
        PoseSigma {
            x_m: sigma.x_m.hypot(dx * sigma.theta_rad),
            y_m: sigma.y_m.hypot(dy * sigma.theta_rad),
            theta_rad: sigma.theta_rad,
        }
    }

    /// `trajectory` of the tag as the robot's trajectory: every row's pose and σ.
    pub fn robot_trajectory(&self, trajectory: &Trajectory) -> Trajectory {
        if self.is_identity() {
            return trajectory.clone();
        }
        Trajectory {
            rows: trajectory
                .rows
                .iter()
                .map(|r| TrajectoryRow {
                    pose: self.robot_pose(&r.pose),
                    sigma: r.sigma.map(|s| self.robot_sigma(&r.pose, &s)),
                    ..*r
                })
                .collect(),
        }
    }
}

/// A step for the mount fit: the position moved at least this far or the heading turned at
/// least [`STEP_TURN_RAD`] (tracking noise is a fraction of a millimetre).
const STEP_M: f64 = 0.02;

/// See [`STEP_M`] (3°).
const STEP_TURN_RAD: f64 = 0.052;

/// Steps longer than this are not one motion (a gap in the trajectory), seconds.
const MAX_STEP_S: f64 = 0.5;

/// Steps needed to judge the yaw.
const MIN_STEPS: usize = 10;

/// Turning needed to judge the distance ahead, radians (90° in all).
const MIN_TURN_RAD: f64 = std::f64::consts::FRAC_PI_2;

/// The steps of one run of rows for the mount fit: from each step's end to the first row that
/// moved [`STEP_M`] or turned [`STEP_TURN_RAD`] from it, none over more than [`MAX_STEP_S`].
fn mount_steps(rows: &[TrajectoryRow]) -> Vec<(&TrajectoryRow, &TrajectoryRow)> {
    let mut steps = Vec::new();
    let mut anchor = 0;
    for i in 1..rows.len() {
        let (a, b) = (&rows[anchor], &rows[i]);
        if b.t_s - a.t_s > MAX_STEP_S {
            anchor = i;
            continue;
        }
        let moved_m = (b.pose.position() - a.pose.position()).norm();
        let turn = wrap_angle(b.pose.theta_rad - a.pose.theta_rad);
        if moved_m >= STEP_M || turn.abs() >= STEP_TURN_RAD {
            steps.push((a, b));
            anchor = i;
        }
    }
    steps
}

/// Where a trajectory's point and heading sit on a differential-drive robot, read off the
/// trajectory alone. Over a step the axle midpoint moves along the robot's mean heading; a
/// point `a` ahead of it moves `2 a sin(Δθ/2)` further to the left while the robot turns by
/// Δθ, at any speed; a heading turned by ψ from the robot's turns the step by -ψ. Both are
/// fitted together, so the sideways swing of a tag off the axle does not read as a turned
/// tag, nor the reverse.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MountFit {
    /// The trajectory's heading less the robot's, radians in (-π, π] (the robot taken to
    /// drive forwards more than backwards).
    pub yaw_rad: f64,
    /// Its standard deviation from the fit's residuals, radians.
    pub yaw_sigma_rad: f64,
    /// Distance of the trajectory's point ahead of the axle midpoint, metres (negative:
    /// behind it); `None` without 90° of turning.
    pub ahead_m: Option<f64>,
    /// Its standard deviation, metres.
    pub ahead_sigma_m: f64,
    /// Turning behind the fit, radians (absolute turns summed).
    pub turned_rad: f64,
    /// Steps in the fit.
    pub steps: usize,
}

impl MountFit {
    /// Offsets ahead below this are not named, metres: a tag mounted by hand is rarely within
    /// a centimetre or two of the axle, and wheel slip on turns moves the axle itself a little.
    pub const NAMED_AHEAD_M: f64 = 0.02;

    /// Yaws below this are not named, radians (2°): a tag laid by eye is a degree or two off.
    pub const NAMED_YAW_RAD: f64 = 0.035;

    /// Fits the mount to every step of `trajectory`; `None` with fewer than 10 steps.
    pub fn of(trajectory: &Trajectory) -> Option<Self> {
        Self::of_runs(&[&trajectory.rows])
    }

    /// Fits the mount to the steps within each of `runs`, stretches of one continuous motion:
    /// the step from one run's last row to the next run's first is no motion of the robot
    /// (two recordings joined, a robot lifted and set down), and its chord alone turned a
    /// straight-driven tag's fit by 50°. `None` with fewer than 10 steps.
    pub fn of_runs(runs: &[&[TrajectoryRow]]) -> Option<Self> {
        // Sums for the fit of n·z = a·s, with z the step in the heading's frame (u forwards,
        // w to the left), s = 2 sin(Δθ/2) and n = (sin ψ, cos ψ) the robot's left in it.
        let (mut suu, mut suw, mut sww, mut ssu, mut ssw, mut sss) = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
        let (mut su, mut sw) = (0.0, 0.0);
        let mut turned_rad = 0.0;
        let mut steps = 0usize;
        for (a, b) in runs.iter().flat_map(|rows| mount_steps(rows)) {
            let (dx, dy) = (b.pose.x_m - a.pose.x_m, b.pose.y_m - a.pose.y_m);
            let turn = wrap_angle(b.pose.theta_rad - a.pose.theta_rad);
            let (sm, cm) = (a.pose.theta_rad + 0.5 * turn).sin_cos();
            let u = cm * dx + sm * dy;
            let w = -sm * dx + cm * dy;
            let s = 2.0 * (0.5 * turn).sin();
            suu += u * u;
            suw += u * w;
            sww += w * w;
            ssu += s * u;
            ssw += s * w;
            sss += s * s;
            su += u;
            sw += w;
            turned_rad += turn.abs();
            steps += 1;
        }
        if steps < MIN_STEPS {
            return None;
        }
        // With `a` solved for, n is the eigenvector of the smallest eigenvalue of M.
        let (m11, m12, m22) = if sss > 0.0 {
            (
                suu - ssu * ssu / sss,
                suw - ssu * ssw / sss,
                sww - ssw * ssw / sss,
            )
        } else {
            (suu, suw, sww)
        };
        let half_trace = 0.5 * (m11 + m22);
        let gap = (0.25 * (m11 - m22).powi(2) + m12 * m12).sqrt();
        let (small, big) = (half_trace - gap, half_trace + gap);
        if big <= 0.0 {
            return None;
        }
        // Eigenvector of `small`: (m12, small - m11) or (small - m22, m12), the larger.
        let (v1, v2) = if (small - m11).abs() + m12.abs() >= (small - m22).abs() + m12.abs() {
            (m12, small - m11)
        } else {
            (small - m22, m12)
        };
        let norm = v1.hypot(v2);
        let (mut sin_yaw, mut cos_yaw) = if norm > 0.0 {
            (v1 / norm, v2 / norm)
        } else if m11 <= m22 {
            (1.0, 0.0)
        } else {
            (0.0, 1.0)
        };
        // The robot's forward travel, u cos ψ - w sin ψ, is taken to be positive overall.
        if cos_yaw * su - sin_yaw * sw < 0.0 {
            sin_yaw = -sin_yaw;
            cos_yaw = -cos_yaw;
        }
        let variance = small.max(0.0) / (steps - 2) as f64;
        let enough_turning = turned_rad >= MIN_TURN_RAD && sss > 0.0;
        Some(Self {
            yaw_rad: sin_yaw.atan2(cos_yaw),
            yaw_sigma_rad: (variance / big).sqrt(),
            ahead_m: enough_turning.then(|| (sin_yaw * ssu + cos_yaw * ssw) / sss),
            ahead_sigma_m: if enough_turning {
                (variance / sss).sqrt()
            } else {
                f64::NAN
            },
            turned_rad,
            steps,
        })
    }

    /// The distance ahead, when large enough to name and well beyond its σ.
    pub fn named_ahead_m(&self) -> Option<f64> {
        self.ahead_m
            .filter(|a| a.abs() > Self::NAMED_AHEAD_M && a.abs() > 5.0 * self.ahead_sigma_m)
    }

    /// The yaw, when large enough to name and well beyond its σ.
    pub fn named_yaw_rad(&self) -> Option<f64> {
        let y = self.yaw_rad;
        (y.abs() > Self::NAMED_YAW_RAD && y.abs() > 5.0 * self.yaw_sigma_rad).then_some(y)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    #[test]
    fn a_yaw_is_a_finite_angle_within_a_turn() {
        let t = TagToRobot::from_degrees(0.1, 0.0, -270.0).unwrap();
        assert!((t.0.theta_rad - PI / 2.0).abs() < 1e-12);
        assert!(TagToRobot::from_degrees(0.0, 0.0, 360.0).is_ok());
        for bad in [
            f64::NAN,
            f64::INFINITY,
            -f64::INFINITY,
            1e300,
            360.5,
            -361.0,
        ] {
            let e = TagToRobot::from_degrees(0.0, 0.0, bad)
                .unwrap_err()
                .to_string();
            assert!(
                e.starts_with(&format!("--tag-yaw {bad:?}: ")) && e.contains("-360 to 360 degrees"),
                "{e}"
            );
        }
    }

    /// A robot driving figure-eights: 0.3 m/s, turning at ±1.2 rad/s, 30 rows a second, its
    /// axle midpoint's poses.
    fn figure_eights(seconds: f64) -> Vec<(f64, Pose2)> {
        let dt = 1.0 / 30.0;
        let mut p = Pose2::new(1.0, 0.5, 0.3);
        let mut out = Vec::new();
        let mut t = 0.0;
        while t < seconds {
            out.push((t, p));
            let omega = if (t / 5.0) as i64 % 2 == 0 { 1.2 } else { -1.2 };
            let h = p.theta_rad + 0.5 * omega * dt;
            p = Pose2::new(
                p.x_m + 0.3 * dt * h.cos(),
                p.y_m + 0.3 * dt * h.sin(),
                p.theta_rad + omega * dt,
            );
            t += dt;
        }
        out
    }

    fn tag_trajectory(mount: &TagToRobot, seconds: f64, noise_m: f64) -> Trajectory {
        let mut k = 0u32;
        // A deterministic ±noise pattern (no random source needed for the bound).
        let mut jitter = || {
            k = k.wrapping_mul(1_103_515_245).wrapping_add(12_345);
            noise_m * ((k >> 16) as f64 / 32_768.0 - 1.0)
        };
        Trajectory::new(
            figure_eights(seconds)
                .into_iter()
                .map(|(t_s, p)| {
                    let tag = mount.tag_pose(&p);
                    TrajectoryRow {
                        t_s,
                        pose: Pose2::new(tag.x_m + jitter(), tag.y_m + jitter(), tag.theta_rad),
                        quality: 1.0,
                        sigma: Some(PoseSigma {
                            x_m: 3e-4,
                            y_m: 3e-4,
                            theta_rad: 0.01,
                        }),
                    }
                })
                .collect(),
        )
        .unwrap()
    }

    #[test]
    fn robot_pose_undoes_the_mount_and_sigma_grows_with_the_lever() {
        let mount = TagToRobot::new(0.12, -0.03, 0.5 * PI);
        let robot = Pose2::new(1.0, 2.0, 0.7);
        let tag = mount.tag_pose(&robot);
        let back = mount.robot_pose(&tag);
        assert!((back.position() - robot.position()).norm() < 1e-12);
        assert!(wrap_angle(back.theta_rad - robot.theta_rad).abs() < 1e-12);
        assert!(((tag.position() - robot.position()).norm() - 0.12f64.hypot(0.03)).abs() < 1e-12);
        // σθ 0.01 rad over a 12.4 cm lever: about 1.2 mm across it.
        let s = PoseSigma {
            x_m: 1e-4,
            y_m: 1e-4,
            theta_rad: 0.01,
        };
        let r = mount.robot_sigma(&tag, &s);
        let across = (r.x_m.powi(2) + r.y_m.powi(2) - 2e-8).sqrt();
        assert!(
            (across - 0.01 * 0.12f64.hypot(0.03)).abs() < 1e-9,
            "{across}"
        );
        assert_eq!(TagToRobot::IDENTITY.robot_sigma(&tag, &s), s);
    }

    #[test]
    fn the_mount_is_read_off_the_motion() {
        for (ahead, left, yaw_deg) in [
            (0.10, 0.0, 0.0),
            (-0.06, 0.04, 3.0),
            (0.0, 0.05, 0.0),
            (0.10, 0.02, 90.0),
            (0.05, 0.0, 180.0),
            (0.0, 0.0, -20.0),
            (0.0, 0.0, 1.0),
        ] {
            let mount = TagToRobot::new(ahead, left, f64::to_radians(yaw_deg));
            let fit = MountFit::of(&tag_trajectory(&mount, 20.0, 3e-4)).unwrap();
            // The distance ahead is along the robot's forward axis, whatever the tag's yaw.
            let a = fit.ahead_m.unwrap();
            assert!(
                (a - ahead).abs() < 2e-3 && fit.ahead_sigma_m < 2e-3,
                "{ahead} {left} {yaw_deg}°: {fit:?}"
            );
            assert!(
                wrap_angle(fit.yaw_rad - yaw_deg.to_radians()).abs() < 0.2f64.to_radians(),
                "{ahead} {left} {yaw_deg}°: {fit:?}"
            );
            assert_eq!(fit.named_ahead_m().is_some(), ahead.abs() > 0.02, "{fit:?}");
            assert_eq!(
                fit.named_yaw_rad().is_some(),
                yaw_deg.abs() > 2.0,
                "{fit:?}"
            );
            // Taken off again, the axle does not slip and the heading is the robot's.
            let robot = mount.robot_trajectory(&tag_trajectory(&mount, 20.0, 3e-4));
            let fit = MountFit::of(&robot).unwrap();
            assert!(
                fit.ahead_m.unwrap().abs() < 2e-3 && fit.named_ahead_m().is_none(),
                "{fit:?}"
            );
            assert!(fit.named_yaw_rad().is_none(), "{fit:?}");
        }
        // A straight drive says nothing.
        let straight = Trajectory::new(
            (0..90)
                .map(|i| TrajectoryRow {
                    t_s: i as f64 / 30.0,
                    pose: Pose2::new(0.01 * i as f64, 0.0, 0.0),
                    quality: 1.0,
                    sigma: None,
                })
                .collect(),
        )
        .unwrap();
        let fit = MountFit::of(&straight).unwrap();
        assert!(fit.ahead_m.is_none() && fit.yaw_rad.abs() < 1e-9, "{fit:?}");
    }
}
