//! Borenstein's UMBMark (University of Michigan Benchmark): a square driven several times
//! clockwise and counter-clockwise; the centres of gravity of each direction's return-position
//! errors measure the systematic odometry error (E_max,syst), and their combination gives the
//! classic correction of the two dominant systematic errors, the wheel-diameter ratio E_d and
//! the wheel-base factor E_b (Borenstein and Feng, 1996).
//!
//! Errors here are "true minus computed" return positions in the square's start frame (x along
//! the first side, y to its left), as in the paper; its α and β formulas hold unchanged (a unit
//! test recovers known diameters and base from noise-free squares).

use odocal_dataset::{RobotParams, WheelGeometry};
use serde::{Deserialize, Serialize};

use crate::error::TrainError;

/// Squares per direction in Borenstein's UMBMark protocol.
pub const PROTOCOL_RUNS_PER_DIRECTION: usize = 5;

/// One return-position error of a square run, metres ("true minus computed", start frame).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SquareError {
    /// Driven clockwise.
    pub clockwise: bool,
    /// Error [x, y], metres.
    pub error_m: [f64; 2],
}

/// The centres of gravity of the clockwise and counter-clockwise errors and E_max,syst.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Umbmark {
    /// Centre of gravity of the clockwise errors [x, y], metres.
    pub cg_cw_m: [f64; 2],
    /// Centre of gravity of the counter-clockwise errors [x, y], metres.
    pub cg_ccw_m: [f64; 2],
    /// Distance of the clockwise centre from the origin, metres.
    pub r_cw_m: f64,
    /// Distance of the counter-clockwise centre from the origin, metres.
    pub r_ccw_m: f64,
    /// Borenstein's measure of systematic error: the larger of the two, metres.
    pub e_max_syst_m: f64,
    /// Runs per direction [cw, ccw].
    pub runs: [usize; 2],
}

impl Umbmark {
    /// The benchmark of square errors; needs at least one run in each direction.
    pub fn of(errors: &[SquareError]) -> Result<Self, TrainError> {
        let cg = |cw: bool| {
            let v: Vec<[f64; 2]> = errors
                .iter()
                .filter(|e| e.clockwise == cw)
                .map(|e| e.error_m)
                .collect();
            let n = v.len();
            let s = v.iter().fold([0.0, 0.0], |a, e| [a[0] + e[0], a[1] + e[1]]);
            (n, [s[0] / n.max(1) as f64, s[1] / n.max(1) as f64])
        };
        let (n_cw, cg_cw_m) = cg(true);
        let (n_ccw, cg_ccw_m) = cg(false);
        if n_cw == 0 || n_ccw == 0 {
            return Err(TrainError::Dataset(format!(
                "UMBMark needs squares in both directions ({n_cw} clockwise, {n_ccw} counter-clockwise)"
            )));
        }
        let r_cw_m = cg_cw_m[0].hypot(cg_cw_m[1]);
        let r_ccw_m = cg_ccw_m[0].hypot(cg_ccw_m[1]);
        Ok(Self {
            cg_cw_m,
            cg_ccw_m,
            r_cw_m,
            r_ccw_m,
            e_max_syst_m: r_cw_m.max(r_ccw_m),
            runs: [n_cw, n_ccw],
        })
    }

    /// A warning when either direction has fewer squares than Borenstein's protocol drives:
    /// a centre of gravity of one or two squares is mostly their random error (the start's
    /// placement, slip on a corner), not the systematic error E_max,syst and the correction
    /// claim to measure.
    pub fn few_squares_warning(&self, what: &str) -> Option<String> {
        let [cw, ccw] = self.runs;
        (cw.min(ccw) < PROTOCOL_RUNS_PER_DIRECTION).then(|| {
            format!(
                "warning: {what} rests on {cw} clockwise and {ccw} counter-clockwise squares, where Borenstein's protocol drives {PROTOCOL_RUNS_PER_DIRECTION} each way: with fewer, each direction's centre of gravity carries the squares' random error (start placement, slip) as if it were systematic; drive more squares"
            )
        })
    }

    /// Borenstein's correction from squares of side `side_m` driven by `robot`: the wheel
    /// diameter ratio E_d = D_R / D_L and the wheel-base factor E_b, and the wheel geometry
    /// they give (the mean diameter kept nominal).
    pub fn correction(&self, side_m: f64, robot: &RobotParams) -> UmbmarkCorrection {
        let l = side_m;
        let b = robot.wheel_base_m;
        // Type A (wheel base) turns every corner too far or too short in both directions; it
        // shows in the sum of the x centres; type B (diameters) curves every side the same
        // way, showing in their difference.
        let alpha = (self.cg_cw_m[0] + self.cg_ccw_m[0]) / (-4.0 * l);
        let beta = (self.cg_cw_m[0] - self.cg_ccw_m[0]) / (-4.0 * l);
        let r = (0.5 * l) / (0.5 * beta).sin();
        let e_d = if beta.abs() < 1e-12 {
            1.0
        } else {
            (r + 0.5 * b) / (r - 0.5 * b)
        };
        let e_b = std::f64::consts::FRAC_PI_2 / (std::f64::consts::FRAC_PI_2 - alpha);
        let d = robot.wheel_diameter_m;
        UmbmarkCorrection {
            alpha_rad: alpha,
            beta_rad: beta,
            e_d,
            e_b,
            geometry: WheelGeometry {
                left_wheel_diameter_m: 2.0 / (e_d + 1.0) * d,
                right_wheel_diameter_m: 2.0 / (1.0 / e_d + 1.0) * d,
                wheel_base_m: e_b * b,
            },
        }
    }
}

