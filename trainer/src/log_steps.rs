//! The check every log a model is applied to passes first (`correct`, `evaluate`): the
//! robot's period, steps on it, and steps a wheel can take.

use odocal_dataset::odometry::STEP_TOLERANCE_PERIODS;
use odocal_dataset::{OdometryLog, RobotParams};

use crate::error::TrainError;

/// What is wrong with a log's steps, with what to do, or `None`: a step off the robot's
/// period by more than `dataset` lets a training step be. A model takes every step for one
/// period (a path model each step, a straight-run model the run's per-step speeds), so a gap
/// (two rows lost) while the wheels turn would read as one step three times as fast and be
/// judged, corrected and scored as such; a gap the wheels stand still across, and a logger's
/// jitter, are taken as `dataset` takes them ([`OdometryLog::off_period_step`]). A log off
/// the period throughout is named as such first; a step no wheel can take is refused too.
/// The fault is the log's, not the model's: callers name the log.
pub fn log_step_problem(log: &OdometryLog, robot: &RobotParams) -> Option<String> {
    // A log whose every step is off (times in milliseconds, another logger) is that, not a
    // dropped row at its first step.
    if let Some(why) = log.period_mismatch(robot.period_s) {
        return Some(format!(
            "{why}; is this log of the model's robot and logger?"
        ));
    }
    if let Some((k, dt)) = log.off_period_step(0, log.len(), robot.period_s, STEP_TOLERANCE_PERIODS)
    {
        return Some(format!(
            "{}; record the run again, or leave it out",
            log.step_message(k, dt, robot.period_s)
        ));
    }
    // A step no wheel can take (a glitch, a counter reset to 0) would be corrected, or
    // refused as outside the training's speeds, as motion; `dataset` rejects it by the same
    // check.
    log.implausible_step(robot)
        .map(|why| format!("{why}; mend or leave out the log"))
}

/// [`log_step_problem`] as an error naming the log (`name`).
pub(crate) fn check_log_steps(
    log: &OdometryLog,
    robot: &RobotParams,
    name: &str,
) -> Result<(), TrainError> {
    match log_step_problem(log, robot) {
        Some(why) => Err(TrainError::Dataset(format!("{name}: {why}"))),
        None => Ok(()),
    }
}
