//! The pose from matched detections, each weighted by its own covariance, and the pose's
//! Cramér–Rao bound.
//!
//! A detection `z` (sensor frame) of landmark `m` (map frame) from pose `(t, θ)` is
//! `z = R(θ)ᵀ (m − t) + e` with `e` of covariance `C` (the detection's, plus the map's
//! isotropic survey variance). In the map frame the residual `R z + t − m` has covariance
//! `R C Rᵀ` and derivative `[I | R' z]` with respect to `(x, y, θ)`, where `R' z` is `R z` turned
//! by 90°. For Gaussian errors the Fisher information of the pose is the sum over the
//! detections of `Jᵀ (R C Rᵀ)⁻¹ J`; its inverse bounds the covariance of any unbiased pose
//! estimate, and the weighted least-squares fit below reaches it (to first order in the noise).

use nalgebra::{Matrix2, Matrix2x3, Matrix3, Point2, Rotation2, Vector2, Vector3};
use odocal_core::{wrap_angle, Pose2};

/// One matched detection.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Observation {
    /// The detection's centre, sensor frame, metres.
    pub sensor: Point2<f64>,
    /// The matched landmark, map frame, metres.
    pub landmark: Point2<f64>,
    /// Covariance of the centre (with the map's survey variance), sensor frame, m².
    pub cov: Matrix2<f64>,
}

/// Residual (map frame), its derivative with respect to (x, y, θ), and its inverse covariance.
fn linearise(
    pose: &Pose2,
    o: &Observation,
) -> Option<(Vector2<f64>, Matrix2x3<f64>, Matrix2<f64>)> {
    let rot = Rotation2::new(pose.theta_rad);
    let rz = rot * o.sensor.coords;
    let r = rz + Vector2::new(pose.x_m, pose.y_m) - o.landmark.coords;
    let j = Matrix2x3::new(1.0, 0.0, -rz.y, 0.0, 1.0, rz.x);
    let rm = rot.matrix();
    let w = (rm * o.cov * rm.transpose()).try_inverse()?;
    Some((r, j, w))
}

/// Fisher information of the pose (x, y, θ) from `obs` at `pose`, in m⁻², m⁻¹ rad⁻¹, rad⁻².
pub(crate) fn pose_information(pose: &Pose2, obs: &[Observation]) -> Option<Matrix3<f64>> {
    let mut info = Matrix3::zeros();
    for o in obs {
        let (_, j, w) = linearise(pose, o)?;
        info += j.transpose() * w * j;
    }
    Some(info)
}

/// The squared Mahalanobis distance of `o`'s residual at `pose` under its own covariance: about
/// 2 (its degrees of freedom) for a right match, far more for a detection matched to the wrong
/// landmark.
pub(crate) fn mahalanobis2(pose: &Pose2, o: &Observation) -> Option<f64> {
    let (r, _, w) = linearise(pose, o)?;
    Some(r.dot(&(w * r)))
}

/// Iterations of the Gauss–Newton fit; from a rigid fit a few millimetres off it converges in
/// two or three.
const MAX_ITERATIONS: usize = 8;

/// The weighted least-squares pose from `guess` (Gauss–Newton) and its covariance, the
/// inverse Fisher information at the solution. None when the geometry does not fix the pose.
pub(crate) fn fit_pose_weighted(
    guess: Pose2,
    obs: &[Observation],
) -> Option<(Pose2, Matrix3<f64>)> {
    if obs.len() < 2 {
        return None;
    }
    let mut pose = guess;
    for _ in 0..MAX_ITERATIONS {
        let mut h = Matrix3::zeros();
        let mut g = Vector3::zeros();
        for o in obs {
            let (r, j, w) = linearise(&pose, o)?;
            h += j.transpose() * w * j;
            g += j.transpose() * w * r;
        }
        let step = h.cholesky()?.solve(&g);
        pose = Pose2::new(
            pose.x_m - step.x,
            pose.y_m - step.y,
            wrap_angle(pose.theta_rad - step.z),
        );
        if step.x.hypot(step.y) < 1e-9 && step.z.abs() < 1e-9 {
            break;
        }
    }
    let cov = pose_information(&pose, obs)?.try_inverse()?;
    Some((pose, cov))
}

/// How far the pose fitted from `obs` at `pose` (x, y, θ; m, m, rad) moves when the landmark of
/// observation `i` lies `offsets[i]` (map frame, metres) from where the map puts it: to first
/// order, the information-weighted mean of the offsets' pulls. The pose a moved landmark
/// pulled, kept because too few others are left to fit it again, is off by about this much.
pub(crate) fn pose_shift(
    pose: &Pose2,
    obs: &[Observation],
    offsets: &[Vector2<f64>],
) -> Option<Vector3<f64>> {
    let mut g = Vector3::zeros();
    for (o, d) in obs.iter().zip(offsets) {
        let (_, j, w) = linearise(pose, o)?;
        g += j.transpose() * w * d;
    }
    Some(pose_information(pose, obs)?.cholesky()?.solve(&g))
}

#[cfg(test)]
mod tests {
    use super::*;
    use odocal_core::fit_rigid;

    /// A small deterministic generator (xorshift64*) and Box–Muller normals, so the test
    /// needs no random-number crate.
    struct Rng(u64);
    impl Rng {
        fn uniform(&mut self) -> f64 {
            self.0 ^= self.0 >> 12;
            self.0 ^= self.0 << 25;
            self.0 ^= self.0 >> 27;
            ((self.0.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 11) as f64 + 0.5) / (1u64 << 53) as f64
        }
        fn normal(&mut self) -> f64 {
            let (u1, u2) = (self.uniform(), self.uniform());
            (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
        }
    }

