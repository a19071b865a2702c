//! The corrector for any path: a small perceptron that, step by step, turns each log step's
//! nominal wheel travels into effective ones (and an effective wheel base), so a corrected
//! trajectory is dead reckoning with learned, speed-dependent kinematics. It is fitted on
//! windows of logs ([`odocal_dataset::WINDOW_RULE`]) by chaining its steps over each window and
//! comparing the chained pose change with the camera's: the chaining is inside the fit, so the
//! encoders' quantisation, which cancels between consecutive steps, is not learned as motion.
//!
//! With no hidden neurons the net is a constant: the least-squares kinematic calibration
//! (effective wheel diameters and base) on the same windows, the classic baseline.

use nalgebra::DVector;
use odocal_core::{wrap_angle, Pose2};
use odocal_dataset::kinematics::step;
use odocal_dataset::{RobotParams, Sample, WheelGeometry};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use crate::error::TrainError;
use crate::net::Perceptron;

/// Wheel speed that maps to a net input of 1, m/s.
const SPEED_SCALE_MPS: f64 = 0.5;
/// Relative correction of a net output of 1.
const OUTPUT_SCALE: f64 = 0.1;
/// Length that weighs a window's heading residual against its position residuals, metres: a
/// heading error of 1 mrad counts as much as a 1 mm position error.
pub const HEADING_WEIGHT_M: f64 = 1.0;

/// Per-step corrected kinematics: a 2-k-3 perceptron from the step's nominal wheel speeds
/// to relative corrections of the left and right wheel travel and of the wheel base.
#[derive(Debug, Clone, PartialEq)]
pub struct StepCorrector {
    robot: RobotParams,
    net: Perceptron,
}

impl StepCorrector {
    /// The corrector of a net (2 inputs, 3 outputs) for `robot`.
    pub fn new(robot: RobotParams, net: Perceptron) -> Result<Self, TrainError> {
        if net.n_in() != 2 || net.n_out() != 3 {
            return Err(TrainError::Model(format!(
                "a step corrector needs a 2-k-3 net, not {}-{}-{}",
                net.n_in(),
                net.hidden(),
                net.n_out()
            )));
        }
        Ok(Self { robot, net })
    }

    /// The uncorrected corrector: nominal kinematics.
    pub fn nominal(robot: RobotParams, hidden: usize) -> Self {
        let mut rng = ChaCha8Rng::seed_from_u64(0);
        let mut net = Perceptron::init(2, hidden, 3, &mut rng);
        net.w2.fill(0.0);
        net.b2.fill(0.0);
        Self { robot, net }
    }

    /// The net.
    pub fn net(&self) -> &Perceptron {
        &self.net
    }

    /// Hidden neurons (0: a constant correction, the kinematic calibration).
    pub fn hidden(&self) -> usize {
        self.net.hidden()
    }

    /// Relative corrections [left travel, right travel, wheel base] of a step with nominal
    /// wheel travels `d_m` = [left, right], metres.
    pub fn corrections(&self, d_m: [f64; 2]) -> [f64; 3] {
        let u = [
            d_m[0] / self.robot.period_s / SPEED_SCALE_MPS,
            d_m[1] / self.robot.period_s / SPEED_SCALE_MPS,
        ];
        let mut g = [0.0; 3];
        self.net.forward(&u, &mut g);
        [
            OUTPUT_SCALE * g[0],
            OUTPUT_SCALE * g[1],
            OUTPUT_SCALE * g[2],
        ]
    }

    /// One corrected dead-reckoning step from `pose` with nominal wheel travels `d_m`.
    pub fn step(&self, pose: &Pose2, d_m: [f64; 2]) -> Pose2 {
        if d_m == [0.0, 0.0] {
            return *pose;
        }
        let g = self.corrections(d_m);
        step(
            pose,
            d_m[0] * (1.0 + g[0]),
            d_m[1] * (1.0 + g[1]),
            self.robot.wheel_base_m * (1.0 + g[2]),
        )
    }

