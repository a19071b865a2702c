//! Training samples of any motion: windows of a log, each with the camera's pose change over
//! the same window as its target. The straight-run samples of the reference experiment are
//! one layout; this is the other, for robots that drive curves, turns in place and squares.
//!
//! The robot clock is mapped to the camera's by the recording's coarse offset (speed-profile
//! cross-correlation, a few milliseconds on these logs) and its clock rate where one was told
//! apart from 1 (`align::clock_rate`: a robot clock 0.2 % fast drifts 0.2 s over 100 s, and
//! every window's target with it); the window's end poses are the camera poses interpolated
//! at its first and last log rows, and its alignment residual is its wheels' speeds against
//! the camera's over its steps. A window of W rows carries the nominal
//! wheel travel of each of its W steps as inputs, so a corrector can be applied step by step
//! and chained; its target is in the window's start frame.

use odocal_core::wrap_angle;

use crate::align::{wheel_speed_residual_mps, CoarseOffset};
use crate::build::coarse_of;
use crate::build::{BuildOptions, Recording, RunOutcome};
use crate::error::DatasetError;
use crate::kinematics::{RunOdometry, WheelGeometry};
use crate::odometry::STEP_TOLERANCE_PERIODS;
use crate::{RejectedRun, Sample};

/// The feature rule of window datasets, exactly; a model trained on one rule refuses data
/// built with another.
pub const WINDOW_RULE: &str = "odocal.features.windows/1: per window of W consecutive log steps, inputs = the nominal wheel travel of each step, left then right (metres, 2W numbers); target = the camera's pose change over the window in its start frame (x, y metres; theta radians, counter-clockwise), camera poses interpolated at the window's first and last log rows shifted by the recording's clock offset";

/// How windows are cut from a log.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WindowOptions {
    /// Log steps per window.
    pub steps: usize,
    /// Log steps between the starts of consecutive windows.
    pub stride: usize,
    /// Least wheel travel (mean of both wheels' absolute travel) of a kept window, metres.
    pub min_travel_m: f64,
}

impl Default for WindowOptions {
    /// 10 s windows every 5 s on a 200 ms log.
    fn default() -> Self {
        Self {
            steps: 50,
            stride: 25,
            min_travel_m: 0.05,
        }
    }
}

/// The dataset's layout: what one sample is.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum Layout {
    /// One straight run per sample, the 18 inputs of the reference experiment.
    #[default]
    StraightRuns,
    /// Windows of any motion.
    Windows(WindowOptions),
}

/// Cuts one recording into window samples; recordings whose log cannot be aligned with the
/// camera are one rejected entry.
pub fn window_samples(
    rec: &Recording,
    opts: &BuildOptions,
    w: &WindowOptions,
) -> Result<Vec<RunOutcome>, DatasetError> {
    window_samples_at(rec, opts, w, coarse_of(rec, opts), &[])
}

