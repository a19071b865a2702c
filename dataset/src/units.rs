//! Catching a trajectory or a robot file in another unit before alignment: motion capture
//! often exports millimetres (and times in milliseconds), and a wheel diameter in millimetres makes every odometry
//! distance a thousand times too long. Alignment would only reject every run with a speed
//! mismatch; comparing the extents of the two paths names the likely cause.

use odocal_core::Trajectory;

use crate::align::{AlignOptions, CoarseOffset};
use crate::build::RunOutcome;
use crate::build::DEFAULT_MIN_GAP_S;
use crate::kinematics::{dead_reckon, WheelGeometry};
use crate::odometry::{LogKind, OdometryLog};
use crate::sample::TravelScale;
use crate::segment::split_runs;
use crate::{Dataset, RejectedRun, RobotParams, Sample};

/// The largest ratio between the camera path's extent and the odometry's that can still be
/// the same motion (odometry drifts by percent, not by factors).
const MAX_EXTENT_RATIO: f64 = 5.0;

/// Feet in a metre: a trajectory exported in feet reads this many times the odometry.
const FOOT_PER_M: f64 = 1.0 / 0.3048;

/// Inches in a metre.
const INCH_PER_M: f64 = 1.0 / 0.0254;

/// Extents below this (metres) are too small to compare (a robot at rest, tracking noise).
const MIN_EXTENT_M: f64 = 0.05;

/// The diagonal of the box holding the points between the 2nd and 98th percentile in x and
/// y (a few false detections do not stretch it), metres.
fn extent_m(points: impl Iterator<Item = [f64; 2]>) -> f64 {
    let (mut xs, mut ys): (Vec<f64>, Vec<f64>) = points.map(|p| (p[0], p[1])).unzip();
    if xs.len() < 2 {
        return 0.0;
    }
    let span = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        let at = |q: f64| v[((v.len() - 1) as f64 * q).round() as usize];
        at(0.98) - at(0.02)
    };
    span(&mut xs).hypot(span(&mut ys))
}

/// Why the camera trajectory and the odometry log cannot be in the same unit, when the
/// camera's extent is more than [`MAX_EXTENT_RATIO`] times the odometry's or less than its
/// 1/[`MAX_EXTENT_RATIO`]; `None` when they fit or either barely moves.
///
/// The log cannot see what happens to the robot at rest: carried back to the start between
/// runs, it dead-reckons a path that grows with every run, while the camera sees the same
/// 1.5 m again and again. The odometry's true extent therefore lies between that of its
/// largest motion segment (split at rests, as runs are) and that of the whole log as one
/// path; only a camera path beyond that range, widened by the ratio, is refused.
pub fn unit_mismatch(
    log: &OdometryLog,
    camera: &Trajectory,
    robot: &RobotParams,
) -> Option<String> {
    extent_mismatch(log, camera, robot).map(|(_, why)| why)
}

/// [`unit_mismatch`] only where the ratio is a unit's (millimetres or centimetres against
/// metres): checked before anything else reads the trajectory, whose other checks would
/// blame the motion (a robot "moving" 738 mm at rest that is 0.7 mm of tracking noise).
pub fn length_unit_mismatch(
    log: &OdometryLog,
    camera: &Trajectory,
    robot: &RobotParams,
) -> Option<String> {
    extent_mismatch(log, camera, robot).and_then(|(unit, why)| unit.then_some(why))
}

