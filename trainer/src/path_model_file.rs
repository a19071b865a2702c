//! The path model file (`odocal.path-model/1`): a trained step corrector with the window
//! layout it was fitted on, its kinematic-calibration peer, and what it was trained on, and
//! applying it to a whole log.

use std::fmt::Write as _;

use nalgebra::{DMatrix, DVector};
use odocal_core::Pose2;
use odocal_dataset::{Dataset, OdometryLog, RobotParams, WheelGeometry, WINDOW_RULE};
use serde::{Deserialize, Serialize};

use crate::baseline::PLAUSIBLE_MULTIPLIER;
use crate::domain::{check_same_robot, StepDirections};
use crate::error::TrainError;
use crate::model::Weights;
use crate::net::Perceptron;
use crate::path_model::{fit_step_corrector, nominal_travels, StepCorrector, WindowFit};

/// The `format` tag of path model files.
pub const PATH_MODEL_FORMAT: &str = "odocal.path-model/1";

/// A step's wheel speed may exceed the fastest seen in training by this share.
const SPEED_MARGIN: f64 = 0.15;

/// Contents of a path model file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PathModelFile {
    /// Always [`PATH_MODEL_FORMAT`].
    pub format: String,
    /// The window layout the model was fitted on ([`WINDOW_RULE`]).
    pub feature_rule: String,
    /// Robot parameters the logs were dead-reckoned with.
    pub robot: RobotParams,
    /// SHA-256 of the dataset file trained on.
    pub dataset_sha256: String,
    /// Windows fitted.
    pub n_windows: usize,
    /// Layer sizes [2, k, 3]: step wheel speeds in, corrections of left travel, right travel
    /// and wheel base out.
    pub layer_sizes: [usize; 3],
    /// Weights (inputs: wheel speeds / 0.5 m/s; outputs: tenths of a relative correction).
    pub weights: Weights,
    /// Seed of the fit.
    pub seed: u64,
    /// The least-squares kinematic calibration on the same windows (effective geometry).
    pub kinematic_fit: WheelGeometry,
    /// Fit to the training windows: raw odometry, the kinematic fit and the model.
    pub window_fit: [WindowFit; 3],
    /// Fastest wheel speed of a training step, m/s; faster logs are outside the domain.
    pub max_wheel_speed_mps: f64,
    /// Which ways the wheels turned in the training steps; a log going mostly another way
    /// (driving backwards after forward tours) is outside the domain. Absent from models
    /// written before it was recorded, which are then not checked for it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub step_directions: Option<StepDirections>,
    /// The first moving window of each training recording, by its steps: a log holding one
    /// is that recording, whose figures are no held-out figures ([`Self::trained_on`]).
    /// Absent from models written before it was recorded.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub training_prints: Vec<RecordingPrint>,
}

/// Steps of a recording's first moving window that identify the recording: the robot-clock
/// time of its first moving step and the wheel revolutions of the steps from there.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RecordingPrint {
    /// The training recording's id.
    pub recording_id: String,
    /// Robot-clock time of the row the window's first moving step starts at, seconds.
    pub t_s: f64,
    /// Wheel revolutions [left, right] of each of the window's first steps.
    pub steps_rev: Vec<[f64; 2]>,
}

/// Steps a [`RecordingPrint`] holds: ten steps of two encoders leave no two recordings alike.
const PRINT_STEPS: usize = 10;

impl RecordingPrint {
    /// The prints of a window dataset: each recording's earliest window.
    fn of(samples: &[&odocal_dataset::Sample]) -> Vec<Self> {
        let mut first: std::collections::BTreeMap<&str, &odocal_dataset::Sample> =
            std::collections::BTreeMap::new();
        for s in samples {
            let e = first.entry(s.recording_id.as_str()).or_insert(s);
            if s.odometry.t_b() < e.odometry.t_b() {
                *e = s;
            }
        }
        // From the window's first moving step: steps at rest are alike in every recording
        // that starts at the same time.
        first
            .into_iter()
            .filter_map(|(id, s)| {
                let (t, rev) = (&s.odometry.t_s, &s.odometry.rev);
                let j = (0..rev.len().saturating_sub(1)).find(|&j| rev[j + 1] != rev[j])?;
                (rev.len() > j + PRINT_STEPS).then(|| Self {
                    recording_id: id.to_string(),
                    t_s: t[j],
                    steps_rev: rev[j..=j + PRINT_STEPS]
                        .windows(2)
                        .map(|w| [w[1][0] - w[0][0], w[1][1] - w[0][1]])
                        .collect(),
                })
            })
            .collect()
    }

