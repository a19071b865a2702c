//! Judging odometry corrections on whole paths: every method dead-reckons each held-out log
//! from its start, and its end point is compared with the camera's. Squares driven both ways
//! give Borenstein's E_max,syst per method; any path gives the end-point error per metre
//! driven.

use odocal_core::{mean_pose, Pose2, Trajectory};
use odocal_dataset::oracle::TrueKinematics;
use odocal_dataset::{OdometryLog, RobotParams, WheelGeometry};
use serde::{Deserialize, Serialize};

use crate::error::TrainError;
use crate::path_model::StepCorrector;
use crate::umbmark::{SquareError, Umbmark};

/// The `format` tag of path evaluations.
pub const PATH_EVALUATION_FORMAT: &str = "odocal.path-evaluation/1";

/// Camera frames at the start and end of a recording averaged for its rest poses, seconds.
const REST_SPAN_S: f64 = 0.25;
/// Largest spread of those frames for the robot to count as at rest, metres.
const REST_SPREAD_M: f64 = 0.005;

/// One held-out recording: its log and the camera's trajectory (the robot at rest at both
/// ends, as a square or tour starts and ends).
pub struct PathRecording {
    /// Manifest id.
    pub id: String,
    /// The robot's log.
    pub log: OdometryLog,
    /// The log's file, as the manifest resolves it (what a message on the log names).
    pub log_file: std::path::PathBuf,
    /// The camera's trajectory.
    pub camera: Trajectory,
}

impl PathRecording {
    /// Every row of a manifest with a camera trajectory file (rows with only a video must be
    /// tracked first: `odocal track`).
    pub fn read_manifest(m: &odocal_dataset::Manifest) -> Result<Vec<Self>, TrainError> {
        m.check_files()
            .map_err(|e| TrainError::Dataset(e.to_string()))?;
        m.runs
            .iter()
            .map(|row| {
                let Some(traj) = &row.trajectory else {
                    return Err(TrainError::Dataset(format!(
                        "run \"{}\" has no trajectory file; track its video with `odocal track` and name the CSV in the manifest",
                        row.id
                    )));
                };
                let dataset = |e: odocal_dataset::DatasetError| TrainError::Dataset(e.to_string());
                let log_file = m.resolve(&row.odometry);
                Ok(Self {
                    id: row.id.clone(),
                    log: OdometryLog::read_csv(&log_file).map_err(dataset)?,
                    log_file,
                    camera: Trajectory::read_csv(&m.resolve(traj))?,
                })
            })
            .collect()
    }
}

/// A way of dead-reckoning a log.
pub enum Reckoner<'a> {
    /// Fixed wheel geometry (nominal, or a calibration).
    Geometry(WheelGeometry),
    /// A learned step corrector.
    Corrector(&'a StepCorrector),
    /// The simulator's true kinematics (synthetic experiments only).
    Truth(TrueKinematics),
}

impl Reckoner<'_> {
    fn end(&self, rev: &[[f64; 2]], robot: &RobotParams) -> Pose2 {
        let poses = match self {
            Reckoner::Geometry(g) => odocal_dataset::dead_reckon(rev, g),
            Reckoner::Corrector(c) => c.dead_reckon(rev),
            Reckoner::Truth(k) => k.dead_reckon(rev, robot.period_s),
        };
        poses.last().copied().unwrap_or_default()
    }
}

/// One recording judged.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RunResult {
    /// Manifest id.
    pub id: String,
    /// Some(true) for one clockwise loop (odometry turned by -2π ± π/2 overall), Some(false)
    /// for one counter-clockwise loop, None otherwise.
    pub clockwise: Option<bool>,
    /// Wheel travel of the log (mean of both wheels' absolute travel), metres.
    pub path_length_m: f64,
    /// The camera's end position in the start frame, metres.
    pub true_end_m: [f64; 2],
    /// Per method: "true minus computed" end position, start frame, metres.
    pub errors_m: Vec<[f64; 2]>,
    /// Why the log lies outside the path model's training domain, when it was evaluated
    /// anyway: the perceptron's error on it judges an extrapolation, not the model's accuracy.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub outside_domain: Vec<String>,
}

/// One method's figures.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MethodResult {
    /// What the method is.
    pub name: String,
    /// Mean over recordings of |end error| / path length (a fraction).
    pub end_error_per_m: f64,
    /// Borenstein's figures, when the recordings are squares in both directions.
    pub umbmark: Option<Umbmark>,
}

/// The evaluation of every method on held-out recordings.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PathEvaluation {
    /// Always [`PATH_EVALUATION_FORMAT`].
    pub format: String,
    /// Per method, in the order given.
    pub methods: Vec<MethodResult>,
    /// Per recording.
    pub runs: Vec<RunResult>,
}