/// [`unit_mismatch`]'s message, and whether the ratio is a unit's.
fn extent_mismatch(
    log: &OdometryLog,
    camera: &Trajectory,
    robot: &RobotParams,
) -> Option<(bool, String)> {
    let revs = log.wheel_revs(robot);
    let geom = WheelGeometry::nominal(robot);
    let odometry = dead_reckon(&revs.rev, &geom);
    let whole_m = extent_m(odometry.iter().map(|p| [p.x_m, p.y_m]));
    let run_m = split_runs(log, DEFAULT_MIN_GAP_S)
        .iter()
        .map(|seg| {
            let path = dead_reckon(&seg.odometry(&revs).rev, &geom);
            extent_m(path.iter().map(|p| [p.x_m, p.y_m]))
        })
        .fold(0.0f64, f64::max);
    // No motion detected (a log of counts per period may look at rest): the whole log is
    // the one segment.
    let run_m = if run_m > 0.0 {
        run_m.min(whole_m)
    } else {
        whole_m
    };
    let cam_m = extent_m(camera.rows.iter().map(|r| [r.pose.x_m, r.pose.y_m]));
    if whole_m < MIN_EXTENT_M || cam_m < MIN_EXTENT_M {
        return None;
    }
    // Too large a camera path is judged against the whole log (its largest possible
    // extent), too small a one against the largest segment (its smallest).
    // The true ratio lies between the camera's extent over the whole log's and over its
    // longest run's; a unit's factor is named when it lies within half again of that range
    // (the nearest when two do): dead-reckoned tours and squares drift by tens of percent
    // (their paths in millimetres read 1246 and 1427 times).
    let (lo, hi) = (cam_m / whole_m, cam_m / run_m.max(f64::MIN_POSITIVE));
    let off_range = |k: f64| {
        let (l, h, k) = (lo.ln(), hi.max(lo).ln(), k.ln());
        (l - k).max(k - h).max(0.0)
    };
    // Feet are within the ratio that drift alone may give, so they are named only where the
    // range lies within 15 % of them (straight runs in feet read 3.38); else the robot
    // file's scale check names them, on the wheels' travel.
    let in_feet = off_range(FOOT_PER_M) < 1.15f64.ln();
    let (odo_m, of) = if cam_m > MAX_EXTENT_RATIO * whole_m || in_feet {
        (whole_m, "")
    } else if cam_m * MAX_EXTENT_RATIO < run_m {
        (run_m, " (its longest run between rests)")
    } else {
        return None;
    };
    let ratio = cam_m / odo_m;
    let off = |k: f64| (off_range(k), (k.ln() - ratio.ln()).abs());
    let unit_k = [1000.0, 100.0, INCH_PER_M, FOOT_PER_M, 0.001]
        .into_iter()
        .filter(|&k| off(k).0 < if k == FOOT_PER_M { 1.15f64 } else { 1.5 }.ln())
        .min_by(|&a, &b| {
            off(a)
                .partial_cmp(&off(b))
                .unwrap_or(std::cmp::Ordering::Equal)
        });
    let (unit, hint) = if unit_k == Some(1000.0) {
        (
            true,
            "1000 times: is the trajectory in millimetres? it must be in metres",
        )
    } else if unit_k == Some(100.0) {
        (
            true,
            "100 times: is the trajectory in centimetres? it must be in metres",
        )
    } else if unit_k == Some(INCH_PER_M) {
        (
            true,
            "39.37 times: is the trajectory in inches? it must be in metres (multiply inches by 0.0254)",
        )
    } else if unit_k == Some(FOOT_PER_M) {
        (
            true,
            "3.281 times: is the trajectory in feet? it must be in metres (multiply feet by 0.3048)",
        )
    } else if unit_k == Some(0.001) {
        (
            true,
            "1/1000: is the robot's wheel_diameter_m in millimetres? it must be in metres",
        )
    } else if let Some(side) = negated_wheel(&revs.rev, &geom, cam_m) {
        (false, side)
    } else if log.kind == LogKind::Ticks && ratio > 1.0 {
        (false, "are the ticks cumulative counts (not counts per period), the log paired with the right trajectory, and the robot's parameters its own?")
    } else {
        (
            false,
            "is the log paired with the right trajectory, and are the robot's parameters its own?",
        )
    };
    Some((
        unit,
        format!(
            "the camera's path spans {cam_m:.3} m and the odometry's{of} {odo_m:.3} m, a ratio of {ratio:.3}; {hint}"
        ),
    ))
}

