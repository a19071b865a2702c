//! Time alignment of a robot's odometry log with a camera trajectory.
//!
//! The clock offset (t_camera = t_robot + offset) is found in two steps:
//! 1. coarse: normalised cross-correlation of the speed profiles (odometry speed per log
//!    interval against the camera's speed over the same interval shifted by the lag, both
//!    signed, negative backwards, so that driving a path and back never matches), on a
//!    10 ms lag grid over every lag at which the log's motion lies inside the trajectory (or,
//!    when none matches, at which the camera sees most of it), with parabolic interpolation of
//!    the peak;
//! 2. fine, per run: each wheel's reading at each log row is compared with that wheel's travel
//!    seen by the camera at the shifted time (forward travel of the tag along its own heading,
//!    ∓ b/2 times the heading change), the camera positions being interpolated between frames
//!    so the offset is continuous (sub-frame). Tick logs are quantised: a reading n says the
//!    true count lay in [n, n + 1), so the fit of counts = a + b p (p = wheel travel, a absorbs
//!    the unknown sub-count phase, b the scale) penalises only
//!    departures from those intervals (squared hinge), and the offset is the mean of the
//!    resulting likelihood over a 1 ms scan (quantisation leaves a flat feasible range; a
//!    least-squares fit to mid-counts would be pulled by the shared phase error of the rest
//!    rows). Wheel-speed logs use a least-squares fit (a + b p + c p², c for slow slip) and
//!    its minimum. With 12 counts/rev and 200 ms rows the offset of a slow run is known to a
//!    few milliseconds only: timing information comes from the start and stop transitions.
//!
//! Residuals are reported in metres (travel fit) and m/s (speed per log interval).

use nalgebra::{Matrix2, Matrix3, Vector2, Vector3};
use odocal_core::{wrap_angle, Pose2};

use crate::error::DatasetError;
use crate::kinematics::WheelGeometry;
use crate::odometry::{LogKind, OdometryLog, WheelRevs};
use crate::segment::RunSegment;
use crate::RobotParams;
use odocal_core::Trajectory;

/// Settings of the time alignment.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AlignOptions {
    /// Longest gap between camera frames bridged by interpolation, seconds, for a camera of
    /// 30 frames/s or faster; slower trajectories get more (see [`AlignOptions::frame_gap_s`]).
    pub max_frame_gap_s: f64,
    /// Lag grid step of the coarse cross-correlation, seconds.
    pub coarse_step_s: f64,
    /// Half width of the fine search around the coarse offset, seconds.
    pub refine_half_width_s: f64,
    /// Smallest acceptable speed-profile correlation.
    pub min_correlation: f64,
}

impl Default for AlignOptions {
    fn default() -> Self {
        Self {
            max_frame_gap_s: 0.15,
            coarse_step_s: 0.01,
            refine_half_width_s: 0.15,
            min_correlation: 0.8,
        }
    }
}

/// A trajectory's gap bridged by interpolation, in multiples of its median row spacing.
const FRAME_GAP_PER_SPACING: f64 = 2.5;

impl AlignOptions {
    /// Longest gap between `traj`'s rows bridged by interpolation, seconds: at least
    /// `max_frame_gap_s`, and [`FRAME_GAP_PER_SPACING`] times its median row spacing, so that
    /// one missed scan of a 10 Hz laser (a 0.2 s gap) or a 5 frames/s camera's every frame is
    /// not taken for the robot leaving the camera's view.
    pub fn frame_gap_s(&self, traj: &Trajectory) -> f64 {
        let own = traj
            .median_spacing_s()
            .filter(|s| s.is_finite())
            .map_or(0.0, |s| FRAME_GAP_PER_SPACING * s);
        self.max_frame_gap_s.max(own)
    }
}

/// Result of the coarse cross-correlation: the recording's clock map.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CoarseOffset {
    /// Clock offset, seconds: t_camera = offset + rate t_robot.
    pub offset_s: f64,
    /// Peak normalised cross-correlation of the speed profiles.
    pub correlation: f64,
    /// Camera seconds per robot second: 1 unless [`clock_rate`] told another.
    pub rate: f64,
}

impl CoarseOffset {
    /// The camera-clock time of robot-clock time `t_robot_s`.
    pub fn camera_s(&self, t_robot_s: f64) -> f64 {
        self.offset_s + self.rate * t_robot_s
    }

    /// The clock offset (t_camera - t_robot) at robot-clock time `t_robot_s`: a clock running
    /// at another rate drifts.
    pub fn offset_at(&self, t_robot_s: f64) -> f64 {
        self.camera_s(t_robot_s) - t_robot_s
    }

    /// Why the log's times are no clock's: they run more than [`MAX_CLOCK_RATE`] fast or slow
    /// against the camera's.
    pub fn implausible_rate(&self) -> Option<String> {
        let fast = 1.0 / self.rate - 1.0;
        (fast.abs() > MAX_CLOCK_RATE).then(|| {
            format!(
                "the log's times run {:.1} % {} against the camera's (each of its seconds is {:.3} s of video), more than any clock is off ({:.0} %): are they stamped by a loop counter (t = row × period) while the loop takes another time? Log the robot's clock at each row",
                100.0 * fast.abs(),
                if fast > 0.0 { "fast" } else { "slow" },
                self.rate,
                100.0 * MAX_CLOCK_RATE
            )
        })
    }
}

/// Result of the fine alignment of one run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Alignment {
    /// Clock offset, seconds: t_camera = t_robot + offset.
    pub offset_s: f64,
    /// RMS residual of the travel fit, metres.
    pub residual_m: f64,
    /// RMS residual of the speed per log interval, m/s.
    pub residual_mps: f64,
    /// Log rows used.
    pub rows_used: usize,
}

