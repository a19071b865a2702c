//! Turning recordings (an odometry log and a camera trajectory) into training samples.

use nalgebra::Point2;
use odocal_core::{wrap_angle, Pose2};

use crate::align::{
    clock_rate, coarse_offset, refine_offset, AlignOptions, ClockRate, CoarseOffset,
};
use crate::error::DatasetError;
use crate::glitch::LostStep;
use crate::kinematics::{RunOdometry, WheelGeometry};
use crate::odometry::{OdometryLog, WheelRevs, STEP_TOLERANCE_PERIODS};
use crate::segment::{split_runs, RunSegment};
use crate::speed_label::{camera_peak_speed_mps, commanded_speed_mismatch};
use crate::{Dataset, RejectedRun, RobotParams, Sample, N_INPUTS};
use odocal_core::{mean_pose, PoseSigma, Trajectory, TrajectoryRow};

/// Chord over path length below which a run is not straight (a straight run's drift of a few
/// degrees keeps it above 0.99).
const MIN_STRAIGHTNESS: f64 = 0.9;

/// Largest turn of a straight run's heading from its start, radians (45°): the synthetic
/// experiment's runs veer by up to 18°.
const MAX_STRAIGHT_TURN_RAD: f64 = std::f64::consts::FRAC_PI_4;

/// Shortest rest, seconds, that separates two runs in one log.
pub const DEFAULT_MIN_GAP_S: f64 = 1.0;

/// Settings of the dataset build.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BuildOptions {
    /// Nominal robot used for dead reckoning.
    pub robot: RobotParams,
    /// Time alignment settings.
    pub align: AlignOptions,
    /// Shortest rest, seconds, that separates two runs in one log.
    pub min_gap_s: f64,
    /// Shortest odometry travel of a usable run, metres.
    pub min_travel_m: f64,
    /// Camera frames within this distance of the rest position count as at rest, metres.
    pub rest_tolerance_m: f64,
    /// Length of the camera rest windows before and after a run, seconds.
    pub rest_window_s: f64,
    /// Margin before t_b excluded from the start rest window (sub-tick motion), seconds.
    pub rest_guard_s: f64,
    /// Fewest camera frames at rest needed for the start and end poses.
    pub min_rest_frames: usize,
    /// Largest RMS difference, m/s, between the odometry's speed and the camera's at the best
    /// clock offset for a run to be kept. Good runs of the reference experiment give about
    /// 0.025 m/s (encoder quantisation and slip); a log paired with another run's trajectory
    /// gives 0.1-0.3 m/s. See [`DEFAULT_MAX_ALIGNMENT_RESIDUAL_MPS`].
    pub max_alignment_residual_mps: f64,
    /// What one sample is: a straight run (the reference experiment) or a window of any
    /// motion.
    pub layout: crate::windows::Layout,
    /// Where the point and heading of the manifest's trajectory files sit on the robot (a
    /// motion-capture body defined by hand): each file is taken off it as it is read, so its
    /// trajectory is the axle midpoint's, heading forwards, as the odometry is. Videos are
    /// tracked with their own mount.
    pub trajectory_mount: odocal_core::TagToRobot,
}

/// The default of [`BuildOptions::max_alignment_residual_mps`]: three times what good runs
/// give, well below what a mismatched pair gives.
pub const DEFAULT_MAX_ALIGNMENT_RESIDUAL_MPS: f64 = 0.08;

impl Default for BuildOptions {
    fn default() -> Self {
        Self {
            robot: RobotParams::default(),
            align: AlignOptions::default(),
            min_gap_s: DEFAULT_MIN_GAP_S,
            min_travel_m: 0.3,
            rest_tolerance_m: 0.005,
            rest_window_s: 1.0,
            rest_guard_s: 0.3,
            min_rest_frames: 3,
            max_alignment_residual_mps: DEFAULT_MAX_ALIGNMENT_RESIDUAL_MPS,
            layout: crate::windows::Layout::StraightRuns,
            trajectory_mount: odocal_core::TagToRobot::IDENTITY,
        }
    }
}

/// One recording: a manifest row's odometry log and camera trajectory.
#[derive(Debug, Clone, Copy)]
pub struct Recording<'a> {
    /// Manifest id.
    pub id: &'a str,
    /// Commanded speed from the manifest, m/s, if given.
    pub speed_mps: Option<f64>,
    /// The robot's odometry log.
    pub log: &'a OdometryLog,
    /// The camera trajectory (floor frame, camera clock).
    pub camera: &'a Trajectory,
}

/// What became of one detected run.
#[derive(Debug, Clone, PartialEq)]
pub enum RunOutcome {
    /// A usable run.
    Sample(Box<Sample>),
    /// An unusable run and why.
    Rejected(RejectedRun),
}

/// The features of the single run in a raw odometry log.
#[derive(Debug, Clone, PartialEq)]
pub struct RunFeatures {
    /// The 18 inputs of [`crate::FEATURE_RULE`].
    pub inputs: [f64; N_INPUTS],
    /// Raw odometry end position in the start frame, metres.
    pub raw_end_m: [f64; 2],
    /// The run's odometry rows t_b..t_e.
    pub odometry: RunOdometry,
}

