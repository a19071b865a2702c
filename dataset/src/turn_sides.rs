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

/// Log steps are compared over spans of at least this long, seconds: over one 200 ms step a
/// 12-count encoder's turn is a tick's 6° or nothing, over a second it follows the heading.
const EVIDENCE_SPAN_S: f64 = 1.0;

/// The pooled correlation of the wheels' turns with the camera's below which a dataset's
/// floor frame is taken for mirrored, and the least significance (correlation times the
/// square root of the spans compared) it must carry. A robot's own straight runs give +0.44
/// over 40 runs (the synthetic robot's PI loop keeps its encoders level, so its small turns
/// are what is left of it), a mirrored frame −0.44; spans of noise alone give ±1/√n.
const MIRRORED_CORRELATION: f64 = -0.2;
const MIRRORED_SIGNIFICANCE: f64 = 4.0;

/// The small turns of a recording's log against its camera's, over spans of about a second
/// while the robot moves, each side's steady drift per metre (a wheel's diameter error turns
/// a straight run one way throughout) taken out: sums to pool over a dataset, whose
/// correlation says whether the two turn the same way. A straight run turns a few degrees,
/// too little for [`turn_mismatch`] to judge on its own, but a mirrored floor frame turns
/// every run's camera heading against its wheels.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct TurnEvidence {
    sxy: f64,
    sxx: f64,
    syy: f64,
    /// Spans compared.
    pub n: usize,
}

impl TurnEvidence {
    /// The evidence of one recording, with the clocks `coarse` apart (none when the offset is
    /// not sure).
    pub fn of(
        log: &OdometryLog,
        camera: &Trajectory,
        robot: &RobotParams,
        align: &AlignOptions,
        coarse: &CoarseOffset,
    ) -> Self {
        if coarse.correlation < align.min_correlation {
            return Self::default();
        }
        let geom = WheelGeometry::nominal(robot);
        let revs = log.wheel_revs(robot);
        let circ = [
            std::f64::consts::PI * geom.left_wheel_diameter_m,
            std::f64::consts::PI * geom.right_wheel_diameter_m,
        ];
        let gap = align.frame_gap_s(camera);
        let span = ((EVIDENCE_SPAN_S / robot.period_s).ceil() as usize).max(1);
        // (odometry turn, camera turn, distance) per span.
        let mut spans: Vec<[f64; 3]> = Vec::new();
        let mut k = span;
        while k < revs.t_s.len() {
            let (i, j) = (k - span, k);
            k += span;
            let at = |i: usize| camera.pose_at(coarse.camera_s(revs.t_s[i]), gap);
            let (Some(a), Some(b)) = (at(i), at(j)) else {
                continue;
            };
            let d = |w: usize| (revs.rev[j][w] - revs.rev[i][w]) * circ[w];
            let ds = 0.5 * (d(0) + d(1));
            if ds.abs() < 1e-9 {
                continue;
            }
            let odo = (d(1) - d(0)) / geom.wheel_base_m;
            spans.push([odo, wrap_angle(b.theta_rad - a.theta_rad), ds]);
        }
        let dd: f64 = spans.iter().map(|s| s[2] * s[2]).sum();
        if dd <= 0.0 {
            return Self::default();
        }
        let drift = |c: usize| spans.iter().map(|s| s[c] * s[2]).sum::<f64>() / dd;
        let (drift_odo, drift_cam) = (drift(0), drift(1));
        let mut e = Self::default();
        for s in &spans {
            let (x, y) = (s[0] - drift_odo * s[2], s[1] - drift_cam * s[2]);
            e.sxy += x * y;
            e.sxx += x * x;
            e.syy += y * y;
        }
        e.n = spans.len();
        e
    }

    /// The evidence of both.
    pub fn add(&mut self, other: &Self) {
        self.sxy += other.sxy;
        self.sxx += other.sxx;
        self.syy += other.syy;
        self.n += other.n;
    }

    /// The correlation of the wheels' turns with the camera's; `None` when either never turned.
    pub fn correlation(&self) -> Option<f64> {
        (self.sxx > 0.0 && self.syy > 0.0).then(|| self.sxy / (self.sxx * self.syy).sqrt())
    }

    /// Why the trajectories' floor frame must be mirrored, judged over `recordings` pooled
    /// (`None` when their turns agree, or too few spans tell).
    pub fn mirrored(&self, recordings: usize) -> Option<String> {
        let r = self.correlation()?;
        let significance = r * (self.n as f64).sqrt();
        (r < MIRRORED_CORRELATION && significance < -MIRRORED_SIGNIFICANCE).then(|| {
            format!(
                "over the {recordings} recordings the camera's heading turns against the wheels: their small turns correlate at {r:.2} over {} spans of {EVIDENCE_SPAN_S:.0} s (a robot's own turn with its wheels, about +0.4; noise alone gives ±{:.2}): is the trajectories' floor frame mirrored (y must point to the left of x and theta count counter-clockwise; a left-handed motion-capture export or image coordinates negate both)? If not, are the logs' left and right columns swapped?",
                self.n,
                1.0 / (self.n as f64).sqrt()
            )
        })
    }
}