/// Travel of a pose `a` to `b` along their mean heading, metres: negative when the robot
/// backs up.
pub(crate) fn forward_step(a: &Pose2, b: &Pose2) -> f64 {
    let mid = a.theta_rad + 0.5 * wrap_angle(b.theta_rad - a.theta_rad);
    (b.x_m - a.x_m) * mid.cos() + (b.y_m - a.y_m) * mid.sin()
}

/// The camera's signed speed between times `t0` and `t1` (m/s, negative backwards), as the
/// wheels' mean speed is signed: compared unsigned, a log's forward leg matched the camera's
/// drive back along the same path as well as its own, and a run driven backwards matched
/// nothing. None where the trajectory does not hold both times.
pub(crate) fn camera_speed(traj: &Trajectory, t0: f64, t1: f64, gap: f64) -> Option<f64> {
    let (a, b) = (traj.pose_at(t0, gap)?, traj.pose_at(t1, gap)?);
    Some(forward_step(&a, &b) / (t1 - t0))
}

/// Mean wheel travel per row, metres, with geometry `geom`.
fn travel(revs: &WheelRevs, geom: &WheelGeometry) -> Vec<f64> {
    let cl = std::f64::consts::PI * geom.left_wheel_diameter_m;
    let cr = std::f64::consts::PI * geom.right_wheel_diameter_m;
    revs.rev
        .iter()
        .map(|r| 0.5 * (r[0] * cl + r[1] * cr))
        .collect()
}

/// Shortest span over which the wheels' speed is compared with the camera's, seconds. One
/// tick of a 12-count encoder on 43 mm wheels is 11 mm: over a 200 ms period a 0.06 m/s
/// step of speed, over 50 ms a 0.22 m/s one, and every slow run logged at 50 ms was refused
/// (speed profiles correlating at 0.59) where the same runs at 200 ms correlate at 0.95.
const SPEED_SPAN_S: f64 = 0.2;

/// Log steps per speed compared: the whole number of `t`'s median steps nearest
/// [`SPEED_SPAN_S`]; one on a 200 ms log (a jittery one's 189 ms median too), four at 50 ms.
pub(crate) fn speed_span_steps(t: &[f64]) -> usize {
    let mut steps: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).collect();
    steps.sort_by(f64::total_cmp);
    match steps.get(steps.len() / 2) {
        Some(&m) if m > 0.0 => ((SPEED_SPAN_S / m).round() as usize).max(1),
        _ => 1,
    }
}

/// The wheels' mean speed over the `h` log intervals up to each row (the (k-1)-th ends at row
/// k), m/s on the robot's clock.
fn robot_speeds(revs: &WheelRevs, geom: &WheelGeometry, h: usize) -> Vec<f64> {
    let (r, t) = (travel(revs, geom), &revs.t_s);
    (1..r.len())
        .map(|k| {
            let j = k.saturating_sub(h);
            (r[k] - r[j]) / (t[k] - t[j])
        })
        .collect()
}

/// Smallest share of the log's motion (from its first moving interval to its last, rests
/// between runs included) that the trajectory's time span must hold at all; and, at an offset
/// where it does not hold the whole motion, the share of the shorter of the two (the motion,
/// the trajectory's span) over which they must overlap: more than half, so the speed profiles
/// compared are mostly the log's own and the camera's.
pub const MIN_PARTIAL_COVERAGE: f64 = 0.5;

/// Closest that two clock offsets matching a partly seen log may lie, seconds, and still be
/// one match: farther apart, the log fits the camera twice (runs alike in speed and rest)
/// and which runs the camera saw is a guess.
const DISTINCT_OFFSETS_S: f64 = 1.0;

/// Share of the moving intervals the best partial match sees that another match must see to
/// explain the camera as well: runs alike in speed and rest, one run apart, are seen alike
/// (a count or two apart as their rows fall); a match that leaves one of two runs the camera
/// saw beyond the log's ends sees half.
const ALIKE_SEEN_SHARE: f64 = 0.9;

