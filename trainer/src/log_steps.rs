//! The check every log a model is applied to passes first (`correct`, `evaluate`): the
//! robot's period, steps on it, and steps a wheel can take.

use odocal_dataset::odometry::STEP_TOLERANCE_PERIODS;
use odocal_dataset::{OdometryLog, RobotParams};

use crate::error::TrainError;

/// Refuses a log with a step off the robot's period by more than `dataset` lets a training
/// step be (`name` names the log): a model takes every step for one period (a path model
/// each step, a straight-run model the run's per-step speeds), so a gap (two rows lost)
/// would read as one step three times as fast and be judged, corrected and scored as such;
/// a logger's jitter is taken as `dataset` takes it. A log off the
/// period throughout is named as such first; a step no wheel can take is refused too.
pub(crate) fn check_log_steps(
    log: &OdometryLog,
    robot: &RobotParams,
    name: &str,
) -> Result<(), TrainError> {
    // A log whose every step is off (times in milliseconds, another logger) is that, not a
    // dropped row at its first step.
    if let Some(why) = log.period_mismatch(robot.period_s) {
        return Err(TrainError::Model(format!(
            "{name}: {why}; is this log of the model's robot and logger?"
        )));
    }
    if let Some((k, dt)) = log.off_period_step(0, log.len(), robot.period_s, STEP_TOLERANCE_PERIODS)
    {
        return Err(TrainError::Model(format!(
            "{name}: {}; record the run again, or leave it out",
            OdometryLog::step_message(k, dt, robot.period_s)
        )));
    }
    // A step no wheel can take (a glitch, a counter reset to 0) would be corrected, or
    // refused as outside the training's speeds, as motion; `dataset` rejects it by the same
    // check.
    match log.implausible_step(robot) {
        Some(why) => Err(TrainError::Model(format!(
            "{name}: {why}; mend or leave out the log"
        ))),
        None => Ok(()),
    }
}