/// What to check when one wheel's travel negated makes the odometry's path span the camera's
/// (within a quarter): an encoder counting down as the robot drives forward turns a tour into
/// a spin in place, whose small extent read as counts per period or a mispaired log. Either
/// wheel negated gives that span (the one path driven backwards), so neither is named.
fn negated_wheel(rev: &[[f64; 2]], geom: &WheelGeometry, cam_m: f64) -> Option<&'static str> {
    let flipped: Vec<[f64; 2]> = rev.iter().map(|r| [r[0], -r[1]]).collect();
    let path = dead_reckon(&flipped, geom);
    let m = extent_m(path.iter().map(|p| [p.x_m, p.y_m]));
    ((m / cam_m - 1.0).abs() < 0.25).then_some(
        "with one wheel's counts negated the odometry's path spans the camera's: is one encoder counting down as the robot drives forward? both must count up driving forward; negate that wheel's column",
    )
}

/// The longest median interval between a camera trajectory's rows that can be in seconds,
/// seconds: cameras and motion capture give several rows a second.
const MAX_ROW_INTERVAL_S: f64 = 2.0;

/// Why the camera trajectory's times cannot be seconds: rows a median of more than
/// [`MAX_ROW_INTERVAL_S`] apart (milliseconds give 33 for a 30 frames/s camera), with the
/// likely unit from how its span compares with the log's.
pub fn time_unit_mismatch(log: &OdometryLog, camera: &Trajectory) -> Option<String> {
    let median = camera.median_spacing_s()?;
    if median <= MAX_ROW_INTERVAL_S {
        return None;
    }
    let span = camera.end_s() - camera.start_s();
    let log_span = match (log.t_s.first(), log.t_s.last()) {
        (Some(a), Some(b)) if b > a => b - a,
        _ => f64::NAN,
    };
    let ratio = span / log_span;
    let unit = if (ratio / 1000.0 - 1.0).abs() < 0.5 {
        format!("; it spans {span:.0} against the log's {log_span:.1} s: are its times in milliseconds?")
    } else {
        "; are its times in another unit?".to_string()
    };
    Some(format!(
        "the trajectory's rows are {median:.1} apart (median), where a camera gives several a second{unit} Times must be in seconds"
    ))
}

/// The largest factor between the odometry's distances and the camera's that a robot file
/// of this robot can give: uncalibrated wheels are percents off, not half again.
const MAX_ODOMETRY_SCALE: f64 = 1.5;

/// Odometry this far off the camera is named in a warning (20 %).
const WARN_ODOMETRY_SCALE: f64 = 1.2;

/// Samples whose real end point moved less than this are not compared, metres.
const MIN_TARGET_M: f64 = 0.1;

/// Samples whose wheels' revolutions drift further apart than this share of their travel
/// turned ([`crate::RunOdometry::turn_share`]) are not compared: a straight run's stay within
/// 0.8 % (the demo's 131), a window of a tour with a turn goes past 8 %. A turn bends the
/// odometry's path by its own heading error, so its end lies nearer or farther than the
/// camera's by that, not by the robot file.
const MAX_TURN_SHARE: f64 = 0.02;

/// |raw odometry end point| / |real end point| of a sample; `None` when the real end point
/// moved less than [`MIN_TARGET_M`], or the run turned ([`MAX_TURN_SHARE`]).
fn end_ratio(s: &Sample) -> Option<f64> {
    let real = s.target_m[0].hypot(s.target_m[1]);
    let turned = s.odometry.turn_share().is_some_and(|t| t > MAX_TURN_SHARE);
    (real >= MIN_TARGET_M && !turned).then(|| s.raw_end_m[0].hypot(s.raw_end_m[1]) / real)
}

/// The upper median of `v`; `None` when empty.
fn upper_median(mut v: Vec<f64>) -> Option<f64> {
    v.sort_by(f64::total_cmp);
    v.get(v.len() / 2).copied()
}