/// Detects the one run in a raw log and computes its features exactly as the dataset does
/// (what `odocal correct` must use). Errors if the log holds no run, several runs, or a run cut
/// by the log's start or end.
pub fn features_from_log(
    log: &OdometryLog,
    robot: &RobotParams,
) -> Result<RunFeatures, DatasetError> {
    let segs = split_runs(log, DEFAULT_MIN_GAP_S);
    let seg = match segs.as_slice() {
        [] => return Err(DatasetError::Mismatch("the odometry log shows no motion".into())),
        [s] => *s,
        _ => {
            return Err(DatasetError::Mismatch(format!(
                "the odometry log holds {} runs separated by stops of {DEFAULT_MIN_GAP_S} s or more; give one run per log",
                segs.len()
            )))
        }
    };
    if let Some(why) = cut_reason(&seg) {
        return Err(DatasetError::Mismatch(format!("the odometry log {why}")));
    }
    let odometry = seg.odometry(&log.wheel_revs(robot));
    let g = WheelGeometry::nominal(robot);
    Ok(RunFeatures {
        inputs: odometry.features(&g),
        raw_end_m: odometry.end_m(&g),
        odometry,
    })
}

/// Why a run of camera poses `poses` (rest poses at both ends), `path` metres long and ending
/// at `rel` from its start, is not a straight run; the 18 inputs describe a straight run, and
/// a tour's end point says nothing of its path. Its end must lie at least
/// [`MIN_STRAIGHTNESS`] of its path from its start, and its heading stay within
/// [`MAX_STRAIGHT_TURN_RAD`] of the start's: a turn in place adds no path, so a piece that
/// turned 172° on the spot and then drove 2.2 m passed the first check alone.
fn not_straight(poses: &[Pose2], path: f64, rel: &Pose2) -> Option<String> {
    let chord = rel.x_m.hypot(rel.y_m);
    if path > 0.1 && chord < MIN_STRAIGHTNESS * path {
        return Some(format!(
            "not a straight run: its path is {path:.2} m long and ends {chord:.2} m from its start; runs of any shape take --layout windows"
        ));
    }
    let th0 = poses.first()?.theta_rad;
    let turn = poses
        .iter()
        .map(|p| wrap_angle(p.theta_rad - th0).abs())
        .fold(0.0, f64::max);
    (turn > MAX_STRAIGHT_TURN_RAD).then(|| {
        format!(
            "not a straight run: its heading turns {:.0}° from its start (a straight run's stays within {:.0}°); runs of any shape take --layout windows",
            turn.to_degrees(),
            MAX_STRAIGHT_TURN_RAD.to_degrees()
        )
    })
}

/// Why a straight run's target cannot be its odometry's: the camera's end point lies more
/// than 90° from the wheels' (the run matched to a stretch of the trajectory driven the
/// other way), where a straight run's odometry errs by a few degrees.
fn against_odometry(target_m: [f64; 2], raw_end_m: [f64; 2]) -> Option<String> {
    let dot = target_m[0] * raw_end_m[0] + target_m[1] * raw_end_m[1];
    (dot < 0.0).then(|| {
        format!(
            "the camera has the run end at ({:.3}, {:.3}) m from its start and the wheels at ({:.3}, {:.3}) m, more than 90° apart: the camera's motion there is not this run's; is the log paired with the right video or trajectory?",
            target_m[0], target_m[1], raw_end_m[0], raw_end_m[1]
        )
    })
}

fn cut_reason(seg: &RunSegment) -> Option<&'static str> {
    if seg.starts_in_motion {
        Some("starts during the run's motion (no rest row before it)")
    } else if seg.ends_in_motion {
        Some("ends during the run's motion (log too short, no rest row after it)")
    } else {
        None
    }
}

fn median(mut v: Vec<f64>) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// Camera frames at rest around `anchor` within `rows`: those within `tol` of the median of the
/// frames nearest the anchor (`near` = the 0.3 s next to it).
fn rest_cluster(rows: &[TrajectoryRow], near: &[TrajectoryRow], tol: f64) -> Vec<TrajectoryRow> {
    if near.is_empty() {
        return Vec::new();
    }
    let c = Point2::new(
        median(near.iter().map(|r| r.pose.x_m).collect()),
        median(near.iter().map(|r| r.pose.y_m).collect()),
    );
    rows.iter()
        .filter(|r| (r.pose.position() - c).norm() <= tol)
        .copied()
        .collect()
}

/// Why the camera's trajectory cannot give the run whose motion spans `motion` (camera clock,
/// coarse offset): it starts or ends during the run, or misses frames in it; None when it
/// sees the whole run. A recording's coarse offset may rest on the runs the camera saw, so
/// the others are named here rather than left to the fine alignment's generic failure.
fn unseen_reason(camera: &Trajectory, motion: (f64, f64), max_gap_s: f64) -> Option<String> {
    let (t0, t1) = motion;
    let (c0, c1) = (camera.start_s(), camera.end_s());
    let span = format!("the log puts this run at {t0:.2}-{t1:.2} s on the camera's clock");
    if c1 < t1 {
        let when = if c1 <= t0 { "before" } else { "during" };
        return Some(format!(
            "the camera's trajectory ends at {c1:.2} s, {when} this run ({span})"
        ));
    }
    if c0 > t0 {
        let when = if c0 >= t1 { "after" } else { "during" };
        return Some(format!(
            "the camera's trajectory starts at {c0:.2} s, {when} this run ({span})"
        ));
    }
    // The rows around the motion: the last at or before its start to the first at or after
    // its end.
    let a = camera
        .rows
        .partition_point(|r| r.t_s <= t0)
        .saturating_sub(1);
    let b = camera
        .rows
        .partition_point(|r| r.t_s < t1)
        .min(camera.rows.len().saturating_sub(1));
    let (gap, from) = camera
        .rows
        .get(a..=b)?
        .windows(2)
        .map(|w| (w[1].t_s - w[0].t_s, w[0].t_s))
        .max_by(|x, y| x.0.total_cmp(&y.0))?;
    (gap > max_gap_s).then(|| {
        format!(
            "the camera's trajectory has no rows for {gap:.2} s ({from:.2}-{:.2} s) during this run (missed frames?; {span})",
            from + gap
        )
    })
}