/// Borenstein's correction of the two dominant systematic errors.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct UmbmarkCorrection {
    /// Type A error angle (wheel base), radians.
    pub alpha_rad: f64,
    /// Type B error angle (wheel diameters), radians.
    pub beta_rad: f64,
    /// Wheel diameter ratio D_R / D_L.
    pub e_d: f64,
    /// Wheel base factor: effective base / nominal base.
    pub e_b: f64,
    /// The corrected geometry.
    pub geometry: WheelGeometry,
}

#[cfg(test)]
mod tests {
    use super::*;
    use odocal_core::Pose2;
    use odocal_dataset::kinematics::step;

    /// The true return point of a square whose odometry closed exactly, on a robot of
    /// geometry `g` (odometry nominal): the wheel travels of the nominal square, driven truly.
    fn true_return(robot: &RobotParams, g: &WheelGeometry, side: f64, cw: bool) -> [f64; 2] {
        let d = robot.wheel_diameter_m;
        let b = robot.wheel_base_m;
        let turn = if cw { -1.0 } else { 1.0 } * std::f64::consts::FRAC_PI_2;
        let mut p = Pose2::default();
        let n = 400;
        for _ in 0..4 {
            for _ in 0..n {
                let s = side / n as f64;
                p = step(
                    &p,
                    s * g.left_wheel_diameter_m / d,
                    s * g.right_wheel_diameter_m / d,
                    g.wheel_base_m,
                );
            }
            for _ in 0..n {
                let s = 0.5 * b * turn / n as f64;
                p = step(
                    &p,
                    -s * g.left_wheel_diameter_m / d,
                    s * g.right_wheel_diameter_m / d,
                    g.wheel_base_m,
                );
            }
        }
        [p.x_m, p.y_m]
    }

    #[test]
    fn borenstein_recovers_the_diameter_ratio_and_the_base() {
        let robot = RobotParams::default();
        let side = 1.0;
        // Small errors, where Borenstein's linearisation holds.
        let truth = WheelGeometry {
            left_wheel_diameter_m: 0.043 * (1.0 - 0.0008),
            right_wheel_diameter_m: 0.043 * (1.0 + 0.0008),
            wheel_base_m: 0.10 * 1.006,
        };
        let errors: Vec<SquareError> = [true, false]
            .iter()
            .map(|&cw| SquareError {
                clockwise: cw,
                error_m: true_return(&robot, &truth, side, cw),
            })
            .collect();
        let u = Umbmark::of(&errors).unwrap();
        // One square each way is named as short of the protocol; five each way are not.
        let w = u.few_squares_warning("E").unwrap_or_default();
        assert!(
            w.contains("E rests on 1 clockwise and 1 counter-clockwise squares"),
            "{w}"
        );
        let protocol: Vec<SquareError> = errors.iter().cycle().take(10).copied().collect();
        let five = Umbmark::of(&protocol).unwrap();
        assert_eq!((five.runs, five.few_squares_warning("E")), ([5, 5], None));
        let c = u.correction(side, &robot);
        let e_d_true = truth.right_wheel_diameter_m / truth.left_wheel_diameter_m;
        assert!((c.e_d - e_d_true).abs() < 1e-4, "{c:?} vs E_d {e_d_true}");
        assert!((c.e_b - 1.006).abs() < 5e-4, "{c:?}");
        assert!(u.e_max_syst_m > 0.01, "{u:?}");
        // Driving with the corrected geometry shrinks the errors at least tenfold.
        let after: Vec<SquareError> = [true, false]
            .iter()
            .map(|&cw| {
                let g = WheelGeometry {
                    left_wheel_diameter_m: 0.043 * truth.left_wheel_diameter_m
                        / c.geometry.left_wheel_diameter_m,
                    right_wheel_diameter_m: 0.043 * truth.right_wheel_diameter_m
                        / c.geometry.right_wheel_diameter_m,
                    wheel_base_m: 0.10 * truth.wheel_base_m / c.geometry.wheel_base_m,
                };
                SquareError {
                    clockwise: cw,
                    error_m: true_return(&robot, &g, side, cw),
                }
            })
            .collect();
        let u2 = Umbmark::of(&after).unwrap();
        assert!(u2.e_max_syst_m < 0.1 * u.e_max_syst_m, "{u2:?} vs {u:?}");
    }
}