/// [`window_samples`] with the recording's coarse offset already found; a window across a step
/// of `lost` (the log's glitches, see [`crate::glitch`]) is rejected with its reason.
pub(crate) fn window_samples_at(
    rec: &Recording,
    opts: &BuildOptions,
    w: &WindowOptions,
    coarse: Result<CoarseOffset, DatasetError>,
    lost: &[crate::glitch::LostStep],
) -> Result<Vec<RunOutcome>, DatasetError> {
    if w.steps == 0 || w.stride == 0 {
        return Err(DatasetError::Mismatch(
            "--window-steps and --window-stride must be at least 1".into(),
        ));
    }
    let robot = &opts.robot;
    let geom = WheelGeometry::nominal(robot);
    let revs = rec.log.wheel_revs(robot);
    let coarse = match coarse {
        Ok(c) if c.correlation >= opts.align.min_correlation => c,
        Ok(c) => {
            return Ok(vec![RunOutcome::Rejected(RejectedRun {
                run_id: rec.id.to_string(),
                reason: format!(
                    "odometry and camera speed profiles correlate at only {:.2} (< {:.2}): not the same motion",
                    c.correlation, opts.align.min_correlation
                ),
            })])
        }
        Err(e) => {
            return Ok(vec![RunOutcome::Rejected(RejectedRun {
                run_id: rec.id.to_string(),
                reason: e.to_string(),
            })])
        }
    };
    let offset = coarse.offset_s;
    let frame_gap = opts.align.frame_gap_s(rec.camera);
    let circ = [
        std::f64::consts::PI * geom.left_wheel_diameter_m,
        std::f64::consts::PI * geom.right_wheel_diameter_m,
    ];
    let n = revs.t_s.len();
    // A recording shorter than one window gives none: said, not dropped in silence.
    if n <= w.steps {
        return Ok(vec![RunOutcome::Rejected(RejectedRun {
            run_id: rec.id.to_string(),
            reason: format!(
                "its log has {} periods, fewer than one window of {} (--window-s {:.1} s): give a shorter --window-s",
                n.saturating_sub(1),
                w.steps,
                w.steps as f64 * robot.period_s
            ),
        })]);
    }
    let mut out = Vec::new();
    let mut k = 0;
    while k + w.steps < n {
        let rows = k..=k + w.steps;
        k += w.stride;
        if let Some(step) = lost.iter().find(|s| s.touches(*rows.start(), *rows.end())) {
            out.push(RunOutcome::Rejected(RejectedRun {
                run_id: format!("{}.w{:04}", rec.id, rows.start()),
                reason: format!(
                    "{}: the window's travel across it is unknown (the recording's other windows are kept)",
                    step.reason
                ),
            }));
            continue;
        }
        let t = &revs.t_s[rows.clone()];
        let rev: Vec<[f64; 2]> = revs.rev[rows.clone()]
            .iter()
            .map(|r| {
                [
                    r[0] - revs.rev[*rows.start()][0],
                    r[1] - revs.rev[*rows.start()][1],
                ]
            })
            .collect();
        let inputs: Vec<f64> = rev
            .windows(2)
            .flat_map(|p| [(p[1][0] - p[0][0]) * circ[0], (p[1][1] - p[0][1]) * circ[1]])
            .collect();
        let travel: f64 = inputs.iter().map(|d| 0.5 * d.abs()).sum();
        if travel < w.min_travel_m {
            continue;
        }
        if let Some((k, dt)) = rec.log.off_period_step(
            *rows.start(),
            *rows.end(),
            robot.period_s,
            STEP_TOLERANCE_PERIODS,
        ) {
            out.push(RunOutcome::Rejected(RejectedRun {
                run_id: format!("{}.w{:04}", rec.id, rows.start()),
                reason: format!(
                    "{}: a window's inputs take each step for one period, so this one would read {dt:.3} s of travel as {:.3} s",
                    rec.log.step_message(k, dt, robot.period_s),
                    robot.period_s
                ),
            }));
            continue;
        }
        let (t0, t1) = (coarse.camera_s(t[0]), coarse.camera_s(t[t.len() - 1]));
        let gap = frame_gap;
        let id = format!("{}.w{:04}", rec.id, rows.start());
        let (Some(p0), Some(p1), true) = (
            rec.camera.pose_at(t0, gap),
            rec.camera.pose_at(t1, gap),
            rec.camera.covers(t0, t1, gap),
        ) else {
            out.push(RunOutcome::Rejected(RejectedRun {
                run_id: id,
                reason: format!(
                    "the camera does not see the robot throughout {t0:.2}-{t1:.2} s (camera clock)"
                ),
            }));
            continue;
        };
        let residual =
            wheel_speed_residual_mps(rec.camera, &coarse, t, &rev, &geom, gap).unwrap_or(f64::NAN);
        // A window whose wheels do not follow the camera is off the recording's clock there.
        if residual.is_nan() || residual > opts.max_alignment_residual_mps {
            out.push(RunOutcome::Rejected(RejectedRun {
                run_id: id,
                reason: format!(
                    "odometry and camera disagree over this window: its wheels' speeds differ from the camera's by {residual:.3} m/s RMS on the recording's clock (limit {:.3} m/s; aligned windows give about 0.025): the clock is off here, or the log is not this run's",
                    opts.max_alignment_residual_mps
                ),
            }));
            continue;
        }
        let rel = p1.relative_to(&p0);
        let odometry = RunOdometry {
            t_s: t.to_vec(),
            rev,
        };
        let raw = odometry.poses(&geom);
        let raw_end = raw.last().copied().unwrap_or_default();
        out.push(RunOutcome::Sample(Box::new(Sample {
            run_id: id,
            recording_id: rec.id.to_string(),
            speed_mps: travel / (t[t.len() - 1] - t[0]),
            inputs,
            target_m: [rel.x_m, rel.y_m],
            target_theta_rad: wrap_angle(rel.theta_rad),
            raw_end_m: [raw_end.x_m, raw_end.y_m],
            path_length_m: travel,
            clock_offset_s: offset,
            alignment_residual_mps: residual,
            clock_rate: (coarse.rate != 1.0).then_some(coarse.rate),
            speed_correlation: coarse.correlation,
            start_pose_floor: p0,
            odometry,
            ..Sample::default()
        })));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kinematics::step;
    use crate::OdometryLog;
    use odocal_core::{Pose2, Trajectory, TrajectoryRow};

    /// A 66 s tour of straight legs and turns in place (varied, so no stretch repeats
    /// another), logged every 0.2 s by a robot clock `1 / rate` times the true seconds, seen
    /// by a 30 frames/s camera whose clock is the true one plus 0.8 s. Returns the log, the
    /// camera trajectory and the true pose every millisecond.
    fn tour(clock_fast: f64) -> (OdometryLog, Trajectory, Vec<Pose2>) {
        let (dt, end_s, base) = (0.001, 66.0, 0.1);
        // Wheel speeds (m/s): each 6 s leg drives, stops and turns, ramped over 0.4 s.
        let speeds = |t: f64| -> [f64; 2] {
            let (leg, u) = ((t / 6.0).floor(), t % 6.0);
            if !(1.0..end_s - 2.0).contains(&t) {
                return [0.0; 2];
            }
            let ramp =
                |a: f64, b: f64| ((u - a) / 0.4).clamp(0.0, 1.0) * ((b - u) / 0.4).clamp(0.0, 1.0);
            let v = (0.2 + 0.05 * (leg % 3.0)) * ramp(0.0, 3.0 + 0.3 * (leg % 2.0));
            let w = (0.1 + 0.03 * (leg % 4.0))
                * ramp(3.8, 5.6)
                * if leg % 2.0 == 0.0 { 1.0 } else { -1.0 };
            [v - w, v + w]
        };
        let (mut pose, mut travel) = (Pose2::new(0.3, -0.2, 0.4), [0.0; 2]);
        let (mut poses, mut travels) = (vec![pose], vec![travel]);
        for i in 0..(end_s / dt) as usize {
            let v = speeds((i as f64 + 0.5) * dt);
            pose = step(&pose, v[0] * dt, v[1] * dt, base);
            travel = [travel[0] + v[0] * dt, travel[1] + v[1] * dt];
            poses.push(pose);
            travels.push(travel);
        }
        let circ = std::f64::consts::PI * 0.043;
        let rows: Vec<usize> = (0..)
            .map(|k| (0.2 * k as f64 / clock_fast / dt).round() as usize)
            .take_while(|&i| i < poses.len())
            .collect();
        let ticks = |w: usize| -> Vec<i64> {
            rows.iter()
                .map(|&i| (travels[i][w] / circ * 12.0 + 0.4).floor() as i64)
                .collect()
        };
        let t: Vec<f64> = (0..rows.len()).map(|k| 0.2 * k as f64).collect();
        let log = OdometryLog::from_ticks(t, ticks(0), ticks(1)).unwrap();
        let camera = (0..)
            .map(|f| f as f64 / 30.0)
            .take_while(|&tc| tc < end_s + 0.8)
            .map(|tc| TrajectoryRow {
                t_s: tc,
                pose: poses[(((tc - 0.8).max(0.0)) / dt).round() as usize],
                quality: 1.0,
                sigma: None,
            })
            .collect();
        (log, Trajectory::new(camera).unwrap(), poses)
    }

    /// A robot clock 1 % fast drifted every window 10 ms per second of the recording off the
    /// camera (the targets 60 mm off by its end), with exit 0 and alignment residuals of 0.
    #[test]
    fn a_robot_clock_at_another_rate_is_fitted_and_applied() {
        for clock_fast in [1.0, 1.01] {
            let (log, camera, poses) = tour(clock_fast);
            let rec = Recording {
                id: "tour",
                speed_mps: None,
                log: &log,
                camera: &camera,
            };
            let opts = BuildOptions::default();
            let out = window_samples(&rec, &opts, &WindowOptions::default()).unwrap();
            let samples: Vec<&Sample> = out
                .iter()
                .map(|o| match o {
                    RunOutcome::Sample(s) => &**s,
                    RunOutcome::Rejected(r) => panic!("rejected: {r:?}"),
                })
                .collect();
            assert!(samples.len() >= 10, "{} windows", samples.len());
            let rate = samples[0].clock_rate;
            if clock_fast == 1.0 {
                assert_eq!(rate, None, "a true clock is told no rate");
            } else {
                let rate = rate.expect("the rate is told");
                assert!((rate * clock_fast - 1.0).abs() < 2e-4, "rate {rate}");
            }
            let (mut worst, mut sq) = (0.0f64, 0.0);
            for s in &samples {
                let k: usize = s.run_id[s.run_id.len() - 4..].parse().unwrap();
                let at = |k: usize| poses[(0.2 * k as f64 / clock_fast / 0.001).round() as usize];
                let truth = at(k + 50).relative_to(&at(k));
                let e = (s.target_m[0] - truth.x_m).hypot(s.target_m[1] - truth.y_m);
                worst = worst.max(e);
                sq += e * e;
                assert!(
                    s.alignment_residual_mps > 0.0 && s.alignment_residual_mps < 0.05,
                    "{}: residual {}",
                    s.run_id,
                    s.alignment_residual_mps
                );
            }
            let rms = (sq / samples.len() as f64).sqrt();
            eprintln!("clock {clock_fast}: targets off by {rms} m RMS, {worst} m at most");
            assert!(
                rms < 0.004 && worst < 0.012,
                "clock {clock_fast}: targets off by {rms} m RMS, {worst} m at most"
            );
        }
    }
}