/// Splits a recording into runs and turns each into a sample or a rejection.
///
/// Hard errors (the whole build must stop): a log whose motion cannot overlap the trajectory
/// (another recording's file). A camera that saw too little of the recording rejects its
/// runs, and one that missed some of them rejects those.
pub fn process_recording(
    rec: &Recording,
    opts: &BuildOptions,
) -> Result<Vec<RunOutcome>, DatasetError> {
    process_recording_at(rec, opts, coarse_of(rec, opts), &[])
}

/// The clock of a whole recording: its coarse offset (speed-profile cross-correlation) and,
/// where the recording tells one apart from 1, its rate, the offset then found again on the
/// log's times scaled by it. Found once per recording and shared by the checks and the
/// samples.
pub(crate) fn coarse_of(
    rec: &Recording,
    opts: &BuildOptions,
) -> Result<CoarseOffset, DatasetError> {
    let revs = rec.log.wheel_revs(&opts.robot);
    let geom = WheelGeometry::nominal(&opts.robot);
    let coarse = coarse_offset(rec.log, &revs, &geom, rec.camera, &opts.align, rec.id)?;
    if coarse.correlation < opts.align.min_correlation {
        return Ok(coarse);
    }
    let Some(r) =
        clock_rate(rec.log, &revs, &geom, rec.camera, &opts.align, &coarse).filter(ClockRate::told)
    else {
        return Ok(coarse);
    };
    // The offset again over the whole log on the camera's seconds: the first one, at rate 1,
    // fits the log's middle.
    let scaled = WheelRevs {
        t_s: revs.t_s.iter().map(|t| r.rate * t).collect(),
        rev: revs.rev,
    };
    let c = coarse_offset(rec.log, &scaled, &geom, rec.camera, &opts.align, rec.id)?;
    Ok(CoarseOffset { rate: r.rate, ..c })
}