/// The odometry's distances against the camera's over a dataset's samples: the median of
/// |raw odometry end point| / |real end point| and the samples behind it; `None` when no
/// sample moved 10 cm.
pub fn odometry_scale(samples: &[Sample]) -> Option<(f64, usize)> {
    let ratios: Vec<f64> = samples.iter().filter_map(end_ratio).collect();
    let n = ratios.len();
    upper_median(ratios).map(|m| (m, n))
}

/// The camera's travel below which a recording's wheel travel is not compared with it,
/// metres: a robot standing still, or a camera that saw little.
const MIN_CAMERA_TRAVEL_M: f64 = 0.5;

/// A recording's wheel travel against the camera's: the wheels' mean travel and the camera's
/// along the robot's heading, both summed unsigned over every log step in which the wheels
/// turned and the camera saw the robot, with the clocks `coarse` apart; `None` when the
/// offset is not sure or the camera saw less than [`MIN_CAMERA_TRAVEL_M`]. A turn in place
/// adds to neither, so tours compare as straight runs do.
pub fn travel_against_camera(
    log: &OdometryLog,
    camera: &Trajectory,
    robot: &RobotParams,
    align: &AlignOptions,
    coarse: &CoarseOffset,
) -> Option<[f64; 2]> {
    if coarse.correlation < align.min_correlation {
        return None;
    }
    let geom = WheelGeometry::nominal(robot);
    let revs = log.wheel_revs(robot);
    let circ = [
        std::f64::consts::PI * geom.left_wheel_diameter_m,
        std::f64::consts::PI * geom.right_wheel_diameter_m,
    ];
    let gap = align.frame_gap_s(camera);
    let (mut odo, mut cam) = (0.0, 0.0);
    for k in 1..revs.t_s.len() {
        let d = |w: usize| (revs.rev[k][w] - revs.rev[k - 1][w]) * circ[w];
        if d(0) == 0.0 && d(1) == 0.0 {
            continue;
        }
        let at = |i: usize| camera.pose_at(coarse.camera_s(revs.t_s[i]), gap);
        let (Some(a), Some(b)) = (at(k - 1), at(k)) else {
            continue;
        };
        odo += (0.5 * (d(0) + d(1))).abs();
        cam += crate::align::forward_step(&a, &b).abs();
    }
    (cam >= MIN_CAMERA_TRAVEL_M).then_some([odo, cam])
}

/// The wheels' travel against the camera's over recordings, from their
/// [`travel_against_camera`] sums.
pub fn travel_scale(sums: &[[f64; 2]]) -> Option<TravelScale> {
    let (odo, cam) = sums
        .iter()
        .fold((0.0, 0.0), |(o, c), s| (o + s[0], c + s[1]));
    (!sums.is_empty() && cam > 0.0).then(|| TravelScale {
        ratio: odo / cam,
        camera_m: cam,
        recordings: sums.len(),
    })
}

/// The factor, either way, by which a run's odometry-to-camera distance ratio may differ from
/// the median of the runs' before the run is taken for another robot's log. The synthetic
/// robot's runs lie within 1.4 % of their median (four seeds of 60 runs), a window dataset's
/// recordings (the median of their windows) within 5 %; a log counting twice the edges, or
/// logged by a robot with other encoders or wheels, is off by a factor.
const MAX_RUN_SCALE_SPREAD: f64 = 1.25;

/// The fewest runs among which one can be told apart from the others: of two, either may be
/// the odd one.
const MIN_RUNS_FOR_SPREAD: usize = 3;

