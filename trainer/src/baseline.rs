//! Baselines on the same folds as the perceptron: raw odometry, a UMBMark-style
//! kinematic calibration fitted by least squares, and linear regression on the 18 inputs.

use levenberg_marquardt::{LeastSquaresProblem, LevenbergMarquardt};
use nalgebra::DMatrix;
use nalgebra::{Dyn, Owned};

type LmVector = nalgebra::DVector<f64>;
type LmMatrix = nalgebra::DMatrix<f64>;
use odocal_dataset::{RobotParams, Sample, WheelGeometry};
use serde::{Deserialize, Serialize};

use crate::data::odometry_polyline;
use crate::error::TrainError;
use crate::net::Normalisation;

/// Raw odometry's end point (no correction).
pub fn raw_predict(s: &Sample) -> [f64; 2] {
    s.raw_end_m
}

/// Multipliers of a ROS `diff_drive_controller` (`left_wheel_radius_multiplier`, ...).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct RosMultipliers {
    /// `left_wheel_radius_multiplier`: true / nominal left wheel radius.
    pub left_wheel_radius_multiplier: f64,
    /// `right_wheel_radius_multiplier`: true / nominal right wheel radius.
    pub right_wheel_radius_multiplier: f64,
    /// `wheel_separation_multiplier`: effective / nominal wheel base.
    pub wheel_separation_multiplier: f64,
}

/// A UMBMark-style kinematic calibration of a differential drive (counter-clockwise positive
/// rotation, d_rot = (v_r - v_l) / b): effective left/right wheel radius multipliers c_l, c_r
/// and wheel-base multiplier c_b, fitted by least squares to the real end points.
///
/// When the samples carry their wheel revolutions (`Sample::odometry`), each run is
/// re-dead-reckoned exactly with the calibrated geometry ("wheel revolutions" model).
/// Otherwise the odometry polyline of the sample (start, 8 intermediate points, raw end) is
/// re-integrated ("odometry polyline" model): with scale s = (c_l + c_r)/2 and
/// delta = (c_r - c_l)/2, a step with odometry translation d and rotation w really moves
/// d' ~= s d and turns w' = kappa d + g w, kappa = 2 delta / (c_b b), g = s / c_b; segment k
/// of length d_k and chord heading phi_k becomes length s d_k and heading g phi_k + kappa D_k
/// (D_k = distance to the segment's middle; the small term delta w b / 2 is neglected).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct KinematicCalibration {
    /// Which model was fitted: true for exact re-dead-reckoning of wheel revolutions.
    pub from_wheel_revolutions: bool,
    /// Translation scale s = mean wheel-radius multiplier.
    pub scale: f64,
    /// Systematic curvature kappa, rad per metre of travel (counter-clockwise positive).
    pub curvature_rad_per_m: f64,
    /// Rotation gain g = s / c_b.
    pub rotation_gain: f64,
    /// Effective wheel-diameter ratio E_d = D_right / D_left.
    pub wheel_diameter_ratio: f64,
    /// Multipliers of the nominal robot (ROS diff_drive_controller parameters).
    pub ros: RosMultipliers,
    /// The nominal robot the multipliers apply to.
    pub robot: RobotParams,
}

/// Weight of the prior "the nominal wheel base is right", metres of end-point residual per
/// unit of the wheel-separation multiplier.
///
/// Straight runs see the wheel base only through the heading changes of the two wheels'
/// count differences, which at 12 counts/rev are mostly quantisation: left free, the fit
/// widens the wheel base several-fold to damp them, a multiplier that would make a ROS
/// controller's turns wrong by as much. With this prior a 1 % change costs as much as a
/// 10 cm end-point error: the curvature goes into the wheel-radius ratio, where straight
/// runs do measure it; the separation multiplier is left for runs with turns to find.
const WHEEL_BASE_PRIOR_M: f64 = 10.0;

/// Range of a calibrated multiplier a real robot can have: worn or soft tyres and the wheels'
/// contact points change diameters and base by percents, not by a factor of 2.
pub const PLAUSIBLE_MULTIPLIER: std::ops::RangeInclusive<f64> = 0.5..=2.0;

/// How far a fitted wheel diameter may be from robot.json's before robot.json is doubted:
/// tyres wear and squash by percents.
const NOMINAL_DIAMETER_SHARE: std::ops::RangeInclusive<f64> = 0.9..=1.1;