/// [`process_recording`] with the recording's coarse offset already found; a run across a step
/// of `lost` (the log's glitches, see [`crate::glitch`]) is rejected with its reason.
pub(crate) fn process_recording_at(
    rec: &Recording,
    opts: &BuildOptions,
    coarse: Result<CoarseOffset, DatasetError>,
    lost: &[LostStep],
) -> Result<Vec<RunOutcome>, DatasetError> {
    let reject =
        |id: String, reason: String| RunOutcome::Rejected(RejectedRun { run_id: id, reason });
    let segs = split_runs(rec.log, opts.min_gap_s);
    if segs.is_empty() {
        return Ok(vec![reject(
            rec.id.to_string(),
            "no motion in the odometry log".into(),
        )]);
    }
    let name = |j: usize| {
        if segs.len() == 1 {
            rec.id.to_string()
        } else {
            format!("{}.{}", rec.id, j + 1)
        }
    };
    let revs = rec.log.wheel_revs(&opts.robot);
    let geom = WheelGeometry::nominal(&opts.robot);
    let coarse = match coarse {
        Err(DatasetError::NoClockOffset(why)) => {
            return Ok((0..segs.len())
                .map(|j| reject(name(j), why.clone()))
                .collect())
        }
        c => c?,
    };
    let frame_gap = opts.align.frame_gap_s(rec.camera);
    let mut out = Vec::with_capacity(segs.len());
    for (j, seg) in segs.iter().enumerate() {
        let id = name(j);
        if let Some(step) = lost.iter().find(|s| s.touches(seg.start_row, seg.end_row)) {
            out.push(reject(
                id,
                format!(
                    "{}: the run's travel across it is unknown (the recording's other runs are kept)",
                    step.reason
                ),
            ));
            continue;
        }
        if coarse.correlation < opts.align.min_correlation {
            out.push(reject(
                id,
                format!(
                    "clock offset not found: speed-profile correlation {:.3}, below the {:.2} needed",
                    coarse.correlation, opts.align.min_correlation
                ),
            ));
            continue;
        }
        if let Some(why) = cut_reason(seg) {
            out.push(reject(id, format!("the log {why}")));
            continue;
        }
        if let Some((k, dt)) = rec.log.off_period_step(
            seg.start_row,
            seg.end_row,
            opts.robot.period_s,
            STEP_TOLERANCE_PERIODS,
        ) {
            out.push(reject(
                id,
                format!(
                    "the log's {}: the run's odometry would bridge the gap as one step",
                    rec.log.step_message(k, dt, opts.robot.period_s)
                ),
            ));
            continue;
        }
        let odo = seg.odometry(&revs);
        let travel = odo.travel_m(&geom);
        if travel < opts.min_travel_m {
            out.push(reject(
                id,
                format!(
                    "too short: odometry travel {travel:.3} m < {:.3} m",
                    opts.min_travel_m
                ),
            ));
            continue;
        }
        let motion = (coarse.camera_s(odo.t_b()), coarse.camera_s(odo.t_e()));
        if let Some(why) = unseen_reason(rec.camera, motion, frame_gap) {
            out.push(reject(id, why));
            continue;
        }
        let al = match refine_offset(
            rec.log,
            &revs,
            seg,
            &opts.robot,
            rec.camera,
            // The run's own offset is near the clock's there: a clock at another rate drifts.
            coarse.offset_at(0.5 * (odo.t_b() + odo.t_e())),
            &opts.align,
        ) {
            Ok(a) => a,
            Err(why) => {
                out.push(reject(id, format!("clock offset not found: {why}")));
                continue;
            }
        };
        if al.residual_mps > opts.max_alignment_residual_mps || al.residual_mps.is_nan() {
            out.push(reject(
                id,
                format!(
                    "odometry and camera disagree: their speeds differ by {:.3} m/s RMS at the best clock offset (limit {:.3} m/s; good runs give about 0.025); is the log paired with the right video or trajectory?",
                    al.residual_mps, opts.max_alignment_residual_mps
                ),
            ));
            continue;
        }
        let d = al.offset_s;
        let (tb, te) = (odo.t_b(), odo.t_e());
        // Start pose: camera frames at rest before motion.
        let a = tb + d - opts.rest_guard_s;
        let start_rows = rest_cluster(
            rec.camera.rows_between(a - opts.rest_window_s, a),
            rec.camera.rows_between(a - 0.3, a),
            opts.rest_tolerance_m,
        );
        if start_rows.len() < opts.min_rest_frames {
            out.push(reject(
                id,
                format!(
                    "tag not seen at rest before the run ({} frames in the {:.1} s before t_b)",
                    start_rows.len(),
                    opts.rest_window_s
                ),
            ));
            continue;
        }
        let e = te + d;
        let end_rows = rest_cluster(
            rec.camera.rows_between(e, e + opts.rest_window_s),
            rec.camera.rows_between(e, e + 0.3),
            opts.rest_tolerance_m,
        );
        if end_rows.len() < opts.min_rest_frames {
            out.push(reject(
                id,
                format!(
                    "tag lost at the end of the run ({} frames at rest in the {:.1} s after t_e)",
                    end_rows.len(),
                    opts.rest_window_s
                ),
            ));
            continue;
        }
        let (Some(start), Some(end)) = (mean_pose(&start_rows), mean_pose(&end_rows)) else {
            continue;
        };
        let rel = end.relative_to(&start);
        let target_sigma = target_sigma(&start_rows, &end_rows, &start, &rel);
        // Real path: camera poses at the aligned log rows, rest poses at the ends.
        let mut poses = vec![start];
        poses.extend(
            (seg.start_row + 1..seg.end_row)
                .filter_map(|k| rec.camera.pose_at(revs.t_s[k] + d, frame_gap)),
        );
        poses.push(end);
        let path: f64 = poses
            .windows(2)
            .map(|w| (w[1].position() - w[0].position()).norm())
            .sum();
        if let Some(why) = not_straight(&poses, path, &rel) {
            out.push(reject(id, why));
            continue;
        }
        let raw_end_m = odo.end_m(&geom);
        if let Some(why) = against_odometry([rel.x_m, rel.y_m], raw_end_m) {
            out.push(reject(id, why));
            continue;
        }
        let speeds: Vec<f64> = (1..odo.t_s.len())
            .filter(|&k| odo.rev[k] != odo.rev[k - 1])
            .map(|k| {
                let g = &geom;
                let dl = (odo.rev[k][0] - odo.rev[k - 1][0])
                    * std::f64::consts::PI
                    * g.left_wheel_diameter_m;
                let dr = (odo.rev[k][1] - odo.rev[k - 1][1])
                    * std::f64::consts::PI
                    * g.right_wheel_diameter_m;
                0.5 * (dl + dr).abs() / (odo.t_s[k] - odo.t_s[k - 1])
            })
            .collect();
        let odo_speed = median(speeds);
        // Judged against the camera's speeds, which a wrong robot file does not scale.
        if let Some(v) = rec.speed_mps {
            let run_t_s = &revs.t_s[seg.start_row..=seg.end_row];
            let peak = camera_peak_speed_mps(rec.camera, run_t_s, d, frame_gap);
            if let Some(why) = commanded_speed_mismatch(v, peak, path / (te - tb)) {
                out.push(reject(id, why));
                continue;
            }
        }
        out.push(RunOutcome::Sample(Box::new(Sample {
            run_id: id,
            speed_mps: rec.speed_mps.unwrap_or(odo_speed),
            speed_commanded: rec.speed_mps.is_some(),
            inputs: odo.features(&geom).to_vec(),
            target_m: [rel.x_m, rel.y_m],
            raw_end_m,
            path_length_m: path,
            clock_offset_s: d,
            alignment_residual_mps: al.residual_mps,
            clock_rate: (coarse.rate != 1.0).then_some(coarse.rate),
            recording_id: rec.id.to_string(),
            alignment_residual_m: al.residual_m,
            speed_correlation: coarse.correlation,
            odometry_speed_mps: odo_speed,
            start_pose_floor: Pose2::new(start.x_m, start.y_m, start.theta_rad),
            target_theta_rad: wrap_angle(rel.theta_rad),
            rest_frames: [start_rows.len(), end_rows.len()],
            target_sigma_m: target_sigma.map(|s| [s.x_m, s.y_m]),
            target_sigma_theta_rad: target_sigma.map(|s| s.theta_rad),
            odometry: odo,
        })));
    }
    // A run --min-gap-s joined from runs the default gap keeps apart spans the robot's
    // return between them, which reads as missed frames or a run that is not straight:
    // its rejection names the joining too.
    if opts.min_gap_s > DEFAULT_MIN_GAP_S {
        let apart = split_runs(rec.log, DEFAULT_MIN_GAP_S);
        for o in &mut out {
            let RunOutcome::Rejected(r) = o else { continue };
            let Some(j) = (0..segs.len()).find(|&j| name(j) == r.run_id) else {
                continue;
            };
            let (a, b) = (segs[j].start_row, segs[j].end_row);
            let inside = apart
                .iter()
                .filter(|s| (a..=b).contains(&s.start_row))
                .count();
            if inside > 1 {
                r.reason.push_str(&format!(
                    "; --min-gap-s {} joined {inside} runs that pauses of {DEFAULT_MIN_GAP_S} s or more keep apart: give it less than the pauses between the runs",
                    opts.min_gap_s
                ));
            }
        }
    }
    Ok(out)
}