fn rest_pose(
    rows: &[odocal_core::TrajectoryRow],
    id: &str,
    which: &str,
) -> Result<Pose2, TrainError> {
    let p = mean_pose(rows).ok_or_else(|| {
        TrainError::Dataset(format!("{id}: the camera has no frames at the {which}"))
    })?;
    let spread = rows
        .iter()
        .map(|r| (r.pose.position() - p.position()).norm())
        .fold(0.0, f64::max);
    if spread > REST_SPREAD_M {
        return Err(TrainError::Dataset(format!(
            "{id}: the robot moves during the camera's first or last {REST_SPAN_S} s ({which}: frames spread {:.1} mm > {:.1} mm); the camera must see it at rest before and after the path",
            1e3 * spread,
            1e3 * REST_SPREAD_M
        )));
    }
    Ok(p)
}

/// How far the recordings' camera trajectories end from `oracle`'s true ends (each in its
/// start frame): the RMS over the recordings the truth has, metres, and how many it lacks.
/// A synthetic truth fits its own experiment's cameras to millimetres; another experiment's
/// truth with the same run ids does not, and its oracle row would judge another robot.
pub fn truth_distance(
    recordings: &[PathRecording],
    oracle: &odocal_dataset::OracleFile,
) -> (Option<f64>, usize) {
    let (mut sum, mut n, mut missing) = (0.0, 0usize, 0usize);
    for r in recordings {
        let (Some(first), Some(last), Some(t)) = (
            r.camera.rows.first(),
            r.camera.rows.last(),
            oracle.get(&r.id),
        ) else {
            missing += 1;
            continue;
        };
        let end = last.pose.relative_to(&first.pose);
        sum += (end.x_m - t.true_end_m[0]).powi(2) + (end.y_m - t.true_end_m[1]).powi(2);
        n += 1;
    }
    ((n > 0).then(|| (sum / n as f64).sqrt()), missing)
}

/// A wheel faster than this in a log's first or last step, m/s, means the log starts or ends
/// during the motion (two 12-count ticks a 200 ms step are 0.11 m/s on a 4.3 cm wheel).
const BOUNDARY_MOTION_MPS: f64 = 0.1;

/// A camera trajectory that never leaves this far from its start, metres, shows a robot at
/// rest (tracking noise is millimetres).
const STILL_CAMERA_M: f64 = 0.05;