/// How far a fitted wheel base may be from robot.json's before robot.json is doubted: the
/// tyres' contact and skid move the effective base outward, up to about half again.
const NOMINAL_BASE_SHARE: std::ops::RangeInclusive<f64> = 0.8..=1.6;

/// A warning when a kinematic fit's effective geometry is unlike robot.json's nominal one by
/// more than wear, tyres and skid explain (diameters off by over 10 %, a base under 0.8 or over
/// 1.6 times): within [`PLAUSIBLE_MULTIPLIER`] the fit absorbs it, but a robot.json measured
/// that badly (or another robot's) misstates the raw odometry every figure is judged against.
/// `base_fitted` is false where the runs hold too few turns to fit a base (straight runs).
pub fn unlike_nominal_warning(
    fitted: &WheelGeometry,
    robot: &RobotParams,
    base_fitted: bool,
) -> Option<String> {
    let mut off = Vec::new();
    for (name, fitted_m, nominal_m, range, field) in [
        (
            "left wheel diameter",
            fitted.left_wheel_diameter_m,
            robot.wheel_diameter_m,
            &NOMINAL_DIAMETER_SHARE,
            "wheel_diameter_m",
        ),
        (
            "right wheel diameter",
            fitted.right_wheel_diameter_m,
            robot.wheel_diameter_m,
            &NOMINAL_DIAMETER_SHARE,
            "wheel_diameter_m",
        ),
        (
            "wheel base",
            fitted.wheel_base_m,
            robot.wheel_base_m,
            &NOMINAL_BASE_SHARE,
            "wheel_base_m",
        ),
    ] {
        if name == "wheel base" && !base_fitted {
            continue;
        }
        let share = fitted_m / nominal_m;
        if !range.contains(&share) {
            off.push(format!(
                "a {name} of {:.2} mm, {:.0} % of robot.json's {field} {:.2} mm",
                1e3 * fitted_m,
                100.0 * share,
                1e3 * nominal_m
            ));
        }
    }
    (!off.is_empty()).then(|| {
        format!(
            "the kinematic fit gives {}: real wheels are within 10 % of their measured diameter and an effective base within 0.8-1.6 times the distance between the wheels' contact points; measure the robot again (or is robot.json another robot's?): the model absorbs the difference, but the raw odometry every figure is judged against is then not this robot's",
            off.join(" and ")
        )
    })
}

/// Numerical Jacobian (central differences) of a residual function of 3 parameters.
fn numeric_jacobian(f: &dyn Fn(&[f64; 3]) -> Vec<f64>, p: &[f64; 3]) -> LmMatrix {
    let m = f(p).len();
    let mut j = LmMatrix::zeros(m, 3);
    for c in 0..3 {
        let h = 1e-6 * (1.0 + p[c].abs());
        let mut a = *p;
        let mut b = *p;
        a[c] += h;
        b[c] -= h;
        let (ra, rb) = (f(&a), f(&b));
        for r in 0..m {
            j[(r, c)] = (ra[r] - rb[r]) / (2.0 * h);
        }
    }
    j
}

/// End point of a sample re-dead-reckoned with multipliers (c_l, c_r, c_b).
fn revs_end(s: &Sample, robot: &RobotParams, c: &[f64; 3]) -> [f64; 2] {
    let g = WheelGeometry {
        left_wheel_diameter_m: robot.wheel_diameter_m * c[0],
        right_wheel_diameter_m: robot.wheel_diameter_m * c[1],
        wheel_base_m: robot.wheel_base_m * c[2],
    };
    s.odometry.end_m(&g)
}

/// Generic 3-parameter least-squares problem for the LM crate.
struct Fit3<'a> {
    f: &'a dyn Fn(&[f64; 3]) -> Vec<f64>,
    p: [f64; 3],
}

impl LeastSquaresProblem<f64, Dyn, Dyn> for Fit3<'_> {
    type ResidualStorage = Owned<f64, Dyn>;
    type JacobianStorage = Owned<f64, Dyn, Dyn>;
    type ParameterStorage = Owned<f64, Dyn>;
    fn set_params(&mut self, x: &LmVector) {
        self.p = [x[0], x[1], x[2]];
    }
    fn params(&self) -> LmVector {
        LmVector::from_row_slice(&self.p)
    }
    fn residuals(&self) -> Option<LmVector> {
        Some(LmVector::from_vec((self.f)(&self.p)))
    }
    fn jacobian(&self) -> Option<LmMatrix> {
        Some(numeric_jacobian(self.f, &self.p))
    }
}