/// Coarse clock offset of a whole log by speed-profile cross-correlation.
///
/// Offsets that put the log's whole motion inside the trajectory come first, as the
/// reference experiment records them. Only when none of them correlates at
/// `opts.min_correlation` (a camera started late or stopped early, or frames missed during a
/// run) are offsets searched where the trajectory's span and the motion overlap over more
/// than [`MIN_PARTIAL_COVERAGE`] of the shorter and the camera sees at least half of the
/// moving intervals there; of the offsets that correlate, the one at which the camera sees
/// the most moving intervals is taken, and the runs it did not see are then the caller's to
/// reject.
///
/// Fails with [`DatasetError::Mismatch`] when the trajectory is too short to hold most of the
/// log's motion at any offset (another recording's file), and with
/// [`DatasetError::NoClockOffset`] when it could but the camera saw too little of the motion
/// at every offset, or a partly seen log fits it at two offsets (a reason for the recording's
/// runs, which names no recording); `what` names the pair in the hard errors.
pub fn coarse_offset(
    log: &OdometryLog,
    revs: &WheelRevs,
    geom: &WheelGeometry,
    traj: &Trajectory,
    opts: &AlignOptions,
    what: &str,
) -> Result<CoarseOffset, DatasetError> {
    let n = log.len();
    let moving: Vec<usize> = (1..n).filter(|&i| log.moving_at(i)).collect();
    let (Some(&m0), Some(&m1)) = (moving.first(), moving.last()) else {
        return Err(DatasetError::Mismatch(format!(
            "{what}: the odometry log shows no motion"
        )));
    };
    if traj.rows.len() < 2 {
        return Err(DatasetError::Mismatch(format!(
            "{what}: the trajectory has {} (a camera trajectory needs a row per frame the robot was seen in)",
            match traj.rows.len() {
                0 => "no rows".to_string(),
                _ => format!("only one row, at {:.2} s", traj.start_s()),
            }
        )));
    }
    let t = &revs.t_s;
    let (c0, c1) = (traj.start_s(), traj.end_s());
    let motion_s = t[m1] - t[m0 - 1];
    if c1 - c0 <= MIN_PARTIAL_COVERAGE * motion_s {
        return Err(DatasetError::Mismatch(format!(
            "{what}: the log moves for {motion_s:.2} s but the trajectory spans only {:.2} s: they cannot overlap over half the motion, so it is not this log's recording \
             (check that the manifest pairs the right log and video/trajectory)",
            (c1 - c0).max(0.0)
        )));
    }
    let h = speed_span_steps(t);
    let v_robot = robot_speeds(revs, geom, h);
    let first = m0.saturating_sub(5).max(1);
    let last = (m1 + 5).min(n - 1);
    let mut a = Vec::with_capacity(last - first + 1);
    let mut b = Vec::with_capacity(last - first + 1);
    // The speed-profile correlation at one lag, the moving log intervals the camera sees
    // there, and those inside the trajectory's span.
    let gap = opts.frame_gap_s(traj);
    let mut score_at = |lag: f64| -> (f64, usize, usize) {
        a.clear();
        b.clear();
        let inside = moving
            .iter()
            .filter(|&&k| t[k - 1] + lag >= c0 && t[k] + lag <= c1)
            .count();
        let mut moving_ok = 0;
        for k in first..=last {
            let Some(v) = camera_speed(traj, t[k.saturating_sub(h)] + lag, t[k] + lag, gap) else {
                continue;
            };
            if log.moving_at(k) {
                moving_ok += 1;
            }
            a.push(v_robot[k - 1]);
            b.push(v);
        }
        let score = if a.len() < 3 {
            f64::NEG_INFINITY
        } else {
            ncc(&a, &b)
        };
        (score, moving_ok, inside)
    };
    // The whole motion inside the trajectory, most of its moving intervals seen.
    let need = (moving.len() * 4).div_ceil(5);
    let lo = c0 - t[m0 - 1];
    let hi = c1 - t[m1];
    let whole = (hi >= lo).then(|| {
        let steps = ((hi - lo) / opts.coarse_step_s).floor() as usize;
        let scores: Vec<f64> = (0..=steps)
            .map(|j| {
                let (s, moving_ok, _) = score_at(lo + j as f64 * opts.coarse_step_s);
                if moving_ok < need {
                    f64::NEG_INFINITY
                } else {
                    s
                }
            })
            .collect();
        peak(&scores, lo, opts.coarse_step_s)
    });
    if let Some(Some(c)) = whole {
        if c.correlation >= opts.min_correlation {
            return Ok(c);
        }
    }
    // Part of the motion outside the trajectory or unseen: lags at which the trajectory and
    // the log's motion overlap over most of the shorter of the two, and the camera sees most
    // of the moving intervals there. Measured against the motion alone, a camera that saw two
    // of four runs whole (the rests between them counted as motion) was held to see too
    // little at its own offset, and every run was refused.
    let lo = c0 - t[m1];
    let steps = ((c1 - t[m0 - 1] - lo) / opts.coarse_step_s).floor() as usize;
    let overlap_needed_s = MIN_PARTIAL_COVERAGE * motion_s.min(c1 - c0);
    let (mut best_seen, mut scores) = (0, Vec::with_capacity(steps + 1));
    let mut seen = Vec::with_capacity(steps + 1);
    for j in 0..=steps {
        let lag = lo + j as f64 * opts.coarse_step_s;
        let held = (t[m1] + lag).min(c1) - (t[m0 - 1] + lag).max(c0);
        if held <= overlap_needed_s {
            scores.push(f64::NEG_INFINITY);
            seen.push(0);
            continue;
        }
        let (s, moving_ok, inside) = score_at(lag);
        best_seen = best_seen.max(moving_ok);
        seen.push(moving_ok);
        scores.push(if 2 * moving_ok >= inside.max(1) {
            s
        } else {
            f64::NEG_INFINITY
        });
    }
    let matches = match_peaks(&scores, opts.min_correlation);
    // The match that explains most of the log's motion: one that sees fewer of its moving
    // intervals leaves camera motion unexplained (beyond the log's ends).
    let most_seen = matches
        .iter()
        .copied()
        .max_by(|&i, &j| seen[i].cmp(&seen[j]).then(scores[i].total_cmp(&scores[j])));
    if let Some(jp) = most_seen {
        let p = refined_peak(&scores, jp, lo, opts.coarse_step_s);
        let lag_of = |j: usize| lo + j as f64 * opts.coarse_step_s;
        let other = matches.iter().copied().find(|&j| {
            (lag_of(j) - p.offset_s).abs() >= DISTINCT_OFFSETS_S
                && seen[j] as f64 >= ALIKE_SEEN_SHARE * seen[jp] as f64
        });
        if let Some(jq) = other {
            let part = |lag: f64| {
                let (a, b) = ((t[m0 - 1]).max(c0 - lag), t[m1].min(c1 - lag));
                format!("at {lag:.2} s the log's {a:.1}-{b:.1} s")
            };
            return Err(DatasetError::NoClockOffset(format!(
                "the camera saw only part of the log's motion, and it fits two clock offsets, {} and {} (runs alike in speed and rest); which runs the camera saw cannot be told",
                part(p.offset_s),
                part(lag_of(jq))
            )));
        }
        return Ok(rematch_near(traj, t, &v_robot, h, first..=last, p, opts));
    }
    match (whole.flatten(), peak(&scores, lo, opts.coarse_step_s)) {
        (Some(w), Some(p)) => Ok(if w.correlation >= p.correlation { w } else { p }),
        (Some(c), None) | (None, Some(c)) => Ok(c),
        (None, None) => Err(DatasetError::NoClockOffset(format!(
            "the camera sees at most {best_seen} of the log's {} moving intervals at any clock offset that puts most of the motion inside its trajectory (too many missed frames?)",
            moving.len()
        ))),
    }
}