/// Rejects the runs whose odometry's distances are off the other runs' by more than
/// [`MAX_RUN_SCALE_SPREAD`] (a window dataset's recordings, by the median of their windows,
/// when `per_recording`; a recording is the list of its runs' outcomes). Alignment matches
/// speed profiles whatever their scale, and [`robot_scale_mismatch`] judges only the median:
/// a third of the logs at twice the counts (a second robot's 24-count encoders, firmware
/// counting both edges) used to pass, and trained multipliers of 0.64.
pub fn reject_scale_outliers(outcomes: &mut [Vec<RunOutcome>], per_recording: bool) {
    // Each group is (recording, the outcomes in it) judged as one.
    let groups: Vec<(usize, Vec<usize>)> = if per_recording {
        (0..outcomes.len())
            .map(|r| (r, (0..outcomes[r].len()).collect()))
            .collect()
    } else {
        (0..outcomes.len())
            .flat_map(|r| (0..outcomes[r].len()).map(move |i| (r, vec![i])))
            .collect()
    };
    let ratio_of = |(r, idx): &(usize, Vec<usize>)| {
        upper_median(
            idx.iter()
                .filter_map(|&i| match &outcomes[*r][i] {
                    RunOutcome::Sample(s) => end_ratio(s),
                    RunOutcome::Rejected(_) => None,
                })
                .collect(),
        )
    };
    let ratios: Vec<Option<f64>> = groups.iter().map(ratio_of).collect();
    let judged: Vec<f64> = ratios.iter().flatten().copied().collect();
    let n = judged.len();
    let Some(median) = upper_median(judged).filter(|_| n >= MIN_RUNS_FOR_SPREAD) else {
        return;
    };
    let what = if per_recording { "recordings" } else { "runs" };
    for ((r, idx), ratio) in groups.iter().zip(&ratios) {
        let Some(ratio) = *ratio else { continue };
        if (ratio / median).ln().abs() <= MAX_RUN_SCALE_SPREAD.ln() {
            continue;
        }
        let reason = format!(
            "the odometry's distances are {ratio:.2} times the camera's, where the {n} {what}' median is {median:.2}: is this log of another robot, or do its encoders count other ticks per wheel turn (both edges of each line counted)?"
        );
        let rejected = |run_id: String| {
            RunOutcome::Rejected(RejectedRun {
                run_id,
                reason: reason.clone(),
            })
        };
        if per_recording {
            let id = idx.iter().find_map(|&i| match &outcomes[*r][i] {
                RunOutcome::Sample(s) => Some(s.recording_id.clone()),
                RunOutcome::Rejected(_) => None,
            });
            // The recording's windows are one rejection, as a recording that cannot be
            // aligned is.
            outcomes[*r].retain(|o| matches!(o, RunOutcome::Rejected(_)));
            outcomes[*r].extend(id.map(rejected));
        } else if let RunOutcome::Sample(s) = &outcomes[*r][idx[0]] {
            let id = s.run_id.clone();
            outcomes[*r][idx[0]] = rejected(id);
        }
    }
}

/// Logs whose first run starts this far from the other logs' (median), seconds, count on
/// another clock: a day, where the runs of one recording lie minutes or hours apart.
const MAX_LOG_CLOCK_APART_S: f64 = 86_400.0;

/// Rejects the runs of a recording whose log counts time on another clock than the other
/// recordings' (one log in Unix time among logs counting from their start): t_b and t_e are
/// inputs of the net, so its runs lie 1.7e9 s outside the others, the inputs' normalisation
/// squeezes every other run into one value, and the linear baseline's error read 1e9 %. A
/// recording is the list of its runs' outcomes.
pub fn reject_clock_outliers(outcomes: &mut [Vec<RunOutcome>]) {
    let start_of = |runs: &[RunOutcome]| {
        runs.iter()
            .filter_map(|o| match o {
                RunOutcome::Sample(s) => Some(s.odometry.t_b()),
                RunOutcome::Rejected(_) => None,
            })
            .filter(|t| t.is_finite())
            .reduce(f64::min)
    };
    let starts: Vec<Option<f64>> = outcomes.iter().map(|r| start_of(r)).collect();
    let judged: Vec<f64> = starts.iter().flatten().copied().collect();
    let n = judged.len();
    let Some(median) = upper_median(judged).filter(|_| n >= MIN_RUNS_FOR_SPREAD) else {
        return;
    };
    for (runs, start) in outcomes.iter_mut().zip(starts) {
        let Some(start) = start.filter(|t| (t - median).abs() > MAX_LOG_CLOCK_APART_S) else {
            continue;
        };
        let reason = format!(
            "its log's first run starts at {start:.0} s on the robot's clock, where the {n} logs' first runs start at {median:.1} s (median): is this log timed on another clock (Unix time)? The times t_b and t_e are inputs of the net, so every log must count its seconds alike (from its start)"
        );
        for o in runs.iter_mut() {
            if let RunOutcome::Sample(s) = o {
                *o = RunOutcome::Rejected(RejectedRun {
                    run_id: s.run_id.clone(),
                    reason: reason.clone(),
                });
            }
        }
    }
}