fn minimize3(f: &dyn Fn(&[f64; 3]) -> Vec<f64>, p0: [f64; 3]) -> Result<[f64; 3], TrainError> {
    let (problem, report) = LevenbergMarquardt::new().minimize(Fit3 { f, p: p0 });
    if !report.termination.was_successful() || problem.p.iter().any(|v| !v.is_finite()) {
        return Err(TrainError::Numerical(format!(
            "kinematic calibration did not converge ({:?}); are the dataset's trajectories in metres and its robot parameters right?",
            report.termination
        )));
    }
    Ok(problem.p)
}

/// Segment lengths, chord headings and mid-segment distances of a sample's polyline.
fn segments(s: &Sample) -> [(f64, f64, f64); 9] {
    let p = odometry_polyline(s);
    let mut out = [(0.0, 0.0, 0.0); 9];
    let mut dist = 0.0;
    for k in 0..9 {
        let dx = p[k + 1][0] - p[k][0];
        let dy = p[k + 1][1] - p[k][1];
        let d = dx.hypot(dy);
        let phi = if d > 0.0 { dy.atan2(dx) } else { 0.0 };
        out[k] = (d, phi, dist + d / 2.0);
        dist += d;
    }
    // Headings continuous along the path (no jumps of 2 pi).
    for k in 1..9 {
        let prev = out[k - 1].1;
        out[k].1 = prev + odocal_core::wrap_angle(out[k].1 - prev);
    }
    out
}

/// End point of the re-integrated polyline for (s, kappa, g).
fn kin_end(seg: &[(f64, f64, f64); 9], p: &[f64; 3]) -> [f64; 2] {
    let (s, kappa, g) = (p[0], p[1], p[2]);
    let mut e = [0.0; 2];
    for &(d, phi, dm) in seg {
        let th = g * phi + kappa * dm;
        let (sn, cs) = th.sin_cos();
        e[0] += s * d * cs;
        e[1] += s * d * sn;
    }
    e
}

impl KinematicCalibration {
    fn from_multipliers(c: [f64; 3], robot: &RobotParams, revs: bool) -> Self {
        let (c_l, c_r, c_b) = (c[0], c[1], c[2]);
        let s = 0.5 * (c_l + c_r);
        Self {
            from_wheel_revolutions: revs,
            scale: s,
            curvature_rad_per_m: (c_r - c_l) / (c_b * robot.wheel_base_m),
            rotation_gain: s / c_b,
            wheel_diameter_ratio: c_r / c_l,
            ros: RosMultipliers {
                left_wheel_radius_multiplier: c_l,
                right_wheel_radius_multiplier: c_r,
                wheel_separation_multiplier: c_b,
            },
            robot: *robot,
        }
    }

    fn from_polyline_params(p: [f64; 3], robot: &RobotParams) -> Self {
        let (s, kappa, g) = (p[0], p[1], p[2]);
        let c_b = if g.abs() > 1e-9 { s / g } else { 1.0 };
        let delta = kappa * c_b * robot.wheel_base_m / 2.0;
        Self::from_multipliers([s - delta, s + delta, c_b], robot, false)
    }

    /// Refuses multipliers no real wheel has (outside [`PLAUSIBLE_MULTIPLIER`]): the fit
    /// then followed targets that are not the odometry's motion, and a ROS controller given
    /// them would drive nowhere near where it believes.
    pub fn check_physical(&self) -> Result<(), TrainError> {
        let r = &self.ros;
        let b = &self.robot;
        let (d, base) = (1e3 * b.wheel_diameter_m, 1e3 * b.wheel_base_m);
        for (name, m, what, nominal_mm) in [
            (
                "left wheel radius",
                r.left_wheel_radius_multiplier,
                "left wheel diameter",
                d,
            ),
            (
                "right wheel radius",
                r.right_wheel_radius_multiplier,
                "right wheel diameter",
                d,
            ),
            (
                "wheel separation",
                r.wheel_separation_multiplier,
                "wheel base",
                base,
            ),
        ] {
            if !PLAUSIBLE_MULTIPLIER.contains(&m) {
                return Err(TrainError::Dataset(format!(
                    "the kinematic calibration gives a {name} multiplier of {m:.4} (an effective {what} of {:.3} mm against the nominal {nominal_mm:.3} mm), which no real robot has: the targets do not follow the odometry (a frozen camera track, trajectories in another unit, or logs and trajectories of different runs?); check the dataset's trajectories and rebuild it",
                    m * nominal_mm
                )));
            }
        }
        Ok(())
    }