/// σ of the mean of rest poses: the RMS of their σ over √n (the frames' detection noise is
/// independent from frame to frame); none unless every row has σ.
fn rest_sigma(rows: &[TrajectoryRow]) -> Option<PoseSigma> {
    let n = rows.len() as f64;
    let mut sum = [0.0; 3];
    for r in rows {
        let s = r.sigma?;
        sum[0] += s.x_m * s.x_m;
        sum[1] += s.y_m * s.y_m;
        sum[2] += s.theta_rad * s.theta_rad;
    }
    (n > 0.0).then(|| PoseSigma {
        x_m: (sum[0] / n / n).sqrt(),
        y_m: (sum[1] / n / n).sqrt(),
        theta_rad: (sum[2] / n / n).sqrt(),
    })
}

/// σ of the target `rel` (the end rest pose in the frame of the start rest pose `start`):
/// both rest poses' position σ turned into the start frame, plus the start heading's σ
/// swinging the end point about the start.
fn target_sigma(
    start_rows: &[TrajectoryRow],
    end_rows: &[TrajectoryRow],
    start: &Pose2,
    rel: &Pose2,
) -> Option<PoseSigma> {
    let (a, b) = (rest_sigma(start_rows)?, rest_sigma(end_rows)?);
    let (s, c) = start.theta_rad.sin_cos();
    // Floor-frame position covariance (diagonal) of end − start, rotated into the start frame.
    let (vx, vy) = (a.x_m.powi(2) + b.x_m.powi(2), a.y_m.powi(2) + b.y_m.powi(2));
    let var_x = c * c * vx + s * s * vy + (rel.y_m * a.theta_rad).powi(2);
    let var_y = s * s * vx + c * c * vy + (rel.x_m * a.theta_rad).powi(2);
    Some(PoseSigma {
        x_m: var_x.sqrt(),
        y_m: var_y.sqrt(),
        theta_rad: a.theta_rad.hypot(b.theta_rad),
    })
}

/// Collects the outcomes of all recordings (in manifest order) into a dataset.
pub fn assemble(robot: RobotParams, outcomes: Vec<Vec<RunOutcome>>) -> Dataset {
    let recordings = outcomes.len();
    let mut samples = Vec::new();
    let mut rejected = Vec::new();
    for o in outcomes.into_iter().flatten() {
        match o {
            RunOutcome::Sample(s) => samples.push(*s),
            RunOutcome::Rejected(r) => rejected.push(r),
        }
    }
    Dataset::new(robot, samples, rejected, recordings)
}

/// The samples as CSV: of straight runs, id, speed, the 18 inputs, target, raw end, path
/// length, offset, residuals; of windows, the columns of [`window_rows`].
/// A run id with a comma, quote or line break is quoted, as CSV readers expect.
pub fn samples_csv(ds: &Dataset) -> String {
    let rows = if ds.is_windows() {
        window_rows(ds)
    } else {
        run_rows(ds)
    };
    let mut w = csv::WriterBuilder::new()
        .terminator(csv::Terminator::Any(b'\n'))
        .from_writer(Vec::new());
    for row in &rows {
        // Every row is as wide as the header (built from the same layout), so writing into
        // memory fails only on a field too long for memory.
        if w.write_record(row).is_err() {
            break;
        }
    }
    String::from_utf8_lossy(&w.into_inner().unwrap_or_default()).into_owned()
}

/// The straight runs' rows: the 18 inputs, then the target and what the build measured.
fn run_rows(ds: &Dataset) -> Vec<Vec<String>> {
    let mut header = vec!["run_id".to_string(), "speed_mps".to_string()];
    for i in 1..=8 {
        header.extend([format!("x{i}"), format!("y{i}")]);
    }
    header.extend(
        [
            "t_b",
            "t_e",
            "target_x",
            "target_y",
            "raw_x",
            "raw_y",
            "path_length_m",
            "clock_offset_s",
            "alignment_residual_mps",
        ]
        .map(String::from),
    );
    let mut rows = vec![header];
    for smp in &ds.samples {
        let mut row = vec![smp.run_id.clone(), smp.speed_mps.to_string()];
        row.extend(smp.inputs.iter().map(f64::to_string));
        row.extend(
            [
                smp.target_m[0],
                smp.target_m[1],
                smp.raw_end_m[0],
                smp.raw_end_m[1],
                smp.path_length_m,
                smp.clock_offset_s,
                smp.alignment_residual_mps,
            ]
            .map(|v| v.to_string()),
        );
        rows.push(row);
    }
    rows
}