/// A partial match `p` chosen again near itself on the log intervals `rows` that the camera
/// sees at every lag within half of [`DISTINCT_OFFSETS_S`]: the intervals compared change
/// with the lag as motion slips in and out of the camera's span, and dropping a run's start
/// or end can raise the score (the offset missed by 0.15 s with a camera that started 0.5 s
/// before a run). `p` itself when no lag there reaches the threshold.
fn rematch_near(
    traj: &Trajectory,
    t: &[f64],
    v_robot: &[f64],
    h: usize,
    rows: std::ops::RangeInclusive<usize>,
    p: CoarseOffset,
    opts: &AlignOptions,
) -> CoarseOffset {
    let near = 0.5 * DISTINCT_OFFSETS_S;
    let gap = opts.frame_gap_s(traj);
    let rows: Vec<usize> = rows
        .filter(|&k| traj.covers(t[k - 1] + p.offset_s - near, t[k] + p.offset_s + near, gap))
        .collect();
    best_lag(p.offset_s - near, near, opts.coarse_step_s, |lag, a, b| {
        for &k in &rows {
            if let Some(v) = camera_speed(traj, t[k.saturating_sub(h)] + lag, t[k] + lag, gap) {
                a.push(v_robot[k - 1]);
                b.push(v);
            }
        }
        true
    })
    .filter(|q| q.correlation >= opts.min_correlation)
    .unwrap_or(p)
}

/// The lag among `lo` + j `step` (up to `lo` + 2 `half`) at which the pairs `pair(lag, a, b)`
/// puts into `a` and `b` correlate best, refined as [`peak`] does; a lag scores nothing where
/// `pair` says too little was seen or fewer than 3 pairs were.
fn best_lag(
    lo: f64,
    half: f64,
    step: f64,
    mut pair: impl FnMut(f64, &mut Vec<f64>, &mut Vec<f64>) -> bool,
) -> Option<CoarseOffset> {
    let steps = (2.0 * half / step).round() as usize;
    let (mut a, mut b) = (Vec::new(), Vec::new());
    let scores: Vec<f64> = (0..=steps)
        .map(|j| {
            a.clear();
            b.clear();
            let enough = pair(lo + j as f64 * step, &mut a, &mut b);
            if !enough || a.len() < 3 {
                f64::NEG_INFINITY
            } else {
                ncc(&a, &b)
            }
        })
        .collect();
    peak(&scores, lo, step)
}

/// The best of `scores` (lags `lo` + j `step`), its lag refined on a parabola through its
/// neighbours; None when no lag was scored.
fn peak(scores: &[f64], lo: f64, step: f64) -> Option<CoarseOffset> {
    let (jbest, &best) = scores
        .iter()
        .enumerate()
        .max_by(|x, y| x.1.total_cmp(y.1))?;
    best.is_finite()
        .then(|| refined_peak(scores, jbest, lo, step))
}

/// The lag of `scores[j]` (lags `lo` + j `step`) refined on a parabola through its
/// neighbours, with its score.
fn refined_peak(scores: &[f64], j: usize, lo: f64, step: f64) -> CoarseOffset {
    let mut offset = lo + j as f64 * step;
    if j > 0 && j + 1 < scores.len() {
        let (ym, y0, yp) = (scores[j - 1], scores[j], scores[j + 1]);
        let den = ym - 2.0 * y0 + yp;
        if ym.is_finite() && yp.is_finite() && den < 0.0 {
            offset += 0.5 * (ym - yp) / den * step;
        }
    }
    CoarseOffset {
        offset_s: offset,
        correlation: scores[j],
        rate: 1.0,
    }
}

/// The best lag of each stretch of lags whose `scores` reach `min_correlation`: each stretch
/// is one way the log fits the camera.
fn match_peaks(scores: &[f64], min_correlation: f64) -> Vec<usize> {
    let mut peaks: Vec<usize> = Vec::new();
    let mut inside = false;
    for (j, &s) in scores.iter().enumerate() {
        let ok = s >= min_correlation;
        match peaks.last_mut() {
            Some(top) if ok && inside && s > scores[*top] => *top = j,
            _ if ok && !inside => peaks.push(j),
            _ => {}
        }
        inside = ok;
    }
    peaks
}

/// Robot-clock time each stretch of a rate fit spans, seconds: long enough that its starts,
/// stops and turns fix its own offset, short enough that a clock 2 % off drifts only 0.2 s
/// within it.
const RATE_STRETCH_S: f64 = 10.0;

/// Fewest stretches whose offsets tell a clock rate: fewer leave too little scatter about
/// their line to judge it by.
const MIN_RATE_STRETCHES: usize = 4;

/// Largest departure from the camera's rate that the stretches' offsets are searched for:
/// beyond [`MAX_CLOCK_RATE`], so that a clock running implausibly is found and named.
const SEARCH_RATE: f64 = 0.05;

/// Largest departure from the camera's clock rate a robot's clock plausibly has (a crystal
/// is off by 0.01 %, a clock adjusted by network time by less): beyond it the log's times are
/// not a clock's, such as a loop counter stamping t = k period while each loop takes longer.
pub const MAX_CLOCK_RATE: f64 = 0.02;

/// Departure from rate 1, in its σ, that a fitted rate must pass to be applied.
const RATE_TOLD_SIGMA: f64 = 3.0;

/// Drift over the stretches' span, seconds, that a fitted rate must pass to be applied: less
/// is within the few milliseconds the offset is known to, and would change the windows'
/// targets by noise alone.
const RATE_TOLD_DRIFT_S: f64 = 0.005;

/// A robot clock's rate against the camera's, from the offsets of stretches across a
/// recording.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ClockRate {
    /// Camera seconds per robot second.
    pub rate: f64,
    /// σ of `rate`, from the stretches' scatter about their line.
    pub sigma: f64,
    /// Robot-clock time between the first and last stretch's middles, seconds.
    pub span_s: f64,
}