    /// Whether `revs` (a log's wheel revolutions) holds this print's steps at its time.
    fn found_in(&self, revs: &odocal_dataset::odometry::WheelRevs) -> bool {
        let Some(k) = revs.t_s.iter().position(|t| (t - self.t_s).abs() < 1e-6) else {
            return false;
        };
        revs.rev.len() > k + self.steps_rev.len()
            && self.steps_rev.iter().enumerate().all(|(j, s)| {
                let (a, b) = (revs.rev[k + j], revs.rev[k + j + 1]);
                (b[0] - a[0] - s[0]).abs() < 1e-9 && (b[1] - a[1] - s[1]).abs() < 1e-9
            })
    }
}

/// A log corrected by a path model.
#[derive(Debug, Clone)]
pub struct CorrectedPath {
    /// Per log row: time (robot clock, s), raw pose and corrected pose (start frame).
    pub track: Vec<(f64, Pose2, Pose2)>,
    /// Wheel travel of the log (mean of both wheels' absolute travel), metres.
    pub path_length_m: f64,
    /// Why the log lies outside the model's training domain (empty when inside).
    pub outside_domain: Vec<String>,
}

fn rows(m: &DMatrix<f64>) -> Vec<Vec<f64>> {
    (0..m.nrows())
        .map(|r| m.row(r).iter().copied().collect())
        .collect()
}

/// Refuses an effective geometry no real robot has (a multiplier of the nominal outside
/// [`PLAUSIBLE_MULTIPLIER`]): the windows' targets do not follow their odometry.
fn check_physical(g: &WheelGeometry, robot: &RobotParams) -> Result<(), TrainError> {
    for (name, fitted, nominal) in [
        (
            "left wheel diameter",
            g.left_wheel_diameter_m,
            robot.wheel_diameter_m,
        ),
        (
            "right wheel diameter",
            g.right_wheel_diameter_m,
            robot.wheel_diameter_m,
        ),
        ("wheel base", g.wheel_base_m, robot.wheel_base_m),
    ] {
        if !PLAUSIBLE_MULTIPLIER.contains(&(fitted / nominal)) {
            return Err(TrainError::Dataset(format!(
                "the kinematic fit on the windows gives a {name} of {:.3} mm against the nominal {:.3} mm, which no real robot has: the targets do not follow the odometry (a frozen camera track, trajectories in another unit, or logs and trajectories of different runs?); check the dataset's trajectories and rebuild it",
                1e3 * fitted,
                1e3 * nominal
            )));
        }
    }
    Ok(())
}

/// The largest turn (by nominal odometry) a window must hold for a wheel base to be told
/// from the wheels' diameters: on straight runs both wheels count alike, and only the
/// diameters' difference over the base shows (the synthetic straight runs' windows turn 0°
/// by odometry while the robot veers up to 18.5°); a UMBMark square's or a tour's windows
/// hold turns of 90° and more.
const MIN_WINDOW_TURN_RAD: f64 = std::f64::consts::FRAC_PI_4;

/// Why a kinematic fit gave a geometry no robot has, when no window turns: the targets may
/// follow the odometry perfectly, but a wheel base is fitted from turns.
fn too_little_turning(
    samples: &[&odocal_dataset::Sample],
    robot: &RobotParams,
) -> Option<TrainError> {
    let largest_rad = samples
        .iter()
        .map(|s| {
            let turn_m: f64 = s.inputs.chunks_exact(2).map(|d| d[1] - d[0]).sum();
            (turn_m / robot.wheel_base_m).abs()
        })
        .fold(0.0, f64::max);
    (largest_rad < MIN_WINDOW_TURN_RAD).then(|| {
        TrainError::Dataset(format!(
            "the windows hold too few turns to fit a wheel base: the most any window turns is {:.1}° by its odometry (a path model needs turns of {:.0}° or more); record runs that turn (tours, arcs or UMBMark squares), or train straight runs as straight runs (`odocal dataset` without --layout windows)",
            largest_rad.to_degrees(),
            MIN_WINDOW_TURN_RAD.to_degrees()
        ))
    })
}