/// Judges `methods` (name, reckoner) on `recordings` of `robot`. With `squares`, the
/// recordings are UMBMark squares (each must turn by one full turn one way or the other) and
/// every method gets Borenstein's figures.
pub fn evaluate_paths(
    recordings: &[PathRecording],
    robot: &RobotParams,
    methods: &[(String, Reckoner)],
    squares: bool,
) -> Result<PathEvaluation, TrainError> {
    if recordings.is_empty() {
        return Err(TrainError::Dataset("no recordings to evaluate".into()));
    }
    let mut runs = Vec::with_capacity(recordings.len());
    for (i, r) in recordings.iter().enumerate() {
        let cam = &r.camera;
        let (t0, t1) = (cam.start_s(), cam.end_s());
        if let Some(why) = odocal_dataset::units::length_unit_mismatch(&r.log, cam, robot) {
            return Err(TrainError::Dataset(format!("{}: {why}", r.id)));
        }
        let start = rest_pose(cam.rows_between(t0, t0 + REST_SPAN_S), &r.id, "start")?;
        let end = rest_pose(cam.rows_between(t1 - REST_SPAN_S, t1), &r.id, "end")?;
        let truth = end.relative_to(&start);
        if let Some(why) = r.log.period_mismatch(robot.period_s) {
            return Err(TrainError::Dataset(format!(
                "{}: odometry {why}; is this log of another robot or logger?",
                r.id
            )));
        }
        // Every method dead-reckons step by step; a lost row would be one step of three.
        crate::log_steps::check_log_steps(&r.log, robot, &r.id)?;
        // The camera's rest poses at both ends are the truth: a log cut after the start (or
        // before the end) misses motion the camera saw, and every method would be judged on
        // a path it was not given.
        // A tick or two of creep at either end is a logger started or stopped as the robot
        // did; cruising speed there is motion the log does not hold.
        let revs = r.log.wheel_revs(robot);
        let circ = std::f64::consts::PI * robot.wheel_diameter_m;
        let moves = |a: usize, b: usize| match (revs.rev.get(a), revs.rev.get(b)) {
            (Some(p), Some(q)) => {
                let dt = revs.t_s[b] - revs.t_s[a];
                (0..2).any(|w| (q[w] - p[w]).abs() * circ / dt > BOUNDARY_MOTION_MPS)
            }
            _ => false,
        };
        let n = revs.rev.len();
        if moves(0, 1) || (n >= 2 && moves(n - 2, n - 1)) {
            return Err(TrainError::Dataset(format!(
                "{}: the log {} during the robot's motion (its {} rows already move the wheels): a held-out recording starts and ends at rest, in the log as in the camera's trajectory; give the whole log",
                r.id,
                if moves(0, 1) { "starts" } else { "ends" },
                if moves(0, 1) { "first" } else { "last" }
            )));
        }
        // A recording without motion has nothing to judge a method on; alignment would
        // only blame the pairing.
        let wheels_turn = revs
            .rev
            .first()
            .is_some_and(|a| revs.rev.iter().any(|b| b != a));
        let camera_moved_m = cam.rows.first().map_or(0.0, |a| {
            cam.rows
                .iter()
                .map(|b| (b.pose.x_m - a.pose.x_m).hypot(b.pose.y_m - a.pose.y_m))
                .fold(0.0, f64::max)
        });
        if !wheels_turn {
            let camera = if camera_moved_m < STILL_CAMERA_M {
                "nor does the camera see the robot move: leave the recording out of the manifest"
                    .to_string()
            } else {
                format!(
                    "while the camera sees the robot move up to {:.2} m from its start: is the log this recording's?",
                    camera_moved_m
                )
            };
            return Err(TrainError::Dataset(format!(
                "{}: the log holds no motion (its wheels never turn), {camera}",
                r.id
            )));
        }
        let align = odocal_dataset::align::AlignOptions::default();
        // A log whose wheels do not follow its trajectory at any clock offset is another
        // recording's (two tours' logs swapped passed every other check, and judged every
        // method 20 % off); `dataset` refuses such a row alike.
        let unfollowed = || {
            (!odocal_dataset::log_fits_camera(&r.log, &r.camera, robot, &align)).then(|| {
                "its wheels do not follow the trajectory's motion at any clock offset: is the trajectory another recording's, or the log another robot's?".to_string()
            })
        };
        if let Some(why) = odocal_dataset::units::unit_mismatch(&r.log, &r.camera, robot)
            .or_else(|| odocal_dataset::trajectory_mismatch(&r.log, &r.camera, robot, &align))
            .or_else(unfollowed)
        {
            // UMBMark squares driven the other way round turn against each other's wheels,
            // which reads as swapped wheel columns until the pairs are tried (swapping the
            // columns as told then passed, with figures 2 to 3 times off).
            let fits = |a: usize, b: usize| {
                let (log, camera) = (&recordings[a].log, &recordings[b].camera);
                odocal_dataset::log_fits_camera(log, camera, robot, &align)
            };
            let swap = odocal_dataset::swapped_with(recordings.len(), i, fits).map_or(String::new(), |o| {
                let o = &recordings[o].id;
                format!(" This log and {o}'s trajectory fit, as do {o}'s log and this trajectory: the manifest pairs each with the other's; swap {}'s and {o}'s trajectories back", r.id)
            });
            return Err(TrainError::Dataset(format!("{}: {why}{swap}", r.id)));
        }
        let nominal = WheelGeometry::nominal(robot);
        let raw = odocal_dataset::dead_reckon(&revs.rev, &nominal);
        let turned = raw.last().map_or(0.0, |p| p.theta_rad);
        let c = std::f64::consts::PI * robot.wheel_diameter_m;
        let path_length_m: f64 = revs
            .rev
            .windows(2)
            .map(|w| 0.5 * c * ((w[1][0] - w[0][0]).abs() + (w[1][1] - w[0][1]).abs()))
            .sum();
        if path_length_m <= 0.0 {
            return Err(TrainError::Dataset(format!(
                "{}: the log shows no motion",
                r.id
            )));
        }
        let errors_m = methods
            .iter()
            .map(|(_, m)| {
                let e = m.end(&revs.rev, robot);
                [truth.x_m - e.x_m, truth.y_m - e.y_m]
            })
            .collect();
        runs.push(RunResult {
            id: r.id.clone(),
            clockwise: if (turned.abs() - 2.0 * std::f64::consts::PI).abs()
                <= std::f64::consts::FRAC_PI_2
            {
                Some(turned < 0.0)
            } else {
                None
            },
            path_length_m,
            true_end_m: [truth.x_m, truth.y_m],
            errors_m,
            outside_domain: Vec::new(),
        });
    }
    if squares {
        if let Some(r) = runs.iter().find(|r| r.clockwise.is_none()) {
            return Err(TrainError::Dataset(format!(
                "{}: its odometry does not turn by one full turn (±90°) overall, so it is no UMBMark square",
                r.id
            )));
        }
    }
    let methods = methods
        .iter()
        .enumerate()
        .map(|(i, (name, _))| {
            let per_m = runs
                .iter()
                .map(|r| r.errors_m[i][0].hypot(r.errors_m[i][1]) / r.path_length_m)
                .sum::<f64>()
                / runs.len() as f64;
            let umbmark = if squares {
                let e: Vec<SquareError> = runs
                    .iter()
                    .map(|r| SquareError {
                        clockwise: r.clockwise == Some(true),
                        error_m: r.errors_m[i],
                    })
                    .collect();
                Some(Umbmark::of(&e)?)
            } else {
                None
            };
            Ok(MethodResult {
                name: name.clone(),
                end_error_per_m: per_m,
                umbmark,
            })
        })
        .collect::<Result<_, TrainError>>()?;
    Ok(PathEvaluation {
        format: PATH_EVALUATION_FORMAT.to_string(),
        methods,
        runs,
    })
}