/// How far the robot file puts the odometry's distances from the camera's: `Err` when a
/// factor of [`MAX_ODOMETRY_SCALE`] or more says the file is not this robot's (a quadrature
/// encoder's four edges per line, a radius given as the diameter), `Ok(Some)` with a warning
/// beyond 20 %, `Ok(None)` within. Alignment cannot see it: it matches the speed profiles'
/// shapes, whatever their scale.
pub fn robot_scale_mismatch(
    ds: &Dataset,
    robot: &RobotParams,
    speed_logs: bool,
) -> Result<Option<String>, String> {
    // A window's end point is bent by its turns and, over a long window, by the heading's
    // drift: one 60 s window read 1.835 times the camera's with the right robot file. The
    // wheels' travel against the camera's, log step by log step over whole recordings, is
    // neither; and it is measured before any window is rejected, where a wrong scale used
    // to reject windows one by one as off the clock.
    let (scale, over) = if ds.is_windows() {
        let Some(t) = ds.summary.travel_scale else {
            return Ok(None);
        };
        (
            t.ratio,
            format!(
                "over {:.1} m of the camera's travel in {}",
                t.camera_m,
                if t.recordings == 1 {
                    "1 recording".to_string()
                } else {
                    format!("{} recordings", t.recordings)
                }
            ),
        )
    } else {
        let Some((scale, n)) = odometry_scale(&ds.samples) else {
            return Ok(None);
        };
        (scale, format!("median over {n} samples"))
    };
    let near = |k: f64| (scale / k - 1.0).abs() < 0.1;
    // A trajectory in feet scales every distance of the camera's, whatever the log: the
    // robot file would not mend it.
    if near(1.0 / FOOT_PER_M) {
        return Err(format!(
            "the odometry's distances are {scale:.3} times the camera's ({over}), and 1/3.281 is a trajectory in feet: it must be in metres (multiply feet by 0.3048)"
        ));
    }
    // A speed log's distances are its speeds times its times, whatever the wheels: the robot
    // file cannot scale them, their unit does. km/h read as m/s were blamed on ticks_per_rev.
    if speed_logs {
        let hint = if [3.6, 1.0 / 3.6].into_iter().any(near) {
            "a factor of 3.6 is km/h: the logs' v_left and v_right must be m/s (divide km/h by 3.6)"
                .to_string()
        } else if [100.0, 0.01].into_iter().any(near) {
            "a factor of 100 is cm/s: the logs' v_left and v_right must be m/s (divide cm/s by 100)"
                .to_string()
        } else {
            "a speed log's distances do not depend on the robot file's wheels or ticks: are v_left and v_right in m/s, each the wheel's mean over the period ending at its row?".to_string()
        };
        let text = format!(
            "the odometry's distances are {scale:.3} times the camera's ({over}) with these speed logs; {hint}"
        );
        if !(1.0 / MAX_ODOMETRY_SCALE..=MAX_ODOMETRY_SCALE).contains(&scale) {
            return Err(text);
        }
        return Ok(
            (!(1.0 / WARN_ODOMETRY_SCALE..=WARN_ODOMETRY_SCALE).contains(&scale)).then_some(text),
        );
    }
    // The odometry's distances scale with the diameter and inversely with the ticks per
    // turn: the value of either that would remove the factor `k`.
    let fits = |k: f64| (robot.wheel_diameter_m / k, robot.ticks_per_rev * k);
    let hint = if let Some(k) = [4.0, 0.25].into_iter().find(|&k| near(k)) {
        format!(
            "a factor of 4 is a quadrature encoder's four edges per line: is ticks_per_rev = {} the count of the log's ticks per wheel turn ({} would fit)?",
            robot.ticks_per_rev,
            fits(k).1
        )
    } else if let Some(k) = [2.0, 0.5].into_iter().find(|&k| near(k)) {
        // Both are common: a radius written for the diameter, and an encoder decoded on both
        // edges of its lines (quadrature x2) or on one of them.
        let (diameter, ticks) = fits(k);
        format!(
            "a factor of 2 is a radius for a diameter or an encoder counting twice or half the edges (quadrature decoding x2, x4): is wheel_diameter_m = {} the wheels' diameter ({diameter} would fit), and ticks_per_rev = {} the count of the log's ticks per wheel turn ({ticks} would fit)?",
            robot.wheel_diameter_m, robot.ticks_per_rev
        )
    } else {
        format!(
            "check wheel_diameter_m = {} and ticks_per_rev = {} against the robot",
            robot.wheel_diameter_m, robot.ticks_per_rev
        )
    };
    let text = format!(
        "the odometry's distances are {scale:.3} times the camera's ({over}) with this robot file; {hint}"
    );
    if !(1.0 / MAX_ODOMETRY_SCALE..=MAX_ODOMETRY_SCALE).contains(&scale) {
        return Err(format!(
            "{text} (odometry drifts by percents, not by half again)"
        ));
    }
    Ok((!(1.0 / WARN_ODOMETRY_SCALE..=WARN_ODOMETRY_SCALE).contains(&scale)).then_some(text))
}