impl ClockRate {
    /// Whether the rate departs from 1 by more than its scatter explains, and drifts the clock
    /// by more than the offset is known to over the recording.
    pub fn told(&self) -> bool {
        let d = (self.rate - 1.0).abs();
        d > RATE_TOLD_SIGMA * self.sigma && d * self.span_s > RATE_TOLD_DRIFT_S
    }
}

/// The robot clock's rate against the camera's, `coarse` being the recording's offset at
/// rate 1. Each stretch of [`RATE_STRETCH_S`] of the log's motion gets an offset of its own
/// by speed-profile correlation: first over every lag a rate up to [`SEARCH_RATE`] allows,
/// through which a line robust to a stretch matched elsewhere is drawn (Theil–Sen); then
/// within the fine search's half width of that line, the stretch's times scaled by its rate,
/// and the rate is the least-squares line through those. None when fewer than
/// [`MIN_RATE_STRETCHES`] stretches fit (a recording too short or too still to tell).
pub fn clock_rate(
    log: &OdometryLog,
    revs: &WheelRevs,
    geom: &WheelGeometry,
    traj: &Trajectory,
    opts: &AlignOptions,
    coarse: &CoarseOffset,
) -> Option<ClockRate> {
    let t = &revs.t_s;
    let circ = [
        std::f64::consts::PI * geom.left_wheel_diameter_m,
        std::f64::consts::PI * geom.right_wheel_diameter_m,
    ];
    // Each wheel's speed, so that turns in place time a stretch as well as its starts and
    // stops (the mean speed of a tour's turn is nil).
    // Over spans of a tick's worth of time, as the coarse offset compares speeds.
    let h = speed_span_steps(t);
    let v_wheels: Vec<[f64; 2]> = (1..t.len())
        .map(|k| {
            let j = k.saturating_sub(h);
            let dt = t[k] - t[j];
            [0, 1].map(|w| (revs.rev[k][w] - revs.rev[j][w]) * circ[w] / dt)
        })
        .collect();
    let moving: Vec<usize> = (1..log.len()).filter(|&i| log.moving_at(i)).collect();
    let (&m0, &m1) = (moving.first()?, moving.last()?);
    let per = ((m1 + 1 - m0) as f64 / ((t[m1] - t[m0 - 1]) / RATE_STRETCH_S).max(1.0)) as usize;
    let stretches: Vec<std::ops::Range<usize>> = (m0..=m1)
        .step_by(per.max(5))
        .map(|a| a..(a + per.max(5)).min(m1 + 1))
        .filter(|r| {
            2 * r.len() >= per && 4 * moving.iter().filter(|k| r.contains(k)).count() >= r.len()
        })
        .collect();
    if stretches.len() < MIN_RATE_STRETCHES {
        return None;
    }
    let mid = |r: &std::ops::Range<usize>| 0.5 * (t[r.start - 1] + t[r.end - 1]);
    let t_c = 0.5 * (t[m0 - 1] + t[m1]);
    let gap = opts.frame_gap_s(traj);
    let search = |r: &std::ops::Range<usize>, centre: f64, half: f64, rate: f64| {
        let clock = CoarseOffset {
            offset_s: centre,
            correlation: 0.0,
            rate,
        };
        let half_base = 0.5 * geom.wheel_base_m;
        stretch_offset(
            traj,
            t,
            &v_wheels,
            half_base,
            r.clone(),
            &clock,
            half,
            opts,
            gap,
            h,
        )
        .map(|o| (mid(r), o))
    };
    let wide: Vec<(f64, f64)> = stretches
        .iter()
        .filter_map(|r| {
            let half = opts.refine_half_width_s + SEARCH_RATE * (mid(r) - t_c).abs();
            search(r, coarse.offset_s, half, 1.0)
        })
        .collect();
    let (a, d) = theil_sen(&wide)?;
    let rate = 1.0 + d;
    let fine: Vec<(f64, f64)> = stretches
        .iter()
        .filter_map(|r| search(r, a, opts.refine_half_width_s, rate))
        .collect();
    if fine.len() < MIN_RATE_STRETCHES {
        return None;
    }
    let (d, sigma) = line_slope(&fine)?;
    Some(ClockRate {
        rate: rate + d,
        sigma,
        span_s: fine[fine.len() - 1].0 - fine[0].0,
    })
}

/// The offset of the log intervals `rows` (the k-th spans rows k - 1 to k) within `half` of
/// `clock`'s (its rate scaling their times) by the correlation of the wheels' speeds
/// `v_wheels` with those the camera sees (forward speed ∓ `half_base` times the turn rate);
/// None when it correlates below the threshold or at the edge of the search.
#[allow(clippy::too_many_arguments)]
fn stretch_offset(
    traj: &Trajectory,
    t: &[f64],
    v_wheels: &[[f64; 2]],
    half_base: f64,
    rows: std::ops::Range<usize>,
    clock: &CoarseOffset,
    half: f64,
    opts: &AlignOptions,
    gap: f64,
    h: usize,
) -> Option<f64> {
    let p = best_lag(
        clock.offset_s - half,
        half,
        opts.coarse_step_s,
        |lag, a, b| {
            for k in rows.clone() {
                let j = k.saturating_sub(h);
                let (t0, t1) = (lag + clock.rate * t[j], lag + clock.rate * t[k]);
                let (Some(p0), Some(p1)) = (traj.pose_at(t0, gap), traj.pose_at(t1, gap)) else {
                    continue;
                };
                let v = forward_step(&p0, &p1) / (t1 - t0);
                let turn = half_base * wrap_angle(p1.theta_rad - p0.theta_rad) / (t1 - t0);
                a.extend(v_wheels[k - 1]);
                b.extend([v - turn, v + turn]);
            }
            // Most of the stretch seen, so that its own motion decides.
            5 * a.len() >= 8 * rows.len()
        },
    )?;
    let inside = (p.offset_s - clock.offset_s).abs() < half - opts.coarse_step_s;
    (p.correlation >= opts.min_correlation && inside).then_some(p.offset_s)
}

