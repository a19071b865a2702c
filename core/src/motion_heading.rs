//! How a trajectory's direction of motion sits against its heading. A differential-drive robot
//! moves along its heading whenever it drives straight, forwards or backwards, so on straight
//! stretches the two agree unless the heading is not the robot's: a tag mounted turned, a
//! motion-capture body defined with another forward axis, theta in degrees. The tracker warns
//! on it and the dataset builder refuses it.

use std::f64::consts::{FRAC_PI_2, PI};

use crate::pose::wrap_angle;
use crate::trajectory::{Trajectory, TrajectoryRow};

/// A step: the position moved at least this far, metres (tracking noise is fractions of a
/// millimetre, so its direction is good to a degree).
const STEP_M: f64 = 0.01;

/// Steps whose heading turns by more than this, radians (2°), are left out: while turning,
/// a tag off the axle moves sideways.
const STRAIGHT_RAD: f64 = 0.035;

/// Straight steps needed to judge.
const MIN_STEPS: usize = 10;

/// The direction of motion on a trajectory's straight stretches, relative to its heading.
#[derive(Debug, Clone, PartialEq)]
pub struct MotionAgainstHeading {
    /// Per straight step of at least 1 cm, the direction of motion minus the heading,
    /// radians in (-π, π]: 0 driving forwards, π backwards.
    pub angles_rad: Vec<f64>,
}

impl MotionAgainstHeading {
    /// Median angle between the line of motion and the heading's line above which the
    /// heading is not the robot's, radians (30°; a tag 10 cm ahead of the axle on a gentle
    /// arc is a few degrees off).
    pub const MAX_LINE_MISFIT_RAD: f64 = 0.52;

    /// Share of straight steps (or of wheel travel) that must go one way before that way is
    /// taken as the run's direction.
    pub const ONE_WAY: f64 = 0.9;

    /// The straight steps of `trajectory` with its theta read as `theta * theta_scale`
    /// radians (π/180 reads it as degrees).
    pub fn of(trajectory: &Trajectory, theta_scale: f64) -> Self {
        Self::of_runs(&[&trajectory.rows], theta_scale)
    }

    /// As [`Self::of`], over the steps within each of `runs`, stretches of one continuous
    /// motion: the chord from one run's end to the next one's start is no direction the robot
    /// drove (two recordings joined, a robot lifted and set down).
    pub fn of_runs(runs: &[&[TrajectoryRow]], theta_scale: f64) -> Self {
        let mut angles_rad = Vec::new();
        for rows in runs {
            let mut anchor = 0;
            for i in 1..rows.len() {
                let (a, b) = (&rows[anchor].pose, &rows[i].pose);
                let (dx, dy) = (b.x_m - a.x_m, b.y_m - a.y_m);
                if dx.hypot(dy) < STEP_M {
                    continue;
                }
                let turn = wrap_angle(theta_scale * (b.theta_rad - a.theta_rad));
                if turn.abs() <= STRAIGHT_RAD {
                    let heading = theta_scale * a.theta_rad + 0.5 * turn;
                    angles_rad.push(wrap_angle(dy.atan2(dx) - heading));
                }
                anchor = i;
            }
        }
        Self { angles_rad }
    }

    /// Median angle between the line of motion and the heading's line (forwards and
    /// backwards alike), radians in [0, π/2]; `None` with fewer than 10 straight steps.
    pub fn line_misfit_rad(&self) -> Option<f64> {
        if self.angles_rad.len() < MIN_STEPS {
            return None;
        }
        let mut folded: Vec<f64> = self
            .angles_rad
            .iter()
            .map(|a| {
                let a = a.abs();
                if a > FRAC_PI_2 {
                    PI - a
                } else {
                    a
                }
            })
            .collect();
        folded.sort_by(f64::total_cmp);
        Some(folded[folded.len() / 2])
    }

    /// The mean direction of the motion relative to the heading, radians.
    pub fn mean_offset_rad(&self) -> f64 {
        let (s, c) = self
            .angles_rad
            .iter()
            .fold((0.0, 0.0), |(s, c), a| (s + a.sin(), c + a.cos()));
        s.atan2(c)
    }

    /// Share of the straight steps driven forwards (within 90° of the heading), 0 to 1.
    pub fn forward_share(&self) -> f64 {
        let n = self.angles_rad.len().max(1);
        self.angles_rad
            .iter()
            .filter(|a| a.abs() < FRAC_PI_2)
            .count() as f64
            / n as f64
    }

    /// Straight steps.
    pub fn steps(&self) -> usize {
        self.angles_rad.len()
    }
}