impl PathModelFile {
    /// Fits a path model with `hidden` neurons to a window dataset.
    pub fn fit(
        ds: &Dataset,
        dataset_sha256: &str,
        hidden: usize,
        restarts: usize,
        seed: u64,
    ) -> Result<Self, TrainError> {
        if !ds.is_windows() {
            return Err(TrainError::Dataset(
                "this dataset holds straight runs; a path model is fitted on windows (build it with `odocal dataset --layout windows`)".into(),
            ));
        }
        let samples: Vec<&odocal_dataset::Sample> = ds.samples.iter().collect();
        let kin = fit_step_corrector(&samples, &ds.robot, 0, 1, 0.0, seed)?;
        check_physical(&kin.geometry(), &ds.robot)
            .map_err(|e| too_little_turning(&samples, &ds.robot).unwrap_or(e))?;
        let net = fit_step_corrector(&samples, &ds.robot, hidden, restarts, 1e-4, seed)?;
        let raw = StepCorrector::nominal(ds.robot, 0);
        let max_wheel_speed_mps = samples
            .iter()
            .flat_map(|s| s.inputs.iter())
            .fold(0.0f64, |m, d| m.max(d.abs()))
            / ds.robot.period_s;
        let step_directions = StepDirections::of_steps(
            samples
                .iter()
                .flat_map(|s| s.inputs.chunks_exact(2))
                .map(|d| [d[0], d[1]]),
        );
        let p = net.net();
        Ok(Self {
            format: PATH_MODEL_FORMAT.to_string(),
            feature_rule: WINDOW_RULE.to_string(),
            robot: ds.robot,
            dataset_sha256: dataset_sha256.to_string(),
            n_windows: samples.len(),
            layer_sizes: [2, hidden, 3],
            weights: Weights {
                w1: rows(&p.w1),
                b1: p.b1.iter().copied().collect(),
                w2: rows(&p.w2),
                b2: p.b2.iter().copied().collect(),
            },
            seed,
            kinematic_fit: kin.geometry(),
            window_fit: [
                WindowFit::of(&raw, &samples),
                WindowFit::of(&kin, &samples),
                WindowFit::of(&net, &samples),
            ],
            max_wheel_speed_mps,
            step_directions: Some(step_directions),
            training_prints: RecordingPrint::of(&samples),
        })
    }

    /// The training recording `log` is, if it holds one's first moving window: evaluated, its
    /// figures would be the training's fit, not a held-out judgement.
    pub fn trained_on(&self, log: &OdometryLog) -> Option<&str> {
        if self.training_prints.is_empty() {
            return None;
        }
        let revs = log.wheel_revs(&self.robot);
        self.training_prints
            .iter()
            .find(|p| p.found_in(&revs))
            .map(|p| p.recording_id.as_str())
    }

    /// Reads a path model file, rejecting other formats, sizes and non-finite numbers.
    pub fn read(path: &std::path::Path) -> Result<Self, TrainError> {
        let text = odocal_core::read_text(path)?;
        let name = path.display().to_string();
        let m: PathModelFile = odocal_core::parse_tagged_json(
            &text,
            &name,
            PATH_MODEL_FORMAT,
            "pass a path model written by `odocal train` from a window dataset",
        )?;
        if m.feature_rule != WINDOW_RULE {
            return Err(TrainError::Model(format!(
                "{name}: trained on feature rule '{}', not this build's '{WINDOW_RULE}'; retrain it",
                m.feature_rule
            )));
        }
        m.robot
            .check()
            .map_err(|e| TrainError::Model(format!("{name}: robot.{e}")))?;
        if !(m.max_wheel_speed_mps.is_finite() && m.max_wheel_speed_mps > 0.0) {
            return Err(TrainError::Model(format!(
                "{name}: max_wheel_speed_mps must be a positive number"
            )));
        }
        // Zero, the base read "NaN % of path" and wrote null; negative, plausible wrong rows.
        let g = &m.kinematic_fit;
        for (field, fitted, nominal) in [
            (
                "left_wheel_diameter_m",
                g.left_wheel_diameter_m,
                m.robot.wheel_diameter_m,
            ),
            (
                "right_wheel_diameter_m",
                g.right_wheel_diameter_m,
                m.robot.wheel_diameter_m,
            ),
            ("wheel_base_m", g.wheel_base_m, m.robot.wheel_base_m),
        ] {
            if !PLAUSIBLE_MULTIPLIER.contains(&(fitted / nominal)) {
                return Err(TrainError::Model(format!(
                    "{name}: kinematic_fit.{field} = {fitted} m against the robot's {nominal} m, which no real robot has: the model is damaged or edited; train it again"
                )));
            }
        }
        if let Some(d) = &m.step_directions {
            d.check()
                .map_err(|e| TrainError::Model(format!("{name}: step_directions.{e}")))?;
        }
        m.corrector().map_err(|e| e.in_model_file(&name))?;
        Ok(m)
    }