/// Intercept and slope of a line through `points` (x, y), robust to a minority of outliers:
/// the median of the pairwise slopes, the median intercept at it.
fn theil_sen(points: &[(f64, f64)]) -> Option<(f64, f64)> {
    let mut slopes = Vec::new();
    for (i, p) in points.iter().enumerate() {
        for q in &points[i + 1..] {
            if q.0 != p.0 {
                slopes.push((q.1 - p.1) / (q.0 - p.0));
            }
        }
    }
    let d = median_of(slopes)?;
    let a = median_of(points.iter().map(|p| p.1 - d * p.0).collect())?;
    Some((a, d))
}

fn median_of(mut v: Vec<f64>) -> Option<f64> {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    (n > 0).then(|| 0.5 * (v[(n - 1) / 2] + v[n / 2]))
}

/// Least-squares slope of `points` (x, y) and its σ from their scatter about the line.
fn line_slope(points: &[(f64, f64)]) -> Option<(f64, f64)> {
    let n = points.len() as f64;
    let (mx, my) = (
        points.iter().map(|p| p.0).sum::<f64>() / n,
        points.iter().map(|p| p.1).sum::<f64>() / n,
    );
    let sxx: f64 = points.iter().map(|p| (p.0 - mx).powi(2)).sum();
    if points.len() < 3 || sxx <= 0.0 {
        return None;
    }
    let d = points.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum::<f64>() / sxx;
    let sse: f64 = points
        .iter()
        .map(|p| (p.1 - my - d * (p.0 - mx)).powi(2))
        .sum();
    Some((d, (sse / (n - 2.0) / sxx).sqrt()))
}

/// RMS difference, m/s, between each wheel's speed over the log steps of `rev` (revolutions
/// at robot times `t_s`) and that wheel's speed the camera sees over the same steps on
/// `clock` (forward travel ∓ half the base times the heading change). Aligned, it is the
/// encoders' quantisation and the nominal geometry's error; a fraction of a second off, the
/// robot's starts, stops and turns add to it. None where the camera misses a row's time.
pub(crate) fn wheel_speed_residual_mps(
    traj: &Trajectory,
    clock: &CoarseOffset,
    t_s: &[f64],
    rev: &[[f64; 2]],
    geom: &WheelGeometry,
    gap: f64,
) -> Option<f64> {
    let circ = [
        std::f64::consts::PI * geom.left_wheel_diameter_m,
        std::f64::consts::PI * geom.right_wheel_diameter_m,
    ];
    let poses = t_s
        .iter()
        .map(|&t| traj.pose_at(clock.camera_s(t), gap))
        .collect::<Option<Vec<Pose2>>>()?;
    let mut sq = Vec::with_capacity(2 * t_s.len());
    // Over spans of a tick's worth of time: at 50 ms one tick is a 0.22 m/s step of speed.
    let h = speed_span_steps(t_s);
    for k in h.min(t_s.len())..t_s.len() {
        let j = k - h;
        let dt = clock.rate * (t_s[k] - t_s[j]);
        // The camera's travel step by step, as the wheels' is summed over the span.
        let (mut ds, mut dth) = (0.0, 0.0);
        for i in j + 1..=k {
            ds += forward_step(&poses[i - 1], &poses[i]);
            dth += wrap_angle(poses[i].theta_rad - poses[i - 1].theta_rad);
        }
        let turn = 0.5 * geom.wheel_base_m * dth;
        for (w, cam) in [ds - turn, ds + turn].into_iter().enumerate() {
            let odo = (rev[k][w] - rev[j][w]) * circ[w];
            sq.push(((odo - cam) / dt).powi(2));
        }
    }
    (!sq.is_empty()).then(|| (sq.iter().sum::<f64>() / sq.len() as f64).sqrt())
}

/// Normalised cross-correlation (Pearson) of two equally long series.
fn ncc(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len() as f64;
    let ma = a.iter().sum::<f64>() / n;
    let mb = b.iter().sum::<f64>() / n;
    let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
    for (x, y) in a.iter().zip(b) {
        sab += (x - ma) * (y - mb);
        saa += (x - ma) * (x - ma);
        sbb += (y - mb) * (y - mb);
    }
    if saa <= 0.0 || sbb <= 0.0 {
        return 0.0;
    }
    sab / (saa * sbb).sqrt()
}

/// Camera-derived travel of one run: forward travel along the tag's heading and the heading
/// change, per frame, relative to the first frame of the window.
struct CameraPaths {
    t: Vec<f64>,
    s: Vec<f64>,
    th: Vec<f64>,
}

impl CameraPaths {
    fn build(traj: &Trajectory, t0: f64, t1: f64, max_gap: f64) -> Option<Self> {
        let rows = traj.rows_between(t0, t1);
        if rows.len() < 2 || rows[0].t_s > t0 + max_gap || rows[rows.len() - 1].t_s < t1 - max_gap {
            return None;
        }
        let mut out = CameraPaths {
            t: vec![rows[0].t_s],
            s: vec![0.0],
            th: vec![0.0],
        };
        for w in rows.windows(2) {
            if w[1].t_s - w[0].t_s > max_gap {
                return None;
            }
            let dth = wrap_angle(w[1].pose.theta_rad - w[0].pose.theta_rad);
            let ds = forward_step(&w[0].pose, &w[1].pose);
            let (s_prev, th_prev) = (out.s[out.s.len() - 1], out.th[out.th.len() - 1]);
            out.t.push(w[1].t_s);
            out.s.push(s_prev + ds);
            out.th.push(th_prev + dth);
        }
        Some(out)
    }

