//! Catching a heading that does not point where the robot drives. A differential-drive robot
//! moves along its heading whenever it drives straight, so on straight stretches the camera's
//! direction of motion and its heading agree, forwards or backwards. They do not when the tag
//! is mounted turned (its x axis must point to the robot's front), when a motion-capture body
//! was defined with another forward axis, or when a trajectory's theta is in degrees. Left
//! alone, every target is then turned by that angle: a tag turned 180° gives a dataset whose
//! raw odometry is "200 % off", with every run accepted; turned 90°, alignment finds "no
//! motion" and blames the pairing of files.

use std::f64::consts::PI;

use odocal_core::{MotionAgainstHeading, Trajectory};

use crate::odometry::OdometryLog;
use crate::RobotParams;

/// Median misfit under which a reading of the heading is taken as the one meant, radians
/// (10°).
const FITS_RAD: f64 = 0.17;

/// The wheels must travel this far before their direction is judged, metres.
const MIN_TRAVEL_M: f64 = 0.1;

/// Share of the wheels' travel that is forwards (both wheels' mean turning positive), or
/// `None` when they barely turn.
fn wheels_forward_share(log: &OdometryLog, robot: &RobotParams) -> Option<f64> {
    let revs = log.wheel_revs(robot);
    let (mut fwd, mut all) = (0.0, 0.0);
    for w in revs.rev.windows(2) {
        let step = 0.5 * ((w[1][0] - w[0][0]) + (w[1][1] - w[0][1]));
        fwd += step.max(0.0);
        all += step.abs();
    }
    let travel_m = all * PI * robot.wheel_diameter_m;
    (travel_m >= MIN_TRAVEL_M).then(|| fwd / all)
}