    /// Refuses data of a robot other than the model's (`whose` names the data).
    pub fn check_robot(&self, robot: &RobotParams, whose: &str) -> Result<(), TrainError> {
        check_same_robot(&self.robot, robot, whose)
    }

    /// The step corrector (checks sizes and finiteness).
    pub fn corrector(&self) -> Result<StepCorrector, TrainError> {
        let [n, k, o] = self.layer_sizes;
        let w = &self.weights;
        let shape_ok = n == 2
            && o == 3
            && w.w1.len() == k
            && w.w1.iter().all(|r| r.len() == n)
            && w.b1.len() == k
            && w.w2.len() == o
            && w.w2.iter().all(|r| r.len() == k)
            && w.b2.len() == o;
        if !shape_ok {
            return Err(TrainError::Model(format!(
                "layer sizes {:?} do not match the weights (expected [2, k, 3])",
                self.layer_sizes
            )));
        }
        let net = Perceptron {
            w1: DMatrix::from_fn(k, n, |r, c| w.w1[r][c]),
            b1: DVector::from_vec(w.b1.clone()),
            w2: DMatrix::from_fn(o, k, |r, c| w.w2[r][c]),
            b2: DVector::from_vec(w.b2.clone()),
        };
        if !net.to_params().iter().all(|v| v.is_finite()) {
            return Err(TrainError::Model("weights contain NaN/inf".into()));
        }
        StepCorrector::new(self.robot, net)
    }

    /// Refuses a log of `robot` (`name` names it in the message) with a gap (a step off the
    /// robot's period, refused even with `allow_extrapolation`: its speed would be misread),
    /// or whose steps lie outside what the model was trained on: wheels faster than the
    /// training's, or driven mostly in a direction the training hardly saw (backwards after
    /// forward tours). With `allow_extrapolation` the reasons are returned instead, for the
    /// caller to flag; an empty list means the log lies inside. `odocal correct` and `odocal
    /// evaluate` judge logs by this one check.
    pub fn check_domain(
        &self,
        log: &OdometryLog,
        robot: &RobotParams,
        name: &str,
        allow_extrapolation: bool,
    ) -> Result<Vec<String>, TrainError> {
        crate::log_steps::check_log_steps(log, robot, name)?;
        let revs = log.wheel_revs(robot);
        let steps = nominal_travels(&revs.rev, robot);
        self.check_steps_domain(&steps, &revs.t_s, name, allow_extrapolation)
    }

    /// [`Self::check_domain`] on a log's nominal wheel travels per step, the steps ending at
    /// the rows `t_s` times after the first.
    fn check_steps_domain(
        &self,
        steps: &[[f64; 2]],
        t_s: &[f64],
        name: &str,
        allow_extrapolation: bool,
    ) -> Result<Vec<String>, TrainError> {
        // Each step over its own duration: a logger's jitter stretches a step to 1.4 periods,
        // and its travel over one period read as a speed the wheels never reached.
        let fastest = steps.iter().zip(t_s.windows(2)).fold(0.0f64, |a, (d, t)| {
            a.max(d[0].abs().max(d[1].abs()) / (t[1] - t[0]))
        });
        let mut outside_domain = Vec::new();
        if fastest > (1.0 + SPEED_MARGIN) * self.max_wheel_speed_mps {
            outside_domain.push(format!(
                "a wheel reaches {fastest:.2} m/s, the training only {:.2} m/s",
                self.max_wheel_speed_mps
            ));
        }
        if let Some(trained) = &self.step_directions {
            outside_domain
                .extend(trained.outside(&StepDirections::of_steps(steps.iter().copied())));
        }
        if !outside_domain.is_empty() && !allow_extrapolation {
            return Err(TrainError::Model(format!(
                "{name}: outside what the model was trained on: {}; a correction there would be a guess (pass --allow-extrapolation to get it anyway, flagged)",
                outside_domain.join("; ")
            )));
        }
        Ok(outside_domain)
    }