#[cfg(test)]
mod tests {
    use super::*;
    use odocal_core::{Pose2, TrajectoryRow};

    #[test]
    fn millimetres_and_a_millimetre_wheel_are_named() {
        let robot = RobotParams::default();
        // 30 rows of a straight drive: 2 ticks per row on both wheels.
        let ticks: Vec<i64> = (0..30).map(|i| 2 * i).collect();
        let t: Vec<f64> = (0..30).map(|i| 0.2 * i as f64).collect();
        let log = OdometryLog::from_ticks(t.clone(), ticks.clone(), ticks).expect("log");
        let per_tick_m = std::f64::consts::PI * robot.wheel_diameter_m / robot.ticks_per_rev;
        let camera = |scale: f64| {
            let rows = t
                .iter()
                .enumerate()
                .map(|(i, &t_s)| TrajectoryRow {
                    t_s,
                    pose: Pose2::new(scale * 2.0 * i as f64 * per_tick_m, 0.0, 0.0),
                    quality: 1.0,
                    sigma: None,
                })
                .collect();
            Trajectory::new(rows).expect("trajectory")
        };
        assert_eq!(unit_mismatch(&log, &camera(1.0), &robot), None);
        assert_eq!(unit_mismatch(&log, &camera(1.3), &robot), None);
        let mm = unit_mismatch(&log, &camera(1000.0), &robot).expect("mm");
        assert!(mm.contains("in millimetres?"), "{mm}");
        let wheel_mm = RobotParams {
            wheel_diameter_m: robot.wheel_diameter_m * 1000.0,
            ..robot
        };
        let w = unit_mismatch(&log, &camera(1.0), &wheel_mm).expect("wheel");
        assert!(w.contains("wheel_diameter_m in millimetres"), "{w}");
    }