    /// The identity calibration of `robot`.
    pub fn identity(robot: &RobotParams) -> Self {
        Self::from_multipliers([1.0, 1.0, 1.0], robot, true)
    }

    /// Least-squares fit to the samples' real end points; uses the wheel revolutions when
    /// every sample carries them, the odometry polyline otherwise.
    pub fn fit(samples: &[&Sample], robot: &RobotParams) -> Result<Self, TrainError> {
        if samples.len() < 2 {
            return Err(TrainError::TooFewSamples(
                "kinematic calibration needs at least 2 runs".into(),
            ));
        }
        let revs = samples.iter().all(|s| s.odometry.rev.len() >= 2);
        if revs {
            let f = |c: &[f64; 3]| -> Vec<f64> {
                samples
                    .iter()
                    .flat_map(|s| {
                        let e = revs_end(s, robot, c);
                        [e[0] - s.target_m[0], e[1] - s.target_m[1]]
                    })
                    .chain(std::iter::once(WHEEL_BASE_PRIOR_M * (c[2] - 1.0)))
                    .collect()
            };
            let c = minimize3(&f, [1.0, 1.0, 1.0])?;
            Ok(Self::from_multipliers(c, robot, true))
        } else {
            let segs: Vec<_> = samples.iter().map(|s| segments(s)).collect();
            let f = |p: &[f64; 3]| -> Vec<f64> {
                segs.iter()
                    .zip(samples)
                    .flat_map(|(seg, s)| {
                        let e = kin_end(seg, p);
                        [e[0] - s.target_m[0], e[1] - s.target_m[1]]
                    })
                    .collect()
            };
            let p = minimize3(&f, [1.0, 0.0, 1.0])?;
            Ok(Self::from_polyline_params(p, robot))
        }
    }

    /// Corrected end point of a sample.
    pub fn predict(&self, s: &Sample) -> [f64; 2] {
        if self.from_wheel_revolutions && s.odometry.rev.len() >= 2 {
            let r = &self.ros;
            revs_end(
                s,
                &self.robot,
                &[
                    r.left_wheel_radius_multiplier,
                    r.right_wheel_radius_multiplier,
                    r.wheel_separation_multiplier,
                ],
            )
        } else {
            kin_end(
                &segments(s),
                &[self.scale, self.curvature_rad_per_m, self.rotation_gain],
            )
        }
    }
}

/// Ridge-stabilised linear regression of the end point on the normalised 18 inputs.
#[derive(Debug, Clone, PartialEq)]
pub struct LinearRegression {
    norm: Normalisation,
    /// (1 + n_inputs) x 2 coefficients: intercept first.
    coef: DMatrix<f64>,
}

impl LinearRegression {
    /// Least-squares fit (with a tiny ridge for collinear inputs).
    pub fn fit(samples: &[&Sample]) -> Result<Self, TrainError> {
        let rows: Vec<&[f64]> = samples.iter().map(|s| s.inputs.as_slice()).collect();
        let norm = Normalisation::fit(&rows);
        let n_in = norm.offset.len();
        if samples.len() < 2 {
            return Err(TrainError::TooFewSamples(
                "linear regression needs at least 2 runs".into(),
            ));
        }
        let x = DMatrix::from_fn(samples.len(), n_in + 1, |r, c| {
            if c == 0 {
                1.0
            } else {
                norm.forward(c - 1, samples[r].inputs[c - 1])
            }
        });
        let y = DMatrix::from_fn(samples.len(), 2, |r, c| samples[r].target_m[c]);
        let mut xtx = x.transpose() * &x;
        for i in 1..=n_in {
            xtx[(i, i)] += 1e-6 * samples.len() as f64;
        }
        let xty = x.transpose() * y;
        let coef = xtx
            .cholesky()
            .ok_or_else(|| {
                TrainError::Numerical("linear regression normal equations singular".into())
            })?
            .solve(&xty);
        Ok(Self { norm, coef })
    }

    /// Predicted end point for one sample.
    pub fn predict(&self, s: &Sample) -> [f64; 2] {
        let mut out = [self.coef[(0, 0)], self.coef[(0, 1)]];
        for (c, v) in s.inputs.iter().enumerate() {
            let xn = self.norm.forward(c, *v);
            out[0] += self.coef[(c + 1, 0)] * xn;
            out[1] += self.coef[(c + 1, 1)] * xn;
        }
        out
    }
}