/// Why the camera trajectory's heading cannot be the robot's, or `None` when it follows the
/// direction of motion (or there is too little straight driving to tell).
pub fn heading_mismatch(
    log: &OdometryLog,
    camera: &Trajectory,
    robot: &RobotParams,
) -> Option<String> {
    let radians = MotionAgainstHeading::of(camera, 1.0);
    let misfit = radians.line_misfit_rad();
    // Read as degrees, a heading near 0 fits any motion near 0 whatever the unit, so only
    // values beyond a turn (which radians reach only unwrapped) make degrees certain, and
    // only when radians fit worse than degrees would.
    let degrees = MotionAgainstHeading::of(camera, PI / 180.0);
    let fits_in_degrees = degrees.line_misfit_rad().is_some_and(|m| m <= FITS_RAD);
    let beyond_a_turn = camera
        .rows
        .iter()
        .any(|r| r.pose.theta_rad.abs() > 2.0 * PI);
    let fits_in_radians = misfit.is_some_and(|m| m <= FITS_RAD);
    // Degrees' frame-to-frame noise, read as radians, turns most steps by more than 2°; a short
    // run lacks straight steps for want of travel, its steps being as straight either way.
    let turning_in_radians = misfit.is_none() && 2 * radians.steps() < degrees.steps();
    if fits_in_degrees && !fits_in_radians && (beyond_a_turn || turning_in_radians) {
        return Some(format!(
            "theta is in degrees: read as degrees the heading follows the direction of motion over {} straight steps, read as radians it does not; write theta in radians",
            degrees.steps()
        ));
    }
    let misfit = misfit?;
    if misfit > MotionAgainstHeading::MAX_LINE_MISFIT_RAD {
        return Some(format!(
            "the heading is {:.0}° off the direction the robot moves in (median over {} straight steps; the robot moves at {:.0}° to its heading on average), where a wheeled robot moves along its heading: is the tag (or laser scanner) mounted turned (its x axis must point to the robot's front), or the trajectory's forward axis another one{}?",
            misfit.to_degrees(),
            radians.steps(),
            radians.mean_offset_rad().to_degrees(),
            if fits_in_degrees {
                ", or theta in degrees (read as degrees it follows the motion)"
            } else {
                ""
            }
        ));
    }
    // Along the line of motion; but which way?
    let wheels = wheels_forward_share(log, robot)?;
    let camera_fwd = radians.forward_share();
    let one_way = MotionAgainstHeading::ONE_WAY;
    let opposite = (wheels >= one_way && camera_fwd <= 1.0 - one_way)
        || (wheels <= 1.0 - one_way && camera_fwd >= one_way);
    opposite.then(|| {
        format!(
            "the wheels drive the robot {} ({:.0} % of their travel) but the trajectory has it move {} ({:.0} % of {} straight steps), so its heading points to the robot's back: is the tag (or laser scanner) mounted turned 180° (its x axis must point to the robot's front), or do the wheel counts fall when the robot drives forwards?",
            if wheels >= 0.5 { "forwards" } else { "backwards" },
            100.0 * wheels.max(1.0 - wheels),
            if camera_fwd >= 0.5 { "forwards" } else { "backwards" },
            100.0 * camera_fwd.max(1.0 - camera_fwd),
            radians.steps()
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use odocal_core::{Pose2, TrajectoryRow};
    use std::f64::consts::FRAC_PI_2;

    /// 60 rows of a drive at 0.2 m/s along `dir_deg` (backwards when `speed` < 0) with 0.2
    /// mrad of heading noise, and its tick log.
    fn drive_along(
        dir_deg: f64,
        speed: f64,
        theta_of: impl Fn(f64) -> f64,
    ) -> (OdometryLog, Trajectory) {
        let robot = RobotParams::default();
        let dir = dir_deg.to_radians();
        let per_tick_m = PI * robot.wheel_diameter_m / robot.ticks_per_rev;
        let t: Vec<f64> = (0..60).map(|i| 0.1 * i as f64).collect();
        let rows = t
            .iter()
            .enumerate()
            .map(|(i, &t_s)| TrajectoryRow {
                t_s,
                pose: Pose2::new(
                    speed * t_s * dir.cos(),
                    speed * t_s * dir.sin(),
                    theta_of(dir + 2e-4 * ((i * 7919) % 11) as f64 / 11.0),
                ),
                quality: 1.0,
                sigma: None,
            })
            .collect();
        let ticks: Vec<i64> = t
            .iter()
            .map(|&t_s| (speed * t_s / per_tick_m).round() as i64)
            .collect();
        let log = OdometryLog::from_ticks(t, ticks.clone(), ticks).expect("log");
        (log, Trajectory::new(rows).expect("trajectory"))
    }

    fn verdict(speed: f64, theta_of: impl Fn(f64) -> f64) -> Option<String> {
        verdict_along(30.0, speed, theta_of)
    }

    fn verdict_along(dir_deg: f64, speed: f64, theta_of: impl Fn(f64) -> f64) -> Option<String> {
        let (log, traj) = drive_along(dir_deg, speed, theta_of);
        heading_mismatch(&log, &traj, &RobotParams::default())
    }

    #[test]
    fn a_heading_along_the_motion_passes_forwards_and_backwards() {
        assert_eq!(verdict(0.2, |t| t), None);
        assert_eq!(verdict(-0.2, |t| t), None);
        // A tag a little off the axle on an arc: 15° off is still the robot's heading.
        assert_eq!(verdict(0.2, |t| t + 0.26), None);
    }

    #[test]
    fn a_turned_tag_and_degrees_are_named() {
        let back = verdict(0.2, |t| t + PI).expect("turned 180°");
        assert!(back.contains("mounted turned 180°"), "{back}");
        assert!(back.contains("forwards (100 % of their travel)"), "{back}");
        let back = verdict(-0.2, |t| t + PI).expect("driving backwards, turned 180°");
        assert!(back.contains("drive the robot backwards"), "{back}");
        let side = verdict(0.2, |t| t + FRAC_PI_2).expect("turned 90°");
        assert!(side.contains("heading is 90° off"), "{side}");
        assert!(side.contains("at -90° to its heading"), "{side}");
        let deg = verdict(0.2, f64::to_degrees).expect("degrees");
        assert!(deg.contains("theta is in degrees"), "{deg}");
        // Driving along 2°: a tag turned 90° reads as a heading near 0 in degrees, and so
        // does a heading of 2 degrees; both are named, neither is called certain.
        for theta_of in [|t: f64| t + FRAC_PI_2, f64::to_degrees] {
            let near_zero = verdict_along(2.0, 0.2, theta_of).expect("near 0");
            assert!(
                near_zero.contains("off the direction the robot moves in")
                    && near_zero.contains("or theta in degrees"),
                "{near_zero}"
            );
        }
    }

    /// A trajectory of rows 0.1 s apart at `(x, y, theta)`, and a tick log driving along it.
    fn rows_of(poses: &[(f64, f64, f64)]) -> (OdometryLog, Trajectory) {
        let t: Vec<f64> = (0..poses.len()).map(|i| 0.1 * i as f64).collect();
        let rows = poses
            .iter()
            .zip(&t)
            .map(|(&(x, y, theta), &t_s)| TrajectoryRow {
                t_s,
                pose: Pose2::new(x, y, theta),
                quality: 1.0,
                sigma: None,
            })
            .collect();
        let ticks: Vec<i64> = (0..poses.len() as i64).collect();
        let log = OdometryLog::from_ticks(t, ticks.clone(), ticks).expect("log");
        (log, Trajectory::new(rows).expect("trajectory"))
    }

    #[test]
    fn a_short_run_is_not_taken_for_degrees() {
        let robot = RobotParams::default();
        // 12 cm in 10 steps along 0°, the first turning 3° (a synthetic 0.15 m run): 9
        // straight steps read as radians, 10 as degrees. It was "theta is in degrees".
        let short: Vec<_> = (0..11)
            .map(|i| (0.012 * i as f64, 0.0, if i == 0 { -0.05 } else { 0.0 }))
            .collect();
        let (log, traj) = rows_of(&short);
        assert_eq!(heading_mismatch(&log, &traj, &robot), None);
        // Degrees with half a degree of noise, along 2°: read as radians, every step turns.
        let noisy: Vec<_> = (0..30)
            .map(|i| {
                let d = 0.012 * i as f64;
                let noise_deg = if i % 2 == 0 { 0.5 } else { -0.5 };
                (
                    d * 2f64.to_radians().cos(),
                    d * 2f64.to_radians().sin(),
                    2.0 + noise_deg,
                )
            })
            .collect();
        let (log, traj) = rows_of(&noisy);
        let deg = heading_mismatch(&log, &traj, &robot).expect("degrees");
        assert!(deg.contains("theta is in degrees"), "{deg}");
    }

    #[test]
    fn too_little_driving_is_not_judged() {
        // Turning in place: the tag, off the axle or not, gives no straight steps.
        let robot = RobotParams::default();
        let rows = (0..60)
            .map(|i| TrajectoryRow {
                t_s: 0.1 * i as f64,
                pose: Pose2::new(
                    0.1 * (0.1 * i as f64).cos(),
                    0.1 * (0.1 * i as f64).sin(),
                    0.1 * i as f64,
                ),
                quality: 1.0,
                sigma: None,
            })
            .collect();
        let t: Vec<f64> = (0..60).map(|i| 0.1 * i as f64).collect();
        let left: Vec<i64> = (0..60).map(|i| -3 * i).collect();
        let right: Vec<i64> = (0..60).map(|i| 3 * i).collect();
        let log = OdometryLog::from_ticks(t, left, right).expect("log");
        let traj = Trajectory::new(rows).expect("trajectory");
        assert_eq!(heading_mismatch(&log, &traj, &robot), None);
    }
}