    #[test]
    fn runs_at_another_scale_than_the_others_are_rejected_by_name() {
        // Straight runs of 1.5 m whose odometry reads `ratio` times that.
        let run = |id: usize, ratio: f64| {
            RunOutcome::Sample(Box::new(Sample {
                run_id: format!("run{id:03}"),
                recording_id: format!("run{id:03}"),
                target_m: [1.5, 0.0],
                raw_end_m: [1.5 * ratio, 0.1],
                ..Sample::default()
            }))
        };
        let ids = |outcomes: &[Vec<RunOutcome>]| -> Vec<String> {
            outcomes
                .iter()
                .flatten()
                .filter_map(|o| match o {
                    RunOutcome::Rejected(r) => Some(format!("{}: {}", r.run_id, r.reason)),
                    RunOutcome::Sample(_) => None,
                })
                .collect()
        };
        // The synthetic robot's spread (1.018 to 1.044) and every third log at twice the
        // counts: 2.06 against 1.03.
        let mut outcomes: Vec<Vec<RunOutcome>> = (0..12)
            .map(|i| {
                let clean = 1.018 + 0.026 * (i % 5) as f64 / 4.0;
                vec![run(i, if i % 3 == 0 { 2.0 * clean } else { clean })]
            })
            .collect();
        let clean_only: Vec<Vec<RunOutcome>> = outcomes
            .iter()
            .filter(|o| !matches!(&o[0], RunOutcome::Sample(s) if s.raw_end_m[0] > 2.0))
            .cloned()
            .collect();
        let mut kept = clean_only.clone();
        reject_scale_outliers(&mut kept, false);
        assert_eq!(kept, clean_only);
        reject_scale_outliers(&mut outcomes, false);
        let rejected = ids(&outcomes);
        assert_eq!(rejected.len(), 4, "{rejected:?}");
        assert!(
            rejected[0].starts_with("run000: the odometry's distances are 2.04 times the camera's, where the 12 runs' median is 1.04: is this log of another robot, or do its encoders count other ticks per wheel turn"),
            "{rejected:?}"
        );
        // Windows are judged by recording, and a recording is one rejection.
        let window = |rec: usize, ratio: f64| {
            let mut w = run(rec, ratio);
            if let RunOutcome::Sample(s) = &mut w {
                s.run_id = format!("run{rec:03}.w1");
            }
            w
        };
        let mut recordings: Vec<Vec<RunOutcome>> = (0..4)
            .map(|r| {
                let k = if r == 2 { 2.0 } else { 1.0 };
                vec![window(r, k * 1.02), window(r, k * 0.4), window(r, k * 1.0)]
            })
            .collect();
        reject_scale_outliers(&mut recordings, true);
        let rejected = ids(&recordings);
        assert_eq!(rejected.len(), 1, "{rejected:?}");
        assert!(rejected[0].starts_with("run002: the odometry's distances are 2.00 times the camera's, where the 4 recordings' median is 1.00"), "{rejected:?}");
        // Of two runs either may be the odd one: none is judged.
        let mut two = vec![vec![run(0, 1.0)], vec![run(1, 2.0)]];
        reject_scale_outliers(&mut two, false);
        assert!(ids(&two).is_empty());
    }

    #[test]
    fn trajectory_times_in_milliseconds_are_named() {
        let t: Vec<f64> = (0..50).map(|i| 0.2 * i as f64).collect();
        let ticks: Vec<i64> = (0..50).map(|i| 2 * i).collect();
        let log = OdometryLog::from_ticks(t, ticks.clone(), ticks).expect("log");
        let camera = |scale: f64| {
            let rows = (0..300)
                .map(|i| TrajectoryRow {
                    t_s: scale * i as f64 / 30.0,
                    pose: Pose2::new(0.001 * i as f64, 0.0, 0.0),
                    quality: 1.0,
                    sigma: None,
                })
                .collect();
            Trajectory::new(rows).expect("trajectory")
        };
        assert_eq!(time_unit_mismatch(&log, &camera(1.0)), None);
        let ms = time_unit_mismatch(&log, &camera(1000.0)).expect("ms");
        assert!(
            ms.contains("rows are 33.3 apart") && ms.contains("in milliseconds?"),
            "{ms}"
        );
        // A slow camera in seconds (one frame in 1.5 s) is still seconds.
        assert_eq!(time_unit_mismatch(&log, &camera(45.0)), None);
    }
}