    /// Four landmarks, unequal and anisotropic noise (radial and tangential sigmas per
    /// detection): the geometry of a scan, small enough to check by hand.
    fn scene() -> (Pose2, Vec<(Point2<f64>, f64, f64)>) {
        let truth = Pose2::new(1.0, 2.0, 0.7);
        let lms = vec![
            (Point2::new(4.0, 2.5), 0.004, 0.012),
            (Point2::new(2.0, 5.0), 0.010, 0.003),
            (Point2::new(-1.0, 3.0), 0.006, 0.006),
            (Point2::new(0.5, -1.0), 0.012, 0.002),
        ];
        (truth, lms)
    }

    fn sensor_cov(z: &Point2<f64>, s_rad: f64, s_tan: f64) -> Matrix2<f64> {
        let u = z.coords / z.coords.norm();
        let v = Vector2::new(-u.y, u.x);
        u * u.transpose() * s_rad * s_rad + v * v.transpose() * s_tan * s_tan
    }

    /// The bound computed independently: the information of the measurement model in the
    /// sensor frame, `z = h(pose) = R(θ)ᵀ (m − t)`, with its Jacobian by central differences.
    fn information_by_differences(truth: &Pose2, lms: &[(Point2<f64>, f64, f64)]) -> Matrix3<f64> {
        let h = |p: &Pose2, m: &Point2<f64>| p.isometry().inverse() * m;
        let mut info = Matrix3::zeros();
        for (m, sr, st) in lms {
            let z = h(truth, m);
            let mut jac = Matrix2x3::zeros();
            for k in 0..3 {
                let e = 1e-6;
                let mut d = [0.0; 3];
                d[k] = e;
                let plus = Pose2::new(truth.x_m + d[0], truth.y_m + d[1], truth.theta_rad + d[2]);
                let minus = Pose2::new(truth.x_m - d[0], truth.y_m - d[1], truth.theta_rad - d[2]);
                jac.set_column(k, &((h(&plus, m) - h(&minus, m)) / (2.0 * e)));
            }
            let c = sensor_cov(&z, *sr, *st);
            info += jac.transpose() * c.try_inverse().expect("invertible") * jac;
        }
        info
    }

    #[test]
    fn information_matches_the_measurement_model() {
        let (truth, lms) = scene();
        let obs: Vec<Observation> = lms
            .iter()
            .map(|(m, sr, st)| {
                let z = truth.isometry().inverse() * m;
                Observation {
                    sensor: z,
                    landmark: *m,
                    cov: sensor_cov(&z, *sr, *st),
                }
            })
            .collect();
        let a = pose_information(&truth, &obs).expect("information");
        let b = information_by_differences(&truth, &lms);
        assert!((a - b).norm() < 1e-4 * b.norm(), "{a} vs {b}");
    }

    /// Monte Carlo: with Gaussian detections of the stated covariances, the sample covariance
    /// of the weighted fit equals the bound (it is efficient), and the unweighted rigid fit's
    /// is larger.
    #[test]
    fn weighted_fit_reaches_the_bound() {
        let (truth, lms) = scene();
        let bound = information_by_differences(&truth, &lms)
            .try_inverse()
            .expect("invertible");
        let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
        let trials = 20_000;
        let (mut sw, mut sr) = (Matrix3::zeros(), Matrix3::zeros());
        for _ in 0..trials {
            let obs: Vec<Observation> = lms
                .iter()
                .map(|(m, s_rad, s_tan)| {
                    let z0 = truth.isometry().inverse() * m;
                    let u = z0.coords / z0.coords.norm();
                    let v = Vector2::new(-u.y, u.x);
                    let z = z0 + u * (s_rad * rng.normal()) + v * (s_tan * rng.normal());
                    Observation {
                        sensor: z,
                        landmark: *m,
                        cov: sensor_cov(&z, *s_rad, *s_tan),
                    }
                })
                .collect();
            let src: Vec<Point2<f64>> = obs.iter().map(|o| o.sensor).collect();
            let dst: Vec<Point2<f64>> = obs.iter().map(|o| o.landmark).collect();
            let rigid = fit_rigid(&src, &dst).expect("rigid fit").pose;
            let (w, _) = fit_pose_weighted(rigid, &obs).expect("weighted fit");
            let err = |p: &Pose2| {
                Vector3::new(
                    p.x_m - truth.x_m,
                    p.y_m - truth.y_m,
                    wrap_angle(p.theta_rad - truth.theta_rad),
                )
            };
            sw += err(&w) * err(&w).transpose();
            sr += err(&rigid) * err(&rigid).transpose();
        }
        sw /= trials as f64;
        sr /= trials as f64;
        // Each variance within 4 % of the bound (its sampling error is about 1 %).
        for k in 0..3 {
            let ratio = sw[(k, k)] / bound[(k, k)];
            assert!(
                (0.96..1.04).contains(&ratio),
                "variance {k}: {ratio} of the bound"
            );
        }
        let pos = |m: &Matrix3<f64>| m[(0, 0)] + m[(1, 1)];
        assert!(
            pos(&sr) > 1.2 * pos(&bound),
            "the rigid fit is not efficient here"
        );
    }
}