    /// Chains corrected steps of nominal wheel travels; one pose per row (steps + 1), the
    /// first at the origin.
    pub fn dead_reckon_travels(&self, steps_m: &[[f64; 2]]) -> Vec<Pose2> {
        let mut out = Vec::with_capacity(steps_m.len() + 1);
        let mut pose = Pose2::default();
        out.push(pose);
        for d in steps_m {
            pose = self.step(&pose, *d);
            out.push(pose);
        }
        out
    }

    /// Chains corrected steps of cumulative wheel revolutions (one row per log row).
    pub fn dead_reckon(&self, rev: &[[f64; 2]]) -> Vec<Pose2> {
        self.dead_reckon_travels(&nominal_travels(rev, &self.robot))
    }

    /// The constant corrector as a wheel geometry (meaningful for 0 hidden neurons).
    pub fn geometry(&self) -> WheelGeometry {
        let g = self.corrections([0.0, 0.0]);
        WheelGeometry {
            left_wheel_diameter_m: self.robot.wheel_diameter_m * (1.0 + g[0]),
            right_wheel_diameter_m: self.robot.wheel_diameter_m * (1.0 + g[1]),
            wheel_base_m: self.robot.wheel_base_m * (1.0 + g[2]),
        }
    }
}

/// Nominal wheel travels [left, right] of each step between rows of cumulative revolutions.
pub fn nominal_travels(rev: &[[f64; 2]], robot: &RobotParams) -> Vec<[f64; 2]> {
    let c = std::f64::consts::PI * robot.wheel_diameter_m;
    rev.windows(2)
        .map(|w| [(w[1][0] - w[0][0]) * c, (w[1][1] - w[0][1]) * c])
        .collect()
}

/// Window samples prepared for fitting: the distinct step travels (tick logs repeat a few
/// hundred (left, right) pairs), each window's steps as indices into them, and its target.
struct Windows {
    distinct: Vec<[f64; 2]>,
    windows: Vec<(Vec<u32>, Pose2)>,
}

impl Windows {
    fn new(samples: &[&Sample]) -> Self {
        let mut index = std::collections::HashMap::new();
        let mut distinct = Vec::new();
        let windows = samples
            .iter()
            .map(|s| {
                let steps = s
                    .inputs
                    .chunks_exact(2)
                    .map(|p| {
                        *index
                            .entry((p[0].to_bits(), p[1].to_bits()))
                            .or_insert_with(|| {
                                distinct.push([p[0], p[1]]);
                                (distinct.len() - 1) as u32
                            })
                    })
                    .collect();
                (
                    steps,
                    Pose2::new(s.target_m[0], s.target_m[1], s.target_theta_rad),
                )
            })
            .collect();
        Self { distinct, windows }
    }

    /// Residuals of a corrector: per window the chained end position minus the camera's
    /// (metres) and the heading difference times [`HEADING_WEIGHT_M`].
    fn residuals(&self, c: &StepCorrector, out: &mut Vec<f64>) {
        let b = c.robot.wheel_base_m;
        let table: Vec<[f64; 3]> = self
            .distinct
            .iter()
            .map(|d| {
                let g = c.corrections(*d);
                [d[0] * (1.0 + g[0]), d[1] * (1.0 + g[1]), b * (1.0 + g[2])]
            })
            .collect();
        for (steps, target) in &self.windows {
            let mut pose = Pose2::default();
            for &i in steps {
                let [l, r, base] = table[i as usize];
                if l != 0.0 || r != 0.0 {
                    pose = step(&pose, l, r, base);
                }
            }
            out.push(pose.x_m - target.x_m);
            out.push(pose.y_m - target.y_m);
            out.push(HEADING_WEIGHT_M * wrap_angle(pose.theta_rad - target.theta_rad));
        }
    }
}

/// How well a corrector reproduces windows.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct WindowFit {
    /// Windows compared.
    pub n_windows: usize,
    /// RMS distance of the chained window end from the camera's, metres.
    pub position_rms_m: f64,
    /// RMS heading difference at the window end, radians.
    pub heading_rms_rad: f64,
}