    /// (forward travel, heading change) at time t, linearly interpolated.
    fn at(&self, t: f64) -> Option<(f64, f64)> {
        let n = self.t.len();
        if !(t >= self.t[0] && t <= self.t[n - 1]) {
            return None;
        }
        let i = self
            .t
            .partition_point(|&x| x <= t)
            .saturating_sub(1)
            .min(n - 2);
        let w = (t - self.t[i]) / (self.t[i + 1] - self.t[i]);
        Some((
            self.s[i] + w * (self.s[i + 1] - self.s[i]),
            self.th[i] + w * (self.th[i + 1] - self.th[i]),
        ))
    }
}

/// Fine-alignment problem of one run.
struct Fine {
    t: Vec<f64>,
    /// Per wheel: readings in counts (tick logs) or metres (speed logs), relative to t_b.
    reading: [Vec<f64>; 2],
    cam: CameraPaths,
    half_base: f64,
    /// Run length for conditioning, metres.
    scale: f64,
    quantised: bool,
}

/// Least squares of y on the columns [1, p, p²]; returns the coefficients and the SSE.
fn ls_fit(p: &[f64], y: &[f64]) -> Option<(Vector3<f64>, f64)> {
    let mut m = Matrix3::zeros();
    let mut v = Vector3::zeros();
    for (&pk, &yk) in p.iter().zip(y) {
        let f = Vector3::new(1.0, pk, pk * pk);
        m += f * f.transpose();
        v += f * yk;
    }
    let c = m.lu().solve(&v)?;
    let sse = p
        .iter()
        .zip(y)
        .map(|(&pk, &yk)| (yk - c[0] - c[1] * pk - c[2] * pk * pk).powi(2))
        .sum();
    Some((c, sse))
}

/// Squared departure of x from the interval [n, n + 1) and its signed value.
fn hinge(x: f64, n: f64) -> f64 {
    if x < n {
        x - n
    } else if x > n + 1.0 {
        x - n - 1.0
    } else {
        0.0
    }
}

/// Smallest sum of squared departures of counts = a + b p from the reading intervals.
fn hinge_fit(p: &[f64], n: &[f64]) -> Option<f64> {
    let feat = |pk: f64| Vector2::new(1.0, pk);
    // Start from the least-squares line through the interval midpoints.
    let mut m = Matrix2::zeros();
    let mut v = Vector2::zeros();
    for (&pk, &nk) in p.iter().zip(n) {
        m += feat(pk) * feat(pk).transpose();
        v += feat(pk) * (nk + 0.5);
    }
    let mut c = m.lu().solve(&v)?;
    let cost = |c: &Vector2<f64>| -> f64 {
        p.iter()
            .zip(n)
            .map(|(&pk, &nk)| hinge(c.dot(&feat(pk)), nk).powi(2))
            .sum()
    };
    let mut cur = cost(&c);
    for _ in 0..40 {
        if cur == 0.0 {
            break;
        }
        let mut m = Matrix2::zeros();
        let mut g = Vector2::zeros();
        for (&pk, &nk) in p.iter().zip(n) {
            let f = feat(pk);
            let r = hinge(c.dot(&f), nk);
            if r != 0.0 {
                m += f * f.transpose();
                g += f * r;
            }
        }
        let ridge = 1e-9 * (m.trace() + 1.0);
        let Some(step) = (m + Matrix2::identity() * ridge).lu().solve(&(-g)) else {
            break;
        };
        let mut lam = 1.0;
        let mut improved = false;
        for _ in 0..20 {
            let trial = c + step * lam;
            let tc = cost(&trial);
            if tc < cur {
                improved = cur - tc > 1e-12 * (1.0 + cur);
                c = trial;
                cur = tc;
                break;
            }
            lam *= 0.5;
        }
        if !improved {
            break;
        }
    }
    Some(cur)
}

impl Fine {
    /// Per-wheel camera travel (left, right) at each row for an offset, in run lengths.
    fn paths(&self, offset: f64) -> Option<[Vec<f64>; 2]> {
        let mut l = Vec::with_capacity(self.t.len());
        let mut r = Vec::with_capacity(self.t.len());
        for &tk in &self.t {
            let (s, th) = self.cam.at(tk + offset)?;
            l.push((s - self.half_base * th) / self.scale);
            r.push((s + self.half_base * th) / self.scale);
        }
        Some([l, r])
    }

    /// Alignment cost at an offset: hinge cost in counts² (tick logs) or LS SSE in m² (speeds).
    fn cost(&self, offset: f64) -> f64 {
        let Some(p) = self.paths(offset) else {
            return f64::INFINITY;
        };
        let mut total = 0.0;
        for (pw, rw) in p.iter().zip(&self.reading) {
            let c = if self.quantised {
                hinge_fit(pw, rw)
            } else {
                ls_fit(pw, rw).map(|f| f.1)
            };
            match c {
                Some(c) => total += c,
                None => return f64::INFINITY,
            }
        }
        total
    }
}

/// Spread of the quantisation-interval likelihood, counts (camera noise and slip wander).
const HINGE_SIGMA_COUNTS: f64 = 0.3;