    /// The net's weights and biases, fitted together.
    pub fn parameter_count(&self) -> usize {
        let [inputs, hidden, outputs] = self.layer_sizes;
        inputs * hidden + hidden + outputs * hidden + outputs
    }

    /// Why the fit to the training windows flatters the model, if it does: a window's end
    /// gives three targets (x, y, heading), and fewer than twice the net's parameters let it
    /// follow their noise. None when the windows outnumber it enough.
    pub fn overfit_warning(&self) -> Option<String> {
        let parameters = self.parameter_count();
        let targets = 3 * self.n_windows;
        (targets < 2 * parameters).then(|| {
            let [inputs, hidden, outputs] = self.layer_sizes;
            format!(
                "the perceptron {inputs}-{hidden}-{outputs} has {parameters} parameters fitted to {} windows ({targets} target values, fewer than twice as many): it can follow their noise, so its training figures flatter it; judge it with `odocal evaluate` on held-out recordings, record more, or give a smaller --hidden",
                self.n_windows
            )
        })
    }

    /// Why logs cannot be checked for the directions they were driven in: models written
    /// before the training's directions were recorded (`step_directions` absent). `name`
    /// names the model. None when the record is there.
    pub fn unrecorded_directions(&self, name: &str) -> Option<String> {
        self.step_directions.is_none().then(|| {
            format!(
                "{name} predates the record of the directions its training drove (step_directions): a log driven in directions the training did not see (backwards, turning on the spot one way) cannot be detected and is corrected unflagged; retrain the model with `odocal train` on its window dataset to have logs checked for it"
            )
        })
    }

    /// Corrects a whole log of `robot` (`name` names the log in messages): the raw and the
    /// corrected trajectory from the log's first row. A log outside the training domain
    /// ([`Self::check_domain`]) is refused unless `allow_extrapolation`, when the reasons are
    /// returned.
    pub fn correct_log(
        &self,
        log: &OdometryLog,
        robot: &RobotParams,
        name: &str,
        allow_extrapolation: bool,
    ) -> Result<CorrectedPath, TrainError> {
        self.check_robot(robot, name)?;
        let revs = log.wheel_revs(robot);
        let steps = nominal_travels(&revs.rev, robot);
        crate::log_steps::check_log_steps(log, robot, name)?;
        let outside_domain =
            self.check_steps_domain(&steps, &revs.t_s, name, allow_extrapolation)?;
        let c = self.corrector()?;
        let corrected = c.dead_reckon_travels(&steps);
        let raw = odocal_dataset::dead_reckon(&revs.rev, &WheelGeometry::nominal(robot));
        let path_length_m = steps.iter().map(|d| 0.5 * (d[0].abs() + d[1].abs())).sum();
        Ok(CorrectedPath {
            track: revs
                .t_s
                .iter()
                .zip(raw.iter().zip(&corrected))
                .map(|(&t, (r, c))| (t, *r, *c))
                .collect(),
            path_length_m,
            outside_domain,
        })
    }
}

impl CorrectedPath {
    /// The end poses (raw, corrected), start frame.
    pub fn ends(&self) -> (Pose2, Pose2) {
        self.track
            .last()
            .map(|(_, r, c)| (*r, *c))
            .unwrap_or_default()
    }

    /// The track as CSV:
    /// `t,x_raw,y_raw,theta_raw,x_corrected,y_corrected,theta_corrected,extrapolated` (robot
    /// clock seconds, metres, radians; start frame; `extrapolated` 1 on every row when the log
    /// lies outside the training domain, so the file itself says its correction is a guess).
    pub fn to_csv(&self) -> String {
        let mut csv = String::from(
            "t,x_raw,y_raw,theta_raw,x_corrected,y_corrected,theta_corrected,extrapolated\n",
        );
        let flag = u8::from(!self.outside_domain.is_empty());
        for (t, r, c) in &self.track {
            let _ = writeln!(
                csv,
                "{t:.3},{:.6},{:.6},{:.6},{:.6},{:.6},{:.6},{flag}",
                r.x_m, r.y_m, r.theta_rad, c.x_m, c.y_m, c.theta_rad
            );
        }
        csv
    }
}