impl WindowFit {
    /// The fit of `c` to window samples.
    pub fn of(c: &StepCorrector, samples: &[&Sample]) -> Self {
        let w = Windows::new(samples);
        let mut r = Vec::with_capacity(3 * w.windows.len());
        w.residuals(c, &mut r);
        let n = w.windows.len().max(1) as f64;
        let (mut p, mut h) = (0.0, 0.0);
        for t in r.chunks_exact(3) {
            p += t[0] * t[0] + t[1] * t[1];
            h += (t[2] / HEADING_WEIGHT_M).powi(2);
        }
        Self {
            n_windows: w.windows.len(),
            position_rms_m: (p / n).sqrt(),
            heading_rms_rad: (h / n).sqrt(),
        }
    }
}

/// Fits a step corrector with `hidden` neurons to window samples: first the constant
/// corrector (the kinematic calibration), then, from it, the net over `restarts` seeded
/// initialisations, keeping the lowest cost. `weight_decay` penalises the net's weights.
pub fn fit_step_corrector(
    samples: &[&Sample],
    robot: &RobotParams,
    hidden: usize,
    restarts: usize,
    weight_decay: f64,
    seed: u64,
) -> Result<StepCorrector, TrainError> {
    if samples.len() < 3 {
        return Err(TrainError::TooFewSamples(format!(
            "{} windows; a path corrector needs at least 3",
            samples.len()
        )));
    }
    let windows = Windows::new(samples);
    let cost = |c: &StepCorrector| {
        let mut r = Vec::with_capacity(3 * windows.windows.len());
        windows.residuals(c, &mut r);
        r.iter().map(|v| v * v).sum::<f64>()
    };
    // The constant corrector: three output biases.
    let kin = {
        let base = StepCorrector::nominal(*robot, 0);
        let f = |p: &[f64]| {
            let mut c = base.clone();
            c.net.b2 = DVector::from_column_slice(p);
            let mut r = Vec::with_capacity(3 * windows.windows.len());
            windows.residuals(&c, &mut r);
            r
        };
        let (p, report) = odocal_core::lsq::minimize(&f, vec![0.0; 3], 200);
        if !report.termination.was_successful() || p.iter().any(|v| !v.is_finite()) {
            return Err(TrainError::Numerical(format!(
                "the kinematic fit on windows did not converge ({:?})",
                report.termination
            )));
        }
        let mut c = base;
        c.net.b2 = DVector::from_column_slice(&p);
        c
    };
    if hidden == 0 {
        return Ok(kin);
    }
    let mut best: Option<(f64, StepCorrector)> = None;
    for r in 0..restarts.max(1) {
        let mut rng = ChaCha8Rng::seed_from_u64(crate::crossval::derive_seed(
            seed,
            &[hidden as u64, r as u64],
        ));
        let mut net = Perceptron::init(2, hidden, 3, &mut rng);
        net.w2.fill(0.0);
        net.b2 = kin.net.b2.clone();
        let start = StepCorrector { robot: *robot, net };
        let decay = weight_decay.sqrt();
        let f = |p: &[f64]| {
            let mut c = start.clone();
            c.net.set_params(&DVector::from_column_slice(p));
            let mut res = Vec::with_capacity(3 * windows.windows.len() + p.len());
            windows.residuals(&c, &mut res);
            for (i, v) in p.iter().enumerate() {
                if c.net.is_weight(i) {
                    res.push(decay * v);
                }
            }
            res
        };
        let (p, _) =
            odocal_core::lsq::minimize(&f, start.net.to_params().iter().copied().collect(), 100);
        if p.iter().any(|v| !v.is_finite()) {
            continue;
        }
        let mut c = start.clone();
        c.net.set_params(&DVector::from_column_slice(&p));
        let j = cost(&c);
        if best.as_ref().is_none_or(|(b, _)| j < *b) {
            best = Some((j, c));
        }
    }
    best.map(|(_, c)| c).ok_or_else(|| {
        TrainError::Numerical("every initialisation of the path corrector diverged".into())
    })
}