/// Fine clock offset of one run around a coarse offset; Err gives the reason the run is unusable.
#[allow(clippy::too_many_arguments)]
pub fn refine_offset(
    log: &OdometryLog,
    revs: &WheelRevs,
    seg: &RunSegment,
    robot: &RobotParams,
    traj: &Trajectory,
    coarse_s: f64,
    opts: &AlignOptions,
) -> Result<Alignment, String> {
    let hw = opts.refine_half_width_s;
    let gap = opts.frame_gap_s(traj);
    let geom = WheelGeometry::nominal(robot);
    let first = seg.start_row.saturating_sub(2).max(seg.window_first);
    let last = (seg.end_row + 2).min(seg.window_last);
    let ok = |k: usize| {
        traj.covers(
            revs.t_s[k] + coarse_s - hw - 0.05,
            revs.t_s[k] + coarse_s + hw + 0.05,
            gap,
        )
    };
    if !ok(seg.start_row) || !ok(seg.end_row) {
        return Err("the camera trajectory does not cover the start and end of the run".into());
    }
    // Rows at both ends whose camera window is covered; the span between must be covered too.
    let first = (first..=seg.start_row)
        .find(|&k| ok(k))
        .unwrap_or(seg.start_row);
    let last = (seg.end_row..=last)
        .rev()
        .find(|&k| ok(k))
        .unwrap_or(seg.end_row);
    let Some(cam) = CameraPaths::build(
        traj,
        revs.t_s[first] + coarse_s - hw - 0.05,
        revs.t_s[last] + coarse_s + hw + 0.05,
        gap,
    ) else {
        return Err(
            "the camera misses frames during the run (gap longer than the allowed maximum)".into(),
        );
    };
    let (Some(a), Some(b)) = (
        cam.at(revs.t_s[seg.start_row] + coarse_s),
        cam.at(revs.t_s[seg.end_row] + coarse_s),
    ) else {
        return Err("the camera trajectory does not cover the start and end of the run".into());
    };
    let len = (b.0 - a.0).abs();
    if len < 0.01 {
        return Err(format!(
            "the camera sees no motion during the run ({:.1} mm)",
            len * 1e3
        ));
    }
    let rows: Vec<usize> = (first..=last).collect();
    let quantised = log.kind == LogKind::Ticks;
    let circ = [
        std::f64::consts::PI * geom.left_wheel_diameter_m,
        std::f64::consts::PI * geom.right_wheel_diameter_m,
    ];
    let reading = |w: usize| -> Vec<f64> {
        rows.iter()
            .map(|&k| {
                let r = revs.rev[k][w] - revs.rev[seg.start_row][w];
                if quantised {
                    (r * robot.ticks_per_rev).round()
                } else {
                    r * circ[w] / len
                }
            })
            .collect()
    };
    let fine = Fine {
        t: rows.iter().map(|&k| revs.t_s[k]).collect(),
        reading: [reading(0), reading(1)],
        cam,
        half_base: 0.5 * geom.wheel_base_m,
        scale: len,
        quantised,
    };
    let step = 0.001;
    let n = (2.0 * hw / step).round() as usize;
    let grid: Vec<f64> = (0..=n).map(|j| coarse_s - hw + j as f64 * step).collect();
    let costs: Vec<f64> = grid.iter().map(|&o| fine.cost(o)).collect();
    let (jmin, &cmin) = costs
        .iter()
        .enumerate()
        .min_by(|x, y| x.1.total_cmp(y.1))
        .unwrap_or((0, &f64::INFINITY));
    if !cmin.is_finite() {
        return Err("the travel fit failed (degenerate camera motion)".into());
    }
    let offset = if quantised {
        let s2 = 2.0 * HINGE_SIGMA_COUNTS * HINGE_SIGMA_COUNTS;
        let (mut sw, mut swx) = (0.0, 0.0);
        for (&o, &c) in grid.iter().zip(&costs) {
            if c.is_finite() {
                let w = (-(c - cmin) / s2).exp();
                sw += w;
                swx += w * o;
            }
        }
        swx / sw
    } else {
        golden(|o| fine.cost(o), grid[jmin] - step, grid[jmin] + step)
    };
    if (offset - coarse_s).abs() > hw - 2.0 * step {
        return Err(format!(
            "the fine offset {offset:.3} s runs to the edge of the search around the coarse {coarse_s:.3} s"
        ));
    }
    // Residuals of the mean-wheel travel fit at the chosen offset (metres, m/s).
    let Some(p) = fine.paths(offset) else {
        return Err("the camera trajectory does not cover the start and end of the run".into());
    };
    let pm: Vec<f64> = p[0].iter().zip(&p[1]).map(|(a, b)| 0.5 * (a + b)).collect();
    let rm: Vec<f64> = rows
        .iter()
        .map(|&k| {
            let d = [
                revs.rev[k][0] - revs.rev[seg.start_row][0],
                revs.rev[k][1] - revs.rev[seg.start_row][1],
            ];
            0.5 * (d[0] * circ[0] + d[1] * circ[1]) / len
        })
        .collect();
    let Some((c, sse)) = ls_fit(&pm, &rm) else {
        return Err("the travel fit failed (degenerate camera motion)".into());
    };
    let model: Vec<f64> = pm.iter().map(|&x| c[0] + c[1] * x + c[2] * x * x).collect();
    // Speeds over spans of a tick's worth of time, as the coarse offset compares them.
    let h = speed_span_steps(&fine.t);
    let mut sq = 0.0;
    for k in h.min(fine.t.len())..fine.t.len() {
        let dt = fine.t[k] - fine.t[k - h];
        let e = ((rm[k] - rm[k - h]) - (model[k] - model[k - h])) * len / dt;
        sq += e * e;
    }
    Ok(Alignment {
        offset_s: offset,
        residual_m: (sse / fine.t.len() as f64).sqrt() * len,
        residual_mps: (sq / fine.t.len().saturating_sub(h).max(1) as f64).sqrt(),
        rows_used: fine.t.len(),
    })
}

/// Golden-section minimum of f on [a, b].
fn golden(f: impl Fn(f64) -> f64, mut a: f64, mut b: f64) -> f64 {
    let g = 0.5 * (5f64.sqrt() - 1.0);
    let mut x1 = b - g * (b - a);
    let mut x2 = a + g * (b - a);
    let (mut f1, mut f2) = (f(x1), f(x2));
    while b - a > 1e-6 {
        if f1 < f2 {
            b = x2;
            x2 = x1;
            f2 = f1;
            x1 = b - g * (b - a);
            f1 = f(x1);
        } else {
            a = x1;
            x1 = x2;
            f1 = f2;
            x2 = a + g * (b - a);
            f2 = f(x2);
        }
    }
    0.5 * (a + b)
}