/// The windows' rows: the window and its recording, the target pose change (with heading),
/// raw odometry's, then each step's nominal wheel travel. Written under the straight runs'
/// header, a window's 2W travels ran past it, and the writer stopped after the first row.
fn window_rows(ds: &Dataset) -> Vec<Vec<String>> {
    let steps = ds
        .samples
        .iter()
        .map(|s| s.inputs.len() / 2)
        .max()
        .unwrap_or(0);
    let mut header: Vec<String> = [
        "window_id",
        "recording_id",
        "t_start_s",
        "t_end_s",
        "target_x",
        "target_y",
        "target_theta",
        "raw_x",
        "raw_y",
        "raw_theta",
        "wheel_travel_m",
        "clock_offset_s",
        "alignment_residual_mps",
    ]
    .map(String::from)
    .to_vec();
    for i in 1..=steps {
        header.extend([format!("left_m_{i}"), format!("right_m_{i}")]);
    }
    let width = header.len();
    let mut rows = vec![header];
    for smp in &ds.samples {
        let t = &smp.odometry.t_s;
        let raw = smp
            .odometry
            .poses(&crate::kinematics::WheelGeometry::nominal(&ds.robot));
        let raw_theta = raw.last().map_or(0.0, |p| p.theta_rad);
        let mut row = vec![smp.run_id.clone(), smp.recording_id.clone()];
        row.extend(
            [
                t.first().copied().unwrap_or(f64::NAN),
                t.last().copied().unwrap_or(f64::NAN),
                smp.target_m[0],
                smp.target_m[1],
                smp.target_theta_rad,
                smp.raw_end_m[0],
                smp.raw_end_m[1],
                raw_theta,
                smp.path_length_m,
                smp.clock_offset_s,
                smp.alignment_residual_mps,
            ]
            .map(|v| v.to_string()),
        );
        row.extend(smp.inputs.iter().map(f64::to_string));
        row.resize(width, String::new());
        rows.push(row);
    }
    rows
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Straight run along +x from (0.2, 0.1) heading 0.3 rad: trapezoid speed profile, rest
    /// before and after; returns (log, camera trajectory) with camera clock = robot + offset.
    fn synthetic(offset: f64, cut_end: bool) -> (OdometryLog, Trajectory) {
        let v = 0.5;
        let a = 1.0;
        let t0 = 1.1;
        let dist = 1.5;
        let t_acc = v / a;
        let t_end = t0 + t_acc + (dist - v * t_acc) / v + t_acc;
        let s_at = |t: f64| -> f64 {
            let u = t - t0;
            if u <= 0.0 {
                0.0
            } else if u < t_acc {
                0.5 * a * u * u
            } else if t < t_end - t_acc {
                0.5 * a * t_acc * t_acc + v * (u - t_acc)
            } else if t < t_end {
                let w = t_end - t;
                dist - 0.5 * a * w * w
            } else {
                dist
            }
        };
        let circ = std::f64::consts::PI * 0.043;
        let n_rows = if cut_end { 20 } else { 40 };
        let t: Vec<f64> = (0..n_rows).map(|k| 0.2 * k as f64).collect();
        let ticks = |phase: f64| -> Vec<i64> {
            t.iter()
                .map(|&tk| (s_at(tk) / circ * 12.0 + phase).floor() as i64)
                .collect()
        };
        let log = OdometryLog::from_ticks(t.clone(), ticks(0.37), ticks(0.81)).unwrap();
        let start = Pose2::new(0.2, 0.1, 0.3);
        let rows = (0..300)
            .map(|k| {
                let tc = k as f64 / 30.0;
                let s = s_at(tc - offset);
                TrajectoryRow {
                    t_s: tc,
                    pose: start.compose(&Pose2::new(s, 0.0, 0.0)),
                    quality: 1.0,
                    sigma: None,
                }
            })
            .collect();
        (log, Trajectory::new(rows).unwrap())
    }

    #[test]
    fn recovers_offset_and_target() {
        let (log, cam) = synthetic(0.8373, false);
        let rec = Recording {
            id: "r1",
            speed_mps: Some(0.5),
            log: &log,
            camera: &cam,
        };
        let out = process_recording(&rec, &BuildOptions::default()).unwrap();
        assert_eq!(out.len(), 1);
        let RunOutcome::Sample(s) = &out[0] else {
            panic!("rejected: {out:?}")
        };
        assert!(
            (s.clock_offset_s - 0.8373).abs() < 0.01,
            "offset {}",
            s.clock_offset_s
        );
        assert!((s.target_m[0] - 1.5).abs() < 1e-6 && s.target_m[1].abs() < 1e-6);
        assert!((s.path_length_m - 1.5).abs() < 1e-6);
        assert!((s.raw_end_m[0] - 1.5).abs() < 0.012);
        assert_eq!(s.inputs.len(), N_INPUTS);
        assert_eq!(s.inputs[16], s.odometry.t_b());
        assert!(s.alignment_residual_mps < 0.05);
        assert!(s.speed_mps == 0.5 && s.speed_commanded);
        let f = features_from_log(&log, &RobotParams::default()).unwrap();
        assert_eq!(f.inputs.to_vec(), s.inputs);
    }

    /// An id with a comma, quote or line break used to shift every column after it.
    #[test]
    fn samples_csv_quotes_awkward_run_ids() {
        let (log, cam) = synthetic(0.8373, false);
        let ids = ["run 1, slow", "say \"hi\"", "two\nlines", "run004"];
        let samples: Vec<Sample> = ids
            .iter()
            .map(|id| {
                let rec = Recording {
                    id,
                    speed_mps: Some(0.5),
                    log: &log,
                    camera: &cam,
                };
                match process_recording(&rec, &BuildOptions::default())
                    .unwrap()
                    .remove(0)
                {
                    RunOutcome::Sample(s) => *s,
                    RunOutcome::Rejected(r) => panic!("rejected: {r:?}"),
                }
            })
            .collect();
        let ds = Dataset::new(RobotParams::default(), samples, Vec::new(), ids.len());
        let text = samples_csv(&ds);
        let mut rd = csv::Reader::from_reader(text.as_bytes());
        let width = rd.headers().unwrap().len();
        let rows: Vec<csv::StringRecord> = rd.records().map(|r| r.unwrap()).collect();
        assert_eq!(width, 27);
        assert_eq!(rows.len(), ids.len());
        for (row, (id, smp)) in rows.iter().zip(ids.iter().zip(&ds.samples)) {
            assert_eq!(row.len(), width);
            assert_eq!(&row[0], *id);
            assert_eq!(row[2].parse::<f64>().unwrap(), smp.inputs[0]);
        }
        assert!(text.contains("\nrun004,0.5,"), "{text}");
    }

    #[test]
    fn the_target_carries_the_trajectory_sigma() {
        let (log, mut cam) = synthetic(0.8373, false);
        let rec = Recording {
            id: "r1",
            speed_mps: Some(0.5),
            log: &log,
            camera: &cam,
        };
        let out = process_recording(&rec, &BuildOptions::default()).unwrap();
        let RunOutcome::Sample(plain) = &out[0] else {
            panic!("rejected: {out:?}")
        };
        assert_eq!(plain.target_sigma_m, None, "truth without σ gives none");
        let plain_json = serde_json::to_string(&**plain).unwrap();
        drop(out);
        let sigma = PoseSigma {
            x_m: 0.001,
            y_m: 0.002,
            theta_rad: 0.003,
        };
        cam.rows.iter_mut().for_each(|r| r.sigma = Some(sigma));
        let rec = Recording {
            id: "r1",
            speed_mps: Some(0.5),
            log: &log,
            camera: &cam,
        };
        let out = process_recording(&rec, &BuildOptions::default()).unwrap();
        let RunOutcome::Sample(s) = &out[0] else {
            panic!("rejected: {out:?}")
        };
        // Start heading 0.3 rad, the run 1.5 m straight ahead: x along the run, y across.
        let [n0, n1] = s.rest_frames.map(|n| n as f64);
        let (c, sn) = (0.3f64.cos(), 0.3f64.sin());
        let vx = 1e-6 / n0 + 1e-6 / n1;
        let vy = 4e-6 / n0 + 4e-6 / n1;
        let ex = (c * c * vx + sn * sn * vy).sqrt();
        let ey = (sn * sn * vx + c * c * vy + (1.5 * 0.003 / n0.sqrt()).powi(2)).sqrt();
        let [sx, sy] = s.target_sigma_m.unwrap();
        assert!(
            (sx - ex).abs() < 1e-9 && (sy - ey).abs() < 1e-8,
            "{sx} {sy} vs {ex} {ey}"
        );
        let et = (9e-6 / n0 + 9e-6 / n1).sqrt();
        assert!((s.target_sigma_theta_rad.unwrap() - et).abs() < 1e-12);
        // Written and read back in dataset.json; absent when none.
        let json = serde_json::to_string(&**s).unwrap();
        assert!(json.contains("target_sigma_m"));
        assert!(!plain_json.contains("target_sigma"));
    }

    #[test]
    fn wheel_speed_logs_align_too() {
        // Speeds as a robot computes them from its (quantised) encoders, m/s per interval.
        let (ticks, cam) = synthetic(1.2345, false);
        let circ = std::f64::consts::PI * 0.043 / 12.0;
        let v: Vec<f64> = (0..ticks.len())
            .map(|k| {
                if k == 0 {
                    0.0
                } else {
                    (ticks.left[k] - ticks.left[k - 1]) * circ / 0.2
                }
            })
            .collect();
        let log = OdometryLog::from_speeds(ticks.t_s.clone(), v.clone(), v).unwrap();
        let rec = Recording {
            id: "s1",
            speed_mps: None,
            log: &log,
            camera: &cam,
        };
        let out = process_recording(&rec, &BuildOptions::default()).unwrap();
        let RunOutcome::Sample(s) = &out[0] else {
            panic!("rejected: {out:?}")
        };
        assert!(
            (s.clock_offset_s - 1.2345).abs() < 0.02,
            "offset {}",
            s.clock_offset_s
        );
        assert!((s.target_m[0] - 1.5).abs() < 1e-6);
        assert!((s.odometry_speed_mps - 0.5).abs() < 0.05);
        // No speed in the manifest: the odometry's stands in, marked as no command.
        assert_eq!(s.speed_mps, s.odometry_speed_mps);
        assert!(!s.speed_commanded);
    }

    #[test]
    fn robot_params_file_round_trips() {
        let dir = std::env::temp_dir().join(format!("odocal-robot-{}", std::process::id()));
        let r = RobotParams {
            wheel_base_m: 0.11,
            ..RobotParams::default()
        };
        std::fs::write(&dir, r.to_json()).unwrap();
        assert_eq!(RobotParams::read(&dir).unwrap(), r);
        std::fs::write(&dir, r#"{"format":"odocal.robot/1","wheel_diameter_m":-1,"ticks_per_rev":12,"wheel_base_m":0.1,"period_s":0.2}"#).unwrap();
        assert!(RobotParams::read(&dir)
            .unwrap_err()
            .to_string()
            .contains("positive"));
        // A wheel base a tenth of the e-puck-like robot's, or wheels given in decimetres.
        for (base, diameter, want) in [
            (0.01, 0.043, "less than half the wheel diameter"),
            (0.053, 0.0043, "smallest robot wheels"),
        ] {
            let r = RobotParams {
                wheel_base_m: base,
                wheel_diameter_m: diameter,
                ..RobotParams::default()
            };
            std::fs::write(&dir, r.to_json()).unwrap();
            let e = RobotParams::read(&dir).unwrap_err().to_string();
            assert!(e.contains(want), "{e}");
        }
        let _ = std::fs::remove_file(&dir);
    }

    /// The runs' samples of a recording, or a panic naming the rejections.
    fn samples(log: &OdometryLog, cam: &Trajectory) -> Vec<Sample> {
        let rec = Recording {
            id: "r",
            speed_mps: None,
            log,
            camera: cam,
        };
        process_recording(&rec, &BuildOptions::default())
            .unwrap()
            .into_iter()
            .map(|o| match o {
                RunOutcome::Sample(s) => *s,
                RunOutcome::Rejected(r) => panic!("rejected: {r:?}"),
            })
            .collect()
    }

    fn counts(v: &[f64], sign: f64) -> Vec<i64> {
        v.iter().map(|&c| (sign * c) as i64).collect()
    }

    /// The robot facing the other way (heading + π) and its wheels turning backwards (left
    /// and right change sides): the same path driven backwards. The speeds were compared
    /// unsigned, so the wheels' negative speed matched no camera offset ("correlation 0.50",
    /// "fits two clock offsets"), and every such run was rejected.
    #[test]
    fn a_run_driven_backwards_is_a_backward_run() {
        let (log, mut cam) = synthetic(0.8373, false);
        let log = OdometryLog::from_ticks(
            log.t_s.clone(),
            counts(&log.right, -1.0),
            counts(&log.left, -1.0),
        )
        .unwrap();
        cam.rows
            .iter_mut()
            .for_each(|r| r.pose.theta_rad = wrap_angle(r.pose.theta_rad + std::f64::consts::PI));
        let [s] = &samples(&log, &cam)[..] else {
            panic!("one run")
        };
        assert!(
            (s.clock_offset_s - 0.8373).abs() < 0.01,
            "{}",
            s.clock_offset_s
        );
        assert!(
            (s.target_m[0] + 1.5).abs() < 1e-6 && s.target_m[1].abs() < 1e-6,
            "{:?}",
            s.target_m
        );
        assert!((s.raw_end_m[0] + 1.5).abs() < 0.012, "{:?}", s.raw_end_m);
    }

    /// A run driven forwards, then back along the same path in reverse (still facing
    /// forwards), one clock offset for both. Compared unsigned, the legs' speeds matched at
    /// no offset here (correlation 0.49); in a user's recordings the forward leg matched the
    /// camera's return 12 s off, its target pointing back to the start.
    #[test]
    fn there_and_back_legs_align_each_with_its_own_direction() {
        let offset = 0.8373;
        let (log, cam) = synthetic(offset, false);
        let t_end = log.t_s[log.len() - 1];
        let mirror = |v: &[f64]| -> Vec<f64> {
            v.iter()
                .copied()
                .chain(v.iter().rev().skip(1).copied())
                .collect()
        };
        let t: Vec<f64> = log
            .t_s
            .iter()
            .copied()
            .chain(log.t_s.iter().rev().skip(1).map(|&t| 2.0 * t_end - t))
            .collect();
        let log = OdometryLog::from_ticks(
            t,
            counts(&mirror(&log.left), 1.0),
            counts(&mirror(&log.right), 1.0),
        )
        .unwrap();
        // The camera's clock mirrored about the log's last row, so the offset stays.
        let turn_s = t_end + offset;
        let there: Vec<TrajectoryRow> = cam.rows.into_iter().filter(|r| r.t_s < turn_s).collect();
        let back = there.iter().rev().map(|r| TrajectoryRow {
            t_s: 2.0 * turn_s - r.t_s,
            ..*r
        });
        let cam = Trajectory::new(there.iter().copied().chain(back).collect()).unwrap();
        let legs = samples(&log, &cam);
        assert_eq!(legs.len(), 2);
        for (s, x) in legs.iter().zip([1.5, -1.5]) {
            assert!(
                (s.clock_offset_s - offset).abs() < 0.01,
                "{}: {}",
                s.run_id,
                s.clock_offset_s
            );
            assert!(
                (s.target_m[0] - x).abs() < 1e-6 && s.target_m[1].abs() < 1e-6,
                "{}: {:?}",
                s.run_id,
                s.target_m
            );
            assert!((s.raw_end_m[0] - x).abs() < 0.012, "{:?}", s.raw_end_m);
        }
    }

    #[test]
    fn a_target_against_the_odometry_is_named() {
        assert!(against_odometry([1.46, 0.13], [1.50, 0.01]).is_none());
        assert!(against_odometry([-1.46, -0.13], [-1.50, -0.01]).is_none());
        let why = against_odometry([-1.455, 0.157], [1.497, 0.008]).unwrap();
        assert!(
            why.contains("(-1.455, 0.157) m from its start and the wheels at (1.497, 0.008) m"),
            "{why}"
        );
    }

    #[test]
    fn unusable_runs_are_rejected_and_mismatches_fail() {
        let (log, cam) = synthetic(0.5, true);
        let rec = Recording {
            id: "r2",
            speed_mps: None,
            log: &log,
            camera: &cam,
        };
        let out = process_recording(&rec, &BuildOptions::default()).unwrap();
        match &out[..] {
            [RunOutcome::Rejected(r)] => assert!(r.reason.contains("ends during"), "{}", r.reason),
            o => panic!("{o:?}"),
        }
        assert!(features_from_log(&log, &RobotParams::default()).is_err());
        // A camera trajectory far too short for the log's motion cannot overlap it.
        let (log, cam) = synthetic(0.5, false);
        let short = Trajectory::new(cam.rows[..20].to_vec()).unwrap();
        let rec = Recording {
            id: "r3",
            speed_mps: None,
            log: &log,
            camera: &short,
        };
        let e = process_recording(&rec, &BuildOptions::default()).unwrap_err();
        assert!(e.to_string().contains("cannot overlap"), "{e}");
    }
}
