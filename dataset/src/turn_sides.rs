//! Catching a log whose wheels turn the robot the other way from the camera. Left and right
//! columns swapped in the log (or a trajectory in a mirrored floor frame, y to the right of x,
//! as some motion-capture exports are) leave the speed, and so the alignment, untouched:
//! every window of a tour was accepted with raw odometry "63 %" off instead of 11 %. After
//! the speed profiles give the clock offset, the turn of each log step is compared with the
//! camera's over the same interval.

use odocal_core::{wrap_angle, Trajectory};

use crate::align::{AlignOptions, CoarseOffset};
use crate::kinematics::WheelGeometry;
use crate::odometry::OdometryLog;
use crate::RobotParams;

/// The camera must see the robot turn this much in all, radians (90°), before the turns'
/// directions are compared: a straight run's few degrees of drift are the odometry's error
/// itself, which may well go the other way.
const MIN_TURNING_RAD: f64 = std::f64::consts::FRAC_PI_2;

/// Correlation of the two turn rates below which the wheels turn the robot the other way.
const OPPOSITE: f64 = -0.5;

/// Why the log's turns cannot be the camera's (they go the other way) with the clocks `coarse`
/// apart, or `None` when they agree, the offset is not sure, or there is too little turning
/// to tell.
pub fn turn_mismatch(
    log: &OdometryLog,
    camera: &Trajectory,
    robot: &RobotParams,
    align: &AlignOptions,
    coarse: &CoarseOffset,
) -> Option<String> {
    let geom = WheelGeometry::nominal(robot);
    let revs = log.wheel_revs(robot);
    if coarse.correlation < align.min_correlation {
        return None;
    }
    let circ_l = std::f64::consts::PI * geom.left_wheel_diameter_m;
    let circ_r = std::f64::consts::PI * geom.right_wheel_diameter_m;
    let (mut cam_abs, mut sxy, mut sxx, mut syy) = (0.0, 0.0, 0.0, 0.0);
    let gap = align.frame_gap_s(camera);
    for k in 1..revs.t_s.len() {
        let at = |i: usize| camera.pose_at(coarse.camera_s(revs.t_s[i]), gap);
        let (Some(a), Some(b)) = (at(k - 1), at(k)) else {
            continue;
        };
        let cam = wrap_angle(b.theta_rad - a.theta_rad);
        let odo = ((revs.rev[k][1] - revs.rev[k - 1][1]) * circ_r
            - (revs.rev[k][0] - revs.rev[k - 1][0]) * circ_l)
            / geom.wheel_base_m;
        cam_abs += cam.abs();
        sxy += cam * odo;
        sxx += cam * cam;
        syy += odo * odo;
    }
    if cam_abs < MIN_TURNING_RAD || sxx <= 0.0 || syy <= 0.0 {
        return None;
    }
    let correlation = sxy / (sxx * syy).sqrt();
    (correlation < OPPOSITE).then(|| {
        format!(
            "the wheels turn the robot the other way from the trajectory (their turn rates correlate at {correlation:.2} over {:.0}° of turning): is the trajectory another run's, driven the other way round (a clockwise square's log paired with a counter-clockwise one's trajectory)? If not, are the log's left and right columns swapped, or is the trajectory's floor frame mirrored (y must point to the left of x)?",
            cam_abs.to_degrees()
        )
    })
}
